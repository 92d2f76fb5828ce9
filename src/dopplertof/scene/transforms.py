"""Mitsuba XML ``<transform>`` elements as 4x4 float64 matrices.

Each child operation is applied after the previous ones (M = op_n ... op_1), as in
Mitsuba's own loader: matrix, translate, rotate, scale, lookat.
"""

from __future__ import annotations

import re

import numpy as np


class TransformError(ValueError):
    pass


def _numbers(text: str, where: str, count: tuple[int, ...]) -> list[float]:
    try:
        vals = [float(x) for x in re.split(r"[,\s]+", text.strip()) if x]
    except ValueError:
        raise TransformError(f"{where}: expected numbers, got {text!r}") from None
    if len(vals) not in count:
        raise TransformError(f"{where}: expected {' or '.join(map(str, count))} numbers, "
                             f"got {len(vals)} in {text!r}")
    if not all(np.isfinite(vals)):
        raise TransformError(f"{where}: non-finite value in {text!r}")
    return vals


def _xyz(attrs: dict, default: float, where: str) -> list[float]:
    if "value" in attrs:
        vals = _numbers(attrs["value"], where, (1, 3))
        return vals * 3 if len(vals) == 1 else vals
    out = []
    for axis in "xyz":
        out.append(_numbers(attrs[axis], where, (1,))[0] if axis in attrs else default)
    return out


def _rotation(axis, angle_deg) -> np.ndarray:
    axis = np.asarray(axis, float)
    n = np.linalg.norm(axis)
    if n == 0:
        raise TransformError("rotate: the axis is zero")
    x, y, z = axis / n
    a = np.radians(angle_deg)
    c, s = np.cos(a), np.sin(a)
    C = 1 - c
    M = np.eye(4)
    M[:3, :3] = [
        [c + x * x * C, x * y * C - z * s, x * z * C + y * s],
        [y * x * C + z * s, c + y * y * C, y * z * C - x * s],
        [z * x * C - y * s, z * y * C + x * s, c + z * z * C],
    ]
    return M


def _look_at(origin, target, up) -> np.ndarray:
    origin, target, up = (np.asarray(v, float) for v in (origin, target, up))
    d = target - origin
    if np.linalg.norm(d) == 0:
        raise TransformError("lookat: origin and target coincide")
    d /= np.linalg.norm(d)
    left = np.cross(up, d)
    if np.linalg.norm(left) == 0:
        raise TransformError("lookat: 'up' is parallel to the viewing direction")
    left /= np.linalg.norm(left)
    new_up = np.cross(d, left)
    M = np.eye(4)
    M[:3, 0], M[:3, 1], M[:3, 2], M[:3, 3] = left, new_up, d, origin
    return M


def operation_matrix(tag: str, attrs: dict, where: str) -> np.ndarray:
    """The matrix of one transform operation element."""
    if tag == "matrix":
        if "value" not in attrs:
            raise TransformError(f"{where}: <matrix> needs a 'value'")
        vals = _numbers(attrs["value"], where, (9, 16))
        if len(vals) == 9:
            M = np.eye(4)
            M[:3, :3] = np.array(vals).reshape(3, 3)
            return M
        return np.array(vals).reshape(4, 4)
    if tag == "translate":
        M = np.eye(4)
        M[:3, 3] = _xyz(attrs, 0.0, where)
        return M
    if tag == "scale":
        return np.diag(_xyz(attrs, 1.0, where) + [1.0])
    if tag == "rotate":
        if "angle" not in attrs:
            raise TransformError(f"{where}: <rotate> needs an 'angle' (degrees)")
        angle = _numbers(attrs["angle"], where, (1,))[0]
        try:
            return _rotation(_xyz(attrs, 0.0, where), angle)
        except TransformError as e:
            raise TransformError(f"{where}: {e}") from None
    if tag == "lookat":
        for key in ("origin", "target"):
            if key not in attrs:
                raise TransformError(f"{where}: <lookat> needs '{key}'")
        up = _numbers(attrs.get("up", "0 1 0"), where, (3,))
        try:
            return _look_at(_numbers(attrs["origin"], where, (3,)),
                            _numbers(attrs["target"], where, (3,)), up)
        except TransformError as e:
            raise TransformError(f"{where}: {e}") from None
    raise TransformError(f"{where}: unknown transform operation <{tag}>")


def compose(operations) -> np.ndarray:
    """Compose ``[(tag, attrs, where), ...]`` in document order."""
    M = np.eye(4)
    for tag, attrs, where in operations:
        M = operation_matrix(tag, attrs, where) @ M
    return M
