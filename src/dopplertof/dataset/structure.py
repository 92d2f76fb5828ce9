"""One structure for every sample's scene of a dataset, so that its samples share their
Dr.Jit kernels (issue 40, 2026-12-03).

The values of a sample (windows, motions, boxes, seeds, colours) enter the
kernels as opaque values; what else a sample's scene decided was code: how many bodies
it holds (one traced alone, two or three visited by a call over their scenes) and which
shape types and BSDF kinds are alive (Dr.Jit's calls over Mitsuba's shapes and BSDFs
trace one function per kind of every instance alive). Three things make them the same
for every sample of a configuration:

- body slots: the kernels trace objects.count's most bodies, the sample's bodies in the
  first slots and a filler no ray visits (its slot's opaque mask off) in the others
  (``DopplerScene.slot_fillers``: each filler its own motion, so that no two slots
  compute the same values, which Dr.Jit would compute once): the renders are the bodies'
  alone;
- every kind alive: one small scene per kind, each one shape of the configuration's
  shape types and one BSDF of its materials (and the backdrop's diffuse), is kept alive
  beside the samples, never rendered, so that each call holds the same functions
  whatever a sample draws;
- the registries' bounds held: Dr.Jit's getters (a shape's BSDF, a BSDF's flags) read
  tables as long as the highest registry id alive (Shape, BSDF, Emitter), which the
  number of a sample's objects would move; a sentinel instance of each is kept alive
  above :func:`reserved_ids` freed ids, which the samples' own instances fill (Dr.Jit
  hands out the lowest free id).

Meshes are left out (each file's attributes, its normals and texture coordinates, make
its own code): a configuration with meshes still compiles per new kind of mesh.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from .config import DatasetConfig
from .generate import rotation
from .scene_text import bsdf_xml

#: (variant, shape types, BSDF kinds) -> the scenes kept alive (one shape each, the
#: first of which is the filler's) and the sentinels of the registries' bounds
_ALIVE = {}


def kinds_alive(config: DatasetConfig) -> list:
    """The scenes (one shape each) that hold every shape type and BSDF kind the
    configuration may draw, made once per variant and kept alive."""
    import mitsuba as mi

    shapes = [s for s in config["objects"]["shapes"] if s != "mesh"] or ["sphere"]
    materials = sorted(set(config["objects"]["materials"]) | {"diffuse"})
    key = (mi.variant(), tuple(shapes), tuple(materials), reserved_ids(config))
    if key not in _ALIVE:
        scenes = [mi.load_string(_kind_scene(shapes[k % len(shapes)],
                                             materials[k % len(materials)], k))
                  for k in range(max(len(shapes), len(materials)))]
        _ALIVE[key] = scenes, _sentinels(mi, reserved_ids(config))
    return _ALIVE[key][0]


def reserved_ids(config: DatasetConfig) -> int:
    """How many free registry ids (of shapes, BSDFs and emitters each) are kept below
    the sentinels: a sample's objects and backdrop (a shape and two BSDFs each), its
    light, twice (a redrawn sample's scene loads while the last one is alive), with
    room to spare."""
    return 4 * (int(config["objects"]["count"][1]) + 2) + 8


def _sentinels(mi, count: int) -> list:
    """A sphere and a point light kept alive above ``count`` freed ids of the Shape,
    BSDF (the sphere's default one) and Emitter registries."""
    spare = [(mi.load_dict({"type": "sphere"}), mi.load_dict({"type": "point"}))
             for _ in range(count)]
    sentinels = [mi.load_dict({"type": "sphere"}), mi.load_dict({"type": "point"})]
    del spare
    return sentinels


def _kind_scene(shape: str, material: str, k: int) -> str:
    """A Mitsuba scene of one ``shape`` of BSDF kind ``material``, as a sample's (its
    colour not grey: Mitsuba makes a grey one another kind of texture)."""
    bsdf = bsdf_xml({"kind": material, "colour": [0.3, 0.5, 0.7], "roughness": 0.1})
    return (f'<scene version="3.0.0"><shape type="{shape}" id="kind_{k}">'
            f'<transform name="to_world"><translate value="0 0 {-10.0 - k}"/></transform>'
            f"{bsdf}</shape></scene>")


def filler_body(config: DatasetConfig, description: dict, scene):
    """A body of the samples' motion structure (three keyframes at the sequence's start,
    middle and end; turning when the configuration's bodies may turn), in the first
    kind's scene: what fills a body slot that the sample leaves empty."""
    from ..scene.bodies import MovingBody
    from ..scene.motion import Keyframes, Motion

    times = description["times_s"]
    turns = config["motion"]["angular_speed"][1] > 0
    matrices = []
    for angle in (-1.0, 0.0, 1.0):  # (rad: a slerp, as a turning body's)
        m = np.eye(4)
        m[:3, :3] = rotation([0.0, 0.0, 1.0], angle if turns else 0.0)
        matrices.append(m)
    keyframes = Keyframes.create([times[k] for k in ("start", "mid", "end")], matrices)
    return MovingBody(scene, Motion(keyframes), ("body_slot_filler",))


def with_fixed_structure(scene, config: DatasetConfig, description: dict):
    """The sample's loaded ``scene`` with the dataset's body slots (objects.count's most),
    every kind kept alive: it compiles the kernels every other sample uses."""
    alive = kinds_alive(config)
    left = max(0, int(config["objects"]["count"][1]) - len(scene.bodies))
    return replace(scene, slot_fillers=tuple(filler_body(config, description, alive[0])
                                             for _ in range(left)))
