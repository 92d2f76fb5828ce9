"""The FMCW spectra: the D-ToF path tracer's steps, each contribution splatted at its
beat frequencies (docs/fmcw.md).

A chirp lasts microseconds: the scene is traced at one instant t0 (mid-exposure, the
time of the ground truth). Each lane starts as the D-ToF integrator's (film position,
lens, camera ray: :func:`..integrators.path_steps.film_position`, ``Camera.ray``) and
walks its path with the same steps (``shade``, ``advance``, ``survive``). Alongside its
length L the path carries its rate dL/dt, from the velocities of its vertices as
material points (bodies, camera and lights by their analytic motion at t0):

    dL/dt = sum over segments a -> b of  d_ab . (u_b - u_a)

(d_ab the segment's unit direction). Each contribution (emitter hit or light sample,
with its MIS weight; with a collimated beam, :mod:`.beam`'s direct return and light from
the beam's spot) adds its value (the mean of its colour channels) to its pixel's up and
down spectra at |f_up| and |f_down| (:class:`.chirp.Chirp`), split linearly between the
two nearest bins; beats past the last bin are dropped. Pixels average their own samples
(a box filter). With speckle each contribution also adds its amplitude at a random phase
to its bins' coherent sums.

The adds are atomic (``dr.scatter_reduce`` from the path loop), so a spectrum is
reproducible to float32 rounding, not bitwise as the D-ToF images are.
"""

from __future__ import annotations

from dataclasses import replace

import drjit as dr
import numpy as np

from .. import sampling
from ..fmcw_settings import FMCWSettings
from ..integrators.path_loop import Modality, trace_path_loop
from ..integrators.path_steps import (CameraSample, PassLayout, _as_colour, film_position,
                                      lane_streams)
from ..modulation import SPEED_OF_LIGHT
from ..params import RenderParams
from ..scene import lights
from ..scene.bodies import BodyFrames, nearest_hit, surface_interaction
from ..scene.parameters import parsed
from ..tof.ground_truth import camera_origin, mid_exposure, velocity_field
from .beam import Beam

#: the most spectrum values (pixels x 2 x bins) a frame may hold: 4 GiB on the host in
#: float64, 2 GiB on the device in float32
MAX_SPECTRUM_VALUES = 1 << 29


class VelocityFields:
    """The velocities (m/s) of the scene's material points at t0, each moving part's as
    an affine map u = A x + b of the world point x (float64 on the host, then constants
    of the kernel): the bodies', the moving lights' and the camera centre's."""

    def __init__(self, mi, scene, t0: float, exposure: float):
        self.mi = mi
        self.bodies = [_affine(velocity_field(b.motion, t0, exposure)) for b in scene.bodies]
        self.lights = [(index, _affine(velocity_field(m, t0, exposure)))
                       for index, m in scene.light_motions]
        u_camera = np.zeros(3)
        if scene.sensor_motion is not None:
            centre = scene.sensor_motion.relative_matrix(t0) @ np.append(
                camera_origin(scene), 1.0)
            u_camera = (velocity_field(scene.sensor_motion, t0, exposure) @ centre)[:3]
        self.camera = mi.Vector3f(*map(float, u_camera))  #: the camera centre's velocity

    def _moved(self, x, fields, masks):
        mi = self.mi
        u = mi.Vector3f(0.0)
        for (A, b), mask in zip(fields, masks):
            moving = mi.Vector3f(*(sum(A[i][j] * x[j] for j in range(3)) + b[i]
                                   for i in range(3)))
            u = dr.select(mask, moving, u)
        return u

    def at_surface(self, x, winner):
        """The velocity of surface point ``x`` of the scene ``winner`` names (body k, or
        ``len(bodies)``: static, at rest)."""
        return self._moved(x, self.bodies, [winner == k for k in range(len(self.bodies))])

    def at_light_sample(self, static, ds, u_em, v):
        """The velocity of the point ``ds.p`` that vertex ``v``'s light sample (drawn
        with ``u_em``) reached on its emitter (the emitter chosen again as
        ``Scene.sample_emitter_direction`` chose it)."""
        if not self.lights:
            return self.mi.Vector3f(0.0)
        index, _, _ = static.sample_emitter(u_em.x, v.active_em)
        return self._moved(ds.p, [f for _, f in self.lights],
                           [index == k for k, _ in self.lights])


