"""Figures, a CSV and a JSON file reproducing the supplementary's analysis.

``write_figures(outdir)`` writes one PNG per analysis, ``closed_forms.csv`` and
``rates.json``; ``quick=True`` uses small grids (a few seconds, for the test suite).  Every
file is written atomically: to a temporary file in the same folder, then ``os.replace``;
the files replace the previous ones all or nothing (:func:`dopplertof.io.output_folder`).

Figures are drawn with matplotlib's object-oriented API on an Agg canvas created here, so
they work headless and never change the global (pyplot) backend of the caller.
"""

from __future__ import annotations

import csv
import io
import json
import pathlib

import numpy as np

from .. import modulation
from ..io import check_output_folder, output_folder
from . import antithetic, doppler, mis, waveforms
from .figure_common import (CSV_COLUMNS, DELTA_PULSE_WIDTH, FIGURE_FILES, PI, Settings,
                            new_figure, write_figure, write_text)
from .figures_variance import (closed_form_omegas, convergence_rates, figure_closed_forms,
                               figure_convergence, figure_higher_frequency,
                               figure_mirrored_stratified, figure_shift_variance,
                               figure_truncated, figure_two_shifts, figure_variance_ratio)



# --------------------------------------------------------------------------- Sec. 1

def figure_doppler(settings: Settings, f_g: float = 30e6):
    omega_g = 2.0 * PI * f_g
    speeds = np.logspace(-1, 7.5, settings.speeds)
    geometric = doppler.geometric_doppler_shift(omega_g, speeds) / (2 * PI)
    photon = doppler.photon_doppler_shift(omega_g, speeds) / (2 * PI)
    difference = doppler.doppler_shift_difference(omega_g, speeds) / (2 * PI)
    # the photon path by root finding, where float64 resolves the O(v^2/c^2) difference
    probe = np.logspace(3, 7.5, 7)
    photon_numeric = np.array([doppler.doppler_shift_from_delay(doppler.photon_delay, omega_g, v)
                               for v in probe]) / (2 * PI)
    geometric_numeric = np.array([doppler.doppler_shift_from_delay(doppler.geometric_delay,
                                                                   omega_g, v)
                                  for v in probe]) / (2 * PI)

    figure = new_figure(settings, 11, 4.4)
    left, right = figure.subplots(1, 2)
    left.loglog(speeds, geometric, color="tab:blue", label="geometric path, Eq. (3): 2 f_g v / c")
    left.loglog(speeds, photon, color="tab:orange", linestyle="--",
                label="photon path, Eq. (7): 2 f_g v / (c + v)")
    left.loglog(probe, photon_numeric, "o", color="tab:orange", mfc="none",
                label="photon path, delay solved numerically")
    left.loglog(speeds, difference, color="tab:red", label="difference (geometric − photon)")
    left.loglog(probe, geometric_numeric - photon_numeric, "s", color="tab:red", mfc="none",
                label="difference, numerical")
    left.loglog(speeds, 2 * f_g * (speeds / modulation.SPEED_OF_LIGHT) ** 2, ":", color="k",
                label="2 f_g (v/c)²")
    left.set_xlabel("receding speed v (m/s)")
    left.set_ylabel(f"Doppler shift Δf (Hz) at f_g = {f_g / 1e6:g} MHz")
    left.set_title("Doppler shift: O(v/c); path difference: O(v²/c²)")
    left.legend(fontsize=7.5, loc="lower right")
    left.grid(True, which="major", alpha=0.3)

    relative = difference / geometric
    right.loglog(speeds, relative, color="tab:red")
    for label, v in (("walking 1.5 m/s", 1.5), ("car 30 m/s", 30.0), ("airliner 250 m/s", 250.0)):
        value = float(doppler.doppler_shift_difference(1.0, v)
                      / doppler.geometric_doppler_shift(1.0, v))
        right.plot(v, value, "o", color="k")
        right.annotate(f"{label}: {value:.1e}", (v, value), textcoords="offset points",
                       xytext=(6, -12), fontsize=8)
    right.set_xlabel("receding speed v (m/s)")
    right.set_ylabel("relative error of the geometric shift = v / (c + v)")
    right.set_title("Error of the renderer's geometric-path Doppler shift")
    right.grid(True, which="major", alpha=0.3)
    figure.suptitle("Sec. 1 — camera and light together, surface receding at speed v")
    return figure


