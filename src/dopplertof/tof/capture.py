"""One frame of a D-ToF camera: its captures, what it reports, and the exact truth.

:func:`capture` renders, for one scene and exposure,

* four homodyne captures at sensor offsets 0, 1/4, 1/2, 3/4 (depth; the first two
  also serve velocity), and two heterodyne captures at offsets 0 and 1/4 with h beat
  periods per exposure (velocity);
* optionally four more homodyne captures at a second modulation frequency (depth
  unwrapping);
* a radiance capture: the same path tracer with a constant modulation weight (a 1 Hz
  sinusoid, whose phase over any path is below 1e-6 rad), i.e. the time-averaged
  radiance over the exposure with global illumination, for context and for the
  unmodulated light that the noise model needs;

then reconstructs radial velocity and depth (:mod:`.reconstruct`), optionally after
sensor noise (:mod:`.noise`), and compares them with the truth from the analytic
motion (:mod:`.ground_truth`).

The sensor is monochrome: a capture is the mean of the rendered channels (H, W).
All captures are simulated over the same exposure interval (as if recorded by
parallel pixels) and, by default, with the same seed: common random numbers, so that
Monte Carlo noise largely cancels in the heterodyne/homodyne ratio. Physical noise is
the noise model's business.
"""

from __future__ import annotations

import math
import time as _time
from dataclasses import dataclass, field, fields, replace

import numpy as np

from ..arguments import check_params, check_scene, check_seed, check_spp
from ..hints import did_you_mean
from ..params import CAPTURE_HETERO_FREQUENCY, RenderParams, frequency_problem
from . import reconstruct as rec
from .geometry import camera_geometry
from .ground_truth import GroundTruth, ground_truth, mixed_footprints
from .noise import NoiseModel, apply_noise
from . import precision as prec
from .summary import frame_summary

#: illumination frequency of the radiance capture, MHz (1 Hz)
RADIANCE_FREQUENCY_MHZ = 1e-6

#: default heterodyne beat periods per exposure when the scene gives none
DEFAULT_HETERO_FREQUENCY = CAPTURE_HETERO_FREQUENCY


class CaptureError(ValueError):
    """Capture settings that cannot work; the message names the problem."""


@dataclass(frozen=True)
class CaptureSpec:
    """One exposure of the camera."""

    name: str  #: file stem, e.g. "homodyne_0.25" or "homodyne_25MHz_0.5"
    kind: str  #: "homodyne", "heterodyne" or "radiance"
    frequency_mhz: float  #: illumination frequency f_g
    hetero_frequency: float  #: h, beat periods per exposure
    hetero_offset: float  #: sensor offset o (psi = 2 pi o)

    def params(self, base: RenderParams) -> RenderParams:
        changes = dict(w_g=self.frequency_mhz, w_s=None, hetero_frequency=self.hetero_frequency,
                       hetero_offset=self.hetero_offset)
        if self.kind == "radiance":
            # weight g1 * 0.5 cos(omega_g L / c) = cos(< 1e-6 rad) = 1 - O(1e-12)
            changes.update(g_1=2.0, wave_function_type="sinusoidal",
                           low_frequency_component_only=True)
        return replace(base, **changes).validated(f"capture {self.name}")


def _offset_name(offset: float) -> str:
    return f"{offset:g}"


def plan_captures(frequency_mhz: float, hetero_frequency: float,
                  unwrap_frequency_mhz: float | None = None) -> list:
    """The captures of one frame, in render order."""
    specs = [CaptureSpec(f"homodyne_{_offset_name(o)}", "homodyne", frequency_mhz, 0.0, o)
             for o in rec.DEPTH_OFFSETS]
    specs += [CaptureSpec(f"heterodyne_{_offset_name(o)}", "heterodyne", frequency_mhz,
                          hetero_frequency, o) for o in rec.VELOCITY_OFFSETS]
    if unwrap_frequency_mhz is not None:
        tag = f"{unwrap_frequency_mhz:g}MHz"
        specs += [CaptureSpec(f"homodyne_{tag}_{_offset_name(o)}", "homodyne",
                              unwrap_frequency_mhz, 0.0, o) for o in rec.DEPTH_OFFSETS]
    specs.append(CaptureSpec("radiance", "radiance", RADIANCE_FREQUENCY_MHZ, 0.0, 0.0))
    return specs


