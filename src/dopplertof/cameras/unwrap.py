"""Depth unwrapping over N >= 2 modulation frequencies: a search over wrap counts.

Frequency f_j gives a depth wrapped to [0, R_j), R_j = c / (2 f_j). Every wrap count n of
the lowest frequency (fewest wraps) within the range searched gives a candidate depth
d_0 + n R_0; each other frequency takes its own wrap count nearest to it, and the
candidate's cost is the weighted spread of the N unwrapped depths about their weighted
mean (weights f_j^2: the depth noise of a phase goes as 1 / f). The cheapest candidate
wins; its weighted mean is the depth.

A pixel fails (flagged, its depth NaN, never silently wrong as far as the search can
tell) where the winner's largest deviation from the mean exceeds the tolerance: half the
margin between the right wrap counts and the nearest wrong ones for exact depths
(:func:`wrong_wrap_margin`), unless a tolerance is given.
"""

from __future__ import annotations

import functools
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


@dataclass
class Unwrapped:
    """The result of :func:`unwrap_depths`."""

    depth: np.ndarray  #: (H, W) m, NaN where the search failed or an input is NaN
    failed: np.ndarray  #: (H, W) bool: the wrap counts disagree by more than the tolerance
    deviation: np.ndarray  #: (H, W) m, the winner's largest deviation from the mean
    unambiguous_range: float  #: m, the range searched
    tolerance: float  #: m


def _search(depths, frequencies_hz, max_range: float, below_zero: bool = True):
    """(weighted mean, largest deviation, the smallest largest deviation of the other
    candidates) of the best wrap-count candidate per pixel. The lowest frequency's wrap
    counts 0, 1, ... reach ``max_range``; ``below_zero`` also tries -1 (last, so that a
    tie keeps the count within the range), for depths a little above 0 that noise wrapped."""
    order = np.argsort(frequencies_hz)
    f = np.asarray(frequencies_hz, np.float64)[order]
    d = np.stack([np.asarray(depths[i], np.float64) for i in order])
    ranges = np.array([wrap_distance(x) for x in f])
    weights = (f / f.max())[:, None] ** 2
    shape = d.shape[1:]
    d = d.reshape(len(f), -1)
    best = [np.full(d.shape[1], np.inf), np.full(d.shape[1], np.nan),
            np.full(d.shape[1], np.inf), np.full(d.shape[1], np.inf)]
    wraps = list(range(max(1, int(math.ceil(max_range / ranges[0] - 1e-9)))))
    for n in wraps + ([-1] if below_zero else []):
        reference = d[0] + n * ranges[0]
        counts = np.round((reference - d) / ranges[:, None])
        counts[0] = n
        candidates = d + counts * ranges[:, None]
        mean = (weights * candidates).sum(axis=0) / weights.sum()
        cost = (weights * (candidates - mean) ** 2).sum(axis=0)
        deviation = np.abs(candidates - mean).max(axis=0)
        better = cost < best[0]
        # the previous winner becomes the runner-up where a better candidate comes
        best[3] = np.minimum(best[3], np.where(better, best[2], deviation))
        best[2] = np.where(better, deviation, best[2])
        best[1] = np.where(better, mean, best[1])
        best[0] = np.where(better, cost, best[0])
    return (best[1].reshape(shape), best[2].reshape(shape), best[3].reshape(shape))


@functools.lru_cache(maxsize=64)
def wrong_wrap_margin(frequencies_hz: tuple, max_range: float, points: int = 4096) -> float:
    """The smallest largest-deviation of a wrong wrap-count candidate for exact wrapped
    depths, over true depths in [0, max_range) (m): how far noise must push the depths
    before a wrong candidate can look right."""
    truth = np.linspace(0.0, max_range, points, endpoint=False)
    wrapped = [np.mod(truth, wrap_distance(f)) for f in frequencies_hz]
    _, _, runner_up = _search(wrapped, frequencies_hz, max_range, below_zero=False)
    return float(np.min(runner_up))


def unwrap_depths(depths, frequencies_hz, max_range: float | None = None,
                  tolerance: float | None = None) -> Unwrapped:
    """Unwrapped depth from N >= 2 wrapped depths (m, each in [0, c / (2 f_j))).

    max_range: the range searched (default: the unambiguous range); tolerance: the
    largest deviation (m) accepted between the frequencies' unwrapped depths (default:
    half of :func:`wrong_wrap_margin`, at most a quarter of the smallest wrap distance)."""
    frequencies_hz = tuple(float(f) for f in frequencies_hz)
    if len(frequencies_hz) < 2 or len(depths) != len(frequencies_hz):
        raise ReconstructionError(f"unwrapping needs N >= 2 wrapped depths and as many "
                                  f"frequencies, got {len(depths)} and {len(frequencies_hz)}")
    if len(set(round(f) for f in frequencies_hz)) < len(frequencies_hz):
        raise ReconstructionError(f"unwrapping needs distinct frequencies, got "
                                  f"{', '.join(f'{f / 1e6:g} MHz' for f in frequencies_hz)}")
    limit = unambiguous_range(frequencies_hz)
    searched = limit if max_range is None else min(float(max_range), limit)
    finest = min(wrap_distance(f) for f in frequencies_hz)
    if tolerance is None:
        tolerance = min(0.5 * wrong_wrap_margin(frequencies_hz, searched), 0.25 * finest)
    # a wrap count of -1 of the lowest frequency is no other count's twin only when the
    # range searched stops a lowest-frequency wrap short of the unambiguous range
    below_zero = searched <= limit - wrap_distance(min(frequencies_hz)) + 1e-9
    mean, deviation, _ = _search(depths, frequencies_hz, searched, below_zero)
    finite = np.isfinite(mean) & np.isfinite(deviation)
    failed = finite & (deviation > tolerance)
    depth = np.where(finite & ~failed, mean, np.nan)
    return Unwrapped(depth, failed, deviation, searched, float(tolerance))
