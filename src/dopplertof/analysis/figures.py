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
import math
import pathlib
from dataclasses import dataclass

import numpy as np

from .. import modulation
from ..io import atomic_path, check_output_folder, output_folder
from ..image_files import fit_figure
from . import antithetic, doppler, mis, waveforms
from .signals import PeriodicWaveform, Sinusoid, TruncatedAttenuatedSinusoid

PI = math.pi

#: file names written by ``write_figures``, in order
FIGURE_FILES = (
    "doppler_geometric_vs_photon.png",
    "waveform_correlations.png",
    "antithetic_shift_variance.png",
    "antithetic_variance_ratio.png",
    "truncated_attenuated_variance.png",
    "higher_frequency_variance.png",
    "two_antithetic_shifts.png",
    "convergence_rates.png",
    "mirrored_stratified_shift.png",
    "closed_forms.png",
    "mis_antithetic.png",
)
DATA_FILES = ("closed_forms.csv", "rates.json")
#: width (rad) of the unit-mean box pulse standing in for the delta illumination in Fig. 2
DELTA_PULSE_WIDTH = 1e-3
CSV_COLUMNS = ("omega", "method", "closed_form", "numeric")

METHOD_LABELS = {
    "uniform": "uniform (1 sample)",
    "stratified": "stratified (2 strata)",
    "antithetic": "shifted antithetic (a = 1/2)",
    "antithetic_mirror": "mirrored antithetic (a = 0)",
    "periodic": "periodic (N antithetic samples)",
}
METHOD_COLORS = {"uniform": "tab:gray", "stratified": "tab:green", "antithetic": "tab:blue",
                 "antithetic_mirror": "tab:orange", "periodic": "tab:blue"}


@dataclass(frozen=True)
class Settings:
    """Grid sizes; ``Settings.for_mode(quick)`` picks the full or the quick set."""

    shifts: int                # points on the shift axis a in [0, 1]
    ratio_grid: int            # omega x theta grid of Fig. 4
    truncated_omegas: int      # omegas of the Eq. (26) expectation
    truncated_shifts: int
    truncated_draws: int       # Monte Carlo draws of the Eq. (26) parameters
    two_shift_grid: int        # a x b grid of Fig. 7
    sample_counts: tuple       # N of Fig. 8
    fit_from: int              # smallest N in the slope fit
    omega_nodes: int           # Gauss-Legendre nodes over omega in Fig. 8
    thetas: int                # equispaced theta points for averages over theta
    closed_form_omegas: int    # rows per method in closed_forms.csv
    mis_tilts: int
    mis_nodes: int             # quadrature nodes per axis for Sec. 4.2
    speeds: int
    dpi: int
    layout: object             # matplotlib layout engine; None (fixed margins) is ~2x faster

    @staticmethod
    def for_mode(quick: bool) -> "Settings":
        if quick:
            return Settings(shifts=41, ratio_grid=61, truncated_omegas=4, truncated_shifts=21,
                            truncated_draws=64, two_shift_grid=31,
                            sample_counts=(1, 2, 4, 8, 16), fit_from=4, omega_nodes=12,
                            thetas=8, closed_form_omegas=8, mis_tilts=5, mis_nodes=24,
                            speeds=25, dpi=60, layout=None)
        return Settings(shifts=201, ratio_grid=241, truncated_omegas=16, truncated_shifts=51,
                        truncated_draws=512, two_shift_grid=101,
                        sample_counts=(1, 2, 3, 4, 6, 8, 12, 16, 24, 32, 48, 64), fit_from=4,
                        omega_nodes=24, thetas=16, closed_form_omegas=64, mis_tilts=13,
                        mis_nodes=48, speeds=121, dpi=110, layout="constrained")


# --------------------------------------------------------------------------- writing

def _new_figure(settings, width, height):
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    figure = Figure(figsize=(width, height), layout=settings.layout)
    if settings.layout is None:
        figure.subplots_adjust(left=0.07, right=0.97, bottom=0.1, top=0.84, wspace=0.3,
                               hspace=0.45)
    FigureCanvasAgg(figure)
    return figure


