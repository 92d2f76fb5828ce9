"""Mesh files checked before Mitsuba reads them, and meshes checked after it has.

Mitsuba 3.9 reports a bad mesh file with messages that do not say what is wrong (an
empty .obj: "Could not map ... to memory!"; one cut inside its first face: a
``jit_var_fma`` size mismatch; binary junk: a message about normals) or not at all (a
.ply face pointing past the last vertex loads). :func:`mesh_file_problem` reads an .obj
or .ply file and names its problem: empty, not text, truncated, no faces, a face index
out of range, a non-finite vertex, counts that disagree with the data.
:func:`loaded_meshes_problem` checks what Mitsuba loaded (any loader, any format).
"""

from __future__ import annotations

import math
import os

import numpy as np

#: shape plugins whose ``filename`` this module reads
MESH_PLUGINS = ("obj", "ply")

#: PLY scalar types and their numpy codes
_PLY_TYPES = {"char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1", "short": "i2",
              "int16": "i2", "ushort": "u2", "uint16": "u2", "int": "i4", "int32": "i4",
              "uint": "u4", "uint32": "u4", "float": "f4", "float32": "f4",
              "double": "f8", "float64": "f8"}


def mesh_file_problem(path: str, plugin: str) -> str | None:
    """What is wrong with the mesh file ``path`` read by the shape plugin ``plugin``
    (None: nothing this check finds)."""
    with open(path, "rb") as f:
        data = f.read()
    if not data:
        return "the file is empty"
    return (_obj_problem if plugin == "obj" else _ply_problem)(data)


# ---- OBJ ----------------------------------------------------------------------------

def _obj_problem(data: bytes) -> str | None:
    """Vertices with three finite coordinates, faces of at least three vertices that
    exist, and at least one face."""
    nul = data.find(b"\0")
    if nul >= 0:
        return f"binary data (a NUL byte at offset {nul}), not an OBJ text file"
    vertices = faces = 0
    for number, line in enumerate(data.decode("latin-1").splitlines(), start=1):
        words = line.split()
        if not words or words[0] not in ("v", "f"):
            continue
        if words[0] == "v":
            problem = _obj_vertex_problem(words[1:])
            vertices += 1
        else:
            problem = _obj_face_problem(words[1:], vertices)
            faces += 1
        if problem:
            return f"line {number}: {problem}"
    if not faces:
        return (f"no faces (vertices: {vertices}): not an OBJ mesh, or cut off before its "
                "faces")
    return None


def _obj_vertex_problem(coordinates: list) -> str | None:
    try:
        values = [float(c) for c in coordinates[:3]]
    except ValueError:
        return f"vertex coordinates {' '.join(coordinates[:3])!r} are not numbers"
    if len(values) < 3:
        return f"a vertex with {len(values)} of 3 coordinates (is the file cut off?)"
    if not all(math.isfinite(v) for v in values):
        return f"non-finite vertex {' '.join(coordinates[:3])}"
    return None


def _obj_face_problem(corners: list, vertices: int) -> str | None:
    if len(corners) < 3:
        return (f"a face with only {len(corners)} of at least 3 vertices (is the file cut "
                "off?)")
    for corner in corners:
        try:
            index = int(corner.split("/")[0])
        except ValueError:
            return f"face vertex {corner!r} is not an index"
        if index == 0 or index > vertices or index < -vertices:
            return (f"a face uses vertex {index}, but {vertices} vertices come before it "
                    "(indices start at 1, negative ones count back)")
    return None


# ---- PLY ----------------------------------------------------------------------------

