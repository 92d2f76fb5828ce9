"""Camera trajectories in the TUM RGB-D format, as the camera's keyframes.

A TUM trajectory file has one pose per line, ``timestamp tx ty tz qx qy qz qw``: the
time in seconds, the position of the camera's optical centre in the world and its
orientation as a unit quaternion (scalar last), the camera's axes being the optical
frame's (x right, y down, z forward: OpenCV's). Lines starting with ``#`` and empty
lines are comments. The tools that evaluate trajectories (the TUM benchmark's scripts,
evo) read this form.

A trajectory moves a scene's camera through the scene's own camera motion: its poses
become the sensor's keyframes (:class:`.motion.Keyframes`, rigid interpolation: the
position linear, the rotation SLERPed between consecutive poses along the shorter arc),
so the renderer, the truth and the camera's illuminator see one motion.
:meth:`Trajectory.keyframes` gives the stretch of them a time window needs, on the
scene's clock.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from decimal import Decimal, InvalidOperation

import numpy as np

#: how far a quaternion's norm may be from 1 (files round their quaternions: four
#: decimals change the norm by at most 2e-4)
UNIT_TOLERANCE = 1e-3
#: the columns of a line
COLUMNS = ("timestamp", "tx", "ty", "tz", "qx", "qy", "qz", "qw")
#: the comment line written above the poses
HEADER = "# " + " ".join(COLUMNS)


class TrajectoryError(ValueError):
    """A trajectory that cannot be used; the message names the file and the line."""


@dataclass(frozen=True)
class Trajectory:
    """The poses of a TUM file: times relative to its first stamp, camera-to-world."""

    path: str
    first_stamp: Decimal  #: the first line's timestamp, exactly as written
    times: tuple  #: seconds after first_stamp, strictly increasing
    positions: tuple  #: (x, y, z) per pose
    quaternions: tuple  #: (x, y, z, w) per pose, normalized
    lines: tuple  #: the file's line number of each pose

    @property
    def duration(self) -> float:
        return self.times[-1]

    def pose(self, i: int) -> np.ndarray:
        """Pose ``i`` as a 4x4 camera-to-world matrix (OpenCV axes)."""
        return pose_matrix(self.positions[i], self.quaternions[i])

    def keyframes(self, start: float, end: float, scene_time: float):
        """The sensor's keyframes (:class:`.motion.Keyframes` of Mitsuba's to_world) over
        [start, end] (seconds after the first stamp), on a clock where the first stamp
        is ``scene_time``: the poses from the last one at or before ``start`` to the
        first at or after ``end``, so that the motion between them is the file's
        exactly. A window outside the file's times is a TrajectoryError naming them."""
        from ..tof.geometry import MITSUBA_TO_OPENCV
        from .motion import Keyframes

        slack = 1e-9 * max(1.0, abs(end))  # (a window's end rounded past the last stamp)
        if start < -slack or end > self.duration + slack:
            raise TrajectoryError(
                f"{self.path}: the camera's pose is needed from {start:.9g} s to {end:.9g} s "
                f"after the first stamp (line {self.lines[0]}), but the file ends "
                f"{self.duration:.9g} s after it (line {self.lines[-1]}): give poses over "
                "the whole stream, or fewer frames")
        times = np.asarray(self.times)
        first = max(0, int(np.searchsorted(times, start, side="right")) - 1)
        last = min(len(times) - 1, max(first + 1, int(np.searchsorted(times, end, "left"))))
        return Keyframes.create(
            [scene_time + self.times[i] for i in range(first, last + 1)],
            [self.pose(i) @ MITSUBA_TO_OPENCV for i in range(first, last + 1)],
            "rigid", f"{self.path} (lines {self.lines[first]} to {self.lines[last]})")


def pose_matrix(position, quaternion) -> np.ndarray:
    """4x4 from a position and a unit quaternion (x, y, z, w)."""
    from .motion import quaternion_matrix

    x, y, z, w = (float(v) for v in quaternion)
    M = np.eye(4)
    M[:3, :3] = np.array(quaternion_matrix(w, x, y, z), dtype=np.float64)
    M[:3, 3] = [float(v) for v in position]
    return M


