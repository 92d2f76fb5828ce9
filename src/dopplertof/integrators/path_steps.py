"""The steps of a D-ToF path, shared by the sampled and the analytic path loops.

Each pass's lane layout, the modulation weight w(L, t), the film position and camera
ray of a lane, and at each surface hit the emission, the light sample (next-event
estimation), the BSDF sample and Russian roulette, with MIS as in Mitsuba's path
tracer. The loops themselves are in :mod:`.dtof_path` (time sampled) and
:mod:`.analytic` (time integrated).
"""

from __future__ import annotations

import drjit as dr

from .. import sampling
from ..modulation import SPEED_OF_LIGHT, WAVEFORMS, correlation_by_index, wave
from ..scene import lights
from ..scene.bodies import intersect, nearest_hit, occluded, surface_interaction
from .antithetic_map import PairedCameraRays


class PassLayout:
    """Which pixel, group and sample each lane of a pass renders.

    Lanes are pixel-major: lane = pixel * samples + s, for samples s0 .. s0+samples-1
    of every pixel.
    """

    def __init__(self, mi, n_pixels: int, samples: int, first_sample, group_size: int):
        lane = dr.arange(mi.UInt32, n_pixels * samples)
        per_pixel = dr.opaque(mi.UInt32, samples)  # (opaque: one kernel for every spp)
        self._set(lane // per_pixel, first_sample + lane % per_pixel, group_size)

    @classmethod
    def of_lanes(cls, mi, pixel, sample, group_size: int):
        """A layout from host arrays of each lane's pixel and sample index (adaptive
        sample counts: pixels render different numbers of samples in a pass)."""
        layout = cls.__new__(cls)
        layout._set(mi.UInt32(pixel), mi.UInt32(sample), group_size)
        return layout

    def _set(self, pixel, sample, group_size):
        self.pixel = pixel
        self.sample = sample
        self.group = sample // group_size
        self.index = sample % group_size


def _mis_power(pdf_a, pdf_b):
    a2 = dr.square(pdf_a)
    w = a2 / (a2 + dr.square(pdf_b))
    return dr.select(dr.isfinite(w), w, 0.0)


class ModulationWeight:
    """w(L, t): the modulation weight of a contribution of path length L at time t.

    Scalars enter the kernel as opaque variables, so that one compiled kernel serves
    every frequency, offset and (in low-pass mode) waveform.
    """

    def __init__(self, mi, modulation):
        self.low_pass = modulation.low_pass
        self.to_float32 = mi.Float
        F = mi.Float if self.low_pass else mi.Float64
        self.F = F
        self.omega_g = dr.opaque(F, modulation.omega_g)
        self.omega_d = dr.opaque(F, modulation.omega_d)
        self.omega_s = dr.opaque(F, modulation.omega_s)
        self.psi = dr.opaque(F, modulation.psi)
        self.g0 = dr.opaque(F, modulation.g0)
        self.g1 = dr.opaque(F, modulation.g1)
        self.k_length = dr.opaque(F, modulation.omega_g / SPEED_OF_LIGHT)  # rad per metre
        self.waveform = modulation.waveform
        self.waveform_index = dr.opaque(mi.UInt32, WAVEFORMS.index(modulation.waveform))

    def __call__(self, path_length, t):
        """Weight of a contribution; ``t`` is the time since the exposure start (s)."""
        if self.low_pass:
            # g1 * C(theta), theta = omega_d t + psi + omega_g L / c
            theta = self.omega_d * t + self.psi + self.k_length * path_length
            return self.g1 * correlation_by_index(self.waveform_index, theta, dr)
        # s(t) * g(t - L / c), phases in float64 (omega_g t reaches ~1e5 rad)
        sensor = wave(self.waveform, self.omega_s * t + self.psi, dr)
        light = self.g0 + self.g1 * wave(self.waveform, self.omega_g * t
                                         - self.k_length * path_length, dr)
        return self.to_float32(sensor * light)


def length_derivative(weight: ModulationWeight, path_length, t):
    """d w(L, t) / d L at the path length ``path_length``, by forward-mode AD of the
    weight itself (so that each waveform's derivative is the one the renderer's
    forward-mode derivatives take); the result is detached."""
    import drjit as dr

    with dr.resume_grad():  # (the rest of the pass runs with gradients suspended)
        length = weight.F(dr.detach(path_length))
        dr.enable_grad(length)
        value = weight(length, dr.detach(t))
        dr.forward_from(length, flags=dr.ADFlag.ClearEdges)
        return dr.detach(dr.grad(value))


def contributions(weight: ModulationWeight, v, t):
    """Vertex ``v``'s two modulated contributions to the measurement: its emitter hit
    and its light sample (each zero where it has none)."""
    import drjit as dr

    return (dr.select(v.hit_emitter, v.emitted * v.mis_hit * weight(v.length_hit, t), 0.0),
            dr.select(v.active_em, v.em_value * v.mis_em * weight(v.length_em, t), 0.0))


def length_derivatives(weight: ModulationWeight, v, t):
    """The derivatives of vertex ``v``'s two contributions (its emitter hit and its
    light sample) with respect to their path lengths, summed."""
    import drjit as dr

    return (dr.select(v.hit_emitter, v.emitted * v.mis_hit
                      * length_derivative(weight, v.length_hit, t), 0.0)
            + dr.select(v.active_em, v.em_value * v.mis_em
                        * length_derivative(weight, v.length_em, t), 0.0))


def _as_colour(mi, value, wavelengths):
    """A sample's value for the film: spectral variants convert the sampled wavelengths'
    values to linear sRGB, as Mitsuba's film does; others keep their Spectrum."""
    return mi.spectrum_to_srgb(value, wavelengths) if mi.is_spectral else value


def _camera_rays(mi, setup, layout, pos, center, window, time, partner_fraction, lens):
    """Each lane's camera ray, its weight, the path length to its origin, its first hit
    when already traced (else None), whether the lane renders at all, and its film
    position when it is not ``pos`` (else None)."""
    if setup.projection is None:
        ray, weight, offset = setup.camera.ray(pos, time, *lens)
        return ray, weight, offset, None, mi.Bool(True), None
    # ---- Motion-compensated antithetic pairs ----
    mod = setup.modulation
    partner = mi.Float(partner_fraction * setup.exposure) + setup.opens
    primal = layout.index == 0
    crop_size = setup.scene.sensor.film().crop_size()
    pair = PairedCameraRays(
        mi, setup.scene, setup.camera, setup.projection, setup.film_sampler, pos, center,
        window, crop_size, dr.select(primal, time, partner), dr.select(primal, partner, time),
        layout.index, lens, (setup.shutter_open, setup.shutter_open + mod.exposure))
    return (pair.ray, pair.weight * pair.scale, pair.offset, (pair.pi, pair.winner),
            pair.scale != 0.0, pair.position)


def _intersect(mi, static, frames, ray, active, depth, first_hit, fresh):
    """The path's next surface interaction; the first one (``fresh`` lanes) from
    ``first_hit`` when the camera rays were traced before the loop (the loop's first
    query then skips)."""
    if first_hit is None:  # camera rays are coherent, as in Mitsuba's path tracer
        return intersect(mi, static, frames, ray, active, coherent=depth == 0)
    pi, winner = nearest_hit(mi, static, frames, ray, active & ~fresh, skip_idle=True)
    pi = dr.select(fresh, first_hit[0], pi)
    winner = dr.select(fresh, first_hit[1], winner)
    return surface_interaction(mi, static, frames, ray, pi, winner, active)


def lane_streams(mi, setup, layout: PassLayout):
    """The correlated random streams of a pass's lanes (groups of K share the time
    stream, path groups of Kp the path stream)."""
    return sampling.CorrelatedStreams(
        mi, layout.pixel, layout.group, layout.sample, setup.seed, setup.correlation_depth,
        path_group=(None if setup.path_group_size == setup.group_size
                    else layout.sample // setup.path_group_size), seed_high=setup.seed_high,
        joint=setup.joint_sets)


def film_position(mi, setup, layout: PassLayout, streams):
    """Each lane's film position (normalized) and its offset from its pixel centre (in
    pixels; uniform in the pixel for the splat film, drawn from the filter for the
    importance film), the centre, the crop window seen from the centre (pixels, low and
    high corners) and the lens numbers (lens position and, in spectral variants, the
    wavelengths)."""
    # Film positions are normalized over the crop window, as Mitsuba's sensors take them.
    crop_size = setup.scene.sensor.film().crop_size()
    px = mi.Float(layout.pixel % crop_size[0])
    py = mi.Float(layout.pixel // crop_size[0])
    u_film = streams.film_2d(layout.group, layout.index, setup.groups_per_pixel)
    center = mi.Point2f((px + 0.5) / crop_size[0], (py + 0.5) / crop_size[1])
    # the crop window seen from the pixel centre (pixels)
    window_lo = mi.Vector2f(-(px + 0.5), -(py + 0.5))
    window_hi = mi.Vector2f(crop_size[0] - (px + 0.5), crop_size[1] - (py + 0.5))
    sampler = setup.film_sampler
    film_offset = mi.Vector2f(sampler.offset(mi, u_film.x, window_lo.x, window_hi.x),
                              sampler.offset(mi, u_film.y, window_lo.y, window_hi.y))
    pos = center + mi.Vector2f(film_offset.x / crop_size[0], film_offset.y / crop_size[1])
    # the lens position and (spectral variants) the wavelengths, shared like the film
    lens = (streams.get_2d(0, sampling.DIM_APERTURE), streams.get_1d(0, sampling.DIM_WAVELENGTH))
    return pos, film_offset, center, window_lo, window_hi, lens


def vertex_numbers(streams, depth, u_em_first, u_dir_first):
    """The random numbers of the decisions at surface hit ``depth`` (0-based, sampling
    stage depth + 1): light sample, BSDF lobe and direction, Russian roulette; the
    first hit's light and BSDF samples from the pixel's low-discrepancy set."""
    stage = depth + 1
    dim_em = sampling.bounce_dim(depth, sampling.BOUNCE_EMITTER)
    dim_dir = sampling.bounce_dim(depth, sampling.BOUNCE_BSDF_DIR)
    if streams.joint is not None:  # every hit's light and BSDF samples from joint sets
        further_em, further_dir = (streams.joint_decision(depth, k) for k in (0, 1))
    else:
        further_em, further_dir = streams.get_2d(stage, dim_em), streams.get_2d(stage, dim_dir)
    u_em = dr.select(depth == 0, u_em_first, further_em)
    u_dir = dr.select(depth == 0, u_dir_first, further_dir)
    u_lobe = streams.get_1d(stage, sampling.bounce_dim(depth, sampling.BOUNCE_BSDF_LOBE))
    u_rr = streams.get_1d(stage, sampling.bounce_dim(depth, sampling.BOUNCE_RR))
    return u_em, u_lobe, u_dir, u_rr


class Vertex:
    """What a path finds at one surface hit: the emission it hits and the light sample
    it takes (each as its contribution without the modulation, its MIS weight and its
    full path length), and the BSDF sample that continues it (``em_sample``: the light
    sample's DirectionSample3f, where the FMCW loop reads its point and direction)."""

    __slots__ = ("valid", "through", "hit_emitter", "emitted", "mis_hit", "length_hit",
                 "active_em", "em_value", "mis_em", "length_em", "active_next", "bs",
                 "bsdf_weight", "em_sample")


#: a path's state, the tuple that shade and advance take and advance returns, in this order
PATH_STATE = ("ray", "throughput", "length from the camera (m)", "surface hits so far",
              "whether it goes on", "previous vertex (MIS)", "last BSDF sample's pdf",
              "whether that sample was a delta lobe", "relative index of refraction")


def path_start(mi, ray, weight, offset, active, F=None):
    """A path's state (PATH_STATE) at its camera ray (``F``: the path length's type)."""
    return (ray, mi.Spectrum(weight), (F or mi.Float)(offset), mi.UInt32(0), mi.Bool(active),
            dr.zeros(mi.Interaction3f), mi.Float(1.0), mi.Bool(True), mi.Float(1.0))


def shade(mi, settings: LoopSettings, path: tuple, frames: tuple, si, numbers, visible=None,
          light=None) -> Vertex:
    """One surface hit ``si`` of a path (``path``: its state, PATH_STATE, whose ray found
    ``si``), the bodies and lights placed by ``frames`` = (BodyFrames, LightFrames) at
    its lanes' times (each None where nothing moves), with the decisions' random numbers
    ``numbers`` (vertex_numbers); ``visible``: whether its light sample is unoccluded,
    where that is known (a Bool; None: the shadow ray is traced); ``light``: None (the
    scene's lights), or a function ``(si, active) -> (ds, weight)`` drawing the light
    sample instead (the FMCW collimated beam's spot, fmcw/beam.py)."""
    ray, beta, length, depth, active, prev_si, prev_bsdf_pdf, prev_bsdf_delta, _ = path
    static, F, max_depth = settings.static, settings.F, settings.max_depth
    body_frames, light_frames = frames
    v = Vertex()
    u_em, u_lobe, u_dir, _ = numbers
    valid = active & si.is_valid()
    length_hit = length + F(dr.select(valid, si.t, 0.0))

    # ---- Emission from an emitter hit by the ray ----
    # (null emitter pointers evaluate to zero)
    emitter = si.emitter(static)
    # hide_emitters, as in Mitsuba 3.9's path tracer: camera rays pass through
    # emitters (the path goes on behind them, its length too)
    through = (valid & (depth == 0) & (emitter != None)  # noqa: E711
               if settings.hide_direct_emitters else mi.Bool(False))
    hit_emitter = valid & ((depth > 0) | (not settings.hide_direct_emitters))
    ds = mi.DirectionSample3f(static, si, prev_si)
    em_pdf = dr.select(prev_bsdf_delta, 0.0,
                       static.pdf_emitter_direction(prev_si, ds, hit_emitter & ~prev_bsdf_delta))
    v.mis_hit = _mis_power(prev_bsdf_pdf, em_pdf)
    v.emitted = beta * emitter.eval(si, hit_emitter)

    active_next = valid & (depth + 1 < max_depth) & ~through
    bsdf = si.bsdf(ray)

    # ---- Next-event estimation ----
    active_em = active_next & mi.has_flag(bsdf.flags(), mi.BSDFFlags.Smooth)
    ds, em_weight = (sample_light(mi, static, light_frames, si, u_em, active_em)
                     if light is None else light(si, active_em))
    active_em &= (ds.pdf != 0.0) & dr.isfinite(ds.dist)
    if visible is None:
        active_em &= ~occluded(mi, static, body_frames, si.spawn_ray_to(ds.p), active_em)
    else:
        active_em &= visible
    wo = si.to_local(ds.d)

    # ---- BSDF evaluation and sampling ----
    bsdf_val, bsdf_pdf, v.bs, v.bsdf_weight = bsdf.eval_pdf_sample(
        settings.bsdf_ctx, si, wo, u_lobe, u_dir, active_next)
    v.mis_em = dr.select(ds.delta, 1.0, _mis_power(ds.pdf, bsdf_pdf))
    v.em_value = beta * bsdf_val * em_weight
    v.length_em = length_hit + F(ds.dist)
    v.em_sample = ds
    v.valid, v.through, v.hit_emitter, v.length_hit = valid, through, hit_emitter, length_hit
    v.active_em, v.active_next = active_em, active_next
    return v


def sample_light(mi, static, light_frames, si, u_em, active):
    """A light sample seen from ``si`` (no visibility test): (direction sample, weight),
    the lights moved to the lanes' times where any moves (``light_frames``)."""
    if light_frames is not None:
        return lights.sample_emitter_direction(mi, static, light_frames, si, u_em, active)
    return static.sample_emitter_direction(si, u_em, False, active)


def advance(mi, path: tuple, si, v: Vertex) -> tuple:
    """The path's state (PATH_STATE) after vertex ``v`` at ``si``, before the roulette:
    its next ray (straight on through a hidden emitter), its length to the hit and what
    follows the BSDF sample."""
    ray, beta, _, depth, active, prev_si, prev_bsdf_pdf, prev_bsdf_delta, eta = path
    ray = dr.select(v.through, si.spawn_ray(ray.d), si.spawn_ray(si.to_world(v.bs.wo)))
    bounced = ~v.through
    beta = dr.select(bounced, beta * v.bsdf_weight, beta)
    eta = dr.select(bounced, eta * v.bs.eta, eta)
    prev_si = dr.select(bounced, mi.Interaction3f(si.t, si.time, si.wavelengths, si.p, si.n),
                        prev_si)
    prev_bsdf_pdf = dr.select(bounced, v.bs.pdf, prev_bsdf_pdf)
    prev_bsdf_delta = dr.select(bounced, mi.has_flag(v.bs.sampled_type, mi.BSDFFlags.Delta),
                                prev_bsdf_delta)
    depth = dr.select(v.valid & bounced, depth + 1, depth)
    return (ray, beta, v.length_hit, depth, active, prev_si, prev_bsdf_pdf, prev_bsdf_delta,
            eta)


def roulette(beta, eta, depth, rr_depth):
    """Russian roulette: the throughput's largest channel (before the roulette), the
    survival probability, and whether it plays at ``depth``."""
    beta_max = dr.max(beta)
    return beta_max, dr.minimum(beta_max * dr.square(eta), 0.95), depth >= rr_depth


def survive(mi, v, beta, eta, depth, rr_depth, u_rr):
    """Russian roulette after vertex ``v``: the throughput (divided by the survival
    probability where the roulette plays) and whether the path goes on (UInt32 1 or
    0): it has a next ray, survives the roulette and carries light, or passes through
    a hidden emitter."""
    beta_max, rr_prob, rr_active = roulette(beta, eta, depth, rr_depth)
    beta = dr.select(rr_active, beta * dr.rcp(rr_prob), beta)
    going = mi.UInt32(dr.select(
        (v.active_next & (~rr_active | (u_rr < rr_prob)) & (beta_max != 0.0)) | v.through,
        1, 0))
    return beta, going


#: the deepest path whose light samples' visibility a UInt32 holds, a bit per depth
#: (light samples are taken at depths below max_depth - 1; lit_bits)
VISIBILITY_BITS_MAX_DEPTH = 33


def lit_bits(mi, v, depth):
    """The bit of ``depth`` (UInt32) where vertex ``v``'s light sample reached its light:
    OR-ed over a path's vertices, the bits the path-replay adjoint reads back
    (:func:`lit_at`) instead of tracing the shadow rays again (a camera ray's pass
    through a hidden emitter, at the depth of the hit after it, takes no light
    sample)."""
    return dr.select(v.active_em, mi.UInt32(1) << depth, 0)


def lit_at(bits, depth):
    """Whether the light sample at ``depth`` reached its light (lit_bits' ``bits``;
    None where they were not recorded)."""
    if bits is None:
        return None
    return ((bits >> depth) & 1) != 0


class LoopSettings:
    """What every vertex of a pass's paths reads and no vertex changes: the static
    scene, the depth limit (a UInt32), the iteration hint, the Russian roulette depth,
    whether directly visible emitters are hidden, the path length's type ``F`` and the
    BSDF context.

    A plain object (not a dataclass, not a tuple): Dr.Jit's loop transform takes a
    dataclass or tuple read in a loop for loop state. The hint bounds the iterations
    for the loop's reverse-mode replay (its state is recorded on a stack of that many
    entries): max_depth surface hits, plus camera rays that pass through hidden
    emitters without a bounce (one iteration each)."""

    def __init__(self, mi, setup, F=None):
        params = setup.params
        through = 2 if setup.hide_emitters else 0  # (passes through emitters, at depth 0)
        self.static = setup.scene.static
        self.max_depth = mi.UInt32(params.max_depth if params.max_depth > 0 else 0xFFFFFFFF)
        self.max_iterations = params.max_depth + through if params.max_depth > 0 else -1
        self.rr_depth = params.rr_depth
        self.hide_direct_emitters = setup.hide_emitters
        self.F = F or mi.Float
        self.bsdf_ctx = mi.BSDFContext()


class CameraSample:
    """Each lane's start: its time and camera ray, with what the path needs from them."""

    def __init__(self, **fields):
        self.__dict__.update(fields)
