"""The film: where a pixel's samples land and how they become its value.

Two ways, chosen by ``film_sampling``:

``splat`` (the default, as Mitsuba's film): a pixel's film positions are uniform over
the pixel itself (its low-discrepancy set); each sample adds ``w * value`` to every
pixel whose reconstruction filter reaches it, ``w`` the filter at the sample's offset
from that pixel's centre. A sample thus serves up to (2n+1)^2 pixels (n = 1 for a
tent of radius 1, 2 for the default gaussian) and every pixel sees the samples of its
neighbours: the reuse that importance sampling gives away. It stays deterministic
without atomics: each lane's weights for the fixed neighbour offsets are computed in
one kernel whose threads sum their pixel's chunks in lane order into per-(pixel,
offset) totals, and the host shifts and adds them in a fixed order.

``importance``: film positions drawn from the filter itself, so that every sample
belongs to its own pixel with weight 1 and pixels' noise is independent (denoiser
training, error bars).

Normalization (splat). A pixel i is the filter-weighted mean of the image over the
crop window. Its estimate sums, over the source pixels j whose samples reach it, S_ij,
the weighted sum of j's samples divided by j's sample count, and divides by a weight:
``film_normalization="weights"`` (the default, Mitsuba's way) the sampled weight sum
W_ij of the same samples, a ratio estimator; ``"expected"`` its exact expectation N_i,
known from the filter (the filter's integral over each source pixel inside the
window), which keeps the estimate unbiased. The ratio cancels the fluctuation of the
weight sum itself, which on a smooth surface is most of the noise at low spp (a
standard deviation 40-70x lower on the moving plane at 4-16 spp; docs/parameters.md),
and its bias was not measurable (under 2e-5 relative at 4 spp). Both restrict the
filter to the crop window at the edges, as Mitsuba's film does (its samples come from
inside the window only).
"""

from __future__ import annotations

import math

import drjit as dr
import numpy as np

#: Mitsuba's filter classes this film knows (positive filters with a closed-form integral)
SUPPORTED_FILTERS = ("BoxFilter", "TentFilter", "GaussianFilter")


def _filter_of(film):
    rfilter = film.rfilter()
    kind = rfilter.class_name()
    if kind not in SUPPORTED_FILTERS:
        raise ValueError(
            f"reconstruction filter {kind} is not supported (it has negative lobes "
            "or no sampling routine): use box, tent or gaussian")
    return kind, (0.5 if kind == "BoxFilter" else float(rfilter.radius()))


class FilmSampler:
    """Film positions within a pixel's reach, with their density.

    ``FilmSampler(film)`` importance-samples the film's reconstruction filter (box,
    tent, gaussian), so that every sample belongs to its own pixel with weight 1 (the
    ``importance`` film); ``FilmSampler.uniform()`` samples the pixel itself, uniformly
    (the ``splat`` film, whose filter is applied by :class:`SplatFilter`).
    """

    def __init__(self, film):
        self.kind, self.radius = _filter_of(film)

    @classmethod
    def uniform(cls):
        """Positions uniform over the pixel (a box of radius 1/2: the same numbers)."""
        sampler = cls.__new__(cls)
        sampler.kind, sampler.radius = "BoxFilter", 0.5
        return sampler

    @property
    def support(self) -> float:
        """Half-width of the filter's support, in pixels."""
        return 0.5 if self.kind == "BoxFilter" else self.radius

    # ---- One axis: the (separable) filter's CDF and its inverse on [-R, R] ----

    def _gaussian_scale(self):
        sigma = self.radius / 4.0  # Mitsuba: radius = 4 sigma
        return 1.0 / (sigma * math.sqrt(2.0))

    def _cdf(self, x):
        R = self.support
        x = dr.clip(x, -R, R)
        if self.kind == "BoxFilter":
            return (x + R) / (2.0 * R)
        if self.kind == "TentFilter":
            left = dr.square(x + R) / (2.0 * R * R)
            return dr.select(x < 0.0, left, 1.0 - dr.square(R - x) / (2.0 * R * R))
        s = self._gaussian_scale()
        e = math.erf(R * s)
        return (dr.erf(x * s) + e) / (2.0 * e)

    def _inverse_cdf(self, v):
        R = self.support
        if self.kind == "BoxFilter":
            return v * (2.0 * R) - R
        if self.kind == "TentFilter":
            return dr.select(v < 0.5, R * dr.sqrt(2.0 * v) - R,
                             R - R * dr.sqrt(dr.maximum(2.0 * (1.0 - v), 0.0)))
        s = self._gaussian_scale()
        e = math.erf(R * s)
        return dr.erfinv(dr.clip((2.0 * v - 1.0) * e, -0.9999999, 0.9999999)) / s

    def offset(self, mi, u, lo, hi):
        """Offset from the pixel centre, in pixels, for uniform numbers u in [0,1): the
        filter sampled on the part of its support within [lo, hi] (the crop window seen
        from the pixel centre), as Mitsuba's film, which splats only samples inside the
        crop window and normalizes by their weights, averages over that part."""
        a, b = self._cdf(lo), self._cdf(hi)
        return self._inverse_cdf(a + u * (b - a))

    def weight(self, mi, offset, lo, hi):
        """The filter at ``offset`` (pixels, Vector2f) up to a constant: the density of
        :meth:`offset` for one pixel, zero outside the support or the window [lo, hi]."""
        R = self.support
        inside = ((dr.abs(offset.x) < R) & (dr.abs(offset.y) < R)
                  & (offset.x >= lo.x) & (offset.x < hi.x)
                  & (offset.y >= lo.y) & (offset.y < hi.y))
        if self.kind == "BoxFilter":
            value = mi.Float(1.0)
        elif self.kind == "TentFilter":
            value = (1.0 - dr.abs(offset.x) / R) * (1.0 - dr.abs(offset.y) / R)
        else:
            s = self._gaussian_scale()
            value = dr.exp(-(dr.square(offset.x) + dr.square(offset.y)) * (s * s))
        return dr.select(inside, value, 0.0)




