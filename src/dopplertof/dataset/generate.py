"""One random scene per sample index: its description (plain numbers, JSON) and its
Mitsuba 3 XML text (what is rendered, stored with the sample).

Sample i draws from a NumPy PCG64 stream keyed by the configuration's seed words
(:func:`dopplertof.sampling.seed_words`) and i alone, never by which worker runs it or
when. World: +y up; the camera rests at the origin looking down -z (yaw and pitch turn
it). Camera frames are OpenCV's (x right, y down, z forward); poses are camera-to-world.
Motion is rigid with constant velocities about the mid-exposure time t_mid:

    M(t) = Translate(c + v (t - t_mid)) Rotate(w_axis, |w| (t - t_mid)) M_rest

given to the renderer as keyframes at the sequence's start, middle and end (interpolated
rigidly: exact for this motion).
"""

from __future__ import annotations

import math
import os

import numpy as np

from ..sampling import seed_words
from .config import DatasetConfig, bounding_radius, mesh_files

#: the dataset's copy of the mesh folder (its scenes name meshes relative to the dataset)
MESH_DIR = "meshes"
#: the keys of a sample's stream: (seed low, seed high, index, DOMAIN)
DOMAIN = 0x0D5E7
#: Mitsuba's camera axes (left, up, forward) from OpenCV's (right, down, forward)
OPENCV_TO_MITSUBA = np.diag([-1.0, -1.0, 1.0, 1.0])


#: how many times a sample is drawn again (an object enclosing or touching the camera,
#: nothing visible) before it fails
MAX_DRAWS = 16
def sample_rng(config: DatasetConfig, index: int, draw: int = 0) -> np.random.Generator:
    """The random stream of sample ``index``'s ``draw``-th drawing (depends on the seed,
    the index and the draw only; draw 0 is the stream of layout 1)."""
    low, high = seed_words(config[""]["seed"])
    entropy = [low, high or 0, int(index), DOMAIN] + ([int(draw)] if draw else [])
    return np.random.Generator(np.random.PCG64(np.random.SeedSequence(entropy)))


def rotation(axis, angle: float) -> np.ndarray:
    """3x3 rotation by ``angle`` (rad) about ``axis`` (Rodrigues)."""
    axis = np.asarray(axis, np.float64)
    norm = np.linalg.norm(axis)
    if norm == 0 or angle == 0:
        return np.eye(3)
    k = axis / norm
    cross = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + math.sin(angle) * cross + (1 - math.cos(angle)) * cross @ cross


def _unit_vector(rng) -> list:
    v = rng.normal(size=3)
    return (v / np.linalg.norm(v)).tolist()


def _uniform(rng, bounds) -> float:
    return float(rng.uniform(bounds[0], bounds[1]))


def rigid_motion_matrix(rest, velocity, angular_velocity, centre, tau: float) -> np.ndarray:
    """4x4 world matrix at ``tau`` s after mid-exposure of a body whose mid-exposure
    matrix is ``rest``, turning about ``centre`` at ``angular_velocity`` (rad/s,
    world axis) and moving at ``velocity`` (m/s)."""
    w = np.asarray(angular_velocity, np.float64)
    turn = np.eye(4)
    turn[:3, :3] = rotation(w, float(np.linalg.norm(w)) * tau)
    shift = np.eye(4)
    shift[:3, 3] = np.asarray(centre) + np.asarray(velocity) * tau
    back = np.eye(4)
    back[:3, 3] = -np.asarray(centre)
    return shift @ turn @ back @ np.asarray(rest, np.float64)


