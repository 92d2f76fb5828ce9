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
import math

import numpy as np

from .config import DatasetConfig
from .generate import camera_pose, draw_scene
from .scene_text import scene_xml

#: every array of a sample: key -> unit (an HDF5 attribute of each dataset)
UNITS = {
    "raw": "DN", "raw_ideal": "DN", "raw_direct": "DN", "raw_variance": "DN^2",
    "depth": "m", "depth_z": "m", "velocity_gt": "m/s", "velocity_along_ray": "m/s",
    "flow": "px", "scene_flow": "m", "instance": "1", "mask": "1", "normals": "1",
    "albedo": "1", "K": "px", "pose": "m", "pose_start": "m", "pose_end": "m",
    "camera_velocity": "m/s", "camera_angular_velocity": "rad/s",
}


def intrinsics(width: int, height: int, fov_deg: float) -> np.ndarray:
    """K of a pinhole whose horizontal field of view is ``fov_deg``
    (:func:`dopplertof.integrators.camera.pinhole_intrinsics`)."""
    from ..integrators.camera import pinhole_intrinsics

    return pinhole_intrinsics(width, height, fov_deg)


def render_sample(config: DatasetConfig, index: int, folder: str) -> tuple[dict, dict]:
    """(arrays, attributes) of sample ``index`` (see :data:`UNITS`) of the dataset in
    ``folder`` (its scenes' meshes are in ``folder/meshes``)."""
    from ..cameras.preset import load_preset
    from ..scene import load_string

    render = config["render"]
    preset = load_preset(render["camera"])
    description = draw_scene(config, index, preset)
    text = scene_xml(description, render["spp"], render["max_depth"])
    scene = load_string(text, {}, source=f"sample {index}", base_dir=folder)
    arrays = _raw_frames(scene, preset, render["spp"], description)
    arrays.update(sample_truth(scene, description))
    attributes = {"index": int(index), "render_seed": description["render_seed"],
                  "noise_seed": description["noise_seed"], "scene_xml": text,
                  "description": json.dumps(description, sort_keys=True),
                  "camera_preset": json.dumps(preset.describe(), sort_keys=True),
                  "photons_per_unit": arrays.pop("photons_per_unit")}
    return arrays, attributes


def _raw_frames(scene, preset, spp: int, description: dict) -> dict:
    """The three splits' raw frames, their predicted noise variance and the photon scale."""
    from ..cameras.capture import capture_camera
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
                                 photons_per_unit=full.readout.photons_per_unit)
    return {"raw": full.readout.raw, "raw_ideal": full.readout.raw_ideal.astype(np.float32),
            "raw_direct": direct_readout.raw_ideal.astype(np.float32),
            "raw_variance": full.readout.variance.astype(np.float32),
            "photons_per_unit": float(full.readout.photons_per_unit)}


def sample_truth(scene, description: dict) -> dict:
    """Depth, velocities, flow, scene flow, instances, normals, albedo, K and poses."""
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
    toward = np.where((np.sum(truth.normal * truth.direction, -1) > 0)[..., None], -1.0, 1.0)
    normals = (truth.normal * toward) @ pose[:3, :3]  # world -> camera: R^T n
    K = intrinsics(width, height, description["fov_deg"])
    z = truth.direction @ pose[:3, 2]
    half = 0.5 * (times["end"] - times["start"])
    out = {"depth": truth.depth, "depth_z": truth.depth * z, "velocity_gt": truth.velocity,
           "velocity_along_ray": truth.velocity_point, "flow": flow,
           "scene_flow": scene_flow, "normals": np.where(hit[..., None], normals, np.nan),
           "albedo": _albedo(instance, description), "K": K, "pose": pose,
           "pose_start": camera_pose(camera, -half), "pose_end": camera_pose(camera, half),
           "camera_velocity": np.asarray(camera["velocity_m_s"]),
           "camera_angular_velocity": np.asarray(camera["angular_velocity_rad_s"])}
    exact = ("K", "pose", "pose_start", "pose_end", "camera_velocity",
             "camera_angular_velocity")  # (small: kept in float64)
    out = {k: np.asarray(v, np.float64 if k in exact else np.float32) for k, v in out.items()}
    out.update(instance=instance, mask=hit)
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
    times = description["times_s"]
    width, height = description["resolution"]
    K = intrinsics(width, height, description["fov_deg"])
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
