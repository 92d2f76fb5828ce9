"""Keyframed rigid motion of a body (design.md section 3).

A body's shapes are loaded once, in a scene of their own, at the pose of the first
keyframe (the *reference pose*). At time t the body is that geometry moved by the
relative transform  Rel(t) = M(t) M_ref^-1,  where M(t) interpolates the keyframes.

Interpolation modes:

* ``rigid`` (default): each keyframe matrix is split into translation T, rotation R
  and stretch S (polar decomposition, M = T R S); T and S are lerped and R slerped.
* ``matrix``: plain element-wise lerp of the 4x4 matrices (published behaviour).

The same code evaluates the motion on NumPy arrays (ground truth, bounding boxes) and
on Dr.Jit arrays (per-lane in the renderer): transforms are a 3x3 nested list
``A`` (``None`` for the identity) and a translation list ``b``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

INTERPOLATIONS = ("rigid", "matrix")


class MotionError(ValueError):
    """An animation that cannot be interpolated."""


@dataclass(frozen=True)
class Keyframes:
    """Times (seconds, strictly increasing) and 4x4 world matrices of one animation."""

    times: tuple
    matrices: tuple  # of 4x4 nested tuples (hashable: shapes with equal keyframes share a body)
    interpolation: str = "rigid"

    @staticmethod
    def create(times, matrices, interpolation="rigid", where="animation"):
        times = [float(t) for t in times]
        mats = [np.asarray(m, dtype=np.float64).reshape(4, 4) for m in matrices]
        if interpolation not in INTERPOLATIONS:
            raise MotionError(
                f"{where}: unknown interpolation {interpolation!r}: expected one of "
                f"{', '.join(INTERPOLATIONS)}"
            )
        if len(times) < 2:
            raise MotionError(f"{where}: an animation needs at least 2 keyframes, got {len(times)}")
        if not all(np.isfinite(times)):
            raise MotionError(f"{where}: keyframe times must be finite, got {times}")
        for a, b in zip(times, times[1:]):
            if not b > a:
                kind = "duplicate" if a == b else "unsorted"
                raise MotionError(
                    f"{where}: {kind} keyframe times {a} and {b}: times must be strictly increasing"
                )
        for t, m in zip(times, mats):
            if not np.all(np.isfinite(m)):
                raise MotionError(f"{where}: keyframe at time {t} has a non-finite matrix")
            if not np.allclose(m[3], [0, 0, 0, 1]):
                raise MotionError(f"{where}: keyframe at time {t} is not an affine transform")
            det = np.linalg.det(m[:3, :3])
            scale = max(np.abs(m[:3, :3]).max(), 1e-300)
            if abs(det) <= 1e-12 * scale**3:
                raise MotionError(f"{where}: keyframe at time {t} has a non-invertible matrix")
        return Keyframes(
            tuple(times), tuple(tuple(map(tuple, m)) for m in mats), interpolation
        )

    def matrix_array(self) -> np.ndarray:
        return np.array(self.matrices, dtype=np.float64)


# ---- Small generic linear algebra (NumPy or Dr.Jit entries) -----------------

def _is_numpy(x) -> bool:
    return isinstance(x, (np.ndarray, float, int, bool, np.floating, np.bool_))


def _where(mask, a, b):
    if _is_numpy(mask):
        return np.where(mask, a, b)
    import drjit as dr

    return dr.select(mask, a, b)


def _matmul3(A, B):
    return [[sum(A[i][k] * B[k][j] for k in range(3)) for j in range(3)] for i in range(3)]


def _matvec3(A, v):
    if A is None:
        return list(v)
    return [A[i][0] * v[0] + A[i][1] * v[1] + A[i][2] * v[2] for i in range(3)]


def _transpose3(A):
    return [[A[j][i] for j in range(3)] for i in range(3)]


def _cofactors0(A):
    return (A[1][1] * A[2][2] - A[1][2] * A[2][1], A[1][2] * A[2][0] - A[1][0] * A[2][2],
            A[1][0] * A[2][1] - A[1][1] * A[2][0])


def determinant3(A):
    """Determinant of a linear part (``None``: the identity), per lane for JIT arrays."""
    if A is None:
        return 1.0
    c00, c01, c02 = _cofactors0(A)
    return A[0][0] * c00 + A[0][1] * c01 + A[0][2] * c02


def _inverse3(A):
    """Inverse by the adjugate (per lane for JIT arrays)."""
    c00, c01, c02 = _cofactors0(A)
    inv_det = 1.0 / (A[0][0] * c00 + A[0][1] * c01 + A[0][2] * c02)
    return [
        [c00 * inv_det, (A[0][2] * A[2][1] - A[0][1] * A[2][2]) * inv_det,
         (A[0][1] * A[1][2] - A[0][2] * A[1][1]) * inv_det],
        [c01 * inv_det, (A[0][0] * A[2][2] - A[0][2] * A[2][0]) * inv_det,
         (A[0][2] * A[1][0] - A[0][0] * A[1][2]) * inv_det],
        [c02 * inv_det, (A[0][1] * A[2][0] - A[0][0] * A[2][1]) * inv_det,
         (A[0][0] * A[1][1] - A[0][1] * A[1][0]) * inv_det],
    ]


def quaternion_matrix(w, x, y, z):
    return [
        [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
    ]


def rotation_quaternion(R: np.ndarray) -> np.ndarray:
    """The unit quaternion (w, x, y, z) of a proper rotation matrix ``R``: from the
    largest of 1 + trace and the diagonal's 1 + 2 R_ii - trace (Shepperd's choice, so
    that no component comes from a difference of nearly equal numbers). Its sign is
    arbitrary (the caller takes the shortest arcs). Written out: SciPy's Rotation
    costs its package's import, 0.5 s of every scene load."""
    R = np.asarray(R, dtype=np.float64)
    trace = R[0, 0] + R[1, 1] + R[2, 2]
    choice = int(np.argmax([R[0, 0], R[1, 1], R[2, 2], trace]))
    q = np.empty(4)  # (x, y, z, w)
    if choice == 3:
        q[:] = (R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1], 1.0 + trace)
    else:
        i, j, k = choice, (choice + 1) % 3, (choice + 2) % 3
        q[i] = 1.0 - trace + 2.0 * R[i, i]
        q[j] = R[j, i] + R[i, j]
        q[k] = R[k, i] + R[i, k]
        q[3] = R[k, j] - R[j, k]
    q /= np.linalg.norm(q)
    return np.array([q[3], q[0], q[1], q[2]])