@dataclass
class Reconstruction:
    """What the camera reports from one set of captures."""

    velocity: np.ndarray  #: (H, W) m/s, > 0 receding, NaN where it cannot tell
    velocity_reasons: np.ndarray  #: (H, W) int codes, see reconstruct.INVALID_REASONS
    depth: np.ndarray  #: (H, W) m along the ray (wrapped unless unwrapped)
    depth_reasons: np.ndarray
    amplitude: np.ndarray  #: (H, W) homodyne amplitude at f_g


@dataclass
class CaptureResult:
    captures: dict  #: name -> (H, W) float32, what the camera records (noisy if noise is on)
    rendered: dict  #: name -> (H, W) float32, the noise-free renders (mean of channels)
    radiance: np.ndarray  #: (H, W, C) float32, time-averaged radiance
    reconstruction: Reconstruction  #: from ``captures``
    noise_free: Reconstruction | None  #: from ``rendered`` when noise is on
    truth: GroundTruth
    summary: dict = field(default_factory=dict)
    #: predicted standard deviations (precision.Uncertainty) with mc_batches, else None
    uncertainty: object = None
    #: camera.json's content (:func:`dopplertof.tof.geometry.camera_geometry`)
    geometry: dict | None = None

    @property
    def velocity(self):
        return self.reconstruction.velocity

    @property
    def depth(self):
        return self.reconstruction.depth

    @property
    def velocity_gt(self):
        return self.truth.velocity

    @property
    def depth_gt(self):
        return self.truth.depth

    def sensor_model(self):
        """(CaptureModel, unmodulated light g0 R (H, W)) of this frame, from its summary:
        what a repetition of its sensor noise needs."""
        mod = self.summary["modulation"]
        model = rec.CaptureModel(mod["omega_g_rad_s"], mod["exposure_s"],
                                 mod["hetero_frequency"], mod["waveform"])
        return model, mod["g_0"] * self.radiance.mean(axis=-1, dtype=np.float64)

    def write(self, folder, pointcloud: bool = False) -> list:
        """Write every array (.npy), its preview (.png), the side-by-side figure,
        camera.json (and ``pointcloud``: pointcloud.ply) and summary.json into ``folder``
        (created if missing); returns the paths."""
        from .output import write_result

        return write_result(self, folder, pointcloud)


# ---- Settings ----------------------------------------------------------------------

def _resolve_hetero_frequency(base: RenderParams, exposure: float, requested) -> float:
    if requested is not None:
        h = float(requested)
    elif base.hetero_frequency not in (None, 0.0):
        h = float(base.hetero_frequency)
    elif base.w_s is not None and base.w_s != base.w_g:
        h = (base.w_s - base.w_g) * 1e6 * exposure
    else:
        h = DEFAULT_HETERO_FREQUENCY
    return h


def _check_unwrap(unwrap_frequency, w_g):
    if unwrap_frequency is None:
        return None
    try:
        f = float(unwrap_frequency)
    except (TypeError, ValueError):
        raise CaptureError(f"unwrap frequency must be a number of MHz, got {unwrap_frequency!r}"
                           ) from None
    problem = (frequency_problem("unwrap frequency", f) if math.isfinite(f)
               else f"unwrap frequency must be finite, got {unwrap_frequency!r}")
    if problem:
        raise CaptureError(problem)
    if abs(f - w_g) * 1e6 < 1.0:
        raise CaptureError(f"unwrap frequency {f:g} MHz equals the modulation frequency w_g: "
                           "choose a different one")
    return f


def check_spp_seed(base, spp, seed):
    check_spp(spp, "spp", CaptureError)
    check_seed(seed, "seed", CaptureError)
    if spp % base.time_correlate_number:
        raise CaptureError(f"spp {spp} is not a multiple of the group size "
                           f"time_correlate_number={base.time_correlate_number}")


# ---- The pipeline --------------------------------------------------------------------