def draw_scene(config: DatasetConfig, index: int, preset, draw: int = 0) -> dict:
    """The description of sample ``index`` (its ``draw``-th drawing): times, camera,
    light, backdrop, objects."""
    from ..cameras.capture import sequence_window
    from ..cameras.radiometry import confined_field

    rng = sample_rng(config, index, draw)
    first, last = sequence_window(preset)
    times = {"start": first, "mid": 0.5 * (first + last), "end": last}
    width, height = config["render"]["resolution"]
    camera = _draw_camera(config, rng)
    tan_x = math.tan(math.radians(preset.fov_deg) / 2)
    tan_y = tan_x * height / width
    count = int(rng.integers(config["objects"]["count"][0], config["objects"]["count"][1] + 1))
    objects = [_draw_object(config, rng, k, camera["rest"], (tan_x, tan_y))
               for k in range(count)]
    light = {"placement": config["light"]["placement"],
             "offset_m": list(config["light"]["offset"]),
             "intensity": _uniform(rng, config["render"]["light_intensity"])}
    # an absolute preset's illuminator lights only its field: where that leaves part of
    # the view dark, the light is confined to it (cameras/radiometry.py, light_xml)
    offset = light["offset_m"] if light["placement"] == "offset" else (0.0, 0.0, 0.0)
    field_deg = confined_field(preset, (tan_x, tan_y), offset)
    if field_deg is not None:
        light["field_deg"] = field_deg
    return {"index": int(index), "draw": int(draw), "times_s": times, "camera": camera,
            "light": light,
            "backdrop": {"kind": config["backdrop"]["kind"],
                         "size_m": list(config["backdrop"]["size"]),
                         "albedo": _uniform(rng, config["backdrop"]["albedo"])},
            "objects": objects,
            "render_seed": int(rng.integers(0, 1 << 62)),
            "noise_seed": int(rng.integers(0, 1 << 62)),
            "fov_deg": preset.fov_deg, "resolution": [width, height]}


def _draw_camera(config: DatasetConfig, rng) -> dict:
    """The camera's rest pose at mid-exposure (OpenCV axes) and its ego-motion."""
    cam = config["camera"]
    position = [_uniform(rng, cam["position"]) for _ in range(3)]
    yaw = math.radians(_uniform(rng, cam["yaw_deg"]))
    pitch = math.radians(_uniform(rng, cam["pitch_deg"]))
    base = np.array([[1.0, 0, 0], [0, -1.0, 0], [0, 0, -1.0]])  # right, down, forward
    pose = np.eye(4)
    pose[:3, :3] = rotation([0, 1, 0], yaw) @ rotation([1, 0, 0], pitch) @ base
    pose[:3, 3] = position
    velocity = (np.array(_unit_vector(rng)) * _uniform(rng, cam["speed"])).tolist()
    spin = (np.array(_unit_vector(rng)) * _uniform(rng, cam["angular_speed"])).tolist()
    return {"rest": pose.tolist(), "velocity_m_s": velocity,
            "angular_velocity_rad_s": spin,
            "moving": bool(np.any(velocity) or np.any(spin))}


def _draw_object(config: DatasetConfig, rng, k: int, camera_rest, tans) -> dict:
    """Object k: shape, size, material, pose at mid-exposure (in the camera's view) and
    velocities."""
    objects, motion = config["objects"], config["motion"]
    shape = str(rng.choice(objects["shapes"]))
    mesh, normalise = None, np.eye(4)
    if shape == "mesh":
        files = mesh_files(mesh_folder(config))
        path = files[int(rng.integers(0, len(files)))]
        mesh = f"{MESH_DIR}/{os.path.basename(path)}"
        normalise = mesh_normalisation(path)
    size = _uniform(rng, objects["size"])
    depth = _uniform(rng, objects["distance"])
    lateral = [float(rng.uniform(-1, 1)) * objects["spread"] * t * depth for t in tans]
    centre = (np.asarray(camera_rest) @ np.array([*lateral, depth, 1.0]))[:3]
    turn = rotation(_unit_vector(rng), float(rng.uniform(0, 2 * math.pi)))
    if shape == "rectangle":  # faces the camera (+z towards it), spun and tilted a little
        facing = -np.asarray(camera_rest)[:3, :3]
        turn = facing @ np.diag([-1.0, 1.0, 1.0]) @ rotation(_unit_vector(rng), 0.3 * rng.uniform())
    rest = np.eye(4)
    rest[:3, :3] = turn * size
    rest[:3, 3] = centre
    rest = rest @ normalise  # (a mesh: its box centred on ``centre``, half-size ``size``)
    velocity = (np.array(_unit_vector(rng)) * _uniform(rng, motion["speed"])).tolist()
    spin = (np.array(_unit_vector(rng)) * _uniform(rng, motion["angular_speed"])).tolist()
    kind = str(rng.choice(objects["materials"]))
    material = {"kind": kind, "colour": [_uniform(rng, objects["albedo"]) for _ in range(3)]}
    roughness = _uniform(rng, objects["roughness"])  # drawn for every kind: same seed, same scene
    if kind != "diffuse":  # a diffuse BSDF has no roughness
        material["roughness"] = roughness
    return {"id": f"object_{k}", "shape": shape, "mesh": mesh, "size_m": size,
            "material": material,
            "centre_m": centre.tolist(), "rest": rest.tolist(),
            "velocity_m_s": velocity, "angular_velocity_rad_s": spin}