def _polar(A: np.ndarray):
    """A = R S with R a proper rotation and S symmetric (negative when det A < 0)."""
    U, sig, Vt = np.linalg.svd(A)
    R = U @ Vt
    S = Vt.T @ np.diag(sig) @ Vt
    if np.linalg.det(R) < 0:
        R, S = -R, -S
    return R, S


class Motion:
    """The interpolated motion of one body, relative to its reference pose."""

    def __init__(self, keyframes: Keyframes):
        self.keyframes = keyframes
        self.times = np.array(keyframes.times)
        mats = keyframes.matrix_array()
        self.matrices = mats
        self.linear = mats[:, :3, :3]
        self.translation = mats[:, :3, 3]
        self.ref_inverse = np.linalg.inv(mats[0])
        # Translation only when every keyframe has the same linear part: the
        # relative transform is then a pure translation, exactly.
        self.translation_only = bool(np.all(self.linear == self.linear[0]))
        if keyframes.interpolation == "rigid":
            polar = [_polar(a) for a in self.linear]
            quats = [rotation_quaternion(r) for r, _ in polar]
            for i in range(1, len(quats)):  # shortest arcs
                if np.dot(quats[i - 1], quats[i]) < 0:
                    quats[i] = -quats[i]
            self.quats = np.array(quats)
            self.stretch = np.array([s for _, s in polar])
        self._numbers = self._plain_numbers()
        self._opaque = {}  # Dr.Jit array type -> self._numbers as opaque scalars of that type

    # ---- The numbers the interpolation reads ----

    def _plain_numbers(self) -> dict:
        """The keyframes' numbers the interpolation reads, as Python floats: per segment
        its start time and 1 / its duration, per keyframe its translation, linear part,
        quaternion and stretch, per segment its slerp angle and 1 / its sine (None for
        a segment that slerps linearly), and the reference pose's inverse."""
        times = [float(t) for t in self.times]
        numbers = {"times": times,
                   "rate": [1.0 / (t1 - t0) for t0, t1 in zip(times, times[1:])],
                   "translation": self.translation.tolist(), "linear": self.linear.tolist(),
                   "ref_translation": self.translation[0].tolist(),
                   "ref_inverse": [row[:4] for row in self.ref_inverse.tolist()[:3]]}
        if self.keyframes.interpolation == "rigid":
            numbers["quats"], numbers["stretch"] = self.quats.tolist(), self.stretch.tolist()
            numbers["angle"], numbers["inv_sin"] = [], []
            for q0, q1 in zip(self.quats.tolist(), self.quats.tolist()[1:]):
                omega = float(np.arccos(float(np.clip(np.dot(q0, q1), -1.0, 1.0))))
                slerp = omega >= 1e-6  # (below it, the weights are the lerp's)
                numbers["angle"].append(omega if slerp else None)
                numbers["inv_sin"].append(1.0 / float(np.sin(omega)) if slerp else None)
        return numbers

    def numbers(self, t) -> dict:
        """:meth:`_plain_numbers` as the evaluation at times ``t`` reads them: Python
        floats for NumPy times, and for Dr.Jit times opaque scalars of their type (made
        once per motion), so that a kernel does not depend on the keyframes' values
        (one compiled kernel for every window and motion of a scene's shape)."""
        if _is_numpy(t):
            return self._numbers
        kind = type(t)
        if kind not in self._opaque:
            self._opaque[kind] = opaque_tree(kind, self._numbers)
        return self._opaque[kind]

    # ---- Interpolation ----

    def _segment(self, j: int, t):
        """World matrix (A, b) on segment j at times t (alpha clamped to [0, 1])."""
        n = self.numbers(t)
        alpha = (t - n["times"][j]) * n["rate"][j]
        alpha = np.clip(alpha, 0.0, 1.0) if _is_numpy(alpha) else _clip_jit(alpha)
        beta = 1.0 - alpha
        T0, T1 = n["translation"][j], n["translation"][j + 1]
        b = [beta * T0[i] + alpha * T1[i] for i in range(3)]
        if self.translation_only:
            return None, b
        if self.keyframes.interpolation == "matrix":
            A0, A1 = n["linear"][j], n["linear"][j + 1]
            A = [[beta * A0[r][c] + alpha * A1[r][c] for c in range(3)] for r in range(3)]
            return A, b
        q0, q1 = n["quats"][j], n["quats"][j + 1]
        omega = n["angle"][j]
        if omega is None:
            w0, w1 = beta, alpha
        else:
            sin = np.sin if _is_numpy(alpha) else _jit_sin
            w0 = sin(beta * omega) * n["inv_sin"][j]
            w1 = sin(alpha * omega) * n["inv_sin"][j]
        q = [w0 * q0[i] + w1 * q1[i] for i in range(4)]
        norm = (q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]) ** 0.5
        q = [c / norm for c in q]
        R = quaternion_matrix(*q)
        S0, S1 = n["stretch"][j], n["stretch"][j + 1]
        S = [[beta * S0[r][c] + alpha * S1[r][c] for c in range(3)] for r in range(3)]
        return _matmul3(R, S), b

    def world(self, t):
        """Interpolated world matrix at times t: (A or None for unchanged linear part, b)."""
        times = self.numbers(t)["times"]
        A, b = self._segment(0, t)
        for j in range(1, len(self.times) - 1):
            Aj, bj = self._segment(j, t)
            mask = t >= times[j]
            b = [_where(mask, bj[i], b[i]) for i in range(3)]
            if A is not None:
                A = [[_where(mask, Aj[r][c], A[r][c]) for c in range(3)] for r in range(3)]
        return A, b

    def relative(self, t):
        """Rel(t) = M(t) M_ref^-1 as (A or None for identity, b), and its inverse."""
        n = self.numbers(t)
        A, b = self.world(t)
        if A is None:  # pure translation
            ref_b = n["ref_translation"]
            rb = [b[i] - ref_b[i] for i in range(3)]
            return (None, rb), (None, [-x for x in rb])
        ref_inv = n["ref_inverse"]
        RA = _matmul3(A, [row[:3] for row in ref_inv])
        Rb = [b[i] + sum(A[i][k] * ref_inv[k][3] for k in range(3)) for i in range(3)]
        IA = _inverse3(RA)
        Ib = [-x for x in _matvec3(IA, Rb)]
        return (RA, Rb), (IA, Ib)

    def world_matrix(self, t: float) -> np.ndarray:
        """4x4 world matrix at a scalar time (NumPy, float64)."""
        A, b = self.world(np.float64(t))
        M = np.eye(4)
        M[:3, :3] = self.linear[0] if A is None else np.array(A, dtype=np.float64)
        M[:3, 3] = np.array(b, dtype=np.float64)
        return M

    def relative_matrix(self, t: float) -> np.ndarray:
        return self.world_matrix(t) @ self.ref_inverse

    def moved_points(self, points, times) -> np.ndarray:
        """(len(times) x len(points), 3): the points (N x 4, homogeneous, of the
        reference pose) moved to each of ``times``."""
        return np.concatenate([(self.relative_matrix(t) @ points.T).T[:, :3] for t in times])

    def swept_bbox(self, bbox_min, bbox_max, t_start: float, t_end: float, samples: int = 257):
        """World bounding box of the reference-pose box over [t_start, t_end].

        Corners are moved at densely sampled times and every keyframe inside the
        interval; 1% of the diagonal is added to cover rotation between samples.
        """
        lo, hi = np.asarray(bbox_min, float), np.asarray(bbox_max, float)
        corners = np.array([[x, y, z, 1.0] for x in (lo[0], hi[0]) for y in (lo[1], hi[1])
                            for z in (lo[2], hi[2])])
        times = list(np.linspace(t_start, t_end, samples))
        times += [t for t in self.times if t_start <= t <= t_end]
        pts = self.moved_points(corners, np.array(times))
        pmin, pmax = pts.min(axis=0), pts.max(axis=0)
        pad = 0.01 * np.linalg.norm(pmax - pmin) + 1e-6
        return pmin - pad, pmax + pad


