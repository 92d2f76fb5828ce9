"""Sweep configurations: the TOML format, its validation, and the grid of points.

    scene = "scene.xml"            # relative to this file
    name = "tiny"                  # optional label
    variant = "llvm_ad_rgb"        # optional Mitsuba variant

    [defines]                      # the scene's <default> values, like -D name=value
    res = 16

    [fixed]                        # render parameters, spp and seed of every point
    spp = 8

    [grid]                         # one task per combination, in this order
    time_sampling_method = ["uniform", "antithetic"]
    hetero_frequency = [0, 1]

    [reference]                    # optional: what errors are measured against
    spp = 1024
    seed = 1000003

Everything is checked before anything runs: unknown names, wrong types, empty grids,
values out of range, and (against the loaded scene) parameter combinations that the
renderer would refuse. Errors are one line and name the file and the key. The top level
is checked by the package's TOML schema (toml_schema.py); the tables hold scene defines
and render parameters, each checked as the parameter it names (:func:`typed_value`).
"""

from __future__ import annotations

import itertools
import os
import re
from dataclasses import dataclass, field

from .. import toml_schema
from ..arguments import check_seed
from ..file_formats import read_toml
from ..params import FULL_CORRELATION, ParameterError, RenderParams
from ..sampling import seed_words
from ..toml_schema import Key

#: grid and fixed keys besides the render parameters
SAMPLE_KEYS = ("spp", "seed")

#: parameters that change how an image is sampled but not its expected value: a
#: reference is shared by every grid point that differs only in these
SAMPLING_ONLY = frozenset({
    "time_sampling_method", "antithetic_shift", "path_correlation_depth",
    "time_correlate_number", "use_stratified_sampling_for_each_interval", "rr_depth",
    "spp", "seed",
})

#: values spelled as words in a configuration: (parameter, word) -> value
VALUE_WORDS = {("path_correlation_depth", "full"): FULL_CORRELATION}

#: default seed of a reference render: far from the seeds runs use (0, 1, 2...), so
#: that a run never shares random numbers with its reference
DEFAULT_REFERENCE_SEED = 1_000_003

#: the top level's keys (toml_schema); its tables, TABLES, are free-form: the scene's
#: defines and render parameters (typed_value)
TOP_LEVEL = {
    "scene": Key("string", "the scene file, a path relative to the configuration"),
    "name": Key("string", "the sweep's label; default: the file's name", default=None),
    "variant": Key("string", "the Mitsuba variant; default: the scene's", default=None),
}
TABLES = ("defines", "fixed", "grid", "reference")

#: longest folder name written as is; longer ones are shortened with a hash
MAX_FOLDER_NAME = 180


class ConfigError(ValueError):
    """A sweep configuration that cannot run; the message says where and why."""


@dataclass(frozen=True)
class ReferenceConfig:
    spp: int
    seed: int = DEFAULT_REFERENCE_SEED
    params: dict = field(default_factory=dict)  #: render parameters of the reference


@dataclass(frozen=True)
class SweepConfig:
    scene: str  #: absolute path of the scene file
    grid: dict  #: name -> tuple of typed values (insertion order = folder-name order)
    fixed: dict = field(default_factory=dict)  #: name -> typed value
    defines: dict = field(default_factory=dict)  #: scene <default> values (strings)
    reference: ReferenceConfig | None = None
    variant: str | None = None
    name: str = "sweep"
    source: str = "<config>"  #: where it came from, for messages

    def points(self) -> list[dict]:
        """Every grid combination as {name: value}, in a stable order."""
        names = list(self.grid)
        return [dict(zip(names, values))
                for values in itertools.product(*(self.grid[n] for n in names))]

    def to_json(self) -> dict:
        return {
            "name": self.name, "source": self.source, "scene": self.scene,
            "variant": self.variant, "defines": self.defines, "fixed": self.fixed,
            "grid": {k: list(v) for k, v in self.grid.items()},
            "grid_axes": list(self.grid),  # the order (JSON objects are written sorted)
            "reference": None if self.reference is None else {
                "spp": self.reference.spp, "seed": self.reference.seed,
                "params": self.reference.params},
        }


# ---- Values --------------------------------------------------------------------------

