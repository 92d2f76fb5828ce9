"""Adaptive sample counts per pixel from a pilot pass, without bias.

A render with ``adaptive_sampling`` first traces a *pilot*: the first samples of every
pixel. Each pixel's count is then set from the variance of its *neighbours'* pilot
groups, never its own: a pixel's count is a function of other pixels' random numbers
only, so the mean of its samples (pilot included) stays an unbiased estimate, exactly.
Errors concentrate where moving silhouettes, their shadows and their reflections cross
pixels during the exposure, and these regions are larger than a pixel, so the
neighbours predict a pixel's variance almost as well as the pixel itself.

Counts follow sigma^a (a < 1; a = 1 would be the optimum n ~ sigma for known sigma,
the smaller power hedges against the noise of the pilot's estimate), mixed with a
uniform share so that no pixel falls far below the mean. The normalization, which
couples all pixels, is computed for each pixel with its own pilot data left out.
"""

from __future__ import annotations

import numpy as np

#: half-width of the neighbourhood whose pilot variance sets a pixel's count (5x5)
RADIUS = 2
#: counts follow sigma ** EXPONENT
EXPONENT = 1.0
#: share of the budget spread uniformly
UNIFORM_SHARE = 0.4
#: fraction of the samples traced as the pilot
PILOT_FRACTION = 8


def pilot_samples(spp: int, chunk: int) -> int:
    """Samples per pixel in the pilot: an eighth of ``spp`` in whole chunks; raises
    when that is not at least one chunk or ``spp`` is not a whole number of chunks."""
    if spp % chunk != 0 or spp < PILOT_FRACTION * chunk:
        raise ValueError(
            f"adaptive_sampling needs spp a multiple of {chunk} and at least "
            f"{PILOT_FRACTION * chunk} (8 groups of K samples per chunk, a pilot of "
            f"1/{PILOT_FRACTION}), got spp {spp}")
    return (spp // PILOT_FRACTION) // chunk * chunk


def _neighbour_sums(values, radius: int):
    """Sum and count of each pixel's neighbours within ``radius`` (the pixel excluded,
    the image not padded)."""
    h, w = values.shape
    total = np.zeros_like(values)
    count = np.zeros_like(values)
    padded = np.zeros((h + 2 * radius, w + 2 * radius))
    padded[radius:radius + h, radius:radius + w] = values
    inside = np.zeros_like(padded)
    inside[radius:radius + h, radius:radius + w] = 1.0
    for dy in range(-radius, radius + 1):
        for dx in range(-radius, radius + 1):
            if dy == 0 and dx == 0:
                continue
            window = (slice(radius + dy, radius + dy + h), slice(radius + dx, radius + dx + w))
            total += padded[window]
            count += inside[window]
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
    total, count = _neighbour_sums(var, RADIUS)
    p = EXPONENT / 2.0  # variance -> sigma ** EXPONENT

    def weight(s, c):
        return np.where(c > 0, np.maximum(s, 0.0) / np.maximum(c, 1.0), 0.0) ** p

    wt = weight(total, count)  # every pixel's weight (none uses its own variance)
    # W_{-i}: the sum of all weights with pixel i's variance left out of its
    # neighbours' windows (the only weights it enters)
    w_sum = np.full((h, w), wt.sum())
    pad = RADIUS
    big = lambda a: np.pad(a, pad)  # noqa: E731
    T, C, WT = big(total), big(count), big(wt)
    for dy in range(-pad, pad + 1):
        for dx in range(-pad, pad + 1):
            if dy == 0 and dx == 0:
                continue
            window = (slice(pad + dy, pad + dy + h), slice(pad + dx, pad + dx + w))
            # neighbour j = i + (dy, dx): its window holds i; drop var_i from it
            w_without = weight(T[window] - var, C[window] - 1.0)
            w_sum += np.where(C[window] > 0, w_without - WT[window], 0.0)
    share = np.where(w_sum > 0, wt * n / np.where(w_sum > 0, w_sum, 1.0), 1.0)
    target = spp * ((1.0 - UNIFORM_SHARE) * share + UNIFORM_SHARE)
    counts = np.rint(target / chunk).astype(np.int64) * chunk
    return np.maximum(counts, pilot)
