"""Depth unwrapping over N >= 2 modulation frequencies: maximum likelihood over wrap
counts.

Frequency f_j gives a depth wrapped to [0, R_j), R_j = c / (2 f_j), with a predicted
variance v_j. Every combination of wrap counts within the range searched gives a
candidate depth, the inverse-variance mean of the N unwrapped depths, and its chi^2;
the most likely candidate wins (:func:`unwrap_likelihood`). A pixel is flagged (its
depth NaN, never silently wrong as far as the likelihood can tell) where a candidate of
another depth is nearly as likely or where even the best disagrees beyond the noise.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..tof.reconstruct import ReconstructionError, wrap_distance


def unambiguous_range(frequencies_hz) -> float:
    """c / (2 gcd(f_1, ..., f_N)) (m): beyond it every frequency's phase repeats."""
    g = 0
    for f in frequencies_hz:
        g = math.gcd(g, int(round(f)))
    if g == 0:
        raise ReconstructionError("frequencies must be at least 1 Hz to unwrap")
    return wrap_distance(g)


# ---- Maximum likelihood over wrap counts, weighted by each frequency's noise -------------

#: a pixel is reported only where its best wrap-count candidate is this much more likely
#: (in chi^2 = -2 log-likelihood) than any candidate whose depth differs by more than a
#: quarter of the finest wrap: exp(18.4 / 2) = 9900, the best wrap about 10 000 times as
#: likely as any other (ambiguous pixels may still be settled by their neighbours)
LIKELIHOOD_GAP = 18.4

#: a pixel whose best candidate still leaves a chi^2 this far in the tail (N - 1 degrees
#: of freedom) is flagged: its frequencies disagree beyond their noise by more than the
#: tail allows (about 1e-6 under noise alone), as strong multipath or motion makes them
INCONSISTENCY_P = 1e-6


#: the search for wraps reaches this many times the range reported (at most the
#: unambiguous range): a surface up to that far is found and flagged beyond the range,
#: not aliased into it; one farther is at least SEARCH_FACTOR^2 dimmer than at the range's
#: end. (A full search of the unambiguous range finds near-aliases of its own: Azure
#: Kinect's 204 and 193 MHz agree within 2 cm at 13.97 m.)
SEARCH_FACTOR = 2.0
#: pixels per block of the candidate search (its memory: candidates x CHUNK x 16 bytes)
CHUNK = 1 << 15


@dataclass
class UnwrappedML:
    """The result of :func:`unwrap_likelihood`."""

    depth: np.ndarray  #: (H, W) m, NaN where flagged or an input is NaN
    variance: np.ndarray  #: (H, W) m^2, the inverse-variance mean's predicted variance
    ambiguous: np.ndarray  #: (H, W) bool: a wrong wrap is within LIKELIHOOD_GAP of the best
    inconsistent: np.ndarray  #: (H, W) bool: even the best candidate disagrees beyond noise
    chi2: np.ndarray  #: (H, W) the best candidate's chi^2
    gap: np.ndarray  #: (H, W) chi^2 of the best other-depth candidate minus the best's
    unambiguous_range: float  #: m, the range searched
    beyond: np.ndarray | None = None  #: (H, W) bool: found beyond ``max_range`` (NaN)

    @property
    def failed(self) -> np.ndarray:
        return self.ambiguous | self.inconsistent


def _chi2_quantile(p: float, dof: int) -> float:
    """The chi^2 value exceeded with probability ``p`` at ``dof`` degrees of freedom:
    exact for 1 (a squared normal) and 2 (an exponential), Wilson and Hilferty's cube-root
    normal approximation above (7% high at p = 1e-6 and 3 degrees: a little more lenient
    than exact). No SciPy: camera captures import
    none."""
    from statistics import NormalDist

    if dof == 1:
        return NormalDist().inv_cdf(1 - p / 2) ** 2
    if dof == 2:
        return -2.0 * math.log(p)
    z = NormalDist().inv_cdf(1 - p)
    return dof * (1 - 2 / (9 * dof) + z * math.sqrt(2 / (9 * dof))) ** 3