def _affine(V):
    """(A, b) of a 4x4 velocity field, as nested Python floats."""
    return [[float(V[i, j]) for j in range(3)] for i in range(3)], [float(V[i, 3])
                                                                      for i in range(3)]


class SpectrumSplat:
    """The spectra of a pass's pixels, (pixels, 2, M) in one flat Float, and how a
    contribution adds to them; with ``speckle`` also each bin's coherent sum of the
    contributions' amplitudes sqrt(value) e^(i phase), its real and imaginary parts."""

    def __init__(self, mi, chirp, n_pixels: int, speckle: bool = False):
        self.mi = mi
        self.bins = chirp.bins
        size = n_pixels * 2 * chirp.bins
        self.values = dr.zeros(mi.Float, size)
        self.real = dr.zeros(mi.Float, size) if speckle else None
        self.imag = dr.zeros(mi.Float, size) if speckle else None
        for array in (self.values, self.real, self.imag):
            if array is not None:
                dr.make_opaque(array)
        self.per_metre = dr.opaque(mi.Float, chirp.slope / SPEED_OF_LIGHT / chirp.bin_width)
        self.per_rate = dr.opaque(mi.Float, 1.0 / (chirp.wavelength * chirp.bin_width))

    def add(self, pixel, value, path_length, rate, active, phase=None):
        """Add ``value`` at the beats of paths of ``path_length`` and ``rate`` (dL/dt);
        with speckle also its amplitude at ``phase`` (a fraction of a turn; both chirps
        share it: it is the path's)."""
        mi = self.mi
        centre, doppler = path_length * self.per_metre, rate * self.per_rate  # in bins
        for chirp, position in enumerate((centre + doppler, centre - doppler)):
            position = dr.abs(position)
            low = mi.UInt32(dr.floor(position))
            upper = position - mi.Float(low)
            base = (pixel * 2 + chirp) * self.bins
            inside = active & (value != 0.0) & (position < self.bins - 1)
            for index, share in ((base + low, 1.0 - upper), (base + low + 1, upper)):
                dr.scatter_reduce(dr.ReduceOp.Add, self.values, value * share, index, inside)
                if self.real is not None:  # (the split keeps each bin's expected power)
                    amplitude = dr.sqrt(dr.maximum(value * share, 0.0))
                    sin, cos = dr.sincos(dr.two_pi * phase)
                    dr.scatter_reduce(dr.ReduceOp.Add, self.real, amplitude * cos, index,
                                      inside)
                    dr.scatter_reduce(dr.ReduceOp.Add, self.imag, amplitude * sin, index,
                                      inside)


def _grey(mi, value, wavelengths):
    """The mean of a contribution's colour channels (the laser is one wavelength)."""
    colour = _as_colour(mi, value, wavelengths)
    return sum(colour[i] for i in range(len(colour))) * (1.0 / len(colour))


#: the random numbers the FMCW lidar reads of its own: a collimated beam's spot (its
#: film position, per lane: beam.py) and the speckle phases of a hit's two
#: contributions (per bounce)
DIMENSIONS = sampling.ModalityDimensions(lane=(("beam_film", 2),),
                                         bounce=(("phases", 2),))


def path_phases(streams, depth):
    """The random phases (fractions of a turn) of the two contributions at surface hit
    ``depth``: the emitter hit or direct return, and the light sample or the beam's spot
    (:data:`DIMENSIONS`' "phases")."""
    stage = depth + 1
    return tuple(streams.get_1d(stage, DIMENSIONS.bounce_dim(depth, "phases", k))
                 for k in (0, 1))


