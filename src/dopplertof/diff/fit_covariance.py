"""The fit's metric and uncertainties: the Gauss-Newton metric of two independent
Jacobians and which parameters it sees, its truncated inverse, the parameters'
covariance (the sandwich of each residual's estimated noise, or the plain s^2 G^+ for
comparison), the combinations the captures do not constrain, and a radial velocity's
uncertainty. See :mod:`dopplertof.diff.fit`."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .fit_noise import sandwich

#: directions of the (column-scaled) Jacobian below this fraction of its largest
#: singular value are not constrained by the captures: no step along them
RCOND = 0.05

#: the covariances :func:`covariance` computes
COVARIANCES = ("sandwich", "plain")


#: a Jacobian column whose energy is below this fraction of the largest column's is
#: rounding, not signal (the demo's tall box's vertical velocity: 4e-24 beside 5e-7, the
#: same in both seeds' renders; fitted, it gave -19.87 +- 1.17e9 m/s)
NEGLIGIBLE_COLUMN = 1e-12


def metric(jacobians, snr=0.5):
    """The Gauss-Newton metric from two Jacobians of independent noise: G = (J_A^T J_B +
    J_B^T J_A) / 2, whose expectation is J^T J of the expected Jacobian (J_A^T J_A would
    add the noise's energy, and shorten every step by it). The mask of the parameters
    the captures see: those whose column's signal (G's diagonal) is at least ``snr`` of
    its energy (the mean of J_A^T J_A and J_B^T J_B) at the Jacobian's own samples (a
    column of noise only passes as rarely at any sample count: at 512 spp a test scaled
    to the residuals' samples let the tall box's unseen vertical velocity through, and
    its radial velocity 1.3% off), and whose energy is more than rounding: above
    :data:`NEGLIGIBLE_COLUMN` of the largest column's."""
    J_a, J_b = jacobians
    G = 0.5 * (J_a.T @ J_b + J_b.T @ J_a)
    energy = 0.5 * (np.sum(J_a * J_a, 0) + np.sum(J_b * J_b, 0))
    d = np.diag(G)
    floor = NEGLIGIBLE_COLUMN * (energy.max() if energy.size else 0.0)
    seen = (d > 0) & (d >= snr * energy) & (energy > floor)
    return G, seen


def residual_variance(residuals, parameters: int, explained: float = 0.0) -> float:
    """s^2: the squared residual of the two renders' mean over its degrees of freedom
    (the capture's noise and half of one render's, as in the fitted velocities, whose
    steps average the two seeds' residuals; positive, as the cross loss need not be),
    less ``explained`` (a step's predicted reduction: the residual it would leave)."""
    r_a, r_b = residuals
    mean_residual = 0.5 * (r_a + r_b)
    energy = float(mean_residual @ mean_residual)
    return max(energy - explained, 1e-3 * energy) / max(len(r_a) - parameters, 1)


#: a standard deviation above this many times the fitted parameters' norm (at least 1)
#: is no result: the captures do not determine the parameter (a velocity of -19.87 +-
#: 1.17e9 m/s is not one)
UNDETERMINED = 1e3


def _scaled_metric(jacobians, seen):
    """The metric of :func:`metric` over the parameters ``seen`` that it sees too:
    (G, that mask, the columns' scales sqrt(diag G), the column-scaled block of G over
    them), which the covariances and :func:`fixed_combinations` decompose."""
    G, seen_now = metric(jacobians)
    seen = seen & seen_now
    scale = np.sqrt(np.diag(G)[seen])
    return G, seen, scale, G[np.ix_(seen, seen)] / np.outer(scale, scale)


def covariance(state, seen, theta=None, noise=None, report=None, kind: str = "sandwich"):
    """``kind`` "sandwich" (the fit's): cov = G^+ M G^+ of the parameters
    (:func:`.fit_noise.sandwich`: the meat M of
    each residual's estimated noise, the renders' from the two seeds' difference, the
    capture's from ``noise``, a :class:`.fit_noise.CaptureNoise`, by default from the
    residuals), G the metric over the parameters ``seen`` (that the final Jacobian sees
    too; columns scaled, directions below RCOND^2 dropped); and the standard deviations
    (inf for a parameter not seen: unconstrained; with ``theta``, the fitted values,
    also for one whose deviation passes :data:`UNDETERMINED` times their norm, its
    covariances 0). ``report``: a dict that receives the noise's diagnostics (the
    Birge ratio). ``kind`` "plain": s^2 G^+, one variance s^2 for every residual (the
    squared residual of the two renders' mean over its degrees of freedom), for
    comparison (benchmarks/fit_uncertainty.py)."""
    if kind not in COVARIANCES:
        raise ValueError(f"unknown covariance {kind!r}: expected one of "
                         f"{', '.join(COVARIANCES)}")
    residuals, jacobians = state
    G, seen, scale, Gs = _scaled_metric(jacobians, seen)
    n = G.shape[0]
    cov = np.zeros((n, n))
    if seen.any() and kind == "plain":
        s2 = residual_variance(residuals, int(seen.sum()))
        cov[np.ix_(seen, seen)] = (s2 * truncated_inverse(Gs, RCOND ** 2)
                                   / np.outer(scale, scale))
    elif seen.any():
        inverse = np.zeros((n, n))
        inverse[np.ix_(seen, seen)] = (truncated_inverse(Gs, RCOND ** 2)
                                       / np.outer(scale, scale))
        cov, diagnostics = sandwich(residuals, jacobians, inverse, noise)
        if report is not None:
            report.update(diagnostics)
    sigma = np.where(seen, np.sqrt(np.maximum(np.diag(cov), 0.0)), np.inf)
    if theta is not None:
        absurd = sigma > UNDETERMINED * max(float(np.linalg.norm(theta)), 1.0)
        cov[absurd, :] = 0.0
        cov[:, absurd] = 0.0
        sigma[absurd] = np.inf
    return cov, sigma


