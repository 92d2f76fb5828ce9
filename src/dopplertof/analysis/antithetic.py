"""Variance of time-sampling methods for one path's signal (supplementary Sec. 3).

Setting: a pixel integrates x(t) over the exposure, normalized to [0, 1].  Each method
draws one primal number u ~ U[0, 1) and places its samples at times t_i(u) = frac(s_i u + c_i);
the estimate is the mean of x over them.  Its variance is an integral over u,

    Var = integral_0^1 (mean_i x(t_i(u)) - mu_x)^2 du,            (Eq. 12 for two samples)

which we evaluate by breakpoint-aware Gauss-Legendre quadrature (``quadrature``): exact to
rounding for the piecewise-smooth signals of ``signals``.  For a sinusoid the shifted
antithetic variance also has a closed form (Eqs. 20 and 24), and its average over the phase
has the closed forms of Sec. 3.6 for all four methods the renderer offers.

Sample placements (shift ``a``; T = 1):

* uniform:            t_0 = u                                  (one sample)
* antithetic:         t_0 = u, t_1 = frac(u + a)               (shifted; best a = 1/2)
* antithetic_mirror:  t_0 = u, t_1 = frac(1 - u + a)           (mirrored; best a = 0)
* stratified:         t_k = frac(a + (k + u_k) / K), u_k independent  (strata start at a)
* periodic:           t_i = frac(u + i / N)                    (N antithetic samples)
"""

from __future__ import annotations

import math

import numpy as np

from ..sampling import METHODS
from .quadrature import DEFAULT_ORDER, panel_rule
from .signals import Sinusoid, TruncatedAttenuatedSinusoid

TWO_PI = 2.0 * math.pi

#: the renderer's time-sampling methods (``sampling.METHODS``, design.md section 2)
#: and their default shifts
DEFAULT_SHIFTS = {"uniform": 0.0, "stratified": 0.0, "antithetic": 0.5, "antithetic_mirror": 0.0}


# --------------------------------------------------------------------------- quadrature core

def _batch_shape(signal, *offsets):
    return np.broadcast_shapes(signal.breakpoints().shape[:-1], *[np.shape(c) for c in offsets])


def _base_panels(signal):
    # Enough equal panels that each spans a phase omega * width <= 0.75 pi, over which
    # 8-point Gauss-Legendre integrates a sinusoid to ~1e-12.
    return max(2, int(np.ceil(np.max(signal.omega) / (0.75 * math.pi))))


def estimator_variance(signal, time_maps, order: int = DEFAULT_ORDER, base_panels=None):
    """Variance over u ~ U[0, 1) of mean_i x(frac(s_i u + c_i)).

    ``time_maps`` is a list of (slope s_i, offset c_i) with 0 < |s_i| <= 1; offsets may be
    arrays that broadcast against the signal's parameters (a signal has an ``omega``
    attribute, used to choose the number of quadrature panels).  The mean subtracted is the
    estimator's own mean, which equals mu_x for every method here (all are unbiased) and
    is the stratum mean when called for a single stratum.
    """
    offsets = [np.asarray(c, dtype=float) for _, c in time_maps]
    batch = _batch_shape(signal, *offsets)
    # The integrand in u is smooth except where some t_i(u) crosses 0 (the wrap of frac)
    # or a breakpoint of x.  Since |s_i| <= 1 each such crossing happens at most once.
    knots = np.concatenate([np.zeros(signal.breakpoints().shape[:-1] + (1,)),
                            signal.breakpoints()], axis=-1)
    u_breaks = []
    for (slope, _), offset in zip(time_maps, offsets):
        if not 0.0 < abs(slope) <= 1.0:
            raise ValueError(f"time map slope must satisfy 0 < |s| <= 1, got {slope}")
        gap = np.mod(knots - offset[..., None], 1.0) if slope > 0 else \
            np.mod(offset[..., None] - knots, 1.0)
        u = gap / abs(slope)
        u_breaks.append(np.broadcast_to(np.where(u <= 1.0, u, 0.0), batch + knots.shape[-1:]))
    base_panels = _base_panels(signal) if base_panels is None else base_panels
    nodes, weights = panel_rule(np.concatenate(u_breaks, axis=-1), order, base_panels)
    estimate = sum(signal(np.mod(slope * nodes + offset[..., None], 1.0))
                   for (slope, _), offset in zip(time_maps, offsets)) / len(time_maps)
    mean = np.sum(weights * estimate, axis=-1)
    return np.sum(weights * (estimate - mean[..., None]) ** 2, axis=-1)


def signal_mean(signal, order: int = DEFAULT_ORDER):
    """mu_x = integral_0^1 x(t) dt."""
    nodes, weights = panel_rule(signal.breakpoints(), order, _base_panels(signal))
    return np.sum(weights * signal(nodes), axis=-1)


