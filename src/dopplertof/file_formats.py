"""File formats, each written atomically (:func:`dopplertof.io.atomic_path`): NPY (the
bytes ``np.save`` writes, with the system's reason on a failed write), binary PLY point
clouds, JSON (float32 values as their shortest decimal), and TOML read with one-line
errors. Images and figures: image_files.py; output folders written whole: io.py."""

from __future__ import annotations

import json
import math
import os

import numpy as np

from . import io  # io.atomic_path looked up at each write (tests inject faults there)


class _PlainStream:
    """A file that NumPy sees as a stream: it then writes through ``write`` (whose
    errors carry the system's reason) instead of C's fwrite (whose errors say only
    "problem writing element N", and which left a truncated file without an error
    under a small file size limit)."""

    def __init__(self, file):
        self.write = file.write


def write_npy(path, array: np.ndarray) -> None:
    """The bytes ``np.save`` writes, through Python's ``write``: numeric arrays in one
    call (the header, then the data), others through NumPy's chunked stream writes."""
    array = np.asarray(array)
    with io.atomic_path(path) as tmp:
        with open(tmp, "wb") as f:
            if array.dtype.hasobject:
                np.save(_PlainStream(f), array)
                return
            header = np.lib.format.header_data_from_array_1_0(array)
            np.lib.format.write_array_header_1_0(f, header)
            f.write(np.ascontiguousarray(array.T if header["fortran_order"] else array).data)


#: PLY's names of the NumPy types write_ply takes
_PLY_NAMES = {"f4": "float", "f8": "double", "u1": "uchar", "i1": "char", "i2": "short",
              "u2": "ushort", "i4": "int", "u4": "uint"}


def write_ply(path, columns: dict, comment: str = "") -> None:
    """A binary little-endian PLY point cloud: ``columns`` (name -> 1-D array, all of one
    length) as the properties of ``element vertex``, in their order and NumPy types."""
    arrays = [np.asarray(v) for v in columns.values()]
    count = len(arrays[0]) if arrays else 0
    if any(a.ndim != 1 or len(a) != count for a in arrays):
        raise ValueError("write_ply: columns must be 1-D arrays of one length")
    dtype = np.dtype([(name, "<" + a.dtype.str[1:]) for name, a in zip(columns, arrays)])
    table = np.empty(count, dtype)
    for name, a in zip(columns, arrays):
        table[name] = a
    header = ["ply", "format binary_little_endian 1.0"]
    header += [f"comment {line}" for line in comment.splitlines()]
    header += [f"element vertex {count}"]
    header += [f"property {_PLY_NAMES[a.dtype.str[1:]]} {name}"
               for name, a in zip(columns, arrays)]
    with io.atomic_path(path) as tmp:
        with open(tmp, "wb") as f:
            f.write(("\n".join(header + ["end_header"]) + "\n").encode("ascii"))
            f.write(table.tobytes())


def write_json(path, data: dict) -> None:
    """``data`` as JSON (float32 values as their shortest decimal: :func:`json_ready`)."""
    with io.atomic_path(path) as tmp:
        with open(tmp, "w", encoding="utf-8") as f:
            json.dump(json_ready(data), f, indent=2, sort_keys=True, default=json_default)
            f.write("\n")


#: significant digits of a float64 written to JSON: the most that every decimal keeps
#: through a double, so that sums' rounding (0.009999999999999998) reads 0.01
JSON_DIGITS = 15


def json_ready(value):
    """``value`` (dicts, lists, tuples, floats, NumPy scalars and arrays) for JSON, with
    every float that is a float32 value (Mitsuba's shutter times, np.float32 scalars and
    arrays) as its shortest float32 decimal: 0.0015, not 0.001500000013038516; any other
    float to :data:`JSON_DIGITS` significant digits: 0.01, not 0.009999999999999998.
    What JSON cannot hold is left to the encoder."""
    if isinstance(value, dict):
        return {key: json_ready(item) for key, item in value.items()}
    if isinstance(value, (list, tuple)):
        return [json_ready(item) for item in value]
    if isinstance(value, np.ndarray):
        return json_ready(value.tolist())
    if isinstance(value, (float, np.floating)):
        return _shortest_float(float(value))
    if isinstance(value, np.integer):
        return int(value)
    return value


def _shortest_float(x: float) -> float:
    """The float of float32's shortest decimal of ``x`` when ``x`` is exactly a float32
    value (that decimal reads back as the same float32), else ``x`` to
    :data:`JSON_DIGITS` significant digits (not finite: ``x``)."""
    if not math.isfinite(x):
        return x
    with np.errstate(over="ignore"):
        single = np.float32(x)
    if not np.isfinite(single) or float(single) != x:
        return float(f"{x:.{JSON_DIGITS}g}")
    return float(str(single))


def json_default(x):
    if isinstance(x, (np.floating, np.integer)):
        return x.item()
    if isinstance(x, np.ndarray):
        return x.tolist()
    return str(x)


def read_toml(path, error=ValueError) -> dict:
    """A TOML file's tables; an unreadable or malformed file raises ``error`` with one
    line naming it."""
    try:  # Python 3.11+
        import tomllib
    except ModuleNotFoundError:  # pragma: no cover - Python < 3.11
        import tomli as tomllib

    path = os.fspath(path)
    try:
        with open(path, "rb") as f:
            data = f.read()
        # a UTF-8 byte-order mark (Windows editors write one) is no TOML statement: read
        # past it (tomllib says "Invalid statement (at line 1, column 1)")
        return tomllib.loads(data.removeprefix(b"\xef\xbb\xbf").decode("utf-8"))
    except tomllib.TOMLDecodeError as e:
        raise error(f"{path}: malformed TOML: {e}") from None
    except UnicodeDecodeError as e:  # (the file was not named)
        raise error(f"{path}: not a UTF-8 text file, as TOML must be (byte {e.start}: "
                    f"{e.reason}): save it as UTF-8") from None
    except OSError as e:
        raise error(f"{path}: cannot read: {e}") from None