def _write_atomically(path: pathlib.Path, write):
    """Call ``write(temporary_path)``, then move the result onto ``path`` in one step
    (the package's one atomic writer, :func:`dopplertof.io.atomic_path`)."""
    with atomic_path(path) as temporary:
        write(temporary)
    return path


def _save_figure(figure, path: pathlib.Path, dpi: int):
    """``figure`` fitted to what it draws (:func:`dopplertof.image_files.fit_figure`: no title,
    label or legend past an edge), saved atomically as PNG."""
    figure.set_dpi(dpi)  # (measured at the resolution it is saved at: text sizes round)
    fit_figure(figure)
    return _write_atomically(path, lambda tmp: figure.savefig(tmp, format="png", dpi=dpi))


def _save_text(path: pathlib.Path, text: str):
    def write(tmp):
        with open(tmp, "w", encoding="utf-8", newline="") as stream:
            stream.write(text)

    return _write_atomically(path, write)


def _centered_extent(x, y):
    """imshow extent that puts pixel centres on the sample grids x and y (uniform)."""
    half_x, half_y = 0.5 * (x[1] - x[0]), 0.5 * (y[1] - y[0])
    return (x[0] - half_x, x[-1] + half_x, y[0] - half_y, y[-1] + half_y)


def _shift_legend_handles(omegas, colors, thetas, styles):
    from matplotlib.lines import Line2D

    handles = [Line2D([], [], color=c, label=f"ω = {w / PI:.2g}π") for w, c in zip(omegas, colors)]
    handles += [Line2D([], [], color="k", linestyle=s, label=f"θ = {t / PI:.2g}π")
                for t, s in zip(thetas, styles)]
    return handles


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

    figure = _new_figure(settings, 11, 4.4)
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
    figure = _new_figure(settings, 11, 5.4)
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


# --------------------------------------------------------------------------- Sec. 3.1

SHIFT_OMEGAS = (0.5 * PI, PI, 1.5 * PI, 1.9 * PI)
SHIFT_THETAS = (0.0, 0.8 * PI)


def shift_variance_curves(name, shifts, omegas=SHIFT_OMEGAS, thetas=SHIFT_THETAS):
    """Var(omega, theta, a) of the shifted antithetic pair for a waveform: (omega, theta, a)."""
    signal = PeriodicWaveform(name, np.asarray(omegas)[:, None, None],
                              np.asarray(thetas)[None, :, None])
    return antithetic.antithetic_variance(signal, np.asarray(shifts)[None, None, :])


def figure_shift_variance(settings: Settings):
    shifts = np.linspace(0.0, 1.0, settings.shifts)
    colors = ("tab:blue", "tab:orange", "tab:green", "tab:red")
    styles = ("-", "--")
    figure = _new_figure(settings, 11, 7.5)
    axes = figure.subplots(2, 2).ravel()
    for axis, name in zip(axes, modulation.WAVEFORMS):
        variance = shift_variance_curves(name, shifts)
        for i, color in enumerate(colors):
            for j, style in enumerate(styles):
                axis.plot(shifts, variance[i, j], color=color, linestyle=style)
        axis.axvline(0.5, color="k", linewidth=0.8, alpha=0.5)
        title = "trapezoid" if name == "trapezoidal" else name
        axis.set_title(f"{title} signal x(t) = W(ω(t − 1/2) + θ)")
        axis.set_xlabel("antithetic shift a (fraction of the exposure)")
        axis.set_ylabel("Var(ω, θ, a), Eq. (12)")
        axis.grid(True, alpha=0.3)
    axes[0].legend(handles=_shift_legend_handles(SHIFT_OMEGAS, colors, SHIFT_THETAS, styles),
                   fontsize=8, loc="upper center", ncol=2)
    figure.suptitle("Sec. 3.1 / Fig. 3 — shifted antithetic sampling t₁ = frac(t₀ + a): "
                    "symmetric about a = 1/2, minimal there for 0 < ω < 2π")
    return figure


# --------------------------------------------------------------------------- Sec. 3.2

