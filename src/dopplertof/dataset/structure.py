"""Every shape type and BSDF kind a dataset may draw, kept alive beside its samples, so
that samples of other shapes and materials share their Dr.Jit kernels.

The values of a sample (windows, motions, boxes, seeds, colours) enter the kernels as
opaque values; what else a sample's scene decides is code, and scene/kinds.py keeps it
the same: one small scene per shape type and BSDF kind the configuration may draw (and
the backdrop's diffuse), never rendered, and sentinels above :func:`reserved_ids` freed
registry ids, which a sample's own instances fill, made before a process's first scene.

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

from ..scene import kinds
from .config import DatasetConfig
from .scene_text import bsdf_xml


def kinds_alive(config: DatasetConfig) -> list:
    """The scenes (one shape each) that hold every shape type and BSDF kind the
    configuration may draw, made once per variant and kept alive with the registries'
    sentinels (call it before a process loads its first sample's scene)."""
    shapes = [s for s in config["objects"]["shapes"] if s != "mesh"] or ["sphere"]
    materials = sorted(set(config["objects"]["materials"]) | {"diffuse"})

    def make(mi):
        return [mi.load_string(kinds.shape_scene(shapes[k % len(shapes)],
                                                 _kind_bsdf(materials[k % len(materials)]), k))
                for k in range(max(len(shapes), len(materials)))]

    name = f"dataset {shapes} {materials} {reserved_ids(config)}"
    return kinds.keep_alive(name, make, reserved_ids(config))


def release_kinds() -> int:
    """Let go of every set :func:`kinds_alive` keeps alive; returns how many sets were
    dropped. A process that goes on to render other scenes after a dataset calls it:
    Dr.Jit traces a call over Mitsuba's shapes and BSDFs once per instance alive, so the
    kept sets slow every later trace (a fit after six datasets' sets in one process
    traced 7x slower). The next :func:`kinds_alive` makes them again."""
    return kinds.release("dataset ")


def reserved_ids(config: DatasetConfig) -> int:
    """How many free registry ids (of shapes, BSDFs and emitters each) are kept below
    the sentinels: a sample's objects and backdrop (a shape and two BSDFs each), its
    light, twice (a redrawn sample's scene loads while the last one is alive), with
    room to spare."""
    return 4 * (int(config["objects"]["count"][1]) + 2) + 8


def _kind_bsdf(material: str) -> str:
    """A BSDF of kind ``material`` as a sample's (its colour not grey: Mitsuba makes a
    grey one another kind of texture)."""
    return bsdf_xml({"kind": material, "colour": [0.3, 0.5, 0.7], "roughness": 0.1})