# --------------------------------------------------------------------------- sampling methods

def uniform_variance(signal, samples: int = 1):
    """Variance of the mean of ``samples`` independent uniform times: Var[x(u)] / N."""
    return estimator_variance(signal, [(1.0, 0.0)]) / samples


def antithetic_variance(signal, shift=0.5):
    """Shifted antithetic pair t_1 = frac(u + a): Eq. (12)."""
    return estimator_variance(signal, [(1.0, 0.0), (1.0, shift)])


def mirrored_antithetic_variance(signal, shift=0.0):
    """Mirrored antithetic pair t_1 = frac(1 - u + a) (Sec. 3.6)."""
    shift = np.asarray(shift, dtype=float)
    return estimator_variance(signal, [(1.0, 0.0), (-1.0, 1.0 + shift)])


def stratified_variance(signal, start=0.0, strata: int = 2):
    """K strata of width 1/K starting at ``start`` (wrapping), one independent sample each.

    The strata are independent, so Var = (1 / K^2) * sum_k Var[x in stratum k].
    """
    start = np.asarray(start, dtype=float)
    total = 0.0
    for k in range(strata):
        total = total + estimator_variance(signal, [(1.0 / strata, start + k / strata)])
    return total / strata**2


def multi_antithetic_variance(signal, shifts):
    """A primal time and one antithetic time per shift: t_i = frac(u + shift_i) (Sec. 3.5)."""
    return estimator_variance(signal, [(1.0, 0.0)] + [(1.0, s) for s in shifts])


def periodic_variance(signal, samples: int):
    """N antithetic samples at equal spacing, t_i = frac(u + i / N) (Sec. 3.5)."""
    return estimator_variance(signal, [(1.0, i / samples) for i in range(samples)])


def method_variance(method: str, signal, shift=None):
    """Variance of one of the renderer's two-sample methods (``METHODS``) with its shift.

    'uniform' is a single sample, as in the closed forms of Sec. 3.6.
    """
    shift = DEFAULT_SHIFTS[method] if shift is None else shift
    if method == "uniform":
        return uniform_variance(signal)
    if method == "stratified":
        return stratified_variance(signal, start=shift)
    if method == "antithetic":
        return antithetic_variance(signal, shift)
    if method == "antithetic_mirror":
        return mirrored_antithetic_variance(signal, shift)
    raise ValueError(f"unknown method {method!r}: expected one of {', '.join(METHODS)}")


# --------------------------------------------------------------------------- sinusoid closed forms

def sinusoid_mean(omega, theta):
    """mu = integral_0^1 cos(omega (t - 1/2) + theta) dt = cos(theta) sin(omega/2) / (omega/2)."""
    return np.cos(theta) * np.sinc(np.asarray(omega) / TWO_PI)


def sinusoid_mean_square(omega, theta):
    """mu_2^2 = integral_0^1 cos^2(...) dt = 1/2 + cos(2 theta) sin(omega) / (2 omega)."""
    return 0.5 + 0.5 * np.cos(2.0 * theta) * np.sinc(np.asarray(omega) / math.pi)


def _first_term(omega, theta, shift):
    # Eq. (20): F(a) = cos(omega + 2 phi) sin(omega a) / (2 omega) + a/2 cos(omega (1 - a)),
    # with omega + 2 phi = 2 theta; sin(omega a)/(omega a) written with np.sinc for omega -> 0.
    return 0.5 * shift * (np.cos(2.0 * theta) * np.sinc(omega * shift / math.pi)
                          + np.cos(omega * (1.0 - shift)))


def autocorrelation(omega, theta, shift):
    """R(a) = integral_0^1 x(t) x(frac(t + a)) dt = F(a) + F(1 - a), Eqs. (13)-(20)."""
    omega, theta, shift = np.broadcast_arrays(*[np.asarray(v, dtype=float)
                                               for v in (omega, theta, shift)])
    return _first_term(omega, theta, shift) + _first_term(omega, theta, 1.0 - shift)


def autocorrelation_slope(omega, theta, shift):
    """R'(a), Eq. (23) as derived from Eqs. (21)-(22):

    (1 - cos 2 theta) sin(omega/2) sin(omega a - omega/2)
        + 1/2 (a omega sin(omega (1 - a)) - (1 - a) omega sin(omega a)).

    (The printed Eq. 23 drops the factor a in the second term, and Eq. 22 prints
    sin(omega (1 - a)) where F'(1 - a) has sin(omega a); Eq. 19 lacks a 1/omega.  The
    forms here agree with finite differences of ``autocorrelation``.)
    """
    omega, theta, a = np.broadcast_arrays(*[np.asarray(v, dtype=float)
                                           for v in (omega, theta, shift)])
    first = (1.0 - np.cos(2.0 * theta)) * np.sin(0.5 * omega) * np.sin(omega * a - 0.5 * omega)
    second = 0.5 * (a * omega * np.sin(omega * (1.0 - a)) - (1.0 - a) * omega * np.sin(omega * a))
    return first + second


