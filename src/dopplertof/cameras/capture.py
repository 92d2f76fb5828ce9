"""One depth frame of a real camera: its raw frames in time, its sensor, its depth.

:func:`capture_camera` renders each raw frame of a preset in its own time window (frame
k over [t0 + start_k, t0 + start_k + T_k], t0 the scene's shutter_open: the scene's
keyframed motion puts things where they are then), at the frame's modulation frequency
and sensor phase step; one radiance render over the whole sequence gives the
unmodulated light. The sensor (:mod:`.sensor`) turns them into integer DN; the camera's
reconstruction (:mod:`.demodulate`, :mod:`.unwrap`) gives radial range, z depth,
amplitude and its masks (the footprints that mix surfaces during the sequence among them,
:func:`dopplertof.tof.ground_truth.mixed_footprints`, unless kept); presets with
heterodyne frames also give velocity through
:func:`dopplertof.tof.reconstruct.reconstruct_velocity`. The truth is taken at the
middle of the sequence.
"""

from __future__ import annotations

import math
import os
import time as _time
from dataclasses import dataclass, field, replace

import numpy as np

from ..arguments import check_camera_capture
from ..params import RenderParams
from ..scene.scene import keyframe_coverage_warning
from ..tof.capture import RADIANCE_FREQUENCY_MHZ, CaptureError, CaptureSpec, check_spp_seed
from ..tof.geometry import camera_geometry, intrinsics
from ..tof.ground_truth import camera_forward, ground_truth, mixed_footprints
from ..tof.summary import error_stats
from . import radiometry
from . import sensor as camera_sensor
from .preset import CameraPreset, load_preset, sequence_window
from .reconstruct import CameraReconstruction, reconstruct
from .scene_view import load_scene_for_camera


@dataclass
class CameraResult:
    """A depth frame of a camera, with its raw frames and the truth."""

    preset: CameraPreset
    rendered: np.ndarray  #: (K, H, W) the renders of the raw frames (mean of channels)
    radiance: np.ndarray  #: (H, W, C) time-averaged radiance over the sequence
    readout: camera_sensor.Readout  #: raw DN, ideal DN, saturation, predicted variance
    reconstruction: CameraReconstruction
    depth_gt: np.ndarray  #: (H, W) radial range at mid-sequence (m)
    depth_gt_z: np.ndarray  #: (H, W) z depth at mid-sequence (m)
    velocity_gt: np.ndarray  #: (H, W) radial velocity at mid-sequence (m/s)
    summary: dict = field(default_factory=dict)
    #: (H, W) bool: the footprints that mix surfaces during the sequence (masked unless kept)
    mixed_footprints: np.ndarray | None = None
    #: what reaches the pixels (for :meth:`read_again`)
    light: "PixelLight | None" = None
    #: camera.json's content (:func:`dopplertof.tof.geometry.camera_geometry`: the pose at
    #: mid-sequence and at each raw frame)
    geometry: dict | None = None

    def read_again(self, noise_seed: int | None, keep_mixed_pixels: bool = False):
        """(Readout, CameraReconstruction) of the same renders with another noise draw
        (``noise_seed`` None: no noise): the sensor and the depth engine only."""
        mixed = None if keep_mixed_pixels else self.mixed_footprints
        return self.light.read(self.preset, noise_seed, mixed)

    @property
    def raw(self):
        return self.readout.raw

    @property
    def depth(self):
        return self.reconstruction.depth

    def write(self, folder, pointcloud: bool = False) -> list:
        """Every file (docs/cameras.md) into ``folder`` (created if missing); with
        ``pointcloud`` also pointcloud.ply."""
        from .output import write_camera_result

        if not isinstance(pointcloud, (bool, np.bool_)):
            raise TypeError(f"pointcloud must be True or False, got {pointcloud!r}")
        return write_camera_result(self, folder, bool(pointcloud))


# ---- The frames' render settings -------------------------------------------------------

def frame_specs(preset: CameraPreset) -> list:
    """One CaptureSpec per raw frame (name raw_<k>), in read-out order."""
    return [CaptureSpec(f"raw_{k}", "homodyne" if f.homodyne else "heterodyne",
                        f.frequency_mhz, f.hetero_frequency, f.offset)
            for k, f in enumerate(preset.frames)]