@dataclass(frozen=True)
class FinalState:
    """What a fit's uncertainties are computed from, kept on its FitResult (``final``)
    so that other covariance models can be computed on the same fit:
    ``covariance(final.state, final.seen, final.theta, final.noise, report, kind)``
    (benchmarks/fit_uncertainty.py compares them)."""

    state: tuple  #: (residuals, Jacobians) of the two seeds at the end of the fit
    seen: np.ndarray  #: the parameters the captures see (bool per parameter)
    theta: np.ndarray  #: the fitted parameters
    noise: object  #: the capture's noise (.fit_noise.CaptureNoise)


#: a parameter whose unit direction (columns scaled) weighs at least this on a combination
#: the captures do not constrain is not determined by them (the
#: cameras_moving box's front face sees only the velocity along its normal; v_x and v_z
#: each passed the column test, the pseudo-inverse dropped their in-plane combination and
#: gave it no variance: errors of -588 reported standard deviations)
FIXED_WEIGHT = 0.1

#: a radial velocity whose gradient weighs this fraction of its norm on a parameter without
#: an uncertainty has none either: its error along it is the prior's, not the noise's
#: (the street's pedestrian, its uncertainty leaving out its unseen
#: components, read -184.7 sd; that box's, its body in a fixed combination, +16.8 sd)
RADIAL_BLIND = 0.01


def fixed_combinations(state, seen):
    """The combinations of the parameters ``seen`` that the captures do not constrain:
    the eigen-directions of the column-scaled metric at or below RCOND^2 of the largest
    eigenvalue, which :func:`covariance`'s pseudo-inverse leaves out (the steps, at
    RCOND, leave them at their start). Returns (directions, affected): the directions in
    the parameters' own units, unit rows, and the mask of the parameters weighing at least
    :data:`FIXED_WEIGHT` on one of them."""
    G, seen, scale, Gs = _scaled_metric(state[1], seen)
    n = G.shape[0]
    affected, directions = np.zeros(n, bool), []
    if seen.sum() >= 2:
        w, V = np.linalg.eigh(Gs)
        for v in V[:, w <= RCOND ** 2 * max(w.max(), 1e-300)].T:
            affected[np.flatnonzero(seen)[np.abs(v) >= FIXED_WEIGHT]] = True
            d = np.zeros(n)
            d[seen] = v / scale
            d /= np.linalg.norm(d)
            directions.append(d if d[np.argmax(np.abs(d))] > 0 else -d)
    return np.reshape(directions, (-1, n)), affected


def radial_uncertainty(g, cov, sigma, partly, own):
    """sqrt(g^T cov g) of a radial velocity of gradient ``g``, or None where it depends on
    what the captures do not see: where its body's parameters (``own``, their index) weigh on
    a fixed combination (``partly``: the median over its pixels moves along it, each
    pixel by its own ray's share, however small the median pixel's), or where ``g``
    weighs :data:`RADIAL_BLIND` of its norm on a parameter without an uncertainty."""
    if np.any(partly[own]):
        return None
    loose = ~np.isfinite(sigma) & ~partly
    if g.any() and np.any(np.abs(g[loose]) >= RADIAL_BLIND * float(np.linalg.norm(g))):
        return None
    return float(np.sqrt(max(g @ cov @ g, 0.0)))


def truncated_inverse(A, rcond):
    """Pseudo-inverse of a symmetric matrix without its eigen-directions below ``rcond``
    of the largest eigenvalue."""
    w, V = np.linalg.eigh(A)
    keep = w > rcond * max(w.max(), 1e-300)
    return (V[:, keep] / w[keep]) @ V[:, keep].T