@dataclass(frozen=True)
class CaptureSettings:
    """What :func:`capture` is asked to do besides the scene: built by the command line
    and the Python API (``capture(scene, spp=64, noise=True)`` builds one of its keyword
    arguments) and passed through as it is; checked against the scene when the capture
    starts (a CaptureError or PrecisionError names the first bad value)."""

    spp: int | None = None  #: samples per pixel per capture (None: the scene's)
    seed: int = 0
    #: integrator parameter overrides (a dict or RenderParams), applied before the
    #: per-capture ones
    params: object = None
    #: beat periods per exposure of the heterodyne captures (a non-zero integer; None:
    #: the scene's, else 1)
    hetero_frequency: float | None = None
    #: a second modulation frequency (MHz) for depth unwrapping
    unwrap_frequency: float | None = None
    noise: object = None  #: a NoiseModel (True: the default one; None or False: none)
    #: pixels whose homodyne signal is below this fraction of the image's 99th
    #: percentile are NaN (None: 0.01)
    min_signal_fraction: float | None = None
    #: "none" (exact E/H inversion), "inverse-square" (also the brightness change of a
    #: surface under a colocated point light; uses each pixel's depth) or "auto"
    #: (inverse-square for non-sinusoidal waveforms, none for the sinusoid)
    velocity_calibration: str = "auto"
    #: the same seed for every capture, rather than seed + capture index
    common_random_numbers: bool = True
    progress: bool | None = None  #: a progress bar (None: on a terminal)
    on_capture: object = None  #: called as on_capture(spec, seconds) after each render
    #: B renders of each capture (the first the capture itself) for per-pixel standard
    #: deviations (result.uncertainty, summary "precision", its "cost")
    mc_batches: int | None = None
    #: NaN where the predicted standard deviation is larger (implies mc_batches=8)
    max_velocity_std: float | None = None
    max_depth_std: float | None = None
    keep_mixed_pixels: bool = False  #: silhouettes reconstructed, not NaN (reason 5)
    #: a folder keeping every render (:mod:`.checkpoint`): run again, only the missing
    #: ones render, bitwise
    checkpoint: object = None

    @classmethod
    def of(cls, settings=None, **options) -> "CaptureSettings":
        """``settings`` (a CaptureSettings; None: the defaults) with ``options``
        (:func:`capture`'s keyword arguments, named as the fields) over it; a TypeError
        for anything else."""
        if settings is not None and not isinstance(settings, cls):
            raise TypeError(f"settings must be a CaptureSettings, got "
                            f"{type(settings).__name__} {settings!r}")
        known = [f.name for f in fields(cls)]
        for name in options:
            if name not in known:
                raise TypeError(f"capture() got an unexpected keyword argument "
                                f"{name!r}{did_you_mean(name, known)}")
        return replace(settings or cls(), **options)


def capture(scene, spp: int | None = None, seed: int | None = None, *,
            settings: CaptureSettings | None = None, **options) -> CaptureResult:
    """Render every capture of one D-ToF frame, reconstruct velocity and depth, and
    compare them with the exact truth.

    scene: a DopplerScene. ``settings`` (a :class:`CaptureSettings`; None: the
    defaults) says how; ``spp``, ``seed`` (None: the settings') and the keyword
    arguments, named as its fields (``params``, ``hetero_frequency``,
    ``unwrap_frequency``, ``noise``, ``min_signal_fraction``, ``velocity_calibration``,
    ``common_random_numbers``, ``progress``, ``on_capture``, ``mc_batches``,
    ``max_velocity_std``, ``max_depth_std``, ``keep_mixed_pixels``, ``checkpoint``),
    override it: ``capture(scene, spp=64, noise=True)``."""
    given = {name: value for name, value in (("spp", spp), ("seed", seed))
             if value is not None}
    asked = CaptureSettings.of(settings, **given, **options)
    started = _time.perf_counter()
    settings = _check_settings(scene, asked)
    base, model, unwrap = settings.base, settings.model, settings.unwrap

    # ---- Render every capture ----
    rendered, records, radiance, batches = _render_captures(
        scene, plan_captures(base.w_g, model.hetero_frequency, unwrap), settings, asked)

    # ---- The truth; reconstruct (mixed footprints NaN), with sensor noise when asked ----
    truth = ground_truth(scene, base)
    truth.mixed = mixed_footprints(scene, base)
    unmodulated = base.g_0 * radiance.mean(axis=-1, dtype=np.float64)
    clean = _reconstruct(rendered, model, unwrap, settings.min_signal_fraction,
                         settings.calibration, mixed=settings.masked_mixed(truth))
    captures, reconstruction, noise_free, noise, noise_info = _sensor_readout(
        rendered, unmodulated, clean, settings, settings.masked_mixed(truth))

    # ---- Predicted precision and the masks it sets ----
    uncertainty, limit_counts = _predict_precision(rendered, batches, unmodulated, clean,
                                                   reconstruction, noise, settings)

    summary = frame_summary(scene, settings, records, reconstruction, noise_free, truth,
                       noise_info, _time.perf_counter() - started)
    if uncertainty is not None:
        summary["precision"] = _precision_summary(scene, settings, uncertainty, reconstruction,
                                                  truth, limit_counts, records)
    return CaptureResult(captures, rendered, radiance, reconstruction, noise_free, truth,
                         summary, uncertainty, camera_geometry(scene, truth.time))