def figure_variance_ratio(settings: Settings):
    # from 0.02: below ~1e-2 the closed form loses digits to cancellation (Var ~ omega^4)
    omega = np.linspace(0.02, 2 * PI, settings.ratio_grid)
    theta = np.linspace(0.0, 2 * PI, settings.ratio_grid)
    variance = antithetic.antithetic_variance_closed_form(omega[None, :], theta[:, None], 0.5)
    ratio = antithetic.variance_ratio(omega[None, :], theta[:, None])
    figure = _new_figure(settings, 11, 4.6)
    left, right = figure.subplots(1, 2)
    extent = _centered_extent(omega / PI, theta / PI)
    image = left.imshow(variance, origin="lower", extent=extent, aspect="auto", cmap="viridis")
    figure.colorbar(image, ax=left, label="Var(ω, θ, 1/2)")
    left.set_title("Variance of the antithetic pair, a = 1/2 (Eq. 24)")
    image = right.imshow(ratio, origin="lower", extent=extent, aspect="auto", cmap="magma",
                         vmin=0.0, vmax=0.5)
    contours = right.contour(omega / PI, theta / PI, ratio, levels=[0.05, 0.1, 0.2, 0.3, 0.4],
                             colors="w", linewidths=0.7)
    right.clabel(contours, fontsize=7)
    figure.colorbar(image, ax=right, label="Var(ω, θ, 1/2) / (½ Var(ω, θ, 0))")
    right.set_title(f"Ratio to two independent uniform samples (Eq. 25): "
                    f"max {ratio.max():.3f}")
    for axis in (left, right):
        axis.set_xlabel("frequency ω over the exposure (units of π)")
        axis.set_ylabel("mid-exposure phase θ (units of π)")
    figure.suptitle("Sec. 3.2 / Fig. 4 — the antithetic pair at least halves the variance; "
                    "ratio → 1/2 as ω → 0, = 0 at ω = 2π")
    return figure


# --------------------------------------------------------------------------- Sec. 3.3

def figure_truncated(settings: Settings):
    shifts = np.linspace(0.0, 1.0, settings.truncated_shifts)
    example = antithetic.find_truncated_counterexample(omega=PI)
    fine_shifts = np.linspace(0.0, 1.0, settings.shifts)
    keys = ("phi1", "phi2", "l1", "l2", "v1", "v2", "t_d")
    signal = TruncatedAttenuatedSinusoid(example["omega"], *(example[k] for k in keys))
    omegas = np.linspace(3 * PI / settings.truncated_omegas, 3 * PI, settings.truncated_omegas)
    expected = antithetic.expected_truncated_variance(omegas, shifts, settings.truncated_draws)

    figure = _new_figure(settings, 14, 4.4)
    left, middle, right = figure.subplots(1, 3)
    t = np.linspace(0.0, 1.0, 801)
    left.plot(t, signal(t), color="tab:blue")
    left.axvline(example["t_d"], color="k", linestyle=":", label=f"t_d = {example['t_d']:.3f}")
    left.set_xlabel("time t (fraction of the exposure)")
    left.set_ylabel("x(t), Eq. (26)")
    left.set_title("A truncated, attenuated sinusoid (ω = π, seeded search)")
    left.legend(fontsize=8)
    left.grid(True, alpha=0.3)

    middle.plot(fine_shifts, antithetic.antithetic_variance(signal, fine_shifts), color="tab:blue")
    middle.axvline(0.5, color="k", linewidth=0.8, alpha=0.5)
    middle.set_xlabel("antithetic shift a")
    middle.set_ylabel("Var(a)")
    middle.set_title("For this signal a = 1/2 is a local maximum")
    middle.grid(True, alpha=0.3)

    normalized = expected / expected[:, :1]
    image = right.imshow(normalized, origin="lower", aspect="auto", cmap="viridis",
                         extent=_centered_extent(shifts, omegas / PI))
    right.plot(shifts[np.argmin(expected, axis=1)], omegas / PI, "w.", label="minimum over a")
    right.axhline(2.0, color="w", linestyle="--", linewidth=0.8, label="ω = 2π")
    figure.colorbar(image, ax=right, label="E[Var(a)] / E[Var(0)]")
    right.set_xlabel("antithetic shift a")
    right.set_ylabel("frequency ω (units of π)")
    right.set_title(f"Average over l, v, φ, t_d ({settings.truncated_draws} draws)")
    right.legend(fontsize=8, loc="upper left")
    figure.suptitle("Sec. 3.3 / Fig. 5 — with truncation and 1/r² attenuation a = 1/2 can lose "
                    "for one signal, yet is best on average for ω ≤ 2π")
    return figure


