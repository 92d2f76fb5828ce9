"""The D-ToF path tracer: the integrator class (the Mitsuba plugin ``dopplertof``) and
its symbolic path loop, one Dr.Jit kernel per pass.

A unidirectional path tracer (next-event estimation and BSDF sampling combined with
MIS, Russian roulette) in which every contribution is weighted by the modulation of
its own full path length at its own sample time (design.md section 1). Doppler shifts
are not added by hand: they follow because path lengths depend on time.

Time-path sampling (design.md section 2) decides each lane's time and which of its
random numbers it shares with the other samples of its group. The steps of a path
are in :mod:`.path_steps`, the render pipeline around the passes in :mod:`.pipeline`.

The class derives from the variant's ``mi.SamplingIntegrator`` (Dr.Jit variants are
switched at run time), so :func:`integrator_class` makes it once per variant; it is
registered with Mitsuba at the bottom of this file.
"""

from __future__ import annotations

import drjit as dr

from .. import sampling
from ..pixel_sets import JointSets
from ..params import RenderParams
from ..scene import lights
from ..scene.bodies import BodyFrames
from ..scene.motion import opaque_tree
from ..scene.parameters import parsed
from ..scene.scene import DTOF_INTEGRATORS, loaded, require_light
from . import pipeline
from .analytic import trace_analytic_pass
from .control_variate import trace_control_variate_pass
from .camera import Camera, LensDistortion, PinholeProjection, is_pinhole, rest_forward
from .film import FilmSampler, SplatFilter
from .path_loop import Modality, trace_path_loop
from .path_steps import (VISIBILITY_BITS_MAX_DEPTH, CameraSample, ModulationWeight, PassLayout,
                         _as_colour, _camera_rays, _intersect, contributions, film_position,
                         lane_streams, length_derivatives, lit_bits)

_classes: dict = {}  # variant name -> its DopplerToFPath class


def integrator_class(mi):
    """The DopplerToFPath class of the current variant (a ``mi.SamplingIntegrator``)."""
    cls = _classes.get(mi.variant())
    if cls is None:
        cls = _classes[mi.variant()] = _define_class(mi)
    return cls