def opaque_tree(kind, tree):
    """``tree`` (nested lists and dicts of floats, and None) with each float an opaque
    Dr.Jit scalar of type ``kind``: a kernel reads it as a parameter, not a literal of
    its code (values that vary per capture compile no new kernel)."""
    import drjit as dr

    if isinstance(tree, dict):
        return {key: opaque_tree(kind, value) for key, value in tree.items()}
    if isinstance(tree, (list, tuple)):
        return [opaque_tree(kind, value) for value in tree]
    return None if tree is None else dr.opaque(kind, tree)


def lane_times(mi, time, width: int):
    """``width`` lanes of Dr.Jit Float at the one time ``time`` (s; a float, or an opaque
    scalar), which the kernel reads as a parameter, not a literal."""
    import drjit as dr

    if not isinstance(time, mi.Float):
        time = dr.opaque(mi.Float, time)
    return dr.zeros(mi.Float, width) + time


def _clip_jit(x):
    import drjit as dr

    return dr.clip(x, 0.0, 1.0)


def _jit_sin(x):
    import drjit as dr

    return dr.sin(x)


# ---- Applying a transform (A or None, b) -------------------------------------

def transform_point(T, p):
    A, b = T
    q = _matvec3(A, p)
    return [q[i] + b[i] for i in range(3)]