# --------------------------------------------------------------------------- Sec. 3.4

def theta_averaged_shift_variance(omegas, shifts, thetas: int = 16):
    """Mean over theta of Var(omega, theta, a) of the shifted pair, closed form (omega, a)."""
    theta = np.arange(thetas) * (2 * PI / thetas)
    variance = antithetic.antithetic_variance_closed_form(
        np.asarray(omegas)[:, None, None], theta[None, :, None], np.asarray(shifts)[None, None, :])
    return variance.mean(axis=1)


def local_maximum_at_half(omegas, thetas: int = 16, step: float = 1e-3):
    """True where the theta-averaged Var(a) of the shifted pair has a local max at a = 1/2."""
    around = theta_averaged_shift_variance(omegas, [0.5 - step, 0.5, 0.5 + step], thetas)
    return around[:, 1] > np.maximum(around[:, 0], around[:, 2])


def figure_higher_frequency(settings: Settings):
    shifts = np.linspace(0.0, 1.0, settings.shifts)
    omegas = np.linspace(0.05, 8 * PI, 4 * settings.shifts)
    variance = theta_averaged_shift_variance(omegas, shifts, settings.thetas)
    normalized = variance / variance.max(axis=1, keepdims=True)
    local_max = local_maximum_at_half(omegas, settings.thetas)

    figure = _new_figure(settings, 12, 4.8)
    left, right = figure.subplots(1, 2)
    image = left.imshow(normalized, origin="lower", aspect="auto", cmap="viridis",
                        extent=_centered_extent(shifts, omegas / PI))
    figure.colorbar(image, ax=left, label="E_θ[Var(a)] / max over a")
    best = shifts[np.argmin(variance, axis=1)]  # Var(a) = Var(1 - a): mark both minima
    left.plot(np.concatenate([best, 1.0 - best]), np.concatenate([omegas, omegas]) / PI, "w.",
              ms=1.5, label="minimum over a")
    starts = np.flatnonzero(np.diff(local_max.astype(int)) == 1) + 1
    ends = np.flatnonzero(np.diff(local_max.astype(int)) == -1)
    if local_max[-1]:
        ends = np.append(ends, local_max.size - 1)
    for k, (start, end) in enumerate(zip(starts, ends)):
        left.plot([0.5, 0.5], [omegas[start] / PI, omegas[end] / PI], color="r", linewidth=2.5,
                  label="a = 1/2 is a local maximum" if k == 0 else None)
    left.axhline(2.0, color="w", linestyle="--", linewidth=0.8, label="ω = 2π (proof's limit)")
    left.set_xlabel("antithetic shift a")
    left.set_ylabel("frequency ω (units of π)")
    left.set_title("Variance over shift and frequency")
    left.legend(fontsize=8, loc="upper right", markerscale=6)

    for omega, color in zip((1.5 * PI, 3 * PI, 5 * PI, 7 * PI),
                            ("tab:blue", "tab:orange", "tab:green", "tab:red")):
        curve = theta_averaged_shift_variance([omega], shifts, settings.thetas)[0]
        right.plot(shifts, curve, color=color, label=f"ω = {omega / PI:g}π")
    right.axvline(0.5, color="k", linewidth=0.8, alpha=0.5)
    right.set_xlabel("antithetic shift a")
    right.set_ylabel("E_θ[Var(ω, θ, a)]")
    right.set_title("Beyond ω = 2π, a = 1/2 can be a local maximum (3π, 7π)\n"
                    "or a local but not global minimum (5π)")
    right.legend(fontsize=8)
    right.grid(True, alpha=0.3)
    figure.suptitle("Sec. 3.4 / Fig. 6 — shifted antithetic sampling at higher frequencies "
                    "(average over the phase θ)")
    return figure


# --------------------------------------------------------------------------- Sec. 3.5

TWO_SHIFT_CASES = ((PI, 0.0), (1.5 * PI, 0.8 * PI))