def _base_params(scene, preset: CameraPreset, params) -> RenderParams:
    """The scene's parameters with the overrides and the camera's waveform (low-pass)."""
    base = scene.params
    if params:
        base = RenderParams.from_mapping(dict(params), where="capture parameters", base=base)
    return replace(base, wave_function_type=preset.waveform,
                   low_frequency_component_only=True).validated("camera capture")


# ---- The pipeline ----------------------------------------------------------------------

def capture_camera(scene, camera, spp: int | None = None, seed: int = 0, *, params=None,
                   noise: bool = True, noise_seed: int = 0, progress: bool | None = None,
                   on_frame=None, checkpoint=None, keep_mixed_pixels: bool = False,
                   ambient_irradiance: float | None = None) -> CameraResult:
    """Render, read out and reconstruct one depth frame of ``camera`` (a preset name, a
    .toml path or a CameraPreset) on ``scene`` (a DopplerScene: its film is the camera's
    resolution; or a scene file's path, loaded by :func:`.scene_view.load_scene_for_camera` with the
    preset's field of view, resolution and, for a scene without light, its illuminator).

    params: integrator parameter overrides for every frame. noise: shot and read noise
    (numpy PCG64 seeded ``noise_seed``); without it the sensor runs on mean electrons.
    on_frame(spec, seconds) is called after each render. checkpoint: a folder keeping
    every render (:mod:`dopplertof.tof.checkpoint`): run again, only the missing ones
    render, bitwise as uninterrupted. keep_mixed_pixels: the pixels whose footprint
    mixes surfaces during the sequence are reconstructed, not NaN (as
    :func:`dopplertof.capture`'s). ambient_irradiance: ambient light in uW/cm^2/nm at
    the illuminator's wavelength falling on every surface (an absolute preset only;
    None: the preset's documented condition, [conditions] in its file, else 0)."""
    scene = check_camera_capture(scene, camera, spp, seed, params, noise, noise_seed,
                                 on_frame, checkpoint, CameraPreset)
    started = _time.perf_counter()
    if not isinstance(keep_mixed_pixels, (bool, np.bool_)):
        raise CaptureError(f"keep_mixed_pixels must be True or False, got {keep_mixed_pixels!r}")
    preset = camera if isinstance(camera, CameraPreset) else load_preset(camera)
    scene = _scene_through(scene, preset)
    ambient = _ambient_irradiance(preset, ambient_irradiance)
    base = _base_params(scene, preset, params)
    photons = (radiometry.photons_per_unit(preset, scene_light_intensity(scene, preset),
                                           base.g_0) if preset.absolute else None)
    spp = scene.spp if spp is None else spp
    check_spp_seed(base, spp, seed)
    rendered, radiance, records, truth_scene, truth_params = _render_frames(
        scene, preset, base, int(spp), int(seed), progress, on_frame, checkpoint)
    # ---- Truth at mid-sequence (z from the radial range, each pixel's angle) ----
    truth = ground_truth(truth_scene, truth_params)
    forward = camera_forward(truth_scene, truth_scene.sensor_motion, truth.time)
    cosine = truth.direction @ forward
    # ---- The sensor, then the camera's own reconstruction ----
    unmodulated = base.g_0 * radiance.mean(axis=-1, dtype=np.float64)
    light = _light_at_pixels(preset, rendered, unmodulated, truth_scene, truth_params,
                             ambient, cosine, photons)
    mixed = mixed_footprints(truth_scene, truth_params)
    readout, recon = light.read(preset, noise_seed if noise else None,
                                None if keep_mixed_pixels else mixed)
    result = CameraResult(preset, rendered, radiance, readout, recon, truth.depth,
                          truth.depth * cosine, truth.velocity, mixed_footprints=mixed,
                          light=light)
    recon.depth_z = recon.depth * cosine
    result.summary = _summary(scene, preset, result, records, spp, seed, noise, noise_seed,
                              _time.perf_counter() - started, keep_mixed_pixels)
    result.summary["intrinsics"] = _intrinsics(scene)
    result.geometry = camera_geometry(scene, truth.time,
                                      [(r["name"], r["window_s"]) for r in records])
    if preset.absolute:
        result.summary["noise"]["radiometry"] = _radiometry_summary(preset, result, ambient)
    return result


