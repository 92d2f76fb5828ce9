"""Kinds of Mitsuba objects kept alive in a process, so that scenes of other shapes (and,
for a dataset, other materials) share their Dr.Jit kernels.

Dr.Jit's calls over Mitsuba's shapes, BSDFs and emitters trace one function per kind of
every instance alive in the process, whichever scene the call is over; and its getters
(a shape's BSDF, a BSDF's flags) read tables as long as the highest registry id alive.
So the code of a kernel depends on which kinds are alive and on how many instances, not
only on the scene rendered: a scene of a new shape type, or of more shapes, compiles
kernels anew although its values all enter them as opaque parameters.

Keeping one small scene per kind alive, never rendered, makes the calls' functions the
same whatever a scene holds among those kinds; keeping sentinels (a sphere and a point
light) above a number of freed ids makes the tables' length the same for every scene of
fewer instances (Dr.Jit hands out the lowest free id, so a scene's own instances fill
the freed ids below them). Both must be made before a process's first scene, so that
they hold the same ids in every process.

:func:`keep_alive` keeps a given set (a dataset's: dataset/structure.py);
:func:`keep_common_alive` the set a user's scene meets through the command line, the
common shape types and mesh layouts (COMMON_SHAPES, COMMON_MESHES).
"""

from __future__ import annotations

#: (variant, name) -> (the scenes kept alive, the sentinels)
_ALIVE = {}

#: analytic shapes of Mitsuba's everyday kinds
COMMON_SHAPES = ("sphere", "cube", "rectangle", "disk", "cylinder")
#: (vertex normals, texture coordinates) of the meshes kept: a mesh's code depends on both
COMMON_MESHES = ((True, True), (True, False), (False, True), (False, False))
#: the diffuse BSDFs the kept shapes wear: a coloured one and a grey one (Mitsuba gives a
#: grey colour another kind of texture). Other BSDF and emitter kinds are not kept: each
#: kind alive is traced in every call over BSDFs of every kernel, whereas a shape's code
#: is traced only in the calls that intersect (docs/benchmarks.md, "A new scene through
#: a preset")
COMMON_BSDFS = ('<bsdf type="diffuse"><rgb name="reflectance" value="0.3, 0.5, 0.7"/></bsdf>',
                '<bsdf type="diffuse"><rgb name="reflectance" value="0.5"/></bsdf>')
#: free registry ids kept below the sentinels: scenes of up to this many shapes, BSDFs
#: and emitters share the tables' length
COMMON_RESERVED = 256


def keep_alive(name: str, make_scenes, reserved: int) -> list:
    """Keep alive, under ``name`` for the current variant, the Mitsuba scenes that
    ``make_scenes(mi)`` makes and a sentinel sphere and point light above ``reserved``
    freed registry ids; made once, returns the scenes."""
    import mitsuba as mi

    key = (mi.variant(), name)
    if key not in _ALIVE:
        scenes = make_scenes(mi)  # (first: the freed ids below the sentinels stay free)
        _ALIVE[key] = scenes, _sentinels(mi, reserved)
    return _ALIVE[key][0]


def release(prefix: str = "") -> int:
    """Let go of every kept set whose name starts with ``prefix``; returns how many were
    dropped. A process that goes on to other work calls it: every call over shapes and
    BSDFs traces the kept instances too, so kept sets slow each later trace."""
    dropped = [key for key in _ALIVE if key[1].startswith(prefix)]
    for key in dropped:
        del _ALIVE[key]
    return len(dropped)


def keep_common_alive() -> list:
    """Keep :data:`COMMON`'s kinds alive (once per variant): call it before a process
    loads its first scene, so that scenes of those kinds share their kernels."""
    return keep_alive("common", common_scenes, COMMON_RESERVED)


def common_scenes(mi) -> list:
    """One small scene per common shape type and mesh layout."""
    scenes = [mi.load_string(text) for text in _common_scene_texts()]
    return scenes + [mi.load_dict({"type": "scene", "mesh": mesh}) for mesh in _meshes(mi)]


def _common_scene_texts() -> list:
    return [shape_scene(shape, COMMON_BSDFS[k % len(COMMON_BSDFS)], k)
            for k, shape in enumerate(COMMON_SHAPES)]


def shape_scene(shape: str, bsdf: str, k: int) -> str:
    """The XML of a scene of one ``shape`` (a Mitsuba shape type) wearing ``bsdf`` (its
    XML), the ``k``-th kept, out of every camera's way."""
    return (f'<scene version="3.0.0"><shape type="{shape}"><transform name="to_world">'
            f'<translate value="0 0 {-10.0 - k}"/></transform>{bsdf}</shape></scene>')


def _meshes(mi) -> list:
    """A one-triangle mesh of each layout of :data:`COMMON_MESHES`."""
    meshes = []
    for normals, texcoords in COMMON_MESHES:
        mesh = mi.Mesh(f"kind_mesh_{int(normals)}{int(texcoords)}", 3, 1,
                       has_vertex_normals=normals, has_vertex_texcoords=texcoords)
        params = mi.traverse(mesh)
        params["vertex_positions"] = [0.0, 0.0, -10.0, 1.0, 0.0, -10.0, 0.0, 1.0, -10.0]
        params["faces"] = [0, 1, 2]
        if normals:
            params["vertex_normals"] = [0.0, 0.0, 1.0] * 3
        if texcoords:
            params["vertex_texcoords"] = [0.0, 0.0, 1.0, 0.0, 0.0, 1.0]
        params.update()
        meshes.append(mesh)
    return meshes


def _sentinels(mi, count: int) -> list:
    """A sphere and a point light kept alive above ``count`` freed ids of the Shape,
    BSDF (the sphere's default one) and Emitter registries."""
    spare = [(mi.load_dict({"type": "sphere"}), mi.load_dict({"type": "point"}))
             for _ in range(count)]
    sentinels = [mi.load_dict({"type": "sphere"}), mi.load_dict({"type": "point"})]
    del spare
    return sentinels