def antithetic_variance_closed_form(omega, theta, shift):
    """Var(omega, theta, a) = mu_2^2 / 2 - mu^2 + R(a) / 2, Eq. (24), for the sinusoid."""
    return (0.5 * sinusoid_mean_square(omega, theta) - sinusoid_mean(omega, theta) ** 2
            + 0.5 * autocorrelation(omega, theta, shift))


def variance_ratio(omega, theta):
    """Eq. (25): Var(omega, theta, 1/2) / (Var(omega, theta, 0) / 2).

    The denominator is uniform sampling with the same two samples drawn independently.
    Lies in [0, 1/2] for 0 < omega <= 2 pi: 1/2 is approached as omega -> 0 (theta != 0;
    1/8 for theta = 0, where x is even about mid-exposure), 0 is reached at omega = 2 pi.
    Both variances vanish as omega -> 0, so below omega ~ 1e-2 rounding dominates.
    """
    return (antithetic_variance_closed_form(omega, theta, 0.5)
            / (0.5 * antithetic_variance_closed_form(omega, theta, 0.0)))


# --------------------------------------------------------------------------- Sec. 3.6

def theta_integrated_variance_closed_form(method: str, omega):
    """integral over theta in [0, 2 pi] of Var(omega, theta) at the method's best shift, Sec. 3.6.

    (The supplementary calls these E_theta[Var]; they are 2 pi times the mean over theta.)
    """
    w = np.asarray(omega, dtype=float)
    if method == "uniform":
        return math.pi * (w**2 + 2.0 * np.cos(w) - 2.0) / w**2
    if method == "stratified":
        return math.pi * (w**2 + 8.0 * np.cos(0.5 * w) - 8.0) / (2.0 * w**2)
    common = math.pi * (w**2 + 4.0 * np.cos(w) - 4.0) / (2.0 * w**2)
    if method == "antithetic":
        return common + 0.5 * math.pi * np.cos(0.5 * w)
    if method == "antithetic_mirror":
        return common + 0.5 * math.pi * np.sin(w) / w
    raise ValueError(f"unknown method {method!r}: expected one of {', '.join(METHODS)}")


def theta_integrated_variance_numeric(method: str, omega, shift=None, thetas: int = 32):
    """The same integral by quadrature: over t (Gauss-Legendre) and theta (equispaced rule).

    Var is a trigonometric polynomial of degree 2 in theta, so the equispaced rule on the
    period is exact once it has more than 4 points; 32 leaves a wide margin.
    """
    omega = np.asarray(omega, dtype=float)
    theta = np.arange(thetas) * (TWO_PI / thetas)
    signal = Sinusoid(omega[..., None], theta)
    return TWO_PI * np.mean(method_variance(method, signal, shift), axis=-1)


def closed_form_table(omegas):
    """Rows (omega, method, closed_form, numeric) for every method of ``METHODS``."""
    omegas = np.asarray(omegas, dtype=float)
    rows = []
    for method in METHODS:
        closed = theta_integrated_variance_closed_form(method, omegas)
        numeric = theta_integrated_variance_numeric(method, omegas)
        rows += [(float(w), method, float(c), float(n)) for w, c, n in zip(omegas, closed, numeric)]
    return rows


# --------------------------------------------------------------------------- Sec. 3.3

#: parameter ranges of Sec. 3.3 (uniform on each)
TRUNCATION_RANGES = {"l": (1.0, 3.0), "v": (-0.01, 0.01), "phi": (0.0, TWO_PI), "t_d": (0.0, 1.0)}


def draw_truncated_parameters(draws: int, seed: int = 0):
    """Independent uniform draws of (phi1, phi2, l1, l2, v1, v2, t_d) over the Sec. 3.3 ranges."""
    rng = np.random.default_rng(seed)

    def uniform(key):
        low, high = TRUNCATION_RANGES[key]
        return rng.uniform(low, high, draws)

    return {"phi1": uniform("phi"), "phi2": uniform("phi"), "l1": uniform("l"),
            "l2": uniform("l"), "v1": uniform("v"), "v2": uniform("v"), "t_d": uniform("t_d")}