def _define_class(mi):
    class DopplerToFPath(mi.SamplingIntegrator):
        """The D-ToF path tracer, as Mitsuba's ``ADIntegrator``: constructed from the
        plugin's properties (or with the defaults); :meth:`render` is Mitsuba's entry
        point and :meth:`render_result` the pipeline's (integrators/pipeline.py), which
        renders through :meth:`prepared`, a copy that holds everything the kernel reads
        for one render; :meth:`sample_camera` starts each lane (time, film position,
        lens, camera ray) and :meth:`trace` runs the path loop of one pass."""

        def __init__(self, props=None):
            props = mi.Properties() if props is None else props
            super().__init__(props)
            self.mi = mi
            #: the plugin's parameters (a DopplerScene's own are used for it instead),
            #: and the other modalities' settings it carries ({modality: settings})
            self.params, self.modality_settings = parsed(
                {name: props[name] for name in props.keys()}, "integrator dopplertof",
                RenderParams())

        # ---- Mitsuba's interface ----

        def render(self, scene, sensor=0, seed=0, spp=0, develop=True, evaluate=True):
            """``mi.render``: the D-ToF image of a static Mitsuba scene (its first
            sensor), with this plugin's parameters."""
            if not isinstance(sensor, int) and sensor is not scene.sensors()[0]:
                raise ValueError("dopplertof renders the scene's first sensor only")
            dscene = loaded(mi, scene, self.params, settings=self.modality_settings)
            result = self.render_result(dscene, spp=spp or None, seed=int(seed),
                                        progress=False)
            return mi.TensorXf(result.image)

        def sample(self, *args, **kwargs):
            raise NotImplementedError("dopplertof renders whole images: use render()")

        def to_string(self):
            return f"DopplerToFPath[{self.params}]"

        # ---- The render pipeline's interface ----

        def render_result(self, scene, spp=None, seed=0, params=None, **options):
            """Render a DopplerScene (see :func:`dopplertof.render_result`)."""
            return pipeline.render_result(self, scene, spp, seed, params, **options)

        def prepared(self, scene, params, spp: int, seed: int, lit_by_beam: bool = False):
            """A copy of this integrator for one render of ``scene`` with ``params``
            (``auto`` resolved), ``spp`` and ``seed``: its attributes are what the
            kernel reads. A scene without emitters is refused unless an FMCW frame's
            collimated beam lights it (``lit_by_beam``)."""
            require_light(scene.static, scene.source, lit_by_beam)
            integrator = type(self)()
            integrator._prepare(scene, params, spp, seed)
            return integrator

        def _prepare(self, scene, params, spp: int, seed: int) -> None:
            """What the kernel reads, as typed attributes (one render: scene, ``auto``
            resolved parameters, spp, seed)."""
            sensor = scene.sensor
            mod = params.modulation(scene.shutter_interval)
            near_clip = float(sensor.near_clip()) if hasattr(sensor, "near_clip") else 0.0
            analytic = params.time_sampling_method == sampling.ANALYTIC
            splat = params.film_sampling == "splat"
            self.scene = scene  #: the DopplerScene (static scene, bodies, sensor, lights)
            self.params = params  #: RenderParams, ``auto`` resolved
            self.modulation = mod  #: params.Modulation: frequencies, phase, waveform (SI)
            self.modulation_weight = ModulationWeight(mi, mod)  #: w(L, t) of a contribution
            # the seed's stream key: both words of a seed of 2^32 or more (sampling.seed_words)
            low, high = sampling.seed_words(seed)
            self.seed = dr.opaque(mi.UInt32, low)
            self.seed_high = None if high is None else dr.opaque(mi.UInt32, high)
            self.correlation_depth, self.method = _kernel_sampling(mi, params)
            self.antithetic_shift = dr.opaque(self.modulation_weight.F, mod.antithetic_shift)
            self.group_size: int = params.time_correlate_number  #: K
            self.groups_per_pixel: int = spp // params.time_correlate_number
            self.path_group_size: int = params.path_group_size  #: Kp, samples on one path stream
            self.stratify: bool = params.use_stratified_sampling_for_each_interval
            #: the tiles' joint sets (pixel_sets="joint"), else None (each pixel's own)
            crop_width, crop_height = sensor.film().crop_size()
            self.joint_sets = (None if params.pixel_sets != "joint" else JointSets(
                crop_width, spp, self.group_size, self.path_group_size,
                pipeline.pilot_samples(spp, self.group_size, params), crop_height))
            self.shutter_open: float = scene.shutter_open  #: the exposure's start (s)
            #: the exposure's start and length T (s), opaque: one kernel for every window
            self.opens = dr.opaque(mi.Float, scene.shutter_open)
            self.exposure = dr.opaque(self.modulation_weight.F, mod.exposure)
            #: film positions within a pixel: uniform (splat film) or from the filter
            self.film_sampler = FilmSampler.uniform() if splat else FilmSampler(sensor.film())
            #: the splat film's filter, or None for the importance film
            self.splat = SplatFilter(sensor.film()) if splat else None
            lens = LensDistortion.of(sensor, getattr(scene, "lens_distortion", None))
            forward = opaque_tree(mi.Float, [float(x) for x in rest_forward(sensor)])
            self.camera = Camera(mi, sensor, scene.sensor_motion,
                                 dr.opaque(mi.Float, near_clip), mi.Vector3f(*forward), lens)
            #: the pinhole film map, when pairs use the motion mapping (else None)
            self.projection = None
            if params.antithetic_mapping == "motion":
                if lens is not None:
                    raise ValueError("antithetic_mapping='motion' needs an undistorted "
                                     "pinhole; this camera's lens distorts")
                if not is_pinhole(sensor):
                    raise ValueError(
                        "antithetic_mapping='motion' needs a pinhole perspective sensor, got "
                        f"{sensor.class_name()}")
                self.projection = PinholeProjection(mi, sensor, scene.sensor_motion, near_clip)
            self.hide_emitters: bool = params.hide_emitters
            #: time integrated, not sampled (analytic.trace_analytic_pass traces it)
            self.analytic: bool = analytic
            #: the analytic integral as a control variate (control_variate's pass)
            self.control_variate: bool = (
                params.time_sampling_method == sampling.CONTROL_VARIATE)

        def sample_camera(self, layout: PassLayout, streams) -> CameraSample:
            """Each lane's time, film position, lens point and camera ray (sampling stage 0),
            the body and light transforms at its time, and its first hit when the camera
            rays were traced already (motion-mapped pairs)."""
            mi, mod, scene = self.mi, self.modulation, self.scene

            # ---- Time of each lane ----
            def exposure_fraction(index):
                return sampling.time_fraction(
                    mi, streams, layout.group, index, group_size=self.group_size,
                    groups_per_pixel=self.groups_per_pixel, method=self.method,
                    antithetic_shift=self.antithetic_shift, stratify=self.stratify,
                    double=not mod.low_pass,
                )

            t_frac = exposure_fraction(layout.index)
            # since exposure start (float64 in full-waveform mode), and absolute for the motion
            t_rel = t_frac * self.exposure
            time = mi.Float(t_rel) + self.opens

            # ---- Camera ray ----
            pos, film_offset, center, window_lo, window_hi, lens = film_position(
                mi, self, layout, streams)
            partner_fraction = (exposure_fraction(1 - layout.index)
                                if self.projection is not None else None)
            ray, ray_weight, camera_offset, first_hit, active, lane_pos = _camera_rays(
                mi, self, layout, pos, center, (window_lo, window_hi), time, partner_fraction,
                lens)
            if lane_pos is not None:  # a mapped partner's film position is its own
                crop_size = scene.sensor.film().crop_size()
                film_offset = mi.Vector2f((lane_pos.x - center.x) * crop_size[0],
                                          (lane_pos.y - center.y) * crop_size[1])

            # ---- Lights and bodies at the lanes' times, once per path ----
            light_frames = (lights.LightFrames(mi, scene.light_motions, time)
                            if scene.light_motions else None)
            frames = (BodyFrames(mi, scene.bodies, time, self.shutter_open,
                                 self.shutter_open + mod.exposure) if scene.bodies else None)
            return CameraSample(t_rel=t_rel, ray=ray, ray_weight=ray_weight,
                                camera_offset=camera_offset, first_hit=first_hit, active=active,
                                film_offset=film_offset, light_frames=light_frames, frames=frames,
                                time=time, film_position=pos, lens=lens)

        def trace(self, layout: PassLayout, length_derivative: bool = False):
            """Render one pass; returns each lane's time-averaged measurement (the
            variant's Spectrum; RGB in spectral variants) and its film position's offset
            from its pixel's centre, in pixels (Vector2f; the splat film weighs the lane
            with it). With ``length_derivative`` also each lane's sum of its
            contributions' derivatives with respect to their path lengths (the
            sampled loop only: what the path-replay adjoint needs) and which of its
            light samples reached their lights (lit_bits; None for paths deeper than
            VISIBILITY_BITS_MAX_DEPTH)."""
            if self.analytic:
                return trace_analytic_pass(mi, self, layout)
            if self.control_variate:
                return trace_control_variate_pass(mi, self, layout)
            streams = lane_streams(mi, self, layout)
            return _trace_paths(mi, self, layout, streams, self.sample_camera(layout, streams),
                                length_derivative)

        def adjoint(self, layout: PassLayout, delta, total, total_dl, motion: bool = True,
                    lit=None):
            """The path-replay adjoint pass of ``trace(layout, length_derivative=True)``
            (its ``total`` and ``total_dl``): back-propagates each lane's ``delta``
            (d loss / d lane value) into the attached parameters (``motion``: a body's
            or the camera's motion among them), as side effects that the next
            ``dr.eval()`` runs (integrators/path_adjoint.py); ``lit``: the trace's
            light sample bits, where it recorded them (its shadow rays are not traced
            again)."""
            from .path_adjoint import adjoint_paths

            with dr.suspend_grad():
                streams = lane_streams(mi, self, layout)
                adjoint_paths(mi, self, layout, streams, self.sample_camera(layout, streams),
                              delta, total, total_dl, motion, lit)

    DopplerToFPath.__qualname__ = "DopplerToFPath"  # (not _define_class.<locals>...)
    return DopplerToFPath