# --------------------------------------------------------------------------- Sec. 2

def figure_correlations(settings: Settings):
    phase = np.linspace(0.0, 2 * PI, 721)
    markers = np.linspace(0.0, 2 * PI, 37)
    colors = dict(zip(modulation.WAVEFORMS, ("tab:blue", "tab:orange", "tab:green", "tab:red")))
    figure = new_figure(settings, 11, 5.4)
    left, right = figure.subplots(1, 2)
    for name in modulation.WAVEFORMS:
        label = "trapezoid (sensor only)" if name == "trapezoidal" else name
        left.plot(phase / PI, waveforms.sensor_wave(name, phase), color=colors[name], label=label)
    left.set_xlabel("phase (units of π)")
    left.set_ylabel("sensor waveform s (unit amplitude)")
    left.set_title("Raw sensor waveforms over one period\n"
                   "(illumination: the same waveform; a delta for the trapezoid)")
    left.legend(fontsize=8, loc="upper center", bbox_to_anchor=(0.5, -0.14), ncol=2)
    left.grid(True, alpha=0.3)

    for name in modulation.WAVEFORMS:
        closed = modulation.correlation(name, phase)
        if name == "trapezoidal":  # the delta light as a narrow box pulse of unit mean
            numeric = waveforms.pulse_correlation(markers, DELTA_PULSE_WIDTH)
            label = f"trapezoid sensor × delta light ({DELTA_PULSE_WIDTH:g}-rad pulse)"
        else:
            numeric = waveforms.numeric_correlation(name, markers)
            label = f"{name} × {name}"
        error = np.max(np.abs(numeric - modulation.correlation(name, markers)))
        right.plot(phase / PI, closed, color=colors[name], label=f"{label}: max |Δ| = {error:.0e}")
        right.plot(markers / PI, numeric, "o", color=colors[name], mfc="none", ms=4)
    right.plot([], [], "o", color="k", mfc="none", label="markers: quadrature of raw waveforms")
    right.plot([], [], "-", color="k", label="lines: closed forms used by the renderer")
    right.set_xlabel("θ = ω_d t + ψ + ω_g L / c (units of π)")
    right.set_ylabel("low-pass correlation C(θ)")
    right.set_title("Low-pass correlation of sensor and illumination")
    right.legend(fontsize=7.5, loc="upper center", bbox_to_anchor=(0.5, -0.14), ncol=2)
    right.grid(True, alpha=0.3)
    figure.suptitle("Sec. 2 / Fig. 2 — what each waveform pair correlates to")
    return figure


# --------------------------------------------------------------------------- Sec. 4

