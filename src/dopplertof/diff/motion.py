"""A differentiable rigid motion: constant linear and angular velocity about a pivot.

Keyframes say where a body is; a fit wants to say how fast it moves. This motion is
parameterized by velocities, and its poses (and keyframes, when they are wanted)
follow from them:

    x(t) = p + v tau + R(omega tau) (x_ref - p),    tau = t - t_ref

for a point x_ref of the body at its reference pose (the pose at ``t_ref``), the pivot
``p`` (world, m), the linear velocity ``v`` (m/s, of the pivot) and the angular
velocity ``omega`` (rad/s, world axis times rate); R is Rodrigues' rotation. A
two-keyframe ``rigid`` motion (scene/motion.py) is exactly such a motion with the
pivot at the first keyframe's translation: slerp turns about a fixed world axis at a
constant rate and the translation is lerped.

The velocities are Dr.Jit arrays of width 1 (AD-capable variants: gradients may be
enabled on them); the relative transforms at the lanes' times are differentiable in
them. It has the interface the renderer reads from scene/motion.Motion
(``relative``, ``relative_matrix``, ``swept_bbox``).
"""

from __future__ import annotations

import numpy as np

from ..scene.motion import Keyframes, Motion

#: below this (omega tau)^2 the rotation's coefficients come from their Taylor series
SMALL_ANGLE_SQUARED = 1e-4


def _skew(w):
    return [[0.0 * w[0], -w[2], w[1]], [w[2], 0.0 * w[0], -w[0]], [-w[1], w[0], 0.0 * w[0]]]


def rotation(omega, tau, xp):
    """R(omega tau) = I + a [omega]x + b [omega]x^2, a = sin(theta)/|omega|,
    b = (1 - cos theta)/|omega|^2, theta = |omega| tau; series below a small angle (so
    that derivatives at omega = 0 are exact, not NaN). ``xp``: numpy or drjit."""
    n2 = omega[0] * omega[0] + omega[1] * omega[1] + omega[2] * omega[2]
    t2 = tau * tau
    small = n2 * t2 < SMALL_ANGLE_SQUARED
    select = np.where if xp is np else xp.select
    n2_safe = select(small, 1.0, n2)
    norm = xp.sqrt(n2_safe)
    theta = norm * tau
    a = select(small, tau * (1.0 - n2 * t2 / 6.0), xp.sin(theta) / norm)
    b = select(small, t2 * (0.5 - n2 * t2 / 24.0), (1.0 - xp.cos(theta)) / n2_safe)
    K = _skew(omega)
    K2 = [[sum(K[i][k] * K[k][j] for k in range(3)) for j in range(3)] for i in range(3)]
    return [[(1.0 if i == j else 0.0) + a * K[i][j] + b * K2[i][j] for j in range(3)]
            for i in range(3)]


def _cross(a, b):
    return [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]