def _kernel_sampling(mi, params):
    """The kernel's path correlation depth and time-sampling method number (opaque)."""
    method = params.time_sampling_method
    # Kp = 1: every sample its own path stream, whatever the depth (independent paths);
    # the closed forms: a sample's paths share everything, and samples nothing (the
    # control variate's one time per sample is stratified)
    closed_form = method in sampling.CLOSED_FORM
    depth = (0 if params.path_group_size == 1 or closed_form
             else min(params.path_correlation_depth, 1 << 30))
    number = (0 if method == sampling.ANALYTIC else sampling.method_index(
        sampling.TimeSampling.STRATIFIED.value if method == sampling.CONTROL_VARIATE
        else method))
    return dr.opaque(mi.UInt32, depth), dr.opaque(mi.UInt32, number)


def _trace_paths(mi, setup, layout: PassLayout, streams, start: CameraSample,
                 length_derivative: bool = False):
    """The path loop (:func:`.path_loop.trace_path_loop`) measuring the D-ToF camera's
    correlations: from each lane's camera ray to its measurement (and, with
    ``length_derivative``, the sum of d contribution / d its path length)."""
    measured, measured_dl, lit = trace_path_loop(
        mi, setup, layout, streams, start, Correlation(mi, setup, start, length_derivative))
    wavelengths = start.ray.wavelengths  # of the camera ray, for the colour conversion
    value = _as_colour(mi, measured, wavelengths)
    return ((value, start.film_offset, _as_colour(mi, measured_dl, wavelengths), lit)
            if length_derivative else (value, start.film_offset))