@dataclass(frozen=True)
class _Settings:
    """The checked settings of one :func:`capture`."""

    base: RenderParams  #: the scene's parameters with the overrides
    spp: int  #: samples per pixel per capture
    seed: int
    model: rec.CaptureModel  #: what the reconstruction inverts (h included)
    unwrap: float | None  #: second modulation frequency, MHz
    calibration: str  #: "none" or "inverse-square"
    noise: NoiseModel | None
    min_signal_fraction: float | None
    common_random_numbers: bool  #: one seed for every capture (else seed + its index)
    limits: tuple  #: (max_velocity_std, max_depth_std), each None when not set
    mc_batches: int | None
    keep_mixed_pixels: bool = False  #: reconstruct mixed footprints instead of NaN

    def masked_mixed(self, truth: GroundTruth):
        """The footprints to mask as mixed (reason MIXED_FOOTPRINT), or None (kept)."""
        return None if self.keep_mixed_pixels else truth.mixed


def _check_settings(scene, asked: CaptureSettings) -> _Settings:
    """:func:`capture`'s settings checked against ``scene`` and resolved, in the order
    of its error messages (a CaptureError or PrecisionError names the first bad one)."""
    check_scene(scene, "scene")
    params, spp, seed, mc_batches = asked.params, asked.spp, asked.seed, asked.mc_batches
    keep_mixed_pixels = asked.keep_mixed_pixels
    base = scene.params
    if check_params(params):
        base = (params if isinstance(params, RenderParams) else
                RenderParams.from_mapping(dict(params), where="capture parameters", base=base))
    spp = scene.spp if spp is None else spp
    check_spp_seed(base, spp, seed)
    exposure = base.exposure(scene.shutter_interval)
    h = _resolve_hetero_frequency(base, exposure, asked.hetero_frequency)
    model = rec.CaptureModel.of(base.modulation(scene.shutter_interval), h)
    unwrap = _check_unwrap(asked.unwrap_frequency, base.w_g)
    calibration = rec.resolve_calibration(asked.velocity_calibration, model.waveform)
    noise = _check_noise(asked.noise)
    min_signal_fraction = _check_signal_fraction(asked.min_signal_fraction)
    limits = (prec.check_limit("max_velocity_std", asked.max_velocity_std),
              prec.check_limit("max_depth_std", asked.max_depth_std))
    if mc_batches is None and any(limits):
        mc_batches = prec.DEFAULT_MC_BATCHES
    if mc_batches is not None:
        mc_batches = prec.check_batches(mc_batches)
    if not isinstance(keep_mixed_pixels, (bool, np.bool_)):
        raise CaptureError(f"keep_mixed_pixels must be True or False, got {keep_mixed_pixels!r}")
    return _Settings(base, spp, seed, model, unwrap, calibration, noise,
                     min_signal_fraction, asked.common_random_numbers, limits, mc_batches,
                     bool(keep_mixed_pixels))