def frame_description(description: dict, frame: int, fps: float) -> dict:
    """Frame ``frame`` of a clip at ``fps`` frames per second of the scene ``description``
    (its frame 0): the same scene ``frame / fps`` s later, every body and the camera
    moved on along their constant-velocity motions (each pose and centre the frame's own
    at its mid-exposure), its times and the rest kept; its noise seed drawn from the
    sample's and the frame's (frame 0 is ``description`` itself)."""
    if frame == 0:
        return description
    tau = frame / fps
    camera = dict(description["camera"])
    camera["rest"] = camera_pose(description["camera"], tau).tolist()
    objects = [{**obj, "rest": object_matrix(obj, tau).tolist(),
                "centre_m": (np.asarray(obj["centre_m"]) + tau * np.asarray(
                    obj["velocity_m_s"])).tolist()} for obj in description["objects"]]
    noise = np.random.SeedSequence([int(description["noise_seed"]), int(frame)])
    return {**description, "camera": camera, "objects": objects,
            "noise_seed": int(noise.generate_state(1, np.uint64)[0] >> np.uint64(2)),
            "clip_frame": int(frame), "clip_time_s": tau}


def enclosed_camera(description: dict) -> str | None:
    """The first object whose bounding sphere holds the camera's centre at mid-exposure
    (it encloses or touches the camera), said in words; None when none does."""
    centre = np.asarray(description["camera"]["rest"])[:3, 3]
    for obj in description["objects"]:
        gap = float(np.linalg.norm(np.asarray(obj["centre_m"]) - centre))
        radius = bounding_radius(obj["shape"], obj["size_m"])
        if gap <= radius:
            return (f"{obj['id']} ({obj['shape']}, size {obj['size_m']:.3g} m) is "
                    f"{gap:.3g} m from the camera, within its bounding radius {radius:.3g} m")
    return None


def mesh_normalisation(path: str) -> np.ndarray:
    """The 4x4 matrix that puts a mesh file in the cube [-1, 1]^3 as a cube of size 1
    fills it: its bounding box's centre to the origin and its largest half-extent to 1
    (uniform scale: the mesh keeps its proportions). A dataset's meshes come in any
    unit and placement (the Stanford bunny spans 0.16 x 0.15 x 0.12 about (-0.02, 0.11,
    0)); ``objects.size`` then is their half-size in metres, as a cube's."""
    from ..scene.meshes import mesh_file_bounds

    low, high = mesh_file_bounds(path)
    half = float(np.max(high - low)) / 2
    out = np.diag([1.0 / half] * 3 + [1.0])
    out[:3, 3] = -(low + high) / 2 / half
    return out


def mesh_folder(config: DatasetConfig) -> str:
    """The configuration's mesh folder (absolute)."""
    return os.path.join(config.base_dir, config["objects"]["mesh_folder"])


def object_matrix(obj: dict, tau: float) -> np.ndarray:
    """Object ``obj``'s world matrix ``tau`` s after mid-exposure."""
    return rigid_motion_matrix(obj["rest"], obj["velocity_m_s"], obj["angular_velocity_rad_s"],
                               obj["centre_m"], tau)


def camera_pose(camera: dict, tau: float) -> np.ndarray:
    """The camera-to-world pose (OpenCV axes) ``tau`` s after mid-exposure."""
    rest = np.asarray(camera["rest"])
    return rigid_motion_matrix(rest, camera["velocity_m_s"], camera["angular_velocity_rad_s"],
                               rest[:3, 3], tau)


def albedo_of(material: dict) -> list:
    """The diffuse albedo of a material (a conductor has none: 0)."""
    return [0.0, 0.0, 0.0] if material["kind"] == "conductor" else list(material["colour"])