def _scene_through(scene, preset: CameraPreset):
    """The DopplerScene a preset captures: a scene file loaded for it, the preset's lens
    distortion on a scene that has none of its own."""
    if isinstance(scene, (str, os.PathLike)):
        scene = load_scene_for_camera(scene, preset)
    if any(preset.distortion) and scene.lens_distortion is None:
        scene = replace(scene, lens_distortion=tuple(preset.distortion))
    return scene


def _radiometry_summary(preset: CameraPreset, result: CameraResult, ambient: float) -> dict:
    """summary.json's noise.radiometry of an absolute preset's capture."""
    light, readout = result.light, result.readout
    return {"exposure": "absolute: photons from the illuminator's power, the lens and the "
                        "pixel (cameras/radiometry.py)",
            "illuminator_intensity_W_sr": radiometry.radiant_intensity(preset.illuminator),
            "ambient_irradiance_uW_cm2_nm": ambient,
            "signal_electrons_p50": light.electrons_percentile(readout, preset, 50),
            "signal_electrons_p99": light.electrons_percentile(readout, preset, 99),
            **_shutter_summary(readout)}


def _shutter_summary(readout) -> dict:
    """The pixels that took each shutter of a sensor with several (none: {})."""
    if readout.shutter is None:
        return {}
    fractions, counts = np.unique(readout.shutter, return_counts=True)
    return {"pixels_per_shutter": {f"{f:.6g}": int(n) for f, n in zip(fractions[::-1],
                                                                      counts[::-1])}}


def _intrinsics(scene) -> dict:
    """K and the lens distortion of the capture's pinhole (OpenCV's conventions)."""
    found = intrinsics(scene)
    return {"K": found["K"], "distortion_k1_k2_p1_p2_k3": found["distortion_k1_k2_p1_p2_k3"],
            "convention": found["convention"]}


# ---- Absolute radiometry ---------------------------------------------------------------

@dataclass
class PixelLight:
    """What reaches each pixel: the renders times the lens's cos^4 falloff, and the
    ambient photon rate (None through an auto-exposed preset)."""

    rendered: np.ndarray  #: (K, H, W)
    unmodulated: np.ndarray  #: (H, W) g0 R
    ambient_photons: np.ndarray | None  #: (H, W) photons/s
    photons_per_unit: float | None  #: K (None: auto exposure)
    #: (H, W) bool: outside the illuminator's field (:func:`unlit_pixels`), or None
    unlit: np.ndarray | None = None

    def read(self, preset, noise_seed: int | None, mixed=None):
        """(Readout, CameraReconstruction): the sensor's readout (shot and read noise
        from numpy's PCG64 seeded ``noise_seed``; None: mean electrons) and the camera's
        reconstruction, ``mixed`` footprints masked."""
        rng = (None if noise_seed is None
               else np.random.Generator(np.random.PCG64(int(noise_seed))))
        readout = camera_sensor.read_frames(self.rendered, self.unmodulated,
                                            [f.integration_s for f in preset.frames],
                                            preset.sensor, preset.contrast, rng,
                                            photons_per_unit=self.photons_per_unit,
                                            ambient_photons=self.ambient_photons)
        return readout, reconstruct(readout, preset, mixed, self.unlit)

    def electrons_percentile(self, readout, preset, q: float) -> float:
        """A percentile of the unmodulated signal electrons (both taps) of the longest
        frame, at each pixel's shutter, over the lit pixels."""
        longest = max(f.integration_s for f in preset.frames)
        per = preset.sensor["quantum_efficiency"] * readout.photons_per_unit * longest
        if readout.shutter is not None:
            per = per * readout.shutter
        lit = np.isfinite(self.unmodulated) & (self.unmodulated > 0)
        values = (per * self.unmodulated)[lit]
        return float(np.percentile(values, q)) if values.size else 0.0


