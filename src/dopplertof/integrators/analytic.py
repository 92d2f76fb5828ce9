"""Analytic time integration: ``time_sampling_method="analytic"`` (biased by design).

The Mitsuba 0.6 implementation's ``analytic`` mode, one of the paper's comparisons.
Time is not sampled. Each sample traces two paths through the same film position and
lens point: P1 at the exposure start and P2 at its end, P2 with P1's random numbers
(light samples, BSDF samples, Russian roulette). Each contribution of P1 (emitter hit
or light sample, with its MIS weight) is spread over the exposure assuming that along
the exposure

* its path length goes linearly from L1 (P1's) to L2 (P2's), so the low-pass phase
  theta(t) = omega_d t + psi + k L(t), k = omega_g / c, is linear: a t + b with
  a = omega_d + k (L2 - L1) / T and b = k L1 + psi;
* its value goes linearly from C1 to rho C1, rho = C2 / C1 the ratio of P2's
  contribution to P1's (both per unit of the same random numbers, so the pdf Jacobian
  is in it; without the MIS weights), i.e. C1 (1 + c t) with c = (rho - 1) / T.

The sample adds C1 * (g1 / 2) * (1/T) * integral over [0, T] of cos(a t + b) (1 + c t) dt,
in closed form. Low-pass sinusoids only (the published code has no other form).

Why it is biased: phase and amplitude are interpolated linearly between the two ends;
a path that is lost at t = T (occluded, or missing the moved object) fades linearly to
zero over the whole exposure; light that only P2 sees (visible at t = T but not at 0) is
never counted. On the published moving Cornell box its image mean is 0.81 of the
reference's. Exact where the path length and the contribution are linear in time and
visibility does not change (the moving plane of tests/analytic.py, nearly).
"""

from __future__ import annotations

import drjit as dr

from ..modulation import SPEED_OF_LIGHT
from ..scene import lights
from ..scene.bodies import BodyFrames
from ..scene.motion import lane_times
from .path_steps import (LoopSettings, _as_colour, _intersect, advance, film_position,
                         lane_streams, path_start, roulette, shade, vertex_numbers)

#: |phase change over the exposure| (rad) below which the closed forms use their series
#: (float64: the closed forms lose about 1e-16 / x, the series' first dropped terms are
#: below 1e-13 there)
_SMALL_PHASE = 1e-2


def cosine_moments(x, b):
    """Integrals over s in [0, 1] of cos(x s + b) and s cos(x s + b), in the precision
    of ``x`` and ``b`` (Dr.Jit arrays; series near x = 0, where the closed forms cancel)."""
    h = 0.5 * x
    h2 = h * h
    small = dr.abs(x) < _SMALL_PHASE
    sinc = dr.select(small, 1.0 - h2 * (1.0 / 6.0) + h2 * h2 * (1.0 / 120.0), dr.sin(h) / h)
    mean_cos = dr.cos(b + h) * sinc  # (sin(x + b) - sin b) / x
    mean_sin = dr.sin(b + h) * sinc  # (cos b - cos(x + b)) / x
    # sum over n of x^n cos^(n)(b) / (n! (n + 2))
    cos_b, sin_b = dr.cos(b), dr.sin(b)
    x2 = x * x
    series = (cos_b * (0.5 - x2 * (1.0 / 8.0) + x2 * x2 * (1.0 / 144.0))
              - sin_b * x * (1.0 / 3.0 - x2 * (1.0 / 30.0)))
    first_moment = dr.select(small, series, (dr.sin(x + b) - mean_sin) / x)
    return mean_cos, first_moment


class IntegratedWeight:
    """The time average over the exposure of a contribution's low-pass sinusoidal
    weight g1 * 0.5 cos(theta(t)), times its linear amplitude 1 + (rho - 1) t / T,
    for path lengths L1 at the start and L2 at the end (phases in float64)."""

    def __init__(self, mi, modulation):
        F = mi.Float64
        self.F = F
        self.to_float32 = mi.Float
        self.beat = dr.opaque(F, modulation.omega_d * modulation.exposure)  # rad per exposure
        self.k_length = dr.opaque(F, modulation.omega_g / SPEED_OF_LIGHT)  # rad per metre
        self.psi = dr.opaque(F, modulation.psi)
        self.half_g1 = dr.opaque(mi.Float, 0.5 * modulation.g1)

    def __call__(self, length_start, length_end, ratio):
        F = self.F
        x = self.beat + self.k_length * (F(length_end) - F(length_start))  # a T
        b = self.k_length * F(length_start) + self.psi
        mean_cos, first_moment = cosine_moments(x, b)
        return self.half_g1 * (self.to_float32(mean_cos)
                               + (ratio - 1.0) * self.to_float32(first_moment))

    def at(self, length_start, length_end, ratio, fraction):
        """The weight itself at the exposure fraction ``fraction`` in [0, 1] (what
        ``__call__`` averages): g1/2 cos(theta) (1 + (rho - 1) s), theta linear in s."""
        F = self.F
        x = self.beat + self.k_length * (F(length_end) - F(length_start))
        b = self.k_length * F(length_start) + self.psi
        s = F(fraction)
        return self.half_g1 * self.to_float32(dr.cos(x * s + b)) * (1.0 + (ratio - 1.0)
                                                                     * self.to_float32(s))


def _ratio(value_end, value_start):
    """rho per channel: zero where the start contributes nothing (nothing to scale)."""
    return dr.select(value_start != 0.0, value_end / value_start, 0.0)