def figure_mis(settings: Settings):
    figure = new_figure(settings, 14, 4.4)
    left, middle, right = figure.subplots(1, 3)

    x = np.linspace(0.0, 1.0, 401)
    pdf = mis.linear_pdf(1.2)
    T, J = mis.reciprocal_involution, mis.reciprocal_involution_jacobian
    left.plot(x, mis.primal_weight(pdf, T, J, x), color="tab:blue", label="w(x), Eq. (32)")
    left.plot(x, mis.antithetic_weight(pdf, T, J, x), "--", color="tab:orange",
              label="w_T(T(x)), Eq. (33)")
    left.plot(x, mis.primal_weight(pdf, T, J, x) + mis.primal_weight(pdf, T, J, T(x)), ":",
              color="k", label="w(x) + w(T(x))")
    left.set_xlabel("primal sample x")
    left.set_ylabel("balance weight")
    left.set_title("Primal vs antithetic: T(x) = (1 − x)/(1 + x),\np(x) = 1 + 1.2 (x − 1/2)")
    left.set_ylim(0, 1.1)
    left.legend(fontsize=8)
    left.grid(True, alpha=0.3)

    tilt = 0.25
    grid = np.linspace(-PI, PI, 161)
    points = np.stack(np.meshgrid(grid, grid, indexing="xy"), axis=-1)
    alpha, beta = mis.two_strategy_weights(mis.tilted_pdf(tilt), mis.flip_z, mis.unit_jacobian,
                                           mis.flip_y, mis.unit_jacobian, points)
    image = middle.imshow(alpha + beta, origin="lower", extent=(-1, 1, -1, 1), cmap="coolwarm",
                          vmin=0.0, vmax=2.0)
    figure.colorbar(image, ax=middle, label="α + β (1 would keep the cancellation)")
    middle.set_xlabel("y (units of π)")
    middle.set_ylabel("z (units of π)")
    middle.set_title(f"Two maps T₁ = (y, −z), T₂ = (−y, z),\n"
                     f"p ∝ (1 + {tilt} y)(1 + {tilt} z)")

    tilts = np.linspace(0.0, 0.3, settings.mis_tilts)
    results = [mis.counterexample_variances(t, settings.mis_nodes) for t in tilts]
    right.plot(tilts, [r["independent"][1] for r in results], "o-", color="tab:gray",
               label="3 independent samples of f/p")
    right.plot(tilts, [r["two_strategy_mis"][1] for r in results], "o-", color="tab:red",
               label="MIS of T₁ and T₂, Eq. (36)")
    right.plot(tilts, [r["single_antithetic"][1] for r in results], "o-", color="tab:blue",
               label="one antithetic map T₁ (exactly 0)")
    right.set_xlabel("tilt of the density (0: p(y, z) = p(−y, −z))")
    right.set_ylabel("variance of the estimate of ∫ sin y sin z = 0")
    right.set_title("α + β ≠ 1 brings the variance back")
    right.legend(fontsize=8)
    right.grid(True, alpha=0.3)
    figure.suptitle("Sec. 4 — antithetic sampling with MIS: fine between a sample and its "
                    "antithetic, harmful across two antithetic maps")
    return figure


# --------------------------------------------------------------------------- driver

def write_figures(outdir, quick: bool = False) -> list:
    """Write every figure, ``closed_forms.csv`` and ``rates.json`` into ``outdir``.

    Returns the paths written, figures first.  ``quick=True``: small grids, a few seconds.
    """
    check_output_folder(outdir)  # before any work
    settings = Settings.for_mode(quick)
    rows = antithetic.closed_form_table(closed_form_omegas(settings))
    study, slopes = convergence_rates(settings)
    builders = {
        "doppler_geometric_vs_photon.png": lambda: figure_doppler(settings),
        "waveform_correlations.png": lambda: figure_correlations(settings),
        "antithetic_shift_variance.png": lambda: figure_shift_variance(settings),
        "antithetic_variance_ratio.png": lambda: figure_variance_ratio(settings),
        "truncated_attenuated_variance.png": lambda: figure_truncated(settings),
        "higher_frequency_variance.png": lambda: figure_higher_frequency(settings),
        "two_antithetic_shifts.png": lambda: figure_two_shifts(settings),
        "convergence_rates.png": lambda: figure_convergence(settings, study, slopes),
        "mirrored_stratified_shift.png": lambda: figure_mirrored_stratified(settings),
        "closed_forms.png": lambda: figure_closed_forms(settings, rows),
        "mis_antithetic.png": lambda: figure_mis(settings),
    }
    table = io.StringIO()
    writer = csv.writer(table, lineterminator="\n")
    writer.writerow(CSV_COLUMNS)
    writer.writerows((repr(w), m, repr(c), repr(n)) for w, m, c, n in rows)

    rates = {
        "slopes": slopes,
        "expected_slopes": {"uniform": -1.0, "periodic": -2.0, "stratified": -3.0},
        "fit": f"least squares of log(Var) on log(N) for N >= {settings.fit_from}",
        "sample_counts": list(settings.sample_counts),
        "mean_variance": study,
        "quick": bool(quick),
    }
    # ---- every file, replacing the previous ones all or nothing
    with output_folder(outdir, "figures") as staged:
        for name in FIGURE_FILES:
            write_figure(builders[name](), staged.path(name), settings.dpi)
        write_text(staged.path("closed_forms.csv"), table.getvalue())
        write_text(staged.path("rates.json"), json.dumps(rates, indent=2) + "\n")
    return [pathlib.Path(p) for p in staged.written]