def _resolve_by_neighbours(best, best_chi2, runner, runner_chi2, threshold, confident,
                           ambiguous, radius: int, separation: float):
    """((H, W) depths, (H, W) bool resolved): an ambiguous pixel takes whichever of its
    two candidates (each only where its chi^2 is consistent) lies within
    ``separation`` / 2 of the median of the confident pixels in its (2 radius + 1)^2
    neighbourhood (at least 3 of them), as multi-frequency unwrapping with spatial
    support does (Lawin et al. 2016, arXiv 1608.05209: hypotheses weighted by their
    neighbours); otherwise it stays flagged."""
    from numpy.lib.stride_tricks import sliding_window_view

    ys, xs = np.nonzero(ambiguous)
    chosen = np.array(best, np.float64)
    resolved = np.zeros(best.shape, bool)
    if ys.size == 0:
        return chosen, resolved
    padded = np.pad(np.where(confident, best, np.nan), radius, constant_values=np.nan)
    windows = sliding_window_view(padded, (2 * radius + 1, 2 * radius + 1))[ys, xs]
    windows = windows.reshape(ys.size, -1)
    support = np.isfinite(windows).sum(axis=1) >= 3
    with np.errstate(all="ignore"):
        import warnings

        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            reference = np.nanmedian(windows, axis=1)
    near_best = ((np.abs(best[ys, xs] - reference) < 0.5 * separation)
                 & (best_chi2[ys, xs] <= threshold))
    near_runner = ((np.abs(runner[ys, xs] - reference) < 0.5 * separation)
                   & (runner_chi2[ys, xs] <= threshold))
    take = support & (near_best | near_runner)
    chosen[ys, xs] = np.where(near_runner, runner[ys, xs], best[ys, xs])
    resolved[ys[take], xs[take]] = True
    return chosen, resolved


def _candidates(d, w, ranges, searched: float):
    """(depths, chi^2), each (candidates, pixels), of the wrap-count candidates of the
    wrapped depths ``d`` (frequencies ascending, weights ``w`` = 1 / variance): every
    wrap count of the lowest frequency within ``searched`` (and -1), each other
    frequency's count nearest to it and its two neighbours; chi^2 is inf for a depth
    outside [-a quarter of the finest wrap, searched]."""
    import itertools

    depths, chi2s = [], []
    wraps = list(range(max(1, int(math.ceil(searched / ranges[0] - 1e-9))))) + [-1]
    for n0 in wraps:
        reference = d[0] + n0 * ranges[0]
        nearest = np.round((reference - d[1:]) / ranges[1:, None])
        for steps in itertools.product((0, -1, 1), repeat=len(ranges) - 1):
            counts = nearest + np.array(steps, np.float64)[:, None]
            unwrapped = np.concatenate([reference[None], d[1:] + counts * ranges[1:, None]])
            mean = (w * unwrapped).sum(axis=0) / w.sum(axis=0)
            chi2 = (w * (unwrapped - mean) ** 2).sum(axis=0)
            outside = ~((mean >= -0.25 * ranges[-1]) & (mean <= searched))
            depths.append(mean)
            chi2s.append(np.where(outside, np.inf, chi2))
    return np.stack(depths), np.stack(chi2s)


def _best_two(d, w, ranges, searched: float, separation: float):
    """(best depth, its chi^2, the best other depth, its chi^2) of each pixel (column of
    ``d``): the other more than ``separation`` from the best."""
    candidates_depth, candidates_chi2 = _candidates(d, w, ranges, searched)
    columns = np.arange(d.shape[1])
    best = np.argmin(candidates_chi2, axis=0)
    best_chi2 = candidates_chi2[best, columns]
    best_depth = np.where(np.isfinite(best_chi2), candidates_depth[best, columns], np.nan)
    other = np.abs(candidates_depth - best_depth) > separation
    runner_chi2 = np.where(other, candidates_chi2, np.inf)
    runner = np.argmin(runner_chi2, axis=0)
    return best_depth, best_chi2, candidates_depth[runner, columns], runner_chi2[runner, columns]