def _add_flood(mi, splat, fields, static, v, numbers, rate_hit, u_here, pixel, wavelengths,
               phases):
    """Vertex ``v``'s emitter hit and light sample at their beats (the scene's lights;
    ``rate_hit``: dL/dt to the vertex, moving at ``u_here``; ``phases``: theirs)."""
    splat.add(pixel, _grey(mi, v.emitted * v.mis_hit, wavelengths), v.length_hit, rate_hit,
              v.hit_emitter, phases[0])
    ds = v.em_sample
    rate_em = rate_hit + dr.dot(ds.d, fields.at_light_sample(static, ds, numbers[0], v) - u_here)
    splat.add(pixel, _grey(mi, v.em_value * v.mis_em, wavelengths), v.length_em, rate_em,
              v.active_em, phases[1])


def lane_start(mi, setup, layout: PassLayout, streams, t0: float):
    """Each lane's camera ray at t0 (its film position and lens point as the D-ToF
    integrator's), its weight and its length to the ray's origin, and the bodies' and
    the lights' transforms at t0."""
    scene = setup.scene
    pos, _, _, _, _, lens = film_position(mi, setup, layout, streams)
    time = dr.full(mi.Float, t0, dr.width(pos))
    ray, weight, offset = setup.camera.ray(pos, time, *lens)
    frames = BodyFrames(mi, scene.bodies, time, t0, t0) if scene.bodies else None
    light_frames = (lights.LightFrames(mi, scene.light_motions, time)
                    if scene.light_motions else None)
    return ray, weight, offset, frames, light_frames


def trace_spectra(mi, setup, layout: PassLayout, fields: VelocityFields, splat: SpectrumSplat,
                  t0: float, beam: Beam):
    """One pass: every lane's path (the path loop, :func:`trace_path_loop`), its
    contributions splatted into ``splat``."""
    streams = lane_streams(mi, setup, layout)
    ray, ray_weight, offset, frames, light_frames = lane_start(mi, setup, layout, streams, t0)
    start = CameraSample(ray=ray, ray_weight=ray_weight, camera_offset=offset, active=True,
                         frames=frames, light_frames=light_frames)
    spot = beam.start(mi, setup, layout, streams, DIMENSIONS.lane_dim("beam_film"),
                      ray.time, frames, fields)  # (collimated)
    trace_path_loop(mi, setup, layout, streams, start,
                    Spectra(mi, setup.scene.static, splat, fields, beam, spot, streams,
                            layout.pixel, ray.wavelengths))


class Spectra(Modality):
    """The FMCW lidar's modality: each contribution added to its pixel's spectra at its
    beats, from its path length and rate of change (dL/dt, accumulated vertex by vertex
    from the velocity fields: the loop state with the last vertex's velocity)."""

    label = "dopplertof_fmcw"
    dimensions = DIMENSIONS

    def __init__(self, mi, static, splat, fields, beam, spot, streams, pixel, wavelengths):
        self.mi, self.static, self.splat, self.fields = mi, static, splat, fields
        self.beam, self.spot = beam, spot
        self.streams, self.pixel, self.wavelengths = streams, pixel, wavelengths
        self.bsdf_ctx = mi.BSDFContext()

    def state(self) -> tuple:
        # the path's rate dL/dt so far, the velocity of its last vertex (m/s)
        return self.mi.Float(0.0), self.mi.Vector3f(self.fields.camera)

    def hit(self, mi, static, frames, ray, active, depth, fresh):
        pi, winner = nearest_hit(mi, static, frames, ray, active, coherent=depth == 0)
        return surface_interaction(mi, static, frames, ray, pi, winner, active), winner

    def light(self, depth, max_depth, bsdf_ctx):
        return self.beam.spot_light(self.spot, depth, max_depth, bsdf_ctx)

    def vertex(self, state, si, winner, ray, v, beta, depth, numbers):
        mi, splat, beam, pixel = self.mi, self.splat, self.beam, self.pixel
        rate, u_prev = state
        # ---- The contributions at their beats ----
        u_here = self.fields.at_surface(si.p, winner)
        rate_hit = rate + dr.dot(ray.d, u_here - u_prev)
        phases = path_phases(self.streams, depth)  # (speckle only)
        if beam.collimated:  # the direct return, the lane's spot
            for (value, beat_length, beat_rate, lit), phase in zip((
                    beam.direct(si, ray, v, beta, depth, rate_hit, self.bsdf_ctx),
                    beam.from_spot(v, self.spot, rate_hit, u_here)), phases):
                splat.add(pixel, _grey(mi, value, self.wavelengths), beat_length, beat_rate,
                          lit, phase)
        else:  # the emitter hit and the light sample
            _add_flood(mi, splat, self.fields, self.static, v, numbers, rate_hit,
                       u_here, pixel, self.wavelengths, phases)
        return rate_hit, u_here


