"""One sample: its scene rendered through the camera preset (global illumination with
sensor noise, without it, and direct light only) and its exact truth at mid-exposure.

The raw frames are :func:`dopplertof.cameras.capture.capture_camera`'s, in DN: ``raw``
(full: noise), ``raw_ideal`` (the same render on mean electrons, no rounding or clipping)
and ``raw_direct`` (a max_depth = 2 render read out at the full render's photon scale,
no noise). Depth, radial velocity, body per pixel, normals and ray directions are
:func:`dopplertof.tof.ground_truth.ground_truth`'s; optical flow and scene flow follow
each hit point with its body's motion and the camera's, from the start of the sequence
to its end (docs/dataset.md gives every convention).
"""

from __future__ import annotations

import json

import numpy as np

from ..file_formats import json_ready
from ..outputs import CAMERA_SPLITS, MASKS, SAMPLE, SAMPLE_CAMERA
from .config import DatasetConfig
from .generate import camera_pose, draw_scene
from .scene_text import scene_xml

#: the splits' camera outputs (name -> unit) and every array's unit, declared in
#: :mod:`dopplertof.outputs`
CAMERA_OUTPUTS, UNITS = SAMPLE_CAMERA, SAMPLE


def render_sample(config: DatasetConfig, index: int, folder: str) -> tuple[dict, dict]:
    """(arrays, attributes) of sample ``index`` (see :data:`UNITS`) of the dataset in
    ``folder`` (its scenes' meshes are in ``folder/meshes``); a clip of T frames
    (``clip_frames``) stacks each array as (T, ...) (:func:`render_clip`)."""
    from ..cameras.preset import load_preset

    render = config["render"]
    preset = load_preset(render["camera"])
    draw = 0
    while True:  # (drawn again while the camera reports too few pixels in frame 0)
        description, text, scene, truth = drawn_sample(config, index, preset, folder, draw)
        if config.clip_frames > 1:
            arrays, attributes = render_clip(config, preset, description,
                                             (text, scene, truth), folder)
            valid = arrays["camera_valid"][0]
        else:
            arrays, attributes = _frame_arrays(render, preset, description, scene, truth), None
            valid = arrays["camera_valid"]
        problem = too_few_valid(valid, render["min_valid_share"])
        if problem is None:
            break
        draw = _next_draw(index, description["draw"], problem)
    if attributes is None:
        attributes = _attributes(description, text, preset, arrays.pop("photons_per_unit"))
    return arrays, attributes


def _frame_arrays(render: dict, preset, description: dict, scene, truth: dict) -> dict:
    """The arrays of one frame: its raw frames, its truth and the camera's outputs."""
    arrays, readings = _raw_frames(scene, preset, render["spp"], description)
    arrays.update(truth)
    arrays.update(camera_outputs(readings, preset, arrays["depth_z"] / arrays["depth"]))
    return arrays


def _attributes(description: dict, text: str, preset, photons) -> dict:
    return {"index": int(description["index"]), "render_seed": description["render_seed"],
            "noise_seed": description["noise_seed"], "scene_xml": text,
            "description": json.dumps(json_ready(description), sort_keys=True),
            "camera_preset": json.dumps(json_ready(preset.describe()), sort_keys=True),
            "photons_per_unit": photons}


def clip_descriptions(config: DatasetConfig, description: dict, preset) -> list:
    """The descriptions of every frame of the sample whose frame 0 is ``description``
    (:func:`dopplertof.dataset.generate.frame_description`); one frame: itself."""
    from .config import clip_fps
    from .generate import frame_description

    fps = clip_fps(config.values, preset)
    return [frame_description(description, k, fps) for k in range(config.clip_frames)]