def _ply_problem(data: bytes) -> str | None:
    """A header Mitsuba can read, a vertex and a face element with counts the data
    holds, and at least one face. Indices and coordinates are checked on the loaded mesh
    (:func:`loaded_meshes_problem`)."""
    if not data.startswith(b"ply"):
        return "not a PLY file (it does not start with 'ply')"
    end = data.find(b"end_header")
    if end < 0:
        return "no 'end_header' line: the header is cut off or this is not a PLY file"
    body = data[data.index(b"\n", end) + 1:] if b"\n" in data[end:] else b""
    try:
        fmt, elements = _ply_header(data[:end].decode("ascii"))
    except (UnicodeDecodeError, ValueError) as e:
        return f"unreadable header: {e}"
    counts = {name: count for name, count, _ in elements}
    if not counts.get("vertex"):
        return "no vertices (the header's 'element vertex' is missing or 0)"
    if not counts.get("face"):
        return "no faces (the header's 'element face' is missing or 0)"
    if fmt == "ascii":
        return _ply_ascii_problem([line.split() for line in
                                   body.decode("latin-1").splitlines() if line.strip()],
                                  elements)
    needed = sum(count * _ply_min_row_bytes(properties) for _, count, properties in elements)
    return (f"cut off: {len(body)} bytes of data, the header's counts need at least {needed}"
            if len(body) < needed else None)


def _ply_header(text: str) -> tuple[str, list]:
    """(format, [(element name, count, [(value type, list count type or None, name)])])."""
    fmt, elements = None, []
    for line in text.splitlines()[1:]:
        words = line.split()
        if not words or words[0] in ("comment", "obj_info"):
            continue
        if words[0] == "format" and len(words) >= 2:
            fmt = words[1]
        elif words[0] == "element" and len(words) == 3:
            elements.append((words[1], int(words[2]), []))
        elif words[0] == "property" and elements and len(words) in (3, 5):
            # "property TYPE NAME" or "property list COUNT_TYPE TYPE NAME"
            count_type, value_type = (words[2], words[3]) if len(words) == 5 else \
                (None, words[1])
            if value_type not in _PLY_TYPES or (count_type and count_type not in _PLY_TYPES):
                raise ValueError(f"unknown property type in {line.strip()!r}")
            elements[-1][2].append((value_type, count_type, words[-1]))
        else:
            raise ValueError(f"unexpected line {line.strip()!r}")
    if fmt not in ("ascii", "binary_little_endian", "binary_big_endian"):
        raise ValueError(f"unknown format {fmt!r}")
    return fmt, elements


def _ply_ascii_problem(rows: list, elements) -> str | None:
    """Each element's rows are there, each with the numbers its properties take."""
    needed = sum(count for _, count, _ in elements)
    if len(rows) < needed:
        return f"cut off: {len(rows)} data lines, the header's counts need {needed}"
    start = 0
    for name, count, properties in elements:
        for offset, row in enumerate(rows[start:start + count]):
            length = _ply_row_length(row, properties)
            if length is None or len(row) < length:
                return (f"data line {start + offset + 1} ({name} {offset}): "
                        f"{' '.join(row)!r} is not a whole {name} (is the file cut off?)")
        start += count
    return None


def _ply_row_length(row: list, properties) -> int | None:
    """How many numbers an ASCII row of these properties takes (a list: its count and
    its values); None when a list's count is not a number."""
    position = 0
    for _, count_type, _ in properties:
        if count_type is None:
            position += 1
        elif position >= len(row):
            return position + 1
        else:
            try:
                position += 1 + int(row[position])
            except ValueError:
                return None
    return position


def _ply_min_row_bytes(properties) -> int:
    """The fewest bytes a binary row of these properties takes (a face list: its count
    and three indices)."""
    size = 0
    for value_type, count_type, _ in properties:
        value = np.dtype(_PLY_TYPES[value_type]).itemsize
        size += value if count_type is None else \
            np.dtype(_PLY_TYPES[count_type]).itemsize + 3 * value
    return size


# ---- Extent ------------------------------------------------------------------------