def fmcw_params(scene, params=None) -> tuple[RenderParams, FMCWSettings]:
    """The scene's render parameters and FMCW settings with ``params`` over them (a
    mapping of either's names, fmcw_* included, or RenderParams), the render parameters
    set for FMCW: independent samples, each its own film position (no time is sampled)."""
    base, settings = scene.params, scene.modality_settings["fmcw"]
    if isinstance(params, RenderParams):
        base = params
    elif params is not None:
        base, parsed_settings = parsed(dict(params), "render parameters", base,
                                       scene.modality_settings)
        settings = parsed_settings["fmcw"]
    return replace(base, time_correlate_number=1, time_sampling_method="uniform",
                   path_correlate_number=None, antithetic_mapping=None,
                   adaptive_sampling=False, samples_per_pass=-1), settings


def render_spectra(scene, chirp, spp: int, seed: int = 0, params=None, beam: str = "flood",
                   beam_intensity: float = 1.0, speckle: bool = False):
    """The (H, W, 2, M) float64 spectra of ``scene`` (a DopplerScene): each pixel's mean
    over ``spp`` samples of its contributions at their up (0) and down (1) beats, lit by
    ``beam`` (:mod:`.beam`); t0, the time traced; and with ``speckle`` the spectra of the
    coherent sums, |sum of sqrt(value) e^(i phase)|^2 / spp per bin (else None)."""
    from ..integrators.dtof_path import integrator_class
    from ..integrators.pipeline import DEFAULT_MAX_LANES, _resolve

    mi, p, spp, seed = _resolve(scene, spp, seed, fmcw_params(scene, params)[0])
    width, height = (int(v) for v in scene.sensor.film().crop_size())
    if width * height * 2 * chirp.bins > MAX_SPECTRUM_VALUES:
        raise ValueError(f"{width}x{height} pixels x 2 chirps x {chirp.bins} bins is "
                         f"{width * height * 2 * chirp.bins:,} spectrum values, over the "
                         f"{MAX_SPECTRUM_VALUES:,} a frame may hold: fewer bins or pixels")
    setup = integrator_class(mi)().prepared(scene, p, spp, int(seed),
                                            lit_by_beam=beam == "collimated")
    start, t0, end = mid_exposure(scene, p)
    fields = VelocityFields(mi, scene, t0, end - start)
    lidar_beam = Beam(mi, scene, beam, beam_intensity, t0)
    n_pixels = width * height
    per_pass = max(1, DEFAULT_MAX_LANES // n_pixels)  # (the D-ToF passes' bound)
    total = np.zeros(n_pixels * 2 * chirp.bins)
    coherent = np.zeros(n_pixels * 2 * chirp.bins, np.complex128) if speckle else None
    with dr.suspend_grad():
        for s0 in range(0, spp, per_pass):
            layout = PassLayout(mi, n_pixels, min(per_pass, spp - s0),
                                dr.opaque(mi.UInt32, s0), 1)
            splat = SpectrumSplat(mi, chirp, n_pixels, speckle)
            trace_spectra(mi, setup, layout, fields, splat, t0, lidar_beam)
            total += splat.values.numpy()
            if speckle:
                coherent += splat.real.numpy() + 1j * splat.imag.numpy()
    shape = (height, width, 2, chirp.bins)
    return ((total / spp).reshape(shape), t0,
            None if coherent is None else (np.abs(coherent) ** 2 / spp).reshape(shape))