class SplatFilter:
    """The reconstruction filter as a splat: per-lane weights for each neighbour
    offset, their exact integrals over a pixel, and the assembly of the image from
    (source pixel, offset) sums.

    The filter is Mitsuba's, separable: w(dx, dy) = e(dx) e(dy) with e the box (1 on
    |x| < 1/2), the tent max(0, 1 - |x| / R), or the gaussian of standard deviation
    R / 4 lowered to zero at R, max(0, exp(-x^2 / 2 sigma^2) - exp(-R^2 / 2 sigma^2)).
    """

    def __init__(self, film):
        self.kind, self.radius = _filter_of(film)
        #: rings of neighbours a sample reaches: its offset from its own pixel's centre
        #: is within 1/2, so pixel j + o is reached when |o| < R + 1/2
        self.reach = max(0, math.ceil(self.radius + 0.5) - 1)
        n = self.reach
        #: neighbour offsets (ox, oy), row-major: the kernel's sums come in this order
        self.offsets = [(ox, oy) for oy in range(-n, n + 1) for ox in range(-n, n + 1)]
        sigma = self.radius / 4.0
        self._alpha = 1.0 / (2.0 * sigma * sigma)
        self._sigma = sigma
        self._bias = math.exp(-self.radius * self.radius * self._alpha)

    # ---- One axis: the filter's integral on the host (float64) ----

    def _antiderivative(self, x: float) -> float:
        """The integral of e from 0 to x (float64)."""
        R = self.radius
        x = min(max(x, -R), R)
        if self.kind == "BoxFilter":
            return x
        if self.kind == "TentFilter":
            return x - x * abs(x) / (2.0 * R)
        s = self._sigma
        return (s * math.sqrt(math.pi / 2.0) * math.erf(x / (s * math.sqrt(2.0)))
                - self._bias * x)

    def integral(self, lo: float, hi: float) -> float:
        """The integral of e over [lo, hi] (float64)."""
        return self._antiderivative(hi) - self._antiderivative(lo)

    def cell_integral(self, k: int) -> float:
        """The integral of e(delta - k) over a pixel, delta in [-1/2, 1/2]: the expected
        weight, on one axis, of a sample of pixel j in pixel j + k."""
        return self.integral(k - 0.5, k + 0.5)

    # ---- Kernel side ----

    def lane_weights(self, mi, delta):
        """Each lane's weight for every neighbour offset (a list in ``offsets``'
        order); ``delta``: the lane's film position minus its pixel's centre, in pixels
        (Vector2f). None for a box: a sample then weighs 1 in its own pixel only."""
        if self.reach == 0:
            return None
        wx, wy = self.axis_weights(delta.x), self.axis_weights(delta.y)
        return [wy[oy] * wx[ox] for ox, oy in self.offsets]

    def axis_weights(self, d):
        """e(d - k) for every neighbour k = -n..n (a dict), ``d`` a lane's offset from
        its pixel's centre on one axis (Dr.Jit Float). The gaussian's five exponentials
        come from two: exp(-a (d - k)^2) = exp(-a d^2) exp(2 a d k) exp(-a k^2)."""
        n = self.reach
        if self.kind == "BoxFilter":  # (reach 0: the pixel itself)
            return {0: dr.select(dr.abs(d) < 0.5, 1.0, 0.0)}
        if self.kind == "TentFilter":
            return {k: dr.maximum(0.0, 1.0 - dr.abs(d - k) * (1.0 / self.radius))
                    for k in range(-n, n + 1)}
        a = self._alpha
        centre, step = dr.exp(-dr.square(d) * a), dr.exp(d * (2.0 * a))
        powers = {0: centre}
        for k in range(1, n + 1):
            powers[k] = powers[k - 1] * step
        back = dr.rcp(step)
        for k in range(1, n + 1):
            powers[-k] = powers[-k + 1] * back
        return {k: dr.maximum(0.0, powers[k] * math.exp(-a * k * k) - self._bias)
                for k in range(-n, n + 1)}

    def accumulate(self, mi, totals, values, film_offset, pixel, first_lane, lanes,
                   chunk_size: int, with_weights: bool):
        """Add a pass's samples to ``totals``: one Float64 array over the pixels per
        column (offset-major, then channel; then, ``with_weights``, one per offset for
        the sums of weights). Returns the new list.

        One thread per pixel with samples in the pass (host arrays ``pixel``,
        ``first_lane``, ``lanes``: its lanes are consecutive). Each chunk of
        ``chunk_size`` lanes is summed in float32 in lane order and each chunk sum is
        added to the float64 total in chunk order, so that the result does not depend
        on how the samples were cut into passes; every lane is read once, its weights
        computed there, and no two threads write one pixel (no atomics).
        Lanes with a non-finite value count as zero."""
        channels = len(values)
        n_pixels = dr.width(totals[0])
        every_pixel = len(pixel) == n_pixels and np.array_equal(pixel, np.arange(n_pixels))
        index = mi.UInt32(pixel)
        first, count = mi.UInt32(first_lane), mi.UInt32(lanes)
        acc = list(totals) if every_pixel else [dr.gather(mi.Float64, t, index) for t in totals]

        def add_sample(k, part):
            lane = first + k
            f = [dr.gather(mi.Float, v, lane) for v in values]
            finite = dr.isfinite(f[0])
            for v in f[1:]:
                finite &= dr.isfinite(v)
            f = [dr.select(finite, v, 0.0) for v in f]
            wx = self.axis_weights(dr.gather(mi.Float, film_offset.x, lane))
            wy = self.axis_weights(dr.gather(mi.Float, film_offset.y, lane))
            part = list(part)
            for m, (ox, oy) in enumerate(self.offsets):
                w = wy[oy] * wx[ox]
                for c in range(channels):
                    part[m * channels + c] = dr.fma(w, f[c], part[m * channels + c])
                if with_weights:
                    i = len(self.offsets) * channels + m
                    part[i] = part[i] + w
            return k + 1, part

        def add_chunk(k, acc):
            # ---- One chunk: float32 sums in lane order, then into the float64 totals ----
            end = k + chunk_size
            k, part = dr.while_loop(
                state=(k, [mi.Float(0.0) for _ in acc]),
                cond=lambda k, part: k < end, body=add_sample, labels=("k", "part"),
                label="splat_chunk")
            return k, [a + mi.Float64(p) for a, p in zip(acc, part)]

        _, acc = dr.while_loop(state=(mi.UInt32(0), acc), cond=lambda k, acc: k < count,
                               body=add_chunk, labels=("k", "acc"), label="splat")
        dr.eval(acc)  # the loop once (its symbolic outputs, scattered, reran it per column)
        if every_pixel:
            return acc
        out = [dr.copy(t) for t in totals]
        for t, a in zip(out, acc):
            dr.scatter(t, a, index)
        dr.eval(out)
        return out

    # ---- Host side ----

    def expected_weights(self, shape) -> np.ndarray:
        """N_i (H, W): the expected filter weight a pixel receives from one sample of
        each source pixel inside the window (crop window) of ``shape`` = (H, W)."""
        h, w = shape
        n = self.reach

        def axis(size):
            total = np.zeros(size)
            for k in range(-n, n + 1):  # target i receives from source i - k
                lo, hi = max(0, k), min(size, size + k)
                total[lo:hi] += self.cell_integral(k)
            return total

        return axis(h)[:, None] * axis(w)[None, :]

    def shift_add(self, sums, shape) -> np.ndarray:
        """Sum (offset, source pixel) values into their target pixels: ``sums`` is
        (len(offsets), C, H * W) by source pixel; returns (H, W, C), float64, the
        offsets added in a fixed order (deterministic)."""
        h, w = shape
        sums = sums.reshape(len(self.offsets), -1, h, w)
        image = np.zeros(sums.shape[1:])
        for m, (ox, oy) in enumerate(self.offsets):
            # target (y, x) = source (y - oy, x - ox), both inside the window
            ty = slice(max(0, oy), min(h, h + oy))
            tx = slice(max(0, ox), min(w, w + ox))
            sy = slice(max(0, -oy), min(h, h - oy))
            sx = slice(max(0, -ox), min(w, w - ox))
            image[:, ty, tx] += sums[m, :, sy, sx]
        return np.moveaxis(image, 0, -1)