def render_clip(config: DatasetConfig, preset, description: dict, first: tuple,
                folder: str) -> tuple[dict, dict]:
    """A clip's (arrays, attributes): frame k is the scene ``k / fps`` s on (its bodies
    and the camera moved on, its own sensor noise), each array stacked (T, ...); the
    attributes are frame 0's (description, scene_xml, noise_seed), with ``clip_frames``,
    ``fps``, ``clip_times_s`` (each frame's start after frame 0's), ``clip_noise_seeds``,
    ``clip_scene_xml`` (JSON list of every frame's scene) and ``photons_per_unit`` per
    frame."""
    from ..scene import load_string
    from .config import clip_fps

    render = config["render"]
    frames, texts = [], [first[0]]
    descriptions = clip_descriptions(config, description, preset)
    for k, frame in enumerate(descriptions):
        if k == 0:
            text, scene, truth = first
        else:
            text = scene_xml(frame, render["spp"], render["max_depth"])
            scene = load_string(text, {}, source=f"sample {description['index']}, frame {k}",
                                base_dir=folder)
            truth = sample_truth(scene, frame, render["grazing_deg"])
            texts.append(text)
        frames.append(_frame_arrays(render, preset, frame, scene, truth))
    photons = np.asarray([f.pop("photons_per_unit") for f in frames], np.float64)
    arrays = {key: np.stack([f[key] for f in frames]) for key in frames[0]}
    attributes = _attributes(description, first[0], preset, photons)
    attributes.update(clip_frames=len(frames), fps=float(clip_fps(config.values, preset)),
                      clip_times_s=np.asarray([d.get("clip_time_s", 0.0)
                                               for d in descriptions], np.float64),
                      clip_noise_seeds=np.asarray([d["noise_seed"] for d in descriptions],
                                                  np.int64),
                      clip_scene_xml=json.dumps(texts))
    return arrays, attributes


def too_few_valid(valid: np.ndarray, least: float) -> str | None:
    """Why a sample whose camera reports the pixels ``valid`` is not kept (fewer than
    ``least`` of them: render.min_valid_share), or None."""
    share = float(np.mean(valid))
    if share < least:
        return (f"the camera reports {int(np.sum(valid))} of {valid.size} pixels "
                f"({share:.2%}, below render.min_valid_share {least:g})")
    return None


def _next_draw(index: int, draw: int, problem: str) -> int:
    """The drawing after ``draw`` of sample ``index``; a DatasetError naming ``problem``
    where it was the last (MAX_DRAWS)."""
    from .config import DatasetError
    from .generate import MAX_DRAWS

    if draw + 1 >= MAX_DRAWS:
        raise DatasetError(f"sample {index}: drawn {MAX_DRAWS} times, never usable; the "
                           f"last: {problem} (objects.distance, objects.size, "
                           "objects.spread, render.min_valid_share)")
    return draw + 1


def drawn_sample(config: DatasetConfig, index: int, preset, folder: str,
                 first: int = 0) -> tuple:
    """(description, scene XML, loaded scene, truth) of sample ``index``: its first
    drawing from ``first`` on in which no object encloses the camera and something is
    visible (an object, when it has any); drawn again up to MAX_DRAWS drawings in all,
    then a DatasetError saying why."""
    from ..scene import load_string
    from .config import DatasetError
    from .generate import MAX_DRAWS, enclosed_camera
    from .structure import kinds_alive

    render = config["render"]
    kinds_alive(config)  # (before any scene: the same registry ids in every worker)
    for draw in range(first, MAX_DRAWS):
        description = draw_scene(config, index, preset, draw)
        problem = next(filter(None, map(enclosed_camera, clip_descriptions(
            config, description, preset))), None)  # (every frame of a clip)
        if problem is None:
            text = scene_xml(description, render["spp"], render["max_depth"])
            scene = load_string(text, {}, source=f"sample {index}", base_dir=folder)
            truth = sample_truth(scene, description, render["grazing_deg"])
            problem = nothing_visible(truth, description)
            if problem is None:
                return description, text, scene, truth
    raise DatasetError(f"sample {index}: drawn {MAX_DRAWS} times, never usable; the last: "
                       f"{problem} (objects.distance, objects.size, objects.spread)")