def _ambient_irradiance(preset: CameraPreset, value) -> float:
    """The ambient irradiance a capture uses (uW/cm^2/nm), checked."""
    if value is None:
        return preset.default_ambient
    if isinstance(value, (bool, np.bool_)) \
            or not isinstance(value, (int, float, np.integer, np.floating)) \
            or not (math.isfinite(value) and 0 <= value <= 1000):
        raise CaptureError(f"ambient_irradiance must be a number of uW/cm^2/nm in [0, 1000] "
                           f"(indoor 2.2, sunlight at 850 nm about "
                           f"{radiometry.SUNLIGHT_850NM_UW_CM2_NM:g}), got {value!r}")
    if value > 0 and not preset.absolute:
        raise CaptureError(f"ambient_irradiance needs an absolute preset (sensor.auto_exposure "
                           f"= false); {preset.name} is auto-exposed: set its "
                           "sensor.ambient_photons_per_s instead")
    return float(value)


def _light_at_pixels(preset, rendered, unmodulated, scene, params, ambient, cosine,
                     photons_per_unit) -> PixelLight:
    """The renders as the pixels receive them: unchanged through an auto-exposed preset;
    through an absolute one, times cos^4 of each pixel's angle off the axis (``cosine``:
    (H, W) of each pixel's ray with the optical axis), with the ambient light reflected
    by each pixel's surface."""
    if not preset.absolute:
        return PixelLight(rendered, unmodulated, None, None)
    from ..tof.ground_truth import surface_albedo

    falloff = np.asarray(cosine, np.float64) ** 4
    photons = None
    if ambient > 0:
        albedo = np.nan_to_num(surface_albedo(scene, params), nan=0.0)
        photons = radiometry.ambient_photon_rate(preset, ambient, albedo) * falloff
    return PixelLight(rendered * falloff, unmodulated * falloff, photons, photons_per_unit,
                      unlit_pixels(scene, preset))


def unlit_pixels(scene, preset: CameraPreset) -> np.ndarray | None:
    """(H, W) bool: the pixels wholly outside the field of the preset's illuminator
    (:func:`radiometry.outside_field`) where the scene's only light is that illuminator,
    confined to its field (the spot light :func:`with_illuminator` adds when the field
    does not hold the view), at the lens of an undistorted pinhole; None otherwise (the
    scene's own lights; an illuminator beside the lens or a distorting lens, whose lit
    field depends on the depth: the low-signal masks alone)."""
    from ..scene.scene import CAMERA_ILLUMINATOR_ID
    from ..tof.geometry import intrinsics

    emitters = list(scene.static.emitters())
    if (preset.illuminator is None or any(preset.illuminator["offset_m"])
            or any(scene.lens_distortion or ()) or len(emitters) != 1
            or emitters[0].id() != CAMERA_ILLUMINATOR_ID
            or emitters[0].class_name() != "SpotLight"):
        return None
    found = intrinsics(scene)
    if found["K"] is None:
        return None
    reach = max(0.5, float(scene.sensor.film().rfilter().radius()))
    return radiometry.outside_field(preset.illuminator["fov_deg"], found["K"],
                                    *found["resolution"], reach)


def scene_light_intensity(scene, preset: CameraPreset) -> float:
    """I_s (W/sr): the radiant intensity of the scene's brightest point or spot light
    (mean over channels), which stands for the camera's illuminator through an absolute
    preset (cameras/radiometry.py); a CaptureError for a scene whose lights are not
    point or spot lights, or that has none."""
    import mitsuba as mi

    emitters = list(scene.static.emitters())
    if not emitters:
        raise CaptureError(f"{scene.source}: the scene has no light; through {preset.name} "
                           "it is lit by the camera's illuminator: load it with "
                           "dopplertof.cameras.load_scene_for_camera(path, preset), which "
                           "adds it, or pass the scene file's path")
    intensities = []
    for emitter in emitters:
        kind = emitter.class_name()
        values = mi.traverse(emitter)
        if kind not in ("PointLight", "SpotLight") or "intensity.value" not in values:
            article = "an" if kind[:1] in "AEIOU" else "a"
            raise CaptureError(f"{scene.source}: {article} {kind} cannot stand for "
                               f"{preset.name}'s illuminator (absolute radiometry takes "
                               "point and spot lights, or none): the camera sees only its "
                               "own modulated light; give room light as ambient_irradiance "
                               "(load_scene_for_camera leaves a scene file's own room "
                               "lights out, not those of a file it <include>s: move them "
                               "into the scene file)")
        intensities.append(float(np.mean(np.asarray(values["intensity.value"], np.float64))))
    if not max(intensities) > 0:
        raise CaptureError(f"{scene.source}: every light has zero intensity")
    return max(intensities)


