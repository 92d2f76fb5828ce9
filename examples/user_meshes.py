"""A user's own meshes, as Blender exports them (issue 42, 2026-12-03): a torus as an OBJ
of quads with vertex normals (Blender's default torus: major radius 1, minor 0.25, 48 x 12
segments, its axis along y as Blender's Y-up export writes it) and a lumpy blob as a binary
little-endian PLY of triangles with vertex normals (an icosphere of 3 subdivisions whose
radius varies smoothly). examples/user_meshes.xml places them: the torus spinning about
its axis and approaching, the blob moving.

    PYTHONPATH=src .venv/bin/python examples/user_meshes.py [--folder examples/meshes]
    dopplertof capture examples/user_meshes.xml -o out/meshes

writes torus.obj and blob.ply (the committed files are this script's output; the bytes are
the same on every run).
"""

from __future__ import annotations

import argparse
import os

import numpy as np


def torus(major=1.0, minor=0.25, segments=48, rings=12):
    """(vertices (N, 3), normals (N, 3), quads (M, 4) 0-based) of a torus about y."""
    u = 2 * np.pi * np.arange(segments) / segments  # about the axis
    v = 2 * np.pi * np.arange(rings) / rings  # about the tube
    uu, vv = (a.ravel() for a in np.meshgrid(u, v, indexing="ij"))
    normals = np.stack([np.cos(vv) * np.cos(uu), np.sin(vv), np.cos(vv) * np.sin(uu)], 1)
    centres = major * np.stack([np.cos(uu), np.zeros_like(uu), np.sin(uu)], 1)
    vertices = centres + minor * normals
    i, j = (a.ravel() for a in np.meshgrid(np.arange(segments), np.arange(rings),
                                           indexing="ij"))
    index = lambda a, b: (a % segments) * rings + b % rings  # noqa: E731
    # counter-clockwise seen from outside: the normals point out
    quads = np.stack([index(i, j), index(i, j + 1), index(i + 1, j + 1), index(i + 1, j)], 1)
    return vertices, normals, quads


def icosphere(subdivisions=3):
    """(vertices (N, 3) on the unit sphere, triangles (M, 3))."""
    t = (1 + 5 ** 0.5) / 2
    vertices = [(-1, t, 0), (1, t, 0), (-1, -t, 0), (1, -t, 0), (0, -1, t), (0, 1, t),
                (0, -1, -t), (0, 1, -t), (t, 0, -1), (t, 0, 1), (-t, 0, -1), (-t, 0, 1)]
    faces = [(0, 11, 5), (0, 5, 1), (0, 1, 7), (0, 7, 10), (0, 10, 11), (1, 5, 9),
             (5, 11, 4), (11, 10, 2), (10, 7, 6), (7, 1, 8), (3, 9, 4), (3, 4, 2),
             (3, 2, 6), (3, 6, 8), (3, 8, 9), (4, 9, 5), (2, 4, 11), (6, 2, 10),
             (8, 6, 7), (9, 8, 1)]
    vertices = [np.array(p, float) / np.linalg.norm(p) for p in vertices]
    for _ in range(subdivisions):
        middle, refined = {}, []
        for a, b, c in faces:
            ab, bc, ca = (_midpoint(vertices, middle, x, y) for x, y in ((a, b), (b, c), (c, a)))
            refined += [(a, ab, ca), (b, bc, ab), (c, ca, bc), (ab, bc, ca)]
        faces = refined
    return np.array(vertices), np.array(faces)


def _midpoint(vertices, middle, a, b):
    key = (min(a, b), max(a, b))
    if key not in middle:
        p = vertices[a] + vertices[b]
        vertices.append(p / np.linalg.norm(p))
        middle[key] = len(vertices) - 1
    return middle[key]


def blob(radius=0.4, subdivisions=3):
    """(vertices, vertex normals, triangles) of a lumpy sphere: radius
    ``radius`` (1 + 0.15 sin 2x sin 3y + 0.1 cos 4z) along each unit direction."""
    directions, triangles = icosphere(subdivisions)
    x, y, z = directions.T
    vertices = directions * (radius * (1 + 0.15 * np.sin(2 * x) * np.sin(3 * y)
                                       + 0.1 * np.cos(4 * z)))[:, None]
    normals = np.zeros_like(vertices)
    a, b, c = (vertices[triangles[:, k]] for k in range(3))
    face_normals = np.cross(b - a, c - a)
    for k in range(3):
        np.add.at(normals, triangles[:, k], face_normals)
    return vertices, normals / np.linalg.norm(normals, axis=1, keepdims=True), triangles


def obj_text(vertices, normals, faces) -> str:
    """An OBJ of faces (any number of vertices each) with vertex normals, as Blender writes."""
    lines = ["# torus: Blender's default (48 x 12 quads), written by examples/user_meshes.py"]
    lines += [f"v {x:.6f} {y:.6f} {z:.6f}" for x, y, z in vertices]
    lines += [f"vn {x:.4f} {y:.4f} {z:.4f}" for x, y, z in normals]
    lines += ["f " + " ".join(f"{k + 1}//{k + 1}" for k in face) for face in faces]
    return "\n".join(lines) + "\n"


def ply_bytes(vertices, normals, triangles) -> bytes:
    """A binary little-endian PLY (float x y z nx ny nz; uchar/uint vertex_indices)."""
    header = ("ply\nformat binary_little_endian 1.0\ncomment blob, written by "
              "examples/user_meshes.py\n"
              f"element vertex {len(vertices)}\n"
              + "".join(f"property float {n}\n" for n in ("x", "y", "z", "nx", "ny", "nz"))
              + f"element face {len(triangles)}\n"
              "property list uchar uint vertex_indices\nend_header\n")
    rows = np.concatenate([vertices, normals], axis=1).astype("<f4").tobytes()
    faces = np.zeros(len(triangles), dtype=[("n", "u1"), ("i", "<u4", (3,))])
    faces["n"], faces["i"] = 3, triangles
    return header.encode("ascii") + rows + faces.tobytes()


def write_meshes(folder: str) -> list:
    """torus.obj and blob.ply in ``folder``: their paths."""
    os.makedirs(folder, exist_ok=True)
    paths = [os.path.join(folder, "torus.obj"), os.path.join(folder, "blob.ply")]
    with open(paths[0], "w", newline="\n") as f:
        f.write(obj_text(*torus()))
    with open(paths[1], "wb") as f:
        f.write(ply_bytes(*blob()))
    return paths


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--folder", default=os.path.join(os.path.dirname(__file__), "meshes"))
    for path in write_meshes(parser.parse_args(argv).folder):
        print(path)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
