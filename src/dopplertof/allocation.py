"""Adaptive sample counts per pixel from a pilot pass, without bias.

A render with ``adaptive_sampling`` first traces a *pilot*: the first samples of every
pixel. Each pixel's count is then set from the variance of its *neighbours'* pilot
groups, never its own: a pixel's count is a function of other pixels' random numbers
only, so the mean of its samples (pilot included) stays an unbiased estimate, exactly.
Errors concentrate where moving silhouettes, their shadows and their reflections cross
pixels during the exposure, and these regions are larger than a pixel, so the
neighbours predict a pixel's variance almost as well as the pixel itself.

Counts follow the neighbours' mean pilot standard deviation (the nearest ring weighted
3x: n ~ sigma is the optimum for known sigma), mixed with a uniform share of the budget
so that no pixel falls far below the mean, and the pilot fits in that share (the budget
is kept: no count is raised to the pilot). The normalization, which couples all
pixels, is computed for each pixel with its own pilot data left out. The constants were
chosen on the published moving Cornell box (docs/benchmarks.md); the gain moves by a
few percent across reasonable choices (1.135-1.166 measured).
"""

from __future__ import annotations

import numpy as np

#: half-width of the neighbourhood whose pilot variance sets a pixel's count (5x5)
RADIUS = 2
#: share of the budget spread uniformly (at least the pilot: 1 / PILOT_FRACTION)
UNIFORM_SHARE = 0.3
#: the pilot: 1/PILOT_FRACTION of the samples
PILOT_FRACTION = 4
#: chunks in the smallest pilot (8 groups each)
MIN_PILOT_CHUNKS = 2
#: weight of the nearest ring of neighbours (3x3) against the outer ring (5x5) in
#: the neighbourhood mean
INNER_WEIGHT = 3.0


def pilot_samples(spp: int, chunk: int) -> int:
    """Samples per pixel in the pilot: a quarter of ``spp`` in whole chunks; raises when
    ``spp`` is not a whole number of chunks or the pilot would be under two chunks."""
    smallest = PILOT_FRACTION * MIN_PILOT_CHUNKS * chunk
    if spp % chunk != 0 or spp < smallest:
        raise ValueError(
            f"adaptive_sampling needs spp a multiple of {chunk} and at least {smallest} "
            f"(a pilot of 1/{PILOT_FRACTION} of the samples, at least {MIN_PILOT_CHUNKS} "
            f"chunks of 8 groups of K samples), got spp {spp}")
    return (spp // PILOT_FRACTION) // chunk * chunk


def _neighbour_windows(shape, radius: int):
    """(window, weight) per neighbour offset within ``radius`` (the pixel itself
    excluded): the window selects, in an array zero-padded by ``radius``, the value of
    neighbour (y + dy, x + dx) for every pixel (y, x); the nearest ring weighs
    INNER_WEIGHT, the others 1."""
    h, w = shape
    for dy in range(-radius, radius + 1):
        for dx in range(-radius, radius + 1):
            if dy == 0 and dx == 0:
                continue
            window = (slice(radius + dy, radius + dy + h), slice(radius + dx, radius + dx + w))
            yield window, INNER_WEIGHT if max(abs(dy), abs(dx)) == 1 else 1.0


def _neighbour_sums(values, radius: int):
    """Weighted sum and total weight of each pixel's neighbours within ``radius`` (the
    pixel excluded, the image not padded)."""
    padded = np.pad(values, radius)
    inside = np.pad(np.ones_like(values), radius)
    total = np.zeros_like(values)
    count = np.zeros_like(values)
    for window, r in _neighbour_windows(values.shape, radius):
        total += r * padded[window]
        count += r * inside[window]
    return total, count


def sample_counts(pilot_variance, spp: int, pilot: int, chunk: int) -> np.ndarray:
    """Samples per pixel (int64, shape of ``pilot_variance``): whole chunks, at least
    ``pilot``, about ``spp`` on average; pixel (y, x)'s count does not depend on
    ``pilot_variance[y, x]``.

    ``pilot_variance`` holds each pixel's variance estimate from its pilot (any
    non-negative scale; non-finite values count as zero)."""
    var = np.nan_to_num(np.asarray(pilot_variance, dtype=np.float64), nan=0.0,
                        posinf=0.0, neginf=0.0)
    var = np.maximum(var, 0.0)
    h, w = var.shape
    n = var.size
    # neighbours pool standard deviations: one pilot outlier moves them less than it
    # moves a mean of variances (measured: equal at 1024 spp, 1.5% better at 256)
    sd = np.sqrt(var)
    total, count = _neighbour_sums(sd, RADIUS)

    def weight(s, c):  # the neighbours' mean standard deviation
        return np.where(c > 0, np.maximum(s, 0.0) / np.where(c > 0, c, 1.0), 0.0)

    wt = weight(total, count)  # every pixel's weight (none uses its own variance)
    # W_{-i}: the sum of all weights with pixel i's variance left out of its
    # neighbours' windows (the only weights it enters; up to the rounding of these
    # float64 sums, far below what could move a count by a chunk)
    w_sum = np.full((h, w), wt.sum())
    T, C, WT = (np.pad(a, RADIUS) for a in (total, count, wt))
    for window, r in _neighbour_windows((h, w), RADIUS):
        # neighbour j = i + (dy, dx): its window holds i; drop sd_i from it
        w_without = weight(T[window] - r * sd, C[window] - r)
        w_sum += np.where(C[window] > 0, w_without - WT[window], 0.0)
    share = np.where(w_sum > 0, wt * n / np.where(w_sum > 0, w_sum, 1.0), 1.0)
    target = spp * ((1.0 - UNIFORM_SHARE) * share + UNIFORM_SHARE)
    counts = np.rint(target / chunk).astype(np.int64) * chunk
    return np.maximum(counts, pilot)