def figure_two_shifts(settings: Settings):
    grid = np.linspace(0.0, 1.0, settings.two_shift_grid)
    figure = _new_figure(settings, 11, 4.8)
    axes = figure.subplots(1, 2)
    for axis, (omega, theta) in zip(axes, TWO_SHIFT_CASES):
        variance = antithetic.two_shift_variance(omega, theta, grid, grid)
        image = axis.imshow(variance.T, origin="lower", extent=_centered_extent(grid, grid),
                            cmap="viridis")
        figure.colorbar(image, ax=axis, label="Var of (x(t) + x(t+a) + x(t+b)) / 3")
        best = antithetic.optimal_two_shifts(omega, theta)
        axis.plot(*best, "r*", ms=12, label=f"search optimum ({best[0]:.3f}, {best[1]:.3f})")
        axis.plot(best[1], best[0], "r*", ms=12)
        axis.plot(1 / 3, 2 / 3, "wx", ms=9, label="(1/3, 2/3)")
        axis.set_xlabel("first shift a")
        axis.set_ylabel("second shift b")
        axis.set_title(f"ω = {omega / PI:g}π, θ = {theta / PI:g}π")
        axis.legend(fontsize=8, loc="upper right")
    figure.suptitle("Sec. 3.5 / Fig. 7 — two antithetic shifts: the best pair is equally spaced, "
                    "(1/3, 2/3)")
    return figure


def convergence_rates(settings: Settings):
    """({method: variances}, {method: fitted slope}) for Fig. 8 and rates.json."""
    counts = settings.sample_counts
    study = antithetic.convergence_study(counts, omega_nodes=settings.omega_nodes,
                                         thetas=settings.thetas)
    fitted = [i for i, n in enumerate(counts) if n >= settings.fit_from]
    slopes = {method: antithetic.fit_log_log_slope([counts[i] for i in fitted],
                                                   [values[i] for i in fitted])
              for method, values in study.items()}
    return study, slopes


def figure_convergence(settings: Settings, study, slopes):
    counts = np.asarray(settings.sample_counts, dtype=float)
    figure = _new_figure(settings, 7, 5)
    axis = figure.subplots()
    expected = {"uniform": -1, "periodic": -2, "stratified": -3}
    for method in ("uniform", "periodic", "stratified"):
        values = np.asarray(study[method])
        color = METHOD_COLORS[method]
        axis.loglog(counts, values, "o", color=color)
        fit = counts >= settings.fit_from
        anchor = values[fit][0] * (counts[fit] / counts[fit][0]) ** slopes[method]
        axis.loglog(counts[fit], anchor, "-", color=color,
                    label=f"{METHOD_LABELS[method]}: slope {slopes[method]:.2f} "
                          f"(theory {expected[method]})")
    axis.set_xlabel("samples per estimate N (strata, or equally spaced antithetic samples)")
    axis.set_ylabel("E over ω ~ U[0, 2π], θ ~ U[0, 2π] of Var")
    axis.set_title(f"Fitted log-log slopes for N ≥ {settings.fit_from}")
    axis.legend(fontsize=8)
    axis.grid(True, which="both", alpha=0.3)
    figure.suptitle("Sec. 3.5 / Fig. 8 — convergence: uniform 1/N, periodic 1/N², stratified 1/N³")
    return figure


# --------------------------------------------------------------------------- Sec. 3.6

NINE_THETAS = (0.0, 0.25 * PI, 0.5 * PI, 0.75 * PI)
NINE_OMEGAS = (0.5 * PI, PI, 1.5 * PI, 2 * PI)


def theta_averaged_method_variance(method, omegas, shifts, thetas: int = 16):
    """Mean over theta of Var(omega, theta, a) by quadrature: shape (omega, a)."""
    theta = np.arange(thetas) * (2 * PI / thetas)
    signal = Sinusoid(np.asarray(omegas)[:, None, None], theta[None, :, None])
    return antithetic.method_variance(method, signal, np.asarray(shifts)[None, None, :]).mean(1)