def _frame_renders(scene, preset: CameraPreset, base: RenderParams):
    """(name, scene in the render's window, parameters, CaptureSpec) of every render of
    a camera frame: each raw frame in its own window, then the radiance over the
    sequence."""
    t0 = scene.shutter_open
    renders = []
    for spec, frame in zip(frame_specs(preset), preset.frames):
        window = scene.with_shutter(t0 + frame.start_s, frame.integration_s)
        p = replace(spec.params(base), time=frame.integration_s).validated(spec.name)
        renders.append((spec.name, window, p, spec))
    first, last = sequence_window(preset)
    spec = CaptureSpec("radiance", "radiance", RADIANCE_FREQUENCY_MHZ, 0.0, 0.0)
    p = replace(spec.params(base), time=last - first).validated("radiance")
    renders.append(("radiance", scene.with_shutter(t0 + first, last - first), p, spec))
    return renders


def _render_frames(scene, preset: CameraPreset, base: RenderParams, spp: int, seed: int,
                   progress, on_frame, checkpoint=None):
    """Every raw frame in its own window and the radiance over the sequence: (frames
    (K, H, W), radiance (H, W, C), records, the sequence's scene and parameters).
    ``checkpoint``: a folder that keeps every render (tof.checkpoint)."""
    from ..tof.frames import FrameRender, render_frames

    t0 = scene.shutter_open
    renders = _frame_renders(scene, preset, base)
    specs = {name: spec for name, _, _, spec in renders}

    def raw_frame_done(render, done):
        if on_frame is not None and specs[render.name].kind != "radiance":
            on_frame(specs[render.name], done.seconds)

    results = render_frames(
        scene, [FrameRender(name, window, p, seed) for name, window, p, _ in renders], spp,
        progress=progress, checkpoint=checkpoint, what="renders (raw frames and radiance)",
        on_render=raw_frame_done)
    records = [{"name": spec.name, "kind": spec.kind, "w_g_MHz": spec.frequency_mhz,
                "phase_deg": frame.phase_deg, "hetero_frequency": spec.hetero_frequency,
                "window_s": [t0 + frame.start_s, t0 + frame.start_s + frame.integration_s],
                "render_seconds": round(result.seconds, 3)}
               for (_, _, _, spec), frame, result in zip(renders, preset.frames, results)]
    frames = [result.image.mean(axis=-1, dtype=np.float64) for result in results[:-1]]
    _, sequence, p, _ = renders[-1]
    return np.stack(frames), results[-1].image, records, sequence, p


def _summary(scene, preset: CameraPreset, result: CameraResult, records, spp, seed, noise,
             noise_seed, seconds, keep_mixed_pixels: bool = False) -> dict:
    """summary.json of one camera frame."""
    from ..backend import require_variant

    recon, readout = result.reconstruction, result.readout
    height, width = result.depth_gt.shape
    first, last = sequence_window(preset)
    summary = {
        "scene": scene.source, "camera": preset.describe(),
        "variant": require_variant().variant(), "resolution": [width, height],
        "spp_per_frame": int(spp), "seed": int(seed),
        "noise": {"shot_and_read_noise": bool(noise), "seed": int(noise_seed),
                  "exposure": preset.exposure, "photons_per_unit": readout.photons_per_unit,
                  "saturated_pixels": int(recon.saturated.sum())},
        "frames": records,
        "sequence_s": [scene.shutter_open + first, scene.shutter_open + last],
        "ground_truth_time_s": scene.shutter_open + 0.5 * (first + last),
        "depth": recon.describe(),
        "mixed_pixels": "kept" if keep_mixed_pixels else "NaN",
        "mixed_footprints": int(result.mixed_footprints.sum()),
        "errors": {"depth_m": error_stats(recon.depth, result.depth_gt),
                   "depth_z_m": error_stats(recon.depth_z, result.depth_gt_z)},
        "seconds": {"render": round(sum(r["render_seconds"] for r in records), 3),
                    "total": round(seconds, 3)},
    }
    if recon.velocity is not None:
        summary["errors"]["velocity_m_s"] = error_stats(recon.velocity, result.velocity_gt)
    # keyframes shorter than the raw frames' span (the starter sphere's 1.5 ms of
    # motion through kinect-v2's 13 ms passed silently): the capture command prints it
    warning = keyframe_coverage_warning(scene.keyframe_span, scene.shutter_open + first,
                                        last - first, "the raw frames")
    warnings = [w for w in (warning, scene_extent_warning(scene, preset)) if w]
    if warnings:
        summary["warnings"] = warnings
    if scene.left_out_lights:  # (the loader's note says so on stderr)
        summary["room_lights_left_out"] = list(scene.left_out_lights)
    return summary