def _exposure_ends(mi, setup, layout, streams):
    """Each lane's film offset, and at the exposure's start and at its end (one film
    position and lens point): the camera ray, its weight, the path length to its
    origin, and the body and light transforms."""
    scene, mod = setup.scene, setup.modulation
    pos, film_offset, _, _, _, lens = film_position(mi, setup, layout, streams)
    t_start = lane_times(mi, setup.opens, dr.width(pos))
    span = (setup.shutter_open, setup.shutter_open + mod.exposure)
    ends = []
    for t in (t_start, t_start + mi.Float(setup.exposure)):
        ray, ray_weight, offset = setup.camera.ray(pos, t, *lens)
        frames = BodyFrames(mi, scene.bodies, t, *span) if scene.bodies else None
        light_frames = (lights.LightFrames(mi, scene.light_motions, t)
                        if scene.light_motions else None)
        ends.append((ray, ray_weight, offset, frames, light_frames))
    return film_offset, ends[0], ends[1]


def ends_roulette(mi, p1, p2, v1, v2, u_rr, rr_depth):
    """Russian roulette after vertices v1 and v2 of the paths P1 and P2 (path_steps'
    PATH_STATE tuples, advanced): P1's decides for both, with the number ``u_rr``, so
    their ratio stays; their states after it."""
    beta1, beta2, depth1 = p1[1], p2[1], p1[3]
    beta_max1, rr_prob, rr_active = roulette(beta1, p1[8], depth1, rr_depth)
    beta_max2 = dr.max(beta2)
    beta1 = dr.select(rr_active, beta1 * dr.rcp(rr_prob), beta1)
    beta2 = dr.select(rr_active, beta2 * dr.rcp(rr_prob), beta2)
    survives = ~rr_active | (u_rr < rr_prob)
    active1 = p1[4] & ((v1.active_next & survives & (beta_max1 != 0.0)) | v1.through)
    active2 = active1 & ((v2.active_next & survives & (beta_max2 != 0.0)) | v2.through)
    return (p1[:1] + (beta1,) + p1[2:4] + (active1,) + p1[5:],
            p2[:1] + (beta2,) + p2[2:4] + (active2,) + p2[5:])


@dr.syntax
def trace_analytic_pass(mi, setup, layout):
    """Render one pass with analytic time integration; returns each lane's
    time-averaged measurement and film offset, as ``DopplerToFPath.trace`` does."""
    settings = LoopSettings(mi, setup)  # (a plain object: not loop state)
    static = settings.static
    integrated = IntegratedWeight(mi, setup.modulation)
    streams = lane_streams(mi, setup, layout)  # correlation depth 0: samples independent

    # ---- Camera rays: one film position and lens point, at the exposure's two ends ----
    film_offset, (ray1, ray_weight1, offset1, frames1, light_frames1), \
        (ray2, ray_weight2, offset2, frames2, light_frames2) = _exposure_ends(
            mi, setup, layout, streams)
    u_em_first = streams.first_hit_2d(0, layout.group, layout.index, setup.groups_per_pixel)
    u_dir_first = streams.first_hit_2d(1, layout.group, layout.index, setup.groups_per_pixel)
    wavelengths = ray1.wavelengths  # of the camera ray, for the colour conversion

    # ---- Loop state: P1 (start) and P2 (end) ----
    measured = mi.Spectrum(0.0)  # the modulated contributions so far (the measurement)
    p1 = path_start(mi, ray1, ray_weight1, offset1, True)  # P1 (PATH_STATE)
    p2 = path_start(mi, ray2, ray_weight2, offset2, True)  # P2, with P1's numbers
    fresh = mi.Bool(False)  # (no camera hit traced before the loop)

    while dr.hint(p1[4], max_iterations=settings.max_iterations, label="dopplertof_analytic"):
        si1 = _intersect(mi, static, frames1, p1[0], p1[4], p1[3], None, fresh)
        si2 = _intersect(mi, static, frames2, p2[0], p2[4], p2[3], None, fresh)
        numbers = vertex_numbers(streams, p1[3], u_em_first, u_dir_first)  # P1's, for both
        v1 = shade(mi, settings, p1, (frames1, light_frames1), si1, numbers)
        v2 = shade(mi, settings, p2, (frames2, light_frames2), si2, numbers)

        # ---- P1's contributions, integrated over the exposure towards P2's ----
        # (where P2 has none, it fades out at P1's length: P2's has no meaning there)
        rho_hit = _ratio(dr.select(v2.hit_emitter, v2.emitted, 0.0), v1.emitted)
        measured += dr.select(v1.hit_emitter, v1.emitted * v1.mis_hit * integrated(
            v1.length_hit, dr.select(v2.hit_emitter, v2.length_hit, v1.length_hit), rho_hit), 0.0)
        rho_em = _ratio(dr.select(v2.active_em, v2.em_value, 0.0), v1.em_value)
        measured += dr.select(v1.active_em, v1.em_value * v1.mis_em * integrated(
            v1.length_em, dr.select(v2.active_em, v2.length_em, v1.length_em), rho_em), 0.0)

        # ---- Continue both paths; Russian roulette: P1's decides for both ----
        p1, p2 = ends_roulette(mi, advance(mi, p1, si1, v1), advance(mi, p2, si2, v2), v1, v2,
                               numbers[3], settings.rr_depth)

    return _as_colour(mi, measured, wavelengths), film_offset