def figure_mirrored_stratified(settings: Settings):
    shifts = np.linspace(0.0, 1.0, settings.shifts)
    colors = ("tab:blue", "tab:orange", "tab:green", "tab:red")
    figure = _new_figure(settings, 11, 7.5)
    axes = figure.subplots(2, 2)
    for column, method in enumerate(("antithetic_mirror", "stratified")):
        name = "mirrored antithetic t₁ = frac(1 − t₀ + a)" if column == 0 else \
            "stratified, strata start at a"
        top, bottom = axes[0, column], axes[1, column]
        signal = Sinusoid(2 * PI, np.asarray(NINE_THETAS)[:, None])
        variance = antithetic.method_variance(method, signal, shifts[None, :])
        for curve, theta, color in zip(variance, NINE_THETAS, colors):
            top.plot(shifts, curve, color=color, label=f"θ = {theta / PI:g}π")
            top.plot(shifts[np.argmin(curve)], curve.min(), "v", color=color)
        top.set_title(f"{name}\nω = 2π: the best a depends on θ (▼ minima)")
        top.set_ylabel("Var(2π, θ, a)")
        top.set_ylim(top=1.3 * variance.max())  # room for the legend
        averaged = theta_averaged_method_variance(method, NINE_OMEGAS, shifts, settings.thetas)
        for curve, omega, color in zip(averaged, NINE_OMEGAS, colors):
            bottom.plot(shifts, curve / curve[0], color=color, label=f"ω = {omega / PI:g}π")
        best = "a = 0 and 1" if column == 0 else "a = 0, 1/2 and 1"
        bottom.set_title(f"averaged over θ: minimal at {best}\nfor ω < 2π (flat at ω = 2π)")
        bottom.set_ylabel("E_θ[Var(a)] / E_θ[Var(0)]")
        top.legend(fontsize=8, loc="upper center", ncol=4)
        bottom.legend(fontsize=8, loc="upper center" if column == 0 else "upper right")
        for axis in (top, bottom):
            axis.set_xlabel("shift a")
            axis.grid(True, alpha=0.3)
    figure.suptitle("Sec. 3.6 / Fig. 9 — mirrored antithetic and stratified sampling have no "
                    "θ-independent best shift; on average a = 0 is best")
    return figure


def closed_form_omegas(settings: Settings):
    count = settings.closed_form_omegas
    return 4 * PI * np.arange(1, count + 1) / count


def figure_closed_forms(settings: Settings, rows):
    omega = np.linspace(0.02, 4 * PI, 600)
    figure = _new_figure(settings, 12, 4.6)
    left, right = figure.subplots(1, 2)
    uniform = antithetic.theta_integrated_variance_closed_form("uniform", omega)
    for method in antithetic.METHODS:
        color = METHOD_COLORS[method]
        closed = antithetic.theta_integrated_variance_closed_form(method, omega)
        left.plot(omega / PI, closed, color=color, label=METHOD_LABELS[method])
        points = [(w, n) for w, m, _, n in rows if m == method]
        left.plot([w / PI for w, _ in points], [n for _, n in points], "o", color=color,
                  mfc="none", ms=4)
        right.plot(omega / PI, closed / uniform, color=color, label=METHOD_LABELS[method])
    left.plot([], [], "o", color="k", mfc="none", label="markers: numerical quadrature")
    left.set_ylabel(r"$\int_0^{2\pi}\,\mathrm{Var}(\omega, \theta)\,d\theta$")
    left.set_title("Closed forms of Sec. 3.6 vs quadrature")
    right.axvspan(0, 1, color="tab:orange", alpha=0.08, label="mirrored best (ω < π)")
    right.axvspan(1, 2, color="tab:blue", alpha=0.08, label="shifted best (π < ω < 2π)")
    right.set_ylabel("variance / uniform one-sample variance")
    right.set_title("Relative to one uniform sample (two independent: 0.5)")
    for axis in (left, right):
        axis.set_xlabel("frequency ω over the exposure (units of π)")
        axis.legend(fontsize=8)
        axis.grid(True, alpha=0.3)
    figure.suptitle("Sec. 3.6 — variance of each time-sampling method, integrated over the phase θ")
    return figure


# --------------------------------------------------------------------------- Sec. 4

def figure_mis(settings: Settings):
    figure = _new_figure(settings, 14, 4.4)
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
            _save_figure(builders[name](), staged.path(name), settings.dpi)
        _save_text(staged.path("closed_forms.csv"), table.getvalue())
        _save_text(staged.path("rates.json"), json.dumps(rates, indent=2) + "\n")
    return [pathlib.Path(p) for p in staged.written]