class Correlation(Modality):
    """The D-ToF camera's modality: each contribution weighted by the modulation of its
    own full path length at its lane's time, summed (the time-averaged correlation);
    with ``length_derivative`` also what the path-replay adjoint needs (the sum of d
    contribution / d its path length, and which light samples reached their lights)."""

    label = "dopplertof"

    def __init__(self, mi, setup, start: CameraSample, length_derivative: bool):
        self.mi, self.modulation = mi, setup.modulation_weight  # w(L, t) of a contribution
        self.F = self.modulation.F
        self.t_rel, self.first_hit = start.t_rel, start.first_hit
        self.length_derivative = length_derivative
        self.records = _adjoint_records(mi, setup, length_derivative)

    def state(self) -> tuple:
        measured_dl, lit = self.records
        return self.mi.Spectrum(0.0), measured_dl, lit  # (the measurement so far)

    def hit(self, mi, static, frames, ray, active, depth, fresh):
        return _intersect(mi, static, frames, ray, active, depth, self.first_hit, fresh), None

    def vertex(self, state, si, hit, ray, v, beta, depth, numbers):
        measured, measured_dl, lit = state
        # ---- Modulated contributions: the emitter hit and the light sample ----
        hit_contribution, light_contribution = contributions(self.modulation, v, self.t_rel)
        measured += hit_contribution
        measured += light_contribution
        if self.length_derivative:  # (the plain render has none of it)
            measured_dl, lit = _recorded(self.mi, self.modulation, v, self.t_rel, depth,
                                         measured_dl, lit)
        return measured, measured_dl, lit


def _adjoint_records(mi, setup, length_derivative: bool):
    """What the path loop records for the path-replay adjoint, with
    ``length_derivative``: the sum of d contribution / d its path length, and which of
    the light samples reached their lights (lit_bits; None where a path is too deep
    for its bits); else (None, None)."""
    if not length_derivative:
        return None, None
    fits = 0 < setup.params.max_depth <= VISIBILITY_BITS_MAX_DEPTH
    return mi.Spectrum(0.0), (mi.UInt32(0) if fits else None)


def _recorded(mi, modulation, v, t_rel, depth, measured_dl, lit):
    """_adjoint_records' values after vertex ``v``."""
    lit = None if lit is None else lit | lit_bits(mi, v, depth)
    return measured_dl + length_derivatives(modulation, v, t_rel), lit


# ---- Registration: <integrator type="dopplertof"> (alias "dopplertofpath") ----

def register_plugin(mi) -> None:
    """Make the integrator loadable by Mitsuba in the current variant."""
    cls = integrator_class(mi)
    for name in DTOF_INTEGRATORS:
        mi.register_integrator(name, lambda props, cls=cls: cls(props))