def pose_row(pose: np.ndarray) -> tuple:
    """(position (x, y, z), quaternion (x, y, z, w)) of a 4x4 rigid pose, the
    quaternion's scalar non-negative."""
    from .motion import rotation_quaternion

    w, x, y, z = (float(v) for v in rotation_quaternion(np.asarray(pose, np.float64)[:3, :3]))
    sign = -1.0 if w < 0 else 1.0
    return (tuple(float(v) for v in pose[:3, 3]),
            (sign * x + 0.0, sign * y + 0.0, sign * z + 0.0, sign * w + 0.0))  # (no -0.0)


def _line_values(text: str, where: str) -> tuple:
    """(stamp as Decimal, the seven pose numbers) of one line."""
    fields = text.split()
    if len(fields) != len(COLUMNS):
        raise TrajectoryError(f"{where}: expected {len(COLUMNS)} numbers "
                              f"({' '.join(COLUMNS)}), got {len(fields)}")
    try:
        stamp = Decimal(fields[0])
        values = [float(v) for v in fields[1:]]
    except (InvalidOperation, ValueError):
        raise TrajectoryError(f"{where}: expected numbers ({' '.join(COLUMNS)}), got "
                              f"{text.strip()!r}") from None
    if not stamp.is_finite() or not all(math.isfinite(v) for v in values):
        raise TrajectoryError(f"{where}: a value is not finite: {text.strip()!r}")
    return stamp, values


def read_tum(path) -> Trajectory:
    """The TUM trajectory file ``path``, checked: at least two poses, timestamps strictly
    increasing, unit quaternions (within :data:`UNIT_TOLERANCE`, then normalized); any
    other content is one TrajectoryError naming the file and the line."""
    path = os.fspath(path)
    try:
        with open(path, encoding="utf-8") as f:
            text = f.read()
    except (OSError, UnicodeDecodeError) as e:
        raise TrajectoryError(f"{path}: cannot read the trajectory: {e}") from None
    stamps, positions, quaternions, lines = [], [], [], []
    for number, line in enumerate(text.splitlines(), start=1):
        if not line.strip() or line.lstrip().startswith("#"):
            continue
        where = f"{path}, line {number}"
        stamp, values = _line_values(line, where)
        if stamps and not stamp > stamps[-1]:
            kind = "repeats" if stamp == stamps[-1] else "is before"
            raise TrajectoryError(f"{where}: timestamp {stamp} {kind} the previous line's "
                                  f"({stamps[-1]}, line {lines[-1]}): timestamps must "
                                  "increase")
        q = np.array(values[3:], dtype=np.float64)
        norm = float(np.linalg.norm(q))
        if abs(norm - 1.0) > UNIT_TOLERANCE:
            raise TrajectoryError(f"{where}: the quaternion (qx qy qz qw) {values[3:]} has "
                                  f"norm {norm:.6g}, not 1: a rotation is a unit quaternion")
        stamps.append(stamp)
        positions.append(tuple(values[:3]))
        quaternions.append(tuple(float(v) for v in q / norm))
        lines.append(number)
    if len(stamps) < 2:
        raise TrajectoryError(f"{path}: a trajectory needs at least two poses "
                              f"(timestamp tx ty tz qx qy qz qw per line), found {len(stamps)}")
    times = tuple(float(s - stamps[0]) for s in stamps)
    return Trajectory(path, stamps[0], times, tuple(positions), tuple(quaternions),
                      tuple(lines))


def format_tum(rows) -> str:
    """The text of a TUM trajectory file: :data:`HEADER`, then one line per row
    (stamp, 4x4 camera-to-world pose); a stamp is a Decimal or a float, written with
    nine decimals (nanoseconds), the pose's numbers as their shortest round-trip
    decimals."""
    out = [HEADER]
    for stamp, pose in rows:
        position, quaternion = pose_row(np.asarray(pose, np.float64))
        stamp = Decimal(stamp) if not isinstance(stamp, Decimal) else stamp
        out.append(" ".join([f"{stamp:.9f}"] + [repr(v) for v in position + quaternion]))
    return "\n".join(out) + "\n"


def write_tum(path, rows) -> None:
    """:func:`format_tum` of ``rows`` into ``path``, atomically."""
    from .. import io

    with io.atomic_path(path) as tmp:
        with open(tmp, "w", encoding="utf-8") as f:
            f.write(format_tum(rows))
