"""Every shape type and BSDF kind a dataset may draw, kept alive beside its samples, so
that samples of other shapes and materials share their Dr.Jit kernels.

The values of a sample (windows, motions, boxes, seeds, colours) enter the kernels as
opaque values; what else a sample's scene decided was code:

- which shape types and BSDF kinds are alive: Dr.Jit's calls over Mitsuba's shapes and
  BSDFs trace one function per kind of every instance alive. One small scene per kind,
  one shape of each of the configuration's shape types and one BSDF of each of its
  materials (and the backdrop's diffuse), is kept alive in each process, never rendered,
  so that each call holds the same functions whatever a sample draws;
- how many instances are alive: Dr.Jit's getters (a shape's BSDF, a BSDF's flags) read
  tables as long as the highest registry id alive (Shape, BSDF, Emitter), which the
  number of a sample's objects would move. A sentinel sphere and light are kept alive
  above :func:`reserved_ids` freed ids, which the samples' own instances fill (Dr.Jit
  hands out the lowest free id); made before a process's first scene, they hold the same
  ids in every worker.

What is left is the number of bodies (one traced alone, two or three visited by a call
over their scenes): one set of kernels per body count, compiled by the first sample of
that count. Filling every sample up to objects.count's most bodies with bodies that an
opaque mask keeps every ray from removed those too, but each such body's motion and box
tests are computed for every path all the same: a sample of one body rendered 1.6 times
slower (docs/benchmarks.md, "Compile once"); not kept. Meshes are left out (each file's
attributes, its normals and texture coordinates, make its own code): a configuration with
meshes still compiles per new kind of mesh.
"""

from __future__ import annotations

from .config import DatasetConfig
from .scene_text import bsdf_xml

#: (variant, shape types, BSDF kinds, reserved ids) -> the scenes kept alive (one shape
#: each) and the sentinels of the registries' bounds
_ALIVE = {}


def kinds_alive(config: DatasetConfig) -> list:
    """The scenes (one shape each) that hold every shape type and BSDF kind the
    configuration may draw, made once per variant and kept alive with the registries'
    sentinels (call it before a process loads its first sample's scene)."""
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


def release_kinds() -> int:
    """Let go of every scene and sentinel :func:`kinds_alive` keeps alive; returns how
    many sets were dropped. A process that goes on to render other scenes after a dataset
    calls it: Dr.Jit traces a call over Mitsuba's shapes and BSDFs once per instance
    alive, so the kept sets slow every later trace (a fit after six datasets' sets in one
    process traced 7x slower). The next :func:`kinds_alive` makes them again."""
    count = len(_ALIVE)
    _ALIVE.clear()
    return count


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