def nothing_visible(truth: dict, description: dict) -> str | None:
    """Why the sample shows nothing worth storing (no pixel hits anything; or it has
    objects and none is seen), or None."""
    if not truth["mask"].any():
        return "no pixel sees anything"
    if description["objects"] and not (truth["instance"] >= 1).any():
        return f"none of its {len(description['objects'])} objects is seen"
    return None


def _raw_frames(scene, preset, spp: int, description: dict) -> tuple[dict, dict]:
    """The three splits' raw frames, their predicted noise variance and the photon scale;
    and each split's reconstruction by the camera (split -> CameraReconstruction)."""
    from ..cameras.capture import capture_camera
    from ..cameras.reconstruct import reconstruct
    from ..cameras.sensor import read_frames

    seed = description["render_seed"]
    full = capture_camera(scene, preset, spp, seed, noise=True,
                          noise_seed=description["noise_seed"], progress=False)
    direct = capture_camera(scene, preset, spp, seed, params={"max_depth": 2}, noise=False,
                            progress=False)
    unmodulated = scene.params.g_0 * direct.radiance.mean(axis=-1, dtype=np.float64)
    direct_readout = read_frames(direct.rendered, unmodulated,
                                 [f.integration_s for f in preset.frames], preset.sensor,
                                 preset.contrast, None,
                                 photons_per_unit=full.readout.photons_per_unit,
                                 shutter=full.readout.shutter)
    readings = {"full": full.reconstruction, "ideal": full.read_again(None)[1],
                "direct": reconstruct(direct_readout, preset, full.mixed_footprints,
                                      full.reconstruction.unlit)}
    return ({"raw": full.readout.raw, "raw_ideal": full.readout.raw_ideal.astype(np.float32),
             "raw_direct": direct_readout.raw_ideal.astype(np.float32),
             "raw_variance": full.readout.variance.astype(np.float32),
             "photons_per_unit": float(full.readout.photons_per_unit)}, readings)


def camera_outputs(readings: dict, preset, cosine: np.ndarray) -> dict:
    """``camera_*`` arrays of every split (:data:`CAMERA_OUTPUTS`) from each split's
    reconstruction; ``cosine``: (H, W) each pixel's ray with the optical axis (the truth's
    depth_z / depth: NaN where the ray hits nothing, and so is camera_depth_z)."""
    out = {"camera_frequencies": np.asarray(preset.frequencies_mhz, np.float64)}
    for split, recon in readings.items():
        suffix = CAMERA_SPLITS[split]
        arrays = {"depth": recon.depth, "depth_z": recon.depth * cosine,
                  "amplitude": recon.amplitude, "depth_std": np.sqrt(recon.depth_variance),
                  "phase": np.stack([g.phase for g in recon.frequencies])}
        if recon.velocity is not None:
            arrays["radial_velocity"] = recon.velocity
        out.update({f"camera_{k}{suffix}": np.asarray(v, np.float32)
                    for k, v in arrays.items()})
        masks = {name: recon.mask(attribute) for name, (attribute, _) in MASKS.items()}
        masks["valid"] = ~recon.masked
        out.update({f"camera_{k}{suffix}": np.asarray(v, bool) for k, v in masks.items()})
    return out