def transform_vector(T, v):
    return _matvec3(T[0], v)


def transform_normal(T_inverse, n):
    """Normals move with the inverse transpose of the linear part."""
    A = T_inverse[0]
    return list(n) if A is None else _matvec3(_transpose3(A), n)


# ---- Per-lane transforms (Dr.Jit: each lane its own body, time and transform) ----

def vec3(mi, cls, v):
    """A Dr.Jit 3-vector of type ``cls`` from the list ``v``."""
    return cls(v[0], v[1], v[2])


def select_transform(mi, dr, masks, transforms):
    """Per lane, the transform of the body whose mask is set (identity elsewhere)."""
    Float = mi.Float
    any_linear = any(T[0] is not None for T in transforms)
    A = ([[Float(1.0 if r == c else 0.0) for c in range(3)] for r in range(3)]
         if any_linear else None)
    b = [Float(0.0), Float(0.0), Float(0.0)]
    for mask, (TA, Tb) in zip(masks, transforms):
        b = [dr.select(mask, Tb[i], b[i]) for i in range(3)]
        if any_linear:
            TA = TA if TA is not None else [[1.0 if r == c else 0.0 for c in range(3)]
                                            for r in range(3)]
            A = [[dr.select(mask, TA[r][c], A[r][c]) for c in range(3)] for r in range(3)]
    return A, b


def transformed_ray(mi, T, ray, maxt, normalize: bool = False):
    """``ray`` moved by the transform ``T`` (A or None, b). Without ``normalize`` the
    direction keeps its scale, so that ray parameters t stay the same in both frames."""
    import drjit as dr

    d = vec3(mi, mi.Vector3f, transform_vector(T, ray.d))
    return mi.Ray3f(vec3(mi, mi.Point3f, transform_point(T, ray.o)),
                    dr.normalize(d) if normalize else d, maxt, ray.time, ray.wavelengths)