def expected_truncated_variance(omegas, shifts, draws: int = 512, seed: int = 0):
    """E[Var(omega, a)] over the Eq. (26) parameters, by Monte Carlo over ``draws`` signals.

    The same draws serve every omega and shift (common random numbers), so the shape of
    the curve over a is resolved much better than its absolute level.  Shape (omega, shift).
    """
    params = draw_truncated_parameters(draws, seed)
    shifts = np.asarray(shifts, dtype=float)
    result = np.empty((len(omegas), shifts.size))
    for i, omega in enumerate(omegas):
        signal = TruncatedAttenuatedSinusoid(
            omega, *(params[k][:, None] for k in ("phi1", "phi2", "l1", "l2", "v1", "v2", "t_d")))
        result[i] = np.mean(antithetic_variance(signal, shifts[None, :]), axis=0)
    return result


def find_truncated_counterexample(omega: float = 1.5 * math.pi, tries: int = 2048,
                                  seed: int = 1, step: float = 0.05):
    """A seeded search for Eq. (26) parameters where a = 1/2 is a local maximum of Var(a).

    Returns the parameter dict of the draw with the largest Var(1/2) - max Var(1/2 +- step)
    (positive means a local maximum), or None if no draw qualifies.
    """
    params = draw_truncated_parameters(tries, seed)
    signal = TruncatedAttenuatedSinusoid(
        omega, *(params[k][:, None] for k in ("phi1", "phi2", "l1", "l2", "v1", "v2", "t_d")))
    var = antithetic_variance(signal, np.array([0.5 - step, 0.5, 0.5 + step])[None, :])
    margin = var[:, 1] - np.maximum(var[:, 0], var[:, 2])
    best = int(np.argmax(margin))
    if margin[best] <= 0.0:
        return None
    return {"omega": float(omega), **{k: float(v[best]) for k, v in params.items()}}


# --------------------------------------------------------------------------- Sec. 3.5

def two_shift_variance(omega, theta, shifts_a, shifts_b):
    """Var of the triple t = u, frac(u + a), frac(u + b) on the grid a x b (Fig. 7)."""
    a = np.asarray(shifts_a, dtype=float)[:, None]
    b = np.asarray(shifts_b, dtype=float)[None, :]
    return multi_antithetic_variance(Sinusoid(omega, theta), [a, b])


def optimal_two_shifts(omega, theta, grid: int = 61):
    """(a, b) with a < b minimizing the variance of two antithetic shifts: grid, then simplex."""
    from scipy.optimize import minimize

    shifts = np.linspace(0.0, 1.0, grid)
    var = two_shift_variance(omega, theta, shifts, shifts)
    var = np.where(shifts[:, None] < shifts[None, :], var, np.inf)
    i, j = np.unravel_index(np.argmin(var), var.shape)

    def objective(ab):
        return float(multi_antithetic_variance(Sinusoid(omega, theta), [ab[0], ab[1]]))

    result = minimize(objective, x0=[shifts[i], shifts[j]], method="Nelder-Mead",
                      options={"xatol": 1e-6, "fatol": 1e-14})
    return tuple(sorted(float(x) for x in result.x))


# --------------------------------------------------------------------------- Sec. 3.5, Fig. 8

def expected_variance_over_frequency(method: str, samples: int, omega_max: float = TWO_PI,
                                     omega_nodes: int = 16, thetas: int = 8):
    """E over omega ~ U[0, omega_max], theta ~ U[0, 2 pi] of the variance with N samples.

    method: 'uniform' (N independent), 'stratified' (N strata), 'periodic' (N equally
    spaced antithetic samples).  omega by Gauss-Legendre (the variance is smooth in omega),
    theta by the equispaced rule (exact: degree-2 trigonometric polynomial).
    """
    nodes, weights = np.polynomial.legendre.leggauss(omega_nodes)
    omega = 0.5 * omega_max * (nodes + 1.0)
    theta = np.arange(thetas) * (TWO_PI / thetas)
    signal = Sinusoid(omega[:, None], theta[None, :])
    if method == "uniform":
        var = uniform_variance(signal, samples)
    elif method == "stratified":
        var = stratified_variance(signal, 0.0, samples)
    elif method == "periodic":
        var = periodic_variance(signal, samples)
    else:
        raise ValueError(f"unknown method {method!r}: expected uniform, stratified or periodic")
    return float(np.sum(0.5 * weights * np.mean(var, axis=1)))


def convergence_study(sample_counts, **kwargs):
    """{method: [E Var for N in sample_counts]} for uniform, stratified and periodic."""
    return {method: [expected_variance_over_frequency(method, int(n), **kwargs)
                     for n in sample_counts]
            for method in ("uniform", "stratified", "periodic")}


def fit_log_log_slope(sample_counts, variances):
    """Least-squares slope of log Var against log N: the convergence rate exponent."""
    slope, _ = np.polyfit(np.log(np.asarray(sample_counts, float)),
                          np.log(np.asarray(variances, float)), 1)
    return float(slope)