def unwrap_likelihood(depths, variances, frequencies_hz, max_range: float | None = None,
                      gap: float = LIKELIHOOD_GAP,
                      inconsistency_p: float = INCONSISTENCY_P,
                      spatial_radius: int = 2) -> UnwrappedML:
    """Unwrapped depth from N >= 2 wrapped depths d_j (m) with predicted variances v_j
    (m^2): the wrap counts (:func:`_candidates`) minimizing chi^2 = sum_j (d_j + n_j R_j
    - D)^2 / v_j, D their inverse-variance mean (maximum likelihood under Gaussian noise).
    Flagged: ambiguous where a candidate of another depth (over a quarter of the finest
    wrap away) comes within ``gap`` of the best chi^2 (unless ``spatial_radius`` > 0 and
    the confident neighbours settle it, :func:`_resolve_by_neighbours`); inconsistent
    where the best chi^2 exceeds the (1 - ``inconsistency_p``) quantile of chi^2(N - 1).
    The search reaches SEARCH_FACTOR x ``max_range`` (at most the unambiguous range), so
    that a surface beyond ``max_range`` is found there and reported ``beyond`` (NaN), not
    aliased into the range."""

    frequencies_hz = tuple(float(f) for f in frequencies_hz)
    if len(frequencies_hz) < 2 or not len(depths) == len(variances) == len(frequencies_hz):
        raise ReconstructionError("unwrapping needs N >= 2 wrapped depths, as many variances "
                                  f"and frequencies, got {len(depths)}, {len(variances)} and "
                                  f"{len(frequencies_hz)}")
    limit = unambiguous_range(frequencies_hz)
    searched = limit if max_range is None else min(limit, SEARCH_FACTOR * float(max_range))
    order = np.argsort(frequencies_hz)
    f = np.asarray(frequencies_hz)[order]
    ranges = np.array([wrap_distance(x) for x in f])
    shape = np.shape(depths[0])
    d = np.stack([np.asarray(depths[i], np.float64).reshape(-1) for i in order])
    v = np.stack([np.asarray(variances[i], np.float64).reshape(-1) for i in order])
    w = 1.0 / np.maximum(v, 1e-12)
    separation = 0.25 * ranges[-1]
    best_depth, best_chi2, runner_depth, runner_up = (
        np.concatenate(parts) for parts in zip(*(
            _best_two(d[:, i:i + CHUNK], w[:, i:i + CHUNK], ranges, searched, separation)
            for i in range(0, d.shape[1], CHUNK))))
    finite = np.isfinite(best_depth) & np.isfinite(best_chi2)
    with np.errstate(invalid="ignore"):  # (no candidate at all: inf - inf, not finite)
        difference = runner_up - best_chi2
    ambiguous = finite & (difference < gap)
    threshold = _chi2_quantile(inconsistency_p, len(f) - 1)
    inconsistent = finite & ~ambiguous & (best_chi2 > threshold)
    if spatial_radius and len(shape) == 2:
        chosen, resolved = _resolve_by_neighbours(
            best_depth.reshape(shape), best_chi2.reshape(shape), runner_depth.reshape(shape),
            runner_up.reshape(shape),
            threshold, (finite & ~ambiguous & ~inconsistent).reshape(shape),
            ambiguous.reshape(shape), spatial_radius, separation)
        best_depth = np.where(resolved.reshape(-1), chosen.reshape(-1), best_depth)
        ambiguous = ambiguous & ~resolved.reshape(-1)
    failed = ambiguous | inconsistent
    depth = np.where(finite & ~failed, best_depth, np.nan)
    beyond = np.zeros(depth.shape, bool)
    if max_range is not None:
        beyond = depth > float(max_range)
        depth = np.where(beyond, np.nan, depth)
    variance = 1.0 / w.sum(axis=0)
    return UnwrappedML(depth.reshape(shape), variance.reshape(shape),
                       ambiguous.reshape(shape), inconsistent.reshape(shape),
                       best_chi2.reshape(shape), difference.reshape(shape), searched,
                       beyond.reshape(shape))