#: a scene whose bounding box diagonal is this many times the preset's longest range,
#: or this many times smaller than its shortest, reads as written in another unit
EXTENT_RATIO = 100.0


def scene_extent(scene) -> float | None:
    """The diagonal (scene units) of the box around every shape, static and moving (at
    its first pose); None when the scene has no shape."""
    boxes = [b for b in [scene.static.bbox()] + [body.scene.bbox() for body in scene.bodies]
             if b.valid()]
    if not boxes:
        return None
    low = np.min([np.asarray(b.min, np.float64) for b in boxes], axis=0)
    high = np.max([np.asarray(b.max, np.float64) for b in boxes], axis=0)
    return float(np.linalg.norm(high - low))


def scene_extent_warning(scene, preset: CameraPreset) -> str | None:
    """A warning when the scene's extent and the preset's range [min_range_m,
    max_range_m] disagree by orders of magnitude (EXTENT_RATIO): a scene in
    millimetres read as metres, or the reverse; else None."""
    extent = scene_extent(scene)
    low, high = (float(preset.reconstruction[k]) for k in ("min_range_m", "max_range_m"))
    if extent is None or (extent <= EXTENT_RATIO * high
                          and (low <= 0 or extent >= low / EXTENT_RATIO)):
        return None
    return (f"the scene's extent (its bounding box's diagonal, {extent:.3g} m) and "
            f"{preset.name}'s range ({low:g} to {high:g} m) differ by more than "
            f"{EXTENT_RATIO:g} times: is the scene written in another unit than metres? "
            "(-D unit=mm reads it in millimetres; docs/own_scene.md)")


def format_camera_summary(summary: dict, folder: str | None = None) -> str:
    """A few readable lines of a camera frame's summary."""
    w, h = summary["resolution"]
    depth, errors = summary["depth"], summary["errors"]
    lines = [f"{os.path.basename(summary['scene'])} through {summary['camera']['name']}: "
             f"{w}x{h}, {summary['spp_per_frame']} spp x {len(summary['frames'])} raw frames, "
             f"{summary['seconds']['total']:.1f} s" + (f" -> {folder}" if folder else ""),
             f"  depth: {depth['method']}; range {depth['range_m']:.3g} m; masked: "
             + ", ".join(f"{n} px {why}" for why, n in depth["masked_pixels"].items())]
    d = errors["depth_m"]
    lines.append(f"  depth error: median {d['median_abs']:.3g} m, 95th percentile "
                 f"{d['p95_abs']:.3g} m over {d['pixels']} pixels" if d["pixels"]
                 else "  depth error: no valid pixels")
    v = errors.get("velocity_m_s")
    if v is not None:
        lines.append(f"  velocity error: median {v['median_abs']:.3g} m/s, 95th percentile "
                     f"{v['p95_abs']:.3g} m/s over {v['pixels']} pixels" if v["pixels"]
                     else "  velocity error: no valid pixels")
    return "\n".join(lines)


def capture_through(path, cameras, resolution=None, defines=None, **options) -> list:
    """The scene file ``path`` through each of ``cameras`` (names, paths or presets):
    one :class:`CameraResult` each, with ``options`` of :func:`capture_camera`."""
    results = []
    for camera in cameras:
        preset = camera if isinstance(camera, CameraPreset) else load_preset(camera)
        scene = load_scene_for_camera(path, preset, resolution, defines)
        results.append(capture_camera(scene, preset, **options))
    return results
