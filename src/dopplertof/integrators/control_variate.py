"""The analytic time integral as a control variate: ``time_sampling_method="control_variate"``.

For a path-space sample u (a film position, lens point and the random numbers of every
decision along the path), the measurement is the exposure average of f(u, t), the
path's modulated contribution at time t. The analytic mode (:mod:`.analytic`) builds a
model g(u, t) of it from two paths traced with u's numbers, P1 at the exposure's start
and P2 at its end (path length and value linear in t between them), and integrates the
modulation in closed form: G(u) = (1/T) integral of g(u, t) dt. This mode traces a third
path P(t) with the same numbers at a sampled time t and adds the model's error there:

    F(u, t) = G(u) + f(u, t) - g(u, t),

unbiased for any g that depends on u alone (E_t[g(u, t)] = G(u)), with the variance of
f - g in time instead of f's. Where P1 and P2 follow the same surfaces the model is exact
to first order in the motion, f - g is second order, and one time sample per path is
enough; the heterodyne beat (f's largest variation in time, of the size of f itself) is
in g too, so it never reaches the estimate.

Where g would be worse than nothing the model falls back to less, still a function of u
alone: once P1 and P2 part (a surface hit on different shapes: an occlusion boundary
crossed during the exposure), P1's later contributions keep their value and length over
the whole exposure (only the beat is modelled); a contribution that P2 lacks while the
paths agree fades out linearly, as in the analytic mode. Light that only P2 or only P(t)
sees is in f alone. Silhouettes therefore keep about the variance of sampled time.

P1 and P2 share Russian roulette (P1's decides, their ratio stays); P(t) plays its own
with the same numbers, so that f is exactly the sampled estimator's. The time sample is
stratified over a pixel's samples. Low-pass sinusoids only, as the analytic mode.
"""

from __future__ import annotations

import drjit as dr

from .analytic import IntegratedWeight, _exposure_ends, _ratio, ends_roulette
from .path_steps import (LoopSettings, _as_colour, _intersect, advance, contributions,
                         lane_streams, path_start, shade, survive, vertex_numbers)


def model_terms(integrated: IntegratedWeight, v1, v2, coherent, fraction):
    """Vertex v1's two contributions (emitter hit, light sample) under the model built
    with P2's vertex v2: their exposure average G and their value g at ``fraction``."""
    average, now = 0.0, 0.0
    for on1, value1, mis1, length1, on2, value2, length2 in (
            (v1.hit_emitter, v1.emitted, v1.mis_hit, v1.length_hit,
             v2.hit_emitter, v2.emitted, v2.length_hit),
            (v1.active_em, v1.em_value, v1.mis_em, v1.length_em,
             v2.active_em, v2.em_value, v2.length_em)):
        # the paths agree: linear towards P2's (fading out where P2 has none);
        # they parted: P1's value and length over the whole exposure
        ratio = dr.select(coherent, _ratio(dr.select(on2, value2, 0.0), value1), 1.0)
        length_end = dr.select(coherent & on2, length2, length1)
        base = value1 * mis1
        average += dr.select(on1, base * integrated(length1, length_end, ratio), 0.0)
        now += dr.select(on1, base * integrated.at(length1, length_end, ratio, fraction), 0.0)
    return average, now


def _path_vertex(mi, settings, path, frames, numbers):
    """The path's (PATH_STATE) next surface interaction and its vertex (path_steps.shade;
    ``frames``: its bodies' and lights')."""
    ray, _, _, depth, active = path[:5]
    si = _intersect(mi, settings.static, frames[0], ray, active, depth, None, mi.Bool(False))
    return si, shade(mi, settings, path, frames, si, numbers)


def _own_roulette(mi, path, v, u_rr, rr_depth):
    """The sampled path's own Russian roulette (path_steps.survive); its state after it."""
    beta, going = survive(mi, v, path[1], path[8], path[3], rr_depth, u_rr)
    return path[:1] + (beta,) + path[2:4] + (path[4] & (going != 0),) + path[5:]


@dr.syntax
def trace_control_variate_pass(mi, setup, layout):
    """Render one pass with the analytic integral as a control variate; returns each
    lane's measurement and film offset, as ``DopplerToFPath.trace`` does."""
    integrated = IntegratedWeight(mi, setup.modulation)  # G and g of a contribution
    weight = setup.modulation_weight  # f's w(L, t)
    streams = lane_streams(mi, setup, layout)  # correlation depth 0: samples independent

    # ---- Camera rays: one film position and lens point, at the ends and at time t ----
    film_offset, (ray1, weight1, offset1, frames1, light_frames1), \
        (ray2, weight2, offset2, frames2, light_frames2) = _exposure_ends(
            mi, setup, layout, streams)
    start = setup.sample_camera(layout, streams)
    frames_t, light_frames_t = start.frames, start.light_frames
    t_rel = start.t_rel  # the sampled time since the exposure's start (s)
    fraction = t_rel / setup.exposure  # ... as a fraction of the exposure
    u_em_first = streams.first_hit_2d(0, layout.group, layout.index, setup.groups_per_pixel)
    u_dir_first = streams.first_hit_2d(1, layout.group, layout.index, setup.groups_per_pixel)
    wavelengths = ray1.wavelengths  # of the camera ray, for the colour conversion
    settings = LoopSettings(mi, setup)  # (a plain object: not loop state)
    rr_depth = settings.rr_depth

    # ---- Loop state ----
    measured = mi.Spectrum(0.0)  # G + f - g of the contributions so far
    p1 = path_start(mi, ray1, weight1, offset1, True)  # P1, at the exposure's start
    p2 = path_start(mi, ray2, weight2, offset2, True)  # P2, at its end
    pt = path_start(mi, start.ray, start.ray_weight, start.camera_offset, start.active)  # P(t)
    coherent = mi.Bool(True)  # whether P1 and P2 have hit the same shapes so far

    while dr.hint(p1[4] | pt[4], max_iterations=settings.max_iterations,
                  label="dopplertof_control_variate"):
        numbers = vertex_numbers(streams, p1[3], u_em_first, u_dir_first)  # P1's and P2's
        numbers_t = vertex_numbers(streams, pt[3], u_em_first, u_dir_first)
        si1, v1 = _path_vertex(mi, settings, p1, (frames1, light_frames1), numbers)
        si2, v2 = _path_vertex(mi, settings, p2, (frames2, light_frames2), numbers)
        si_t, v_t = _path_vertex(mi, settings, pt, (frames_t, light_frames_t), numbers_t)

        # ---- G - g of P1's contributions, f of P(t)'s ----
        coherent &= ~p2[4] | ((si1.shape == si2.shape) & (si1.is_valid() == si2.is_valid()))
        average, now = model_terms(integrated, v1, v2, coherent, fraction)
        hit_t, light_t = contributions(weight, v_t, t_rel)
        measured += (average - now) + (hit_t + light_t)

        # ---- Continue the three paths; Russian roulette with the same number ----
        p1, p2 = ends_roulette(mi, advance(mi, p1, si1, v1), advance(mi, p2, si2, v2), v1, v2,
                                numbers[3], rr_depth)
        pt = _own_roulette(mi, advance(mi, pt, si_t, v_t), v_t, numbers_t[3], rr_depth)

    return _as_colour(mi, measured, wavelengths), film_offset