class VelocityMotion:
    """Rigid motion of constant velocity (see the module docstring).

    ``pivot``: 3 floats (world, m); ``velocity``, ``angular_velocity``: 3 floats or
    Dr.Jit arrays (width 1) each; ``t_ref``: time of the reference pose (s);
    ``reference``: the body's world matrix at t_ref (4x4); ``base``: the renderer's
    relative transform at t_ref (4x4: from the pose its geometry is loaded at, the
    first keyframe, to the reference pose; identity when they are the same).
    """

    def __init__(self, pivot, velocity, angular_velocity, t_ref: float,
                 reference=None, interval=None, base=None):
        self.pivot = [float(x) for x in pivot]
        self.velocity = list(velocity)
        self.angular_velocity = list(angular_velocity)
        self.t_ref = float(t_ref)
        self.reference = np.eye(4) if reference is None else np.asarray(reference, float)
        self.interval = interval
        self.base = np.eye(4) if base is None else np.asarray(base, float)

    @staticmethod
    def from_motion(motion: Motion, t_start: float, t_end: float, t_ref: float | None = None):
        """The constant-velocity motion through ``motion``'s poses at t_start and t_end
        (its chord over the exposure; exact for two-keyframe rigid motions between
        them), with its reference pose and pivot (the pose's translation) at ``t_ref``
        (default t_start)."""
        from scipy.spatial.transform import Rotation

        t_ref = t_start if t_ref is None else float(t_ref)
        m0, m1 = motion.world_matrix(t_start), motion.world_matrix(t_end)
        rel = m1 @ np.linalg.inv(m0)  # pose change over the interval: x1 = R x0 + c
        U, _, Vt = np.linalg.svd(rel[:3, :3])  # its rotation (stretch is no velocity)
        R, c = U @ Vt, rel[:3, 3]
        dt = t_end - t_start
        omega = Rotation.from_matrix(R).as_rotvec() / dt
        reference = motion.world_matrix(t_ref)
        p = reference[:3, 3]
        # the pivot moves linearly, p(t) = p + v (t - t_ref), and p(t_end) = R p(t_start) + c
        lhs = np.eye(3) * (t_end - t_ref) - R * (t_start - t_ref)
        v = np.linalg.solve(lhs, R @ p + c - p)
        return VelocityMotion(p, v.tolist(), omega.tolist(), t_ref, reference,
                              (t_start, t_end), motion.relative_matrix(t_ref))

    # ---- The relative transform Rel(t) = M(t) M_ref^-1 ----

    def _values(self, as_numpy: bool):
        if not as_numpy:
            return self.velocity, self.angular_velocity
        return ([float(np.asarray(x).ravel()[0]) if not isinstance(x, float) else x
                 for x in self.velocity],
                [float(np.asarray(x).ravel()[0]) if not isinstance(x, float) else x
                 for x in self.angular_velocity])

    def relative(self, t):
        """(A, b) of Rel(t) and of its inverse; Dr.Jit arrays for Dr.Jit times."""
        from ..scene.motion import _is_numpy

        as_numpy = _is_numpy(t)
        if as_numpy:
            xp = np
        else:
            import drjit as dr

            xp = dr
        v, w = self._values(as_numpy)
        tau = t - self.t_ref
        p = self.pivot
        if self._translation_only(w):  # as keyframed translations: the cheap path
            Bt = self.base[:3, 3].tolist()
            b = [Bt[i] + v[i] * tau for i in range(3)]
            return (None, b), (None, [-x for x in b])
        R = rotation(w, tau, xp)
        # D(t): x' = R (x - p) + p + v tau; Rel(t) = D(t) base
        B, Bt = self.base[:3, :3].tolist(), self.base[:3, 3].tolist()
        A = [[sum(R[i][k] * B[k][j] for k in range(3)) for j in range(3)] for i in range(3)]
        q = [Bt[k] - p[k] for k in range(3)]
        b = [R[i][0] * q[0] + R[i][1] * q[1] + R[i][2] * q[2] + p[i] + v[i] * tau
             for i in range(3)]
        # inverse: base^-1 D(t)^-1 (D's linear part is a rotation)
        Bi = np.linalg.inv(self.base)
        Bi3 = Bi[:3, :3].tolist()
        RT = [[R[j][i] for j in range(3)] for i in range(3)]
        IA = [[sum(Bi3[i][k] * RT[k][j] for k in range(3)) for j in range(3)] for i in range(3)]
        ib = [-(IA[i][0] * b[0] + IA[i][1] * b[1] + IA[i][2] * b[2]) for i in range(3)]
        return (A, b), (IA, ib)

    def attached_components(self) -> list:
        """The velocity components that carry gradients: (kind "v" or "w", axis 0-2,
        the Dr.Jit variable), in a fixed order."""
        import drjit as dr

        with dr.resume_grad():  # (whether gradients are enabled, also where suspended)
            return [(kind, axis, x) for kind, values in (("v", self.velocity),
                                                         ("w", self.angular_velocity))
                    for axis, x in enumerate(values)
                    if not isinstance(x, float) and dr.grad_enabled(x)]

    def turn_rates(self, mi, time) -> list:
        """Per attached component (:meth:`attached_components`, same order), the rate
        rho at which the body turns with it at the lanes' ``time`` (detached): d R / d
        component = [rho]x R, rho = tau J(omega tau) e_i for an angular component (J
        the left Jacobian of the rotation exp at the detached angular velocity), zero
        for a linear one."""
        import drjit as dr

        components = self.attached_components()
        tau = dr.detach(time - self.t_ref)
        zero = [0.0 * tau] * 3
        if not any(kind == "w" for kind, _, _ in components):
            return [zero for _ in components]
        phi = [dr.detach(mi.Float(w)) * tau for w in self.angular_velocity]
        t2 = phi[0] * phi[0] + phi[1] * phi[1] + phi[2] * phi[2]
        small = t2 < SMALL_ANGLE_SQUARED
        t2_safe = dr.select(small, 1.0, t2)
        theta = dr.sqrt(t2_safe)
        c1 = dr.select(small, 0.5 - t2 / 24.0, (1.0 - dr.cos(theta)) / t2_safe)
        c2 = dr.select(small, 1.0 / 6.0 - t2 / 120.0,
                       (theta - dr.sin(theta)) / (t2_safe * theta))
        out = []
        for kind, axis, _ in components:
            if kind == "v":
                out.append(zero)
                continue
            e = [1.0 if i == axis else 0.0 for i in range(3)]
            once = _cross(phi, e)
            twice = _cross(phi, once)
            out.append([tau * (e[i] + c1 * once[i] + c2 * twice[i]) for i in range(3)])
        return out

    def point_velocities(self, mi, time, x, rates=None) -> list:
        """Per attached component (same order), d x / d component of the body's
        material point at world ``x`` (3 Floats, per lane) at the lanes' ``time``,
        detached: tau e_i for a linear component, rho x (x - c) for an angular one (rho
        its :meth:`turn_rates`, given as ``rates`` or computed; c = p + v tau the
        pivot's place)."""
        import drjit as dr

        components = self.attached_components()
        tau = dr.detach(time - self.t_ref)
        rates = self.turn_rates(mi, time) if rates is None else rates
        arm = [dr.detach(x[i]) - self.pivot[i] - dr.detach(mi.Float(self.velocity[i])) * tau
               for i in range(3)]
        return [[tau if i == axis else 0.0 * tau for i in range(3)] if kind == "v"
                else _cross(rho, arm) for (kind, axis, _), rho in zip(components, rates)]

    def _translation_only(self, w) -> bool:
        """No rotation (plain zeros, not AD variables) and a base without linear part:
        Rel(t) is a translation, and the renderer's translation-only path serves."""
        return (all(isinstance(x, float) and x == 0.0 for x in w)
                and np.allclose(self.base[:3, :3], np.eye(3), rtol=0.0, atol=1e-12))

    def relative_matrix(self, t: float) -> np.ndarray:
        (A, b), _ = self.relative(np.float64(t))
        M = np.eye(4)
        M[:3, :3] = np.eye(3) if A is None else np.array(A, dtype=np.float64)
        M[:3, 3] = np.array(b, dtype=np.float64)
        return M

    def world_matrix(self, t: float) -> np.ndarray:
        """The body's world matrix at t: D(t) applied to its reference pose."""
        return self.relative_matrix(t) @ np.linalg.inv(self.base) @ self.reference

    def keyframes(self, times) -> Keyframes:
        """Keyframes of this motion at ``times`` (for scenes, ground truth, files)."""
        return Keyframes.create(times, [self.world_matrix(t) for t in times])

    def moved_points(self, points, times) -> np.ndarray:
        """As Motion.moved_points, every time at once (NumPy arrays through
        :meth:`relative`: a fit's bounding boxes were 0.1 s of Python per gradient)."""
        (A, b), _ = self.relative(np.asarray(times, np.float64))
        A = np.eye(3) if A is None else A
        n = len(times)
        out = np.empty((n, len(points), 3))
        for i in range(3):  # (row i of A and b per time, times each point)
            out[:, :, i] = np.broadcast_to(b[i], n)[:, None] + sum(
                np.broadcast_to(A[i][j], n)[:, None] * points[None, :, j] for j in range(3))
        return out.reshape(-1, 3)

    def swept_bbox(self, bbox_min, bbox_max, t_start: float, t_end: float, samples: int = 257):
        # the same sweep as keyframed motion, padded for the small steps of derivatives
        lo, hi = Motion.swept_bbox(self, bbox_min, bbox_max, t_start, t_end, samples)
        pad = 1e-3 * np.linalg.norm(hi - lo)
        return lo - pad, hi + pad

    @property
    def times(self):
        return np.array([] if self.interval is None else self.interval)