def sample_truth(scene, description: dict, grazing_deg: float = 80.0) -> dict:
    """Depth, velocities, flow, scene flow, instances, normals, albedo, K and poses; the
    incidence angle, the pixels seeing a surface beyond ``grazing_deg`` (grazing) and
    those whose depth and velocity truth holds (truth_valid: a hit, not grazing)."""
    from ..integrators.camera import pinhole_intrinsics
    from ..tof.ground_truth import ground_truth

    times = description["times_s"]
    width, height = description["resolution"]
    truth = ground_truth(scene.with_shutter(times["start"], times["end"] - times["start"]))
    camera = description["camera"]
    pose = camera_pose(camera, 0.0)
    hit = truth.body > -2
    points = truth.camera_origin + truth.depth[..., None] * truth.direction  # (H, W, 3)
    instance = _instances(scene, truth.body, description)
    flow, scene_flow = _flows(scene, description, truth.body, points)
    cosine = np.sum(truth.normal * truth.direction, -1)
    toward = np.where((cosine > 0)[..., None], -1.0, 1.0)
    incidence = np.where(hit, np.degrees(np.arccos(np.clip(np.abs(cosine), 0.0, 1.0))), np.nan)
    grazing = hit & ~(incidence <= grazing_deg)
    normals = (truth.normal * toward) @ pose[:3, :3]  # world -> camera: R^T n
    K = pinhole_intrinsics(width, height, description["fov_deg"])
    z = truth.direction @ pose[:3, 2]
    half = 0.5 * (times["end"] - times["start"])
    out = {"depth": truth.depth, "depth_z": truth.depth * z, "velocity_gt": truth.velocity,
           "velocity_point": truth.velocity_point, "flow": flow,
           "scene_flow": scene_flow, "normals": np.where(hit[..., None], normals, np.nan),
           "albedo": _albedo(instance, description), "incidence": incidence,
           "K": K, "pose": pose,
           "pose_start": camera_pose(camera, -half), "pose_end": camera_pose(camera, half),
           "camera_velocity": np.asarray(camera["velocity_m_s"]),
           "camera_angular_velocity": np.asarray(camera["angular_velocity_rad_s"])}
    exact = ("K", "pose", "pose_start", "pose_end", "camera_velocity",
             "camera_angular_velocity")  # (small: kept in float64)
    out = {k: np.asarray(v, np.float64 if k in exact else np.float32) for k, v in out.items()}
    out.update(instance=instance, mask=hit, grazing=grazing, truth_valid=hit & ~grazing)
    return out


def _instances(scene, body: np.ndarray, description: dict) -> np.ndarray:
    """Per pixel: -1 nothing, 0 the backdrop, k + 1 object k."""
    instance = np.where(body == -2, -1, 0).astype(np.int16)
    for k, moving in enumerate(scene.bodies):
        number = int(moving.names[0].rsplit("_", 1)[1]) + 1  # ids object_<k>
        instance[body == k] = number
    return instance


def _albedo(instance: np.ndarray, description: dict) -> np.ndarray:
    """Per pixel: the diffuse albedo (RGB) of what it sees (NaN: nothing)."""
    from .generate import albedo_of

    table = np.full((len(description["objects"]) + 2, 3), np.nan)
    table[1] = [description["backdrop"]["albedo"]] * 3
    for k, obj in enumerate(description["objects"]):
        table[k + 2] = albedo_of(obj["material"])
    return table[instance.astype(np.int64) + 1]


def _flows(scene, description: dict, body: np.ndarray, points: np.ndarray):
    """Optical flow (px) and scene flow (m, camera coordinates) of every hit point
    moving with its body: where the camera sees it at the end of the sequence minus where
    it sees it at the start (the camera's own motion included)."""
    from ..integrators.camera import pinhole_intrinsics

    times = description["times_s"]
    width, height = description["resolution"]
    K = pinhole_intrinsics(width, height, description["fov_deg"])
    camera, half = description["camera"], 0.5 * (times["end"] - times["start"])
    ends = []
    for sign in (-1.0, 1.0):
        moved = points.copy()
        for k, moving in enumerate(scene.bodies):
            on = body == k
            rel = moving.motion.relative_matrix(times["mid"] + sign * half) @ np.linalg.inv(
                moving.motion.relative_matrix(times["mid"]))
            moved[on] = moved[on] @ rel[:3, :3].T + rel[:3, 3]
        to_camera = np.linalg.inv(camera_pose(camera, sign * half))
        ends.append(moved @ to_camera[:3, :3].T + to_camera[:3, 3])
    pixels = [(q @ K.T)[..., :2] / q[..., 2:3] for q in ends]
    return pixels[1] - pixels[0], ends[1] - ends[0]