def _sensor_readout(rendered, unmodulated, clean: Reconstruction, settings: _Settings,
                    mixed=None):
    """What the camera records and reports: (captures, reconstruction, the noise-free
    reconstruction, the noise model resolved, its summary entry), with the footprints
    ``mixed`` masked. Without sensor noise, the renders and ``clean`` (and None for the
    rest)."""
    if settings.noise is None:
        return rendered, clean, None, None, None
    captures, saturated, noise = apply_noise(rendered, unmodulated, settings.model.exposure,
                                             settings.noise)
    reconstruction = _reconstruct(captures, settings.model, settings.unwrap,
                                  settings.min_signal_fraction, settings.calibration,
                                  saturated, mixed)
    noise_info = noise.describe()
    noise_info["saturated_pixels"] = int(saturated.sum())
    noise_info["signal_electrons_per_unit"] = noise.electrons_per_unit(settings.model.exposure)
    return captures, reconstruction, clean, noise, noise_info


def _predict_precision(rendered, batches, unmodulated, clean: Reconstruction,
                       reconstruction: Reconstruction, noise, settings: _Settings):
    """The predicted standard deviations (precision.Uncertainty) from the batches and
    the sensor noise ``noise`` (resolved, or None), and the pixel counts of the limits'
    masks, which it applies to ``reconstruction``; (None, None) without mc_batches."""
    if not settings.mc_batches:
        return None, None
    variances = (prec.capture_variances(rendered, unmodulated, settings.model.exposure, noise)
                 if noise is not None else None)
    uncertainty = prec.predict(rendered, batches, settings.model, settings.unwrap,
                               settings.calibration, clean.depth, variances,
                               clean.velocity_reasons == rec.VALID,
                               clean.depth_reasons == rec.VALID)
    return uncertainty, prec.apply_limits(reconstruction, uncertainty, *settings.limits)


def _precision_summary(scene, settings: _Settings, uncertainty, reconstruction, truth,
                       limit_counts, records) -> dict:
    """summary.json's "precision" section (precision.precision_summary) of one frame,
    with the render time its error bars cost (from the capture ``records``)."""
    section = prec.precision_summary(
        uncertainty, reconstruction, truth, [", ".join(b.names) for b in scene.bodies],
        None if settings.unwrap is not None else settings.model.wrap_distance,
        {"max_velocity_std_m_s": settings.limits[0],
         "max_depth_std_m": settings.limits[1], "masked_pixels": limit_counts})
    section["cost"] = prec.error_bar_cost(records, settings.mc_batches)
    return section


def _check_noise(noise):
    """The NoiseModel asked for (True: the default one), or None."""
    if noise is True:
        return NoiseModel()
    if noise is False or noise is None:
        return None
    if not isinstance(noise, NoiseModel):
        raise CaptureError(f"noise must be a NoiseModel, True or None, got {noise!r}")
    return noise


def _check_signal_fraction(min_signal_fraction):
    min_signal_fraction = prec.optional_number(min_signal_fraction)
    if min_signal_fraction is None:
        return None
    if not 0 <= min_signal_fraction < 1:
        raise CaptureError("min_signal_fraction must be a number in [0, 1), got "
                           f"{min_signal_fraction}")
    return min_signal_fraction