def typed_value(name: str, value, where: str):
    """A configuration value checked and converted to the parameter's type."""
    if isinstance(value, str) and (name, value.strip().lower()) in VALUE_WORDS:
        return VALUE_WORDS[(name, value.strip().lower())]
    if name in SAMPLE_KEYS:
        if isinstance(value, bool) or not isinstance(value, int):
            if isinstance(value, float) and value.is_integer():
                value = int(value)
            else:
                raise ConfigError(f"{where}: {name} must be an integer, got {value!r}")
        if name == "spp" and value < 1:
            raise ConfigError(f"{where}: spp must be >= 1, got {value}")
        if name == "seed":
            check_seed(value, f"{where}: seed", ConfigError)
        return value
    if isinstance(value, (list, dict)):
        raise ConfigError(f"{where}: {name} must be a single value, got {value!r}")
    try:
        params = RenderParams.from_mapping({name: value}, where=where)
    except ParameterError as e:
        raise ConfigError(_unknown_hint(str(e))) from None
    return getattr(params, name)


def _unknown_hint(message: str) -> str:
    if "unknown parameter" in message:
        return message.replace("(known: ", "(known: spp, seed, ", 1)
    return message


def format_value(name: str, value) -> str:
    """A value as it appears in a folder name: short, exact, filesystem-safe."""
    for (word_name, word), word_value in VALUE_WORDS.items():
        if name == word_name and value == word_value:
            return word
    if isinstance(value, bool):
        text = "true" if value else "false"
    elif isinstance(value, int):
        text = str(value)
    elif isinstance(value, float):
        text = repr(value)
        if text.endswith(".0"):
            text = text[:-2]
    else:
        text = str(value)
    return re.sub(r"[^A-Za-z0-9._+-]", "-", text) or "-"


def point_name(point: dict) -> str:
    """A folder name that reads as the parameters: ``name=value__name=value``."""
    if not point:
        return "default"
    name = "__".join(f"{k}={format_value(k, v)}" for k, v in point.items())
    if len(name) > MAX_FOLDER_NAME:
        import hashlib

        digest = hashlib.sha256(name.encode()).hexdigest()[:12]
        name = f"{name[:MAX_FOLDER_NAME - 14]}__{digest}"
    return name


# ---- Parsing ---------------------------------------------------------------------------

def load_config(path) -> SweepConfig:
    """Read and check a sweep TOML file (the scene is checked by :func:`check_with_scene`)."""
    path = os.fspath(path)
    if not os.path.isfile(path):
        raise ConfigError(f"sweep configuration not found: {path}")
    data = read_toml(path, ConfigError)
    return config_from_mapping(data, base_dir=os.path.dirname(os.path.abspath(path)),
                               source=path)


def config_from_mapping(data: dict, base_dir: str = ".", source: str = "<config>") -> SweepConfig:
    """Build a checked SweepConfig from the parsed TOML (or an equivalent dict)."""
    if not isinstance(data, dict):
        raise ConfigError(f"{source}: expected a table at the top level")
    top = toml_schema.section(data, TOP_LEVEL, source, ConfigError, extra=TABLES)
    if not top["scene"].strip():
        raise ConfigError(f"{source}: scene must name the scene file "
                          "(a path relative to the configuration)")
    scene_path = os.path.normpath(os.path.join(base_dir, os.path.expanduser(top["scene"])))
    if not os.path.isfile(scene_path):
        raise ConfigError(f"{source}: scene file not found: {scene_path}")
    name = top["name"]
    if name is None:
        name = os.path.splitext(os.path.basename(source))[0] or "sweep"

    defines = _table(data, "defines", source)
    for key, value in defines.items():
        if isinstance(value, (list, dict)):
            raise ConfigError(f"{source}: defines.{key} must be a single value, got {value!r}")
    defines = {k: _define_text(v) for k, v in defines.items()}

    fixed = {k: typed_value(k, v, f"{source}: fixed.{k}")
             for k, v in _table(data, "fixed", source).items()}

    grid_raw = _table(data, "grid", source)
    if not grid_raw:
        raise ConfigError(f"{source}: the grid is empty: add a [grid] table with at least "
                          "one parameter and a list of values, e.g. spp = [8, 32]")
    grid = {}
    for key, values in grid_raw.items():
        where = f"{source}: grid.{key}"
        if key in fixed:
            raise ConfigError(f"{where}: {key} is both fixed and in the grid; keep one")
        if not isinstance(values, list):
            raise ConfigError(f"{where} must be a list of values, got {values!r} "
                              "(a single value belongs under [fixed])")
        if not values:
            raise ConfigError(f"{where} is an empty list: the grid would have no points")
        typed = tuple(typed_value(key, v, where) for v in values)
        labels = [format_value(key, v) for v in typed]
        duplicates = sorted({x for x in labels if labels.count(x) > 1})
        if duplicates:
            raise ConfigError(f"{where} repeats the value {duplicates[0]}")
        grid[key] = typed

    reference = None
    if "reference" in data:
        reference = _reference(_table(data, "reference", source), fixed, grid, source)
    return SweepConfig(scene=scene_path, grid=grid, fixed=fixed, defines=defines,
                       reference=reference, variant=top["variant"], name=name, source=source)


