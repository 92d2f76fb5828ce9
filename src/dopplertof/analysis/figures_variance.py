"""The supplementary's section 3 as figures: the variance of time sampling methods
(antithetic shifts and their ratio, a truncated attenuated signal, higher frequencies,
two shifts, convergence rates, mirrored and stratified samples, the closed forms)."""

from __future__ import annotations

import numpy as np

from .. import modulation
from . import antithetic
from .figure_common import (METHOD_COLORS, METHOD_LABELS, PI, Settings, centered_extent,
                            new_figure, shift_legend_handles)
from .signals import PeriodicWaveform, Sinusoid, TruncatedAttenuatedSinusoid

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
    figure = new_figure(settings, 11, 7.5)
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
    axes[0].legend(handles=shift_legend_handles(SHIFT_OMEGAS, colors, SHIFT_THETAS, styles),
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
    figure = new_figure(settings, 11, 4.6)
    left, right = figure.subplots(1, 2)
    extent = centered_extent(omega / PI, theta / PI)
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

    figure = new_figure(settings, 14, 4.4)
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
                         extent=centered_extent(shifts, omegas / PI))
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

    figure = new_figure(settings, 12, 4.8)
    left, right = figure.subplots(1, 2)
    image = left.imshow(normalized, origin="lower", aspect="auto", cmap="viridis",
                        extent=centered_extent(shifts, omegas / PI))
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
    figure = new_figure(settings, 11, 4.8)
    axes = figure.subplots(1, 2)
    for axis, (omega, theta) in zip(axes, TWO_SHIFT_CASES):
        variance = antithetic.two_shift_variance(omega, theta, grid, grid)
        image = axis.imshow(variance.T, origin="lower", extent=centered_extent(grid, grid),
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
    figure = new_figure(settings, 7, 5)
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
    figure = new_figure(settings, 11, 7.5)
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
    figure = new_figure(settings, 12, 4.6)
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
