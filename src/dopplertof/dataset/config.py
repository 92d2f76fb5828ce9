"""Dataset configurations: the TOML format of ``dopplertof dataset``, checked strictly.

Every section and key is listed in :data:`SCHEMA` with its type, range and meaning; an
unknown or misspelt key is one line naming the file and the key (with the nearest known
name), by the package's one TOML validator (toml_schema.py), the camera presets' too. A
range is ``[low, high]`` and a sample draws uniformly in it; ``[x, x]`` fixes the value. ``examples/dataset.toml`` is the
commented reference; docs/dataset.md describes what each key does to a scene.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass

from ..arguments import check_seed
from .. import toml_schema
from ..file_formats import read_toml
from ..toml_schema import Key

#: shapes a configuration may draw ("mesh": a file of [objects] mesh_folder)
SHAPES = ("sphere", "cube", "rectangle", "mesh")
#: materials a configuration may draw
MATERIALS = ("diffuse", "plastic", "conductor")
#: backdrops: a closed room around camera and objects, one wall behind them, or nothing
BACKDROPS = ("room", "wall", "none")
#: where the point light is: on the camera's centre, or at an offset riding with it
LIGHT_PLACEMENTS = ("camera", "offset")
#: mesh files a mesh folder may hold
MESH_EXTENSIONS = (".obj", ".ply")
#: a shape's bounding radius per unit of size (a mesh fits the cube [-1, 1]^3)
BOUNDING_RADIUS = {"sphere": 1.0, "cube": math.sqrt(3.0), "rectangle": math.sqrt(2.0),
                   "mesh": math.sqrt(3.0)}
#: the largest turn of a body within half a sequence (the keyframes' interpolation takes
#: the short arc: below pi it is the drawn rotation)
MAX_HALF_TURN = 0.9 * math.pi


class DatasetError(ValueError):
    """A dataset configuration or output folder that cannot be used; one line."""


def _range(lo=None, hi=None):
    """A check of a [low, high] range inside [lo, hi]."""
    def check(v):
        return (len(v) == 2 and v[0] <= v[1] and (lo is None or v[0] >= lo)
                and (hi is None or v[1] <= hi))
    return check


def _positive(x):
    return x > 0


#: section -> key -> Key (toml_schema.py: kind, meaning, range check, default)
SCHEMA = {
    "": {
        "name": Key("string", "the dataset's name", default="dataset"),
        "samples": Key("integer", "how many samples", _positive),
        "seed": Key("integer", "the seed every sample's own is derived from", default=0),
        "samples_per_shard": Key("integer", "samples in one HDF5 shard", _positive,
                                 default=8),
        "clip_frames": Key("integer", "depth frames per sample: a clip of consecutive "
                           "frames of one scene whose bodies keep moving (1: one frame)",
                           _positive, default=1),
        "fps": Key("float", "a clip's frames per second (default: the camera preset's "
                   "frame_rate_hz)", _positive, default=None),
    },
    "render": {
        "resolution": Key("ints", "[width, height] pixels",
                          lambda v: len(v) == 2 and min(v) >= 1),
        "spp": Key("integer", "samples per pixel per raw frame", _positive),
        "max_depth": Key("integer", "path length of the full and ideal splits (2: direct "
                         "light only)", lambda x: x >= 2, default=5),
        "camera": Key("string", "a camera preset's name or a preset .toml file (dopplertof "
                      "cameras --list)", default="paper-dtof"),
        "light_intensity": Key("range", "point light, W/sr, > 0",
                               lambda v: _range(0)(v) and v[0] > 0, default=[20.0, 20.0]),
        "min_valid_share": Key("float", "least share of the pixels the camera reports "
                               "(camera_valid): a sample below it is drawn again",
                               lambda x: 0 <= x <= 1, default=0.01),
        "grazing_deg": Key("float", "incidence angle beyond which a pixel's depth and "
                           "velocity truth is flagged grazing", lambda x: 0 < x <= 90,
                           default=80.0),
    },
    "backdrop": {
        "kind": Key("string", "one of " + ", ".join(BACKDROPS), lambda x: x in BACKDROPS,
                    default="room"),
        "size": Key("floats", "[width, height, depth] m of the room (the wall: width, height "
                    "and its distance)", lambda v: len(v) == 3 and min(v) > 0,
                    default=[6.0, 4.0, 8.0]),
        "albedo": Key("range", "diffuse albedo", _range(0, 1), default=[0.3, 0.8]),
    },
    "objects": {
        "count": Key("ints", "[fewest, most] objects", _range(0), default=[1, 3]),
        "shapes": Key("names", "drawn from " + ", ".join(SHAPES),
                      lambda v: set(v) <= set(SHAPES), default=["sphere", "cube"]),
        "mesh_folder": Key("string", "folder of .obj/.ply meshes in any unit (each "
                           "normalised: its bounding box centred, its largest half-extent 1; "
                           "then scaled by size, as a cube)", default=""),
        "materials": Key("names", "drawn from " + ", ".join(MATERIALS),
                         lambda v: set(v) <= set(MATERIALS), default=["diffuse"]),
        "size": Key("range", "radius or half-size, m", _range(1e-3), default=[0.2, 0.5]),
        "distance": Key("range", "from the camera along its view, m", _range(1e-2),
                        default=[2.0, 4.0]),
        "spread": Key("float", "lateral placement: fraction of the half field of view",
                      lambda x: 0 <= x <= 1, default=0.6),
        "albedo": Key("range", "diffuse albedo", _range(0, 1), default=[0.2, 0.9]),
        "roughness": Key("range", "alpha of conductors and plastics", _range(1e-3, 1),
                         default=[0.05, 0.4]),
    },
    "motion": {
        "speed": Key("range", "objects' linear speed, m/s, random direction", _range(0),
                     default=[0.0, 10.0]),
        "angular_speed": Key("range", "objects' spin, rad/s, random axis", _range(0),
                             default=[0.0, 50.0]),
    },
    "camera": {
        "position": Key("range", "each coordinate's jitter about the origin, m", _range(),
                        default=[0.0, 0.0]),
        "yaw_deg": Key("range", "turn about +y from looking down -z", _range(-90, 90),
                       default=[0.0, 0.0]),
        "pitch_deg": Key("range", "tilt up (+) or down", _range(-60, 60),
                         default=[0.0, 0.0]),
        "speed": Key("range", "ego-motion, m/s, random direction", _range(0),
                     default=[0.0, 0.0]),
        "angular_speed": Key("range", "ego-rotation, rad/s, random axis", _range(0),
                             default=[0.0, 0.0]),
    },
    "light": {
        "placement": Key("string", "one of " + ", ".join(LIGHT_PLACEMENTS),
                         lambda x: x in LIGHT_PLACEMENTS, default="camera"),
        "offset": Key("floats", "[x, y, z] m in the camera's frame (x right, y down, z "
                      "forward) for placement = 'offset'", lambda v: len(v) == 3,
                      default=[0.0, 0.0, 0.0]),
    },
}


@dataclass(frozen=True)
class DatasetConfig:
    """A checked configuration: ``values[section][key]``, every default filled in."""

    values: dict
    source: str  #: the file, for messages
    base_dir: str  #: relative paths (mesh folder, camera file) are relative to it

    def __getitem__(self, section: str) -> dict:
        return self.values[section]

    @property
    def samples(self) -> int:
        return self.values[""]["samples"]

    @property
    def shard_size(self) -> int:
        return self.values[""]["samples_per_shard"]

    @property
    def clip_frames(self) -> int:
        return self.values[""]["clip_frames"]

    def to_json(self) -> dict:
        """The configuration as written to dataset.json and hashed; a clip's keys left
        out at their defaults (one frame: the same hash as before clips existed)."""
        out = {s or "dataset": dict(v) for s, v in self.values.items()}
        for key, default in CLIP_DEFAULTS.items():
            if out["dataset"].get(key) == default:
                del out["dataset"][key]
        return out


#: the clip keys' defaults, left out of :meth:`DatasetConfig.to_json` (a dataset of one
#: frame per sample hashes as one made before clips existed)
CLIP_DEFAULTS = {"clip_frames": 1, "fps": None}


def clip_fps(config_values: dict, preset) -> float | None:
    """A clip's frames per second: the configuration's ``fps``, else the preset's
    frame_rate_hz (None: neither)."""
    fps = config_values[""]["fps"]
    return preset.frame_rate_hz if fps is None else fps


def load_config(path) -> DatasetConfig:
    """The checked configuration of a TOML file (:class:`DatasetError` on anything)."""
    path = os.fspath(path)
    if not os.path.isfile(path):
        raise DatasetError(f"dataset configuration not found: {path}")
    return config_from_mapping(read_toml(path, DatasetError), path,
                               os.path.dirname(os.path.abspath(path)))


def config_from_mapping(data: dict, source: str = "<config>",
                        base_dir: str = ".") -> DatasetConfig:
    """The checked configuration of parsed TOML ``data``."""
    sections = [s for s in SCHEMA if s]
    values = {"": toml_schema.section(data, SCHEMA[""], source, DatasetError,
                                      extra=sections)}
    for name in sections:
        table = toml_schema.table(data, name, source, DatasetError, required=False)
        values[name] = toml_schema.section(table, SCHEMA[name], source, DatasetError, name)
    check_seed(values[""]["seed"], f"{source}: seed", DatasetError)
    _check_together(values, source, base_dir)
    return DatasetConfig(values, source, os.path.abspath(base_dir))


#: the most samples one dataset folder plans: its dataset.json lists every sample (about
#: 10 bytes each) and its plan holds a task per shard (samples = 10**12 planned for 50 s
#: and ended in a MemoryError)
MAX_SAMPLES = 10_000_000


def _check_together(values: dict, source: str, base_dir: str) -> None:
    """What one key cannot say alone: a plan of a size a folder can hold, a mesh folder
    for the mesh shape, a known camera."""
    from ..cameras.preset import PresetError, load_preset

    samples, per_shard = values[""]["samples"], values[""]["samples_per_shard"]
    if samples > MAX_SAMPLES:
        raise DatasetError(
            f"{source}: samples = {samples} plans {-(-samples // per_shard)} shards and a "
            f"dataset.json of about {samples * 10 / 1e9:.3g} GB; at most {MAX_SAMPLES} "
            "samples per dataset folder: make several datasets (another seed each)")
    objects = values["objects"]
    if "mesh" in objects["shapes"]:
        folder = objects["mesh_folder"]
        if not folder:
            raise DatasetError(f"{source}: objects.shapes has 'mesh': set objects.mesh_folder")
        if not mesh_files(os.path.join(base_dir, folder)):
            raise DatasetError(f"{source}: objects.mesh_folder {folder!r} holds no "
                               f"{'/'.join(MESH_EXTENSIONS)} file")
        _check_mesh_sizes(os.path.join(base_dir, folder), objects["size"], source)
    _check_clearance(objects, source)
    _check_something_lit(values, source)
    camera = values["render"]["camera"]
    if camera.endswith(".toml"):
        camera = values["render"]["camera"] = os.path.join(base_dir, camera)
    try:
        preset = load_preset(camera)
    except PresetError as e:
        raise DatasetError(f"{source}: render.camera: {e}") from None
    _check_spins(values, preset, source)
    _check_clip(values, preset, source)
    _check_size(values["render"], source)
    _check_time(values["render"], len(preset.frames) * values[""]["clip_frames"], source)


def _check_clip(values: dict, preset, source: str) -> None:
    """A clip of several frames has a frame rate (``fps`` or the preset's) at which the
    preset's raw frames fit in a frame."""
    from ..cameras.preset import sequence_too_long

    if values[""]["clip_frames"] == 1:
        return
    fps = clip_fps(values, preset)
    if fps is None:
        raise DatasetError(f"{source}: clip_frames = {values['']['clip_frames']} needs fps: "
                           f"the camera preset {preset.name} gives no frame_rate_hz")
    problem = sequence_too_long(preset, fps)
    if problem:
        raise DatasetError(f"{source}: fps = {fps:g}: {problem}")


#: renders of every frame of the preset per sample: the full split (the ideal one is its
#: noiseless readout) and the direct split (dataset.sample)
RENDERS_PER_FRAME = 2
#: the longest a sample may take by the estimate `render` gives (budget.py), beyond
#: which the configuration is refused (spp = 10**9 ran silently for days)
MAX_SAMPLE_SECONDS = 24 * 3600.0


def sample_seconds(render: dict, frames: int) -> float:
    """Roughly how long one sample renders, as `render` estimates (budget.estimate)."""
    from .. import budget

    width, height = render["resolution"]
    spp = render["spp"]
    one = budget.estimate(width, height, 1, spp, min(spp, 8192), 1).seconds
    return one * frames * RENDERS_PER_FRAME


def describe_sample(render: dict, frames: int) -> str:
    from .. import budget

    width, height = render["resolution"]
    return (f"{RENDERS_PER_FRAME * frames} renders of {width}x{height} pixels at "
            f"{render['spp']} spp, roughly {budget.duration(sample_seconds(render, frames))} "
            f"on {os.cpu_count() or 1} core(s)")


def _check_size(render: dict, source: str) -> None:
    """A render's pass holds min(spp, 8192) samples of every pixel in one Dr.Jit array
    (budget.py): past 2^32 entries no machine renders it (a
    resolution of [100000, 100000] failed every sample in the workers with Dr.Jit's
    ``jit_var_counter(): tried to create an array with 10000000000 entries``)."""
    from .. import budget

    width, height = render["resolution"]
    spp = render["spp"]
    lanes = budget.estimate(width, height, 1, spp, min(spp, 8192), 1).largest_array
    if lanes > budget.MAX_LANES:
        raise DatasetError(
            f"{source}: render.resolution = [{width}, {height}] at render.spp = {spp}: a "
            f"render pass holds {lanes:.3g} samples (min(spp, 8192) of each of "
            f"{width * height:.3g} pixels), more than Dr.Jit's {budget.MAX_LANES + 1:.3g} "
            "entries per array: lower render.resolution")


def _check_time(render: dict, frames: int, source: str) -> None:
    from ..params import RenderParams

    group = RenderParams().time_correlate_number  # the dataset's scenes use the integrator's default
    if render["spp"] % group:  # (every sample would fail in the workers)
        raise DatasetError(
            f"{source}: render.spp = {render['spp']} is not a multiple of the correlated "
            f"group size {group} (time_correlate_number): use {group * -(-render['spp'] // group)}")
    if sample_seconds(render, frames) > MAX_SAMPLE_SECONDS:
        raise DatasetError(
            f"{source}: render.spp = {render['spp']}: each sample takes "
            f"{describe_sample(render, frames)}; at most {MAX_SAMPLE_SECONDS / 3600:g} h "
            "per sample: lower render.spp or render.resolution")


def bounding_radius(shape: str, size: float) -> float:
    """The radius (m) of the sphere about an object's centre that holds it."""
    return BOUNDING_RADIUS[shape] * size


def _check_mesh_sizes(folder: str, size: list, source: str) -> None:
    """Every mesh is readable and has an extent to normalise (one line naming the first
    that does not: a mesh of one point, or of non-finite vertices)."""
    import numpy as np

    from ..scene.meshes import mesh_file_bounds, mesh_file_problem

    for path in mesh_files(folder):
        # what is wrong with the file first (a cut-off .obj read as NumPy's "inhomogeneous
        # shape", a NaN vertex as a mesh to rescale)
        plugin = "obj" if path.lower().endswith(".obj") else "ply"
        problem = mesh_file_problem(path, plugin)
        if problem:
            raise DatasetError(f"{source}: objects.mesh_folder: mesh file {path}: {problem}")
        try:
            bounds = mesh_file_bounds(path)
        except (OSError, ValueError) as e:
            raise DatasetError(f"{source}: objects.mesh_folder: {path}: unreadable ({e})") \
                from None
        extent = bounds[1] - bounds[0]
        if not (np.all(np.isfinite(bounds)) and extent.max() > 0):
            raise DatasetError(
                f"{source}: objects.mesh_folder: {path} spans "
                f"{' x '.join(f'{x:.4g}' for x in extent)}: a mesh needs an extent to be "
                f"normalised to objects.size {size} (its largest half-extent)")


#: farthest a light offset may be from the camera, m (a point light's irradiance falls
#: as 1/r^2: at 1e9 m every sample failed "nothing in the image is lit")
MAX_LIGHT_OFFSET = 1000.0


def _check_something_lit(values: dict, source: str) -> None:
    """Every sample has something to see and a light that reaches it (each sample
    failed "nothing in the image is lit ...; give photons_per_unit", a key no dataset
    has, otherwise)."""
    import numpy as np

    backdrop, objects, light = values["backdrop"], values["objects"], values["light"]
    if backdrop["kind"] == "none" and objects["count"][0] == 0:
        raise DatasetError(
            f"{source}: backdrop.kind = 'none' with objects.count {objects['count']}: a "
            "sample without objects has nothing to see: make the fewest objects 1 or more, "
            "or choose a backdrop")
    if light["placement"] != "offset":
        return
    x, y, z = light["offset"]
    width, height, depth = backdrop["size"]
    if float(np.linalg.norm(light["offset"])) > MAX_LIGHT_OFFSET:
        where = f"farther than {MAX_LIGHT_OFFSET:g} m from the camera"
    elif backdrop["kind"] == "room" and not (abs(x) < width / 2 and abs(y) < height / 2
                                             and -1.0 < z < depth - 1.0):
        where = f"outside the room {backdrop['size']} (the camera 1 m from its back)"
    elif backdrop["kind"] == "wall" and z >= depth:
        where = f"behind the wall {depth:g} m ahead"
    else:
        return
    raise DatasetError(f"{source}: light.offset {light['offset']} puts the light {where}: "
                       "nothing it lights is seen; bring it nearer the camera")


def _check_clearance(objects: dict, source: str) -> None:
    """Objects can be drawn clear of the camera: the farthest distance exceeds the
    smallest object's bounding radius (nearer draws are drawn again: generate.py)."""
    radius = min(bounding_radius(shape, objects["size"][0]) for shape in objects["shapes"])
    if objects["distance"][1] <= radius:
        raise DatasetError(
            f"{source}: objects.distance {objects['distance']}: every object of size "
            f"{objects['size']} would enclose or touch the camera (bounding radius "
            f"{radius:.3g} m): place them farther than their size")


def _check_spins(values: dict, preset, source: str) -> None:
    """The fastest spins turn less than MAX_HALF_TURN in half the camera's sequence
    (the keyframes' interpolation takes the short arc)."""
    from ..cameras.capture import sequence_window

    first, last = sequence_window(preset)
    for section in ("motion", "camera"):
        fastest = values[section]["angular_speed"][1]
        if fastest * 0.5 * (last - first) > MAX_HALF_TURN:
            raise DatasetError(f"{source}: {section}.angular_speed: {fastest:g} rad/s turns "
                               f"more than {MAX_HALF_TURN:.3g} rad in half of "
                               f"{preset.name}'s {last - first:g} s sequence")


def mesh_files(folder: str) -> list:
    """The mesh files of ``folder`` (sorted: a sample's draw is by position)."""
    if not os.path.isdir(folder):
        return []
    return sorted(os.path.join(os.path.abspath(folder), n) for n in os.listdir(folder)
                  if n.lower().endswith(MESH_EXTENSIONS))