def _render_captures(scene, specs, settings: _Settings, asked: CaptureSettings):
    """Every capture of ``specs`` (the frame loop, :mod:`.frames`) at the checked
    ``settings`` (with ``asked``'s progress, on_capture and checkpoint): the captures
    (mean of channels, float32), their records for the summary, the radiance image, and
    (mc_batches) each capture's batch stack's channel mean."""
    from .frames import FrameRender, render_frames

    base, spp, seed, mc_batches = (settings.base, int(settings.spp), settings.seed,
                                   settings.mc_batches)
    on_capture = asked.on_capture

    # ---- Every capture's seed, checked before the first render (all below 2^64; the
    # batch seeds, prec.batch_seeds, are below 2^64 by construction) ----
    capture_seeds = [check_seed(int(seed) + (0 if settings.common_random_numbers else index),
                                "seed + capture index", CaptureError)
                     for index in range(len(specs))]
    renders = [FrameRender(spec.name, scene, spec.params(base), capture_seed)
               for spec, capture_seed in zip(specs, capture_seeds)]
    by_name = {spec.name: spec for spec in specs}
    results = render_frames(
        scene, renders, spp, batches=mc_batches or 0, progress=asked.progress,
        checkpoint=asked.checkpoint, what="renders" if mc_batches else "captures",
        on_render=None if on_capture is None else
        lambda r, done: on_capture(by_name[r.name], done.seconds))
    rendered, records, radiance, batches = {}, [], None, {}
    for index, (spec, r, done) in enumerate(zip(specs, renders, results)):
        if spec.kind == "radiance":
            radiance = done.image
        else:
            rendered[spec.name] = done.image.mean(axis=-1, dtype=np.float64).astype(np.float32)
            if mc_batches:
                batches[spec.name] = done.stack.mean(axis=-1, dtype=np.float64)
        records.append({
            "order": index, "name": spec.name, "file": f"{spec.name}.npy", "kind": spec.kind,
            "w_g_MHz": spec.frequency_mhz, "hetero_frequency": spec.hetero_frequency,
            "hetero_offset": spec.hetero_offset, "seed": r.seed, "spp": spp,
            "render_seconds": round(done.seconds, 3),
            "nonfinite_samples_dropped": done.dropped,
        })
        if mc_batches:
            records[-1]["batch_seeds"] = prec.batch_seeds(r.seed, mc_batches)
            records[-1]["error_bar_render_seconds"] = round(done.extra_seconds, 3)
    return rendered, records, radiance, batches


def _homodyne_set(captures, prefix):
    return {o: captures[f"{prefix}_{_offset_name(o)}"] for o in rec.DEPTH_OFFSETS}


def _reconstruct(captures, model, unwrap, min_signal_fraction, calibration, saturated=None,
                 mixed=None):
    """Velocity and depth with their reason codes (rec.INVALID_REASONS) from the captures;
    the pixels ``mixed`` (footprints that see two surfaces) and ``saturated`` are NaN
    with their own reasons (saturation wins: it is what the sensor saw)."""
    homodyne = _homodyne_set(captures, "homodyne")
    heterodyne = {o: captures[f"heterodyne_{_offset_name(o)}"] for o in rec.VELOCITY_OFFSETS}
    depth, phase, amplitude, d_reasons = rec.homodyne_depth(homodyne, model,
                                                            min_signal_fraction)
    if unwrap is not None:
        model2 = replace(model, omega_g=2 * math.pi * unwrap * 1e6)
        depth2, _, _, d2_reasons = rec.homodyne_depth(
            _homodyne_set(captures, f"homodyne_{unwrap:g}MHz"), model2, min_signal_fraction)
        d_reasons = np.maximum(d_reasons, d2_reasons)
        depth = rec.unwrap_two_frequencies(depth, model.frequency_hz, depth2, unwrap * 1e6)
        depth = np.where(d_reasons == rec.VALID, depth, np.nan)
    velocity, v_reasons = rec.reconstruct_velocity(homodyne, heterodyne, model,
                                                   min_signal_fraction, calibration,
                                                   phase, depth)
    for code, masked in ((rec.MIXED_FOOTPRINT, mixed), (rec.SATURATED, saturated)):
        if masked is not None:
            v_reasons = np.where(masked, code, v_reasons)
            d_reasons = np.where(masked, code, d_reasons)
            velocity = np.where(masked, np.nan, velocity)
            depth = np.where(masked, np.nan, depth)
    return Reconstruction(velocity, v_reasons, depth, d_reasons, amplitude)


def reconstruct_noisy(result: CaptureResult, noise: NoiseModel) -> Reconstruction:
    """The reconstruction of ``result``'s noise-free captures after drawing ``noise``
    (its own seed): a repetition of the sensor noise without rendering again."""
    s = result.summary
    model, unmodulated = result.sensor_model()
    noisy, saturated, _ = apply_noise(result.rendered, unmodulated, model.exposure, noise)
    mixed = None if s["velocity"].get("mixed_pixels") == "kept" else result.truth.mixed
    return _reconstruct(noisy, model, s["depth"]["unwrap_frequency_MHz"],
                        s["velocity"]["min_signal_fraction"], s["velocity"]["calibration"],
                        saturated, mixed)


# ---- Summary ---------------------------------------------------------------------------