def _table(data: dict, key: str, source: str) -> dict:
    """The free-form table ``key`` ({} when absent)."""
    return toml_schema.table(data, key, source, ConfigError, required=False)


def _define_text(value) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    return str(value)


def _reference(table: dict, fixed: dict, grid: dict, source: str) -> ReferenceConfig:
    where = f"{source}: reference"
    if "spp" not in table:
        raise ConfigError(f"{where}: give the reference's spp (a high sample count)")
    spp = typed_value("spp", table["spp"], f"{where}.spp")
    seed = typed_value("seed", table.get("seed", DEFAULT_REFERENCE_SEED), f"{where}.seed")
    # the stream keys compared, not the numbers: what would share random numbers
    run_keys = {seed_words(s) for s in grid.get("seed", (fixed.get("seed", 0),))}
    if seed_words(seed) in run_keys:
        raise ConfigError(f"{where}.seed {seed} is also a seed of the runs: a reference must "
                          "not share random numbers with the images it measures")
    params = {}
    for key, value in table.items():
        if key in SAMPLE_KEYS:
            continue
        if key not in SAMPLING_ONLY:
            raise ConfigError(f"{where}.{key}: a reference may only change how it samples "
                              f"({', '.join(sorted(SAMPLING_ONLY - set(SAMPLE_KEYS)))}); "
                              f"{key} changes the expected image")
        params[key] = typed_value(key, value, f"{where}.{key}")
    return ReferenceConfig(spp=spp, seed=seed, params=params)


# ---- Points -> render settings ------------------------------------------------------------

def split_point(config: SweepConfig, point: dict) -> tuple[dict, int | None, int]:
    """(render parameters, spp or None for the scene's, seed) of a grid point."""
    values = {**config.fixed, **point}
    spp = values.pop("spp", None)
    seed = values.pop("seed", 0)
    return values, spp, seed


def measurement_key(params: dict) -> dict:
    """The parameters that fix a point's expected image (what its reference shares)."""
    return {k: v for k, v in params.items() if k not in SAMPLING_ONLY}


@dataclass(frozen=True)
class SceneFacts:
    """What the driver learns from loading the scene once."""

    params: RenderParams
    spp: int
    #: the content hash of the scene file and every file it references (meshes,
    #: textures, included files...: inputs.scene_file_digest); run markers hold it
    sha256: str
    exposure: float  #: T (s) from the scene's parameters and shutter
    shutter_open: float  #: exposure start (s)
    shutter_interval: float  #: shutter_close - shutter_open (s)
    keyframe_span: tuple | None = None  #: (first, last) keyframe time (s); None: static


def load_scene_facts(scene_path: str, defines: dict, variant: str | None) -> SceneFacts:
    """Load the scene in this process (checking it and its defines) and read its settings."""
    import dopplertof
    from ..scene.inputs import scene_file_digest
    from ..scene.kinds import keep_common_alive

    dopplertof.set_variant(variant)
    keep_common_alive()  # (before the scene: kernels shared with the render command's)
    scene = dopplertof.load_file(scene_path, dict(defines))
    return SceneFacts(params=scene.params, spp=scene.spp,
                      sha256=scene_file_digest(scene_path, scene),
                      exposure=scene.params.exposure(scene.shutter_interval),
                      shutter_open=scene.shutter_open,
                      shutter_interval=scene.shutter_interval,
                      keyframe_span=scene.keyframe_span)


def check_render_settings(params: dict, spp: int, facts: SceneFacts, where: str) -> RenderParams:
    """Everything the renderer would refuse, raised as a ConfigError now."""
    try:
        resolved = RenderParams.from_mapping(params, where=where, base=facts.params)
    except ParameterError as e:
        raise ConfigError(str(e)) from None
    from ..sampling import check_sample_count

    try:
        check_sample_count(resolved.time_correlate_number, spp, resolved.path_group_size,
                           resolved.samples_per_pass)
    except ValueError as e:
        raise ConfigError(f"{where}: {e}") from None
    return resolved