def mesh_file_bounds(path: str) -> np.ndarray:
    """(2, 3): the smallest and largest vertex coordinates of an .obj or a .ply file
    (a ValueError naming what it cannot read: a PLY whose vertices are not its first
    element of scalar properties)."""
    with open(path, "rb") as f:
        data = f.read()
    if os.fspath(path).lower().endswith(".obj"):
        points = np.array([line.split()[1:4] for line in data.decode("latin-1").splitlines()
                           if line.startswith("v ")], np.float64)
    else:
        points = _ply_vertices(data)
    if points.size == 0:
        raise ValueError("no vertices")
    return np.stack([points.min(axis=0), points.max(axis=0)])


def _ply_vertices(data: bytes) -> np.ndarray:
    """(N, 3) x, y, z of a PLY file's vertex element (its first)."""
    end = data.find(b"end_header")
    if not data.startswith(b"ply") or end < 0:
        raise ValueError("not a PLY file")
    fmt, elements = _ply_header(data[:end].decode("ascii"))
    name, count, properties = elements[0] if elements else ("", 0, [])
    if name != "vertex" or any(c is not None for _, c, _ in properties):
        raise ValueError("the vertices are not the first element of scalar properties")
    names = [n for _, _, n in properties]
    body = data[data.index(b"\n", end) + 1:]
    if fmt == "ascii":
        rows = np.array([line.split()[:len(names)] for line in
                         body.decode("latin-1").splitlines()[:count]], np.float64)
        return rows[:, [names.index(a) for a in "xyz"]]
    order = "<" if fmt == "binary_little_endian" else ">"
    dtype = np.dtype([(n, order + _PLY_TYPES[t]) for t, _, n in properties])
    table = np.frombuffer(body, dtype, count=count)
    return np.stack([table[a].astype(np.float64) for a in "xyz"], axis=-1)


# ---- Meshes as loaded -----------------------------------------------------------------

def loaded_mesh_problem(mesh) -> str | None:
    """What is wrong with a loaded mi.Mesh: no faces, a face index past the last
    vertex, a non-finite vertex position."""
    vertices, faces = mesh.vertex_count(), mesh.face_count()
    if faces == 0:
        return f"no faces (vertices: {vertices})"
    indices = np.asarray(mesh.faces_buffer(), dtype=np.int64)
    if indices.size != 3 * faces:
        return f"{indices.size} face indices for {faces} triangles"
    if indices.max(initial=0) >= vertices:
        face = int(np.argmax(indices.reshape(-1, 3).max(axis=1) >= vertices))
        return (f"face {face} uses vertex {int(indices.max())} (counting from 0), but the "
                f"mesh has {vertices} vertices")
    positions = np.asarray(mesh.vertex_positions_buffer())
    if not np.isfinite(positions).all():
        return f"vertex {int(np.argmin(np.isfinite(positions.reshape(-1, 3)).all(axis=1)))} " \
               "is not finite"
    return None


def loaded_meshes_problem(mi, scene) -> str | None:
    """The first bad mesh of the loaded mi.Scene ``scene`` and its problem, or None."""
    for shape in scene.shapes():
        if isinstance(shape, mi.Mesh):
            problem = loaded_mesh_problem(shape)
            if problem:
                return f"mesh {shape.id()!r}: {problem}"
    return None


def mesh_file_message(plugin: str, filename, resolver) -> str | None:
    """``mesh file NAME: PROBLEM`` for the ``filename`` of a shape of type ``plugin``,
    found with ``resolver`` (inputs.Resolver, as Mitsuba resolves it), or None (not a
    mesh plugin, nothing wrong, or no such file: Mitsuba says that)."""
    if plugin not in MESH_PLUGINS or not isinstance(filename, str):
        return None
    candidate = resolver.resolve(filename)
    if not os.path.isfile(candidate):
        return None
    try:
        problem = mesh_file_problem(candidate, plugin)
    except OSError as e:
        problem = f"cannot be read: {e.strerror or e}"
    return f"mesh file {filename}: {problem}" if problem else None
