"""Rigidly moving bodies and ray queries against the static scene plus every body.

Stock Mitsuba 3 has no per-ray motion of shapes, and every lane of a D-ToF render has
its own time. Each moving body therefore lives in an ``mi.Scene`` of its own, at its
reference pose; a ray at time t is tested against the static scene and, moved by the
inverse of the body's motion at t, against each body. The nearest hit wins, and its
surface interaction is computed once, with the ray of the scene that won, then moved
back to world space (DESIGN section 3). A body's swept bounding box over the exposure
lets rays that cannot hit it skip it.

This module is the one place that knows how motion is traced, so that upstream
instance motion can replace it when Mitsuba ships it.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .motion import Motion, transform_normal, transform_point, transform_vector


@dataclass
class MovingBody:
    """Shapes that share one animation, loaded at the reference pose (first keyframe)."""

    scene: object = field(repr=False)  #: mi.Scene holding only this body's shapes
    motion: Motion = field(repr=False)
    names: tuple  #: ids of the shapes, for messages
    _swept: dict = field(default_factory=dict, repr=False)

    def swept_bbox(self, t_start: float, t_end: float):
        """mi.ScalarBoundingBox3f of the body over [t_start, t_end] (cached)."""
        import mitsuba as mi

        key = (t_start, t_end)
        if key not in self._swept:
            bb = self.scene.bbox()
            lo, hi = self.motion.swept_bbox(np.array(bb.min), np.array(bb.max), t_start, t_end)
            self._swept[key] = mi.ScalarBoundingBox3f(mi.ScalarPoint3f(*lo), mi.ScalarPoint3f(*hi))
        return self._swept[key]


class BodyFrames:
    """Per-lane transforms of every body at the lanes' times, computed once per path.

    ``to_world[k]`` maps body k from its reference pose to its pose at the lane's time;
    ``to_local[k]`` is its inverse. Entries are ``(A or None, b)`` with Dr.Jit arrays.
    """

    def __init__(self, mi, bodies, time, t_start: float, t_end: float):
        self.mi = mi
        self.bodies = list(bodies)
        self.boxes = [b.swept_bbox(t_start, t_end) for b in self.bodies]
        self.to_world, self.to_local = [], []
        for body in self.bodies:
            rel, inv = body.motion.relative(time)
            self.to_world.append(rel)
            self.to_local.append(inv)


def _vec(mi, cls, v):
    return cls(v[0], v[1], v[2])


def _select_transform(mi, dr, masks, transforms):
    """Per lane, the transform of the body whose mask is set (identity elsewhere)."""
    Float = mi.Float
    any_linear = any(T[0] is not None for T in transforms)
    A = [[Float(1.0 if r == c else 0.0) for c in range(3)] for r in range(3)] if any_linear else None
    b = [Float(0.0), Float(0.0), Float(0.0)]
    for mask, (TA, Tb) in zip(masks, transforms):
        b = [dr.select(mask, Tb[i], b[i]) for i in range(3)]
        if any_linear:
            TA = TA if TA is not None else [[1.0 if r == c else 0.0 for c in range(3)]
                                            for r in range(3)]
            A = [[dr.select(mask, TA[r][c], A[r][c]) for c in range(3)] for r in range(3)]
    return A, b


def intersect(mi, static_scene, frames: BodyFrames | None, ray, active):
    """Nearest surface interaction (world space) of world rays at their lanes' times."""
    import drjit as dr

    if frames is None or not frames.bodies:
        return static_scene.ray_intersect(ray, mi.RayFlags.All, False, active)

    # ---- Cheap preliminary hits: static scene, then each body in its own frame ----
    pi = static_scene.ray_intersect_preliminary(ray, False, active)
    best_t = dr.select(pi.is_valid(), pi.t, dr.inf)
    hit_o, hit_d = mi.Point3f(ray.o), mi.Vector3f(ray.d)
    won = []
    for body, box, inv in zip(frames.bodies, frames.boxes, frames.to_local):
        box_hit, box_near, box_far = box.ray_intersect(ray)
        test = active & box_hit & (box_near < best_t) & (box_far >= 0)
        lo = _vec(mi, mi.Point3f, transform_point(inv, ray.o))
        ld = _vec(mi, mi.Vector3f, transform_vector(inv, ray.d))
        local_ray = mi.Ray3f(lo, ld, dr.minimum(ray.maxt, best_t), ray.time, ray.wavelengths)
        pib = body.scene.ray_intersect_preliminary(local_ray, False, test)
        closer = test & pib.is_valid() & (pib.t < best_t)
        pi = dr.select(closer, pib, pi)
        best_t = dr.select(closer, pib.t, best_t)
        hit_o = dr.select(closer, lo, hit_o)
        hit_d = dr.select(closer, ld, hit_d)
        won = [w & ~closer for w in won] + [closer]

    # ---- One full interaction, with the ray of the scene that won ----
    hit_ray = mi.Ray3f(hit_o, hit_d, ray.maxt, ray.time, ray.wavelengths)
    si = pi.compute_surface_interaction(hit_ray, mi.RayFlags.All, active)

    # ---- Back to world space (identity for static hits) ----
    to_world = _select_transform(mi, dr, won, frames.to_world)
    to_local = _select_transform(mi, dr, won, frames.to_local)
    on_body = won[0]
    for w in won[1:]:
        on_body |= w
    p = _vec(mi, mi.Point3f, transform_point(to_world, si.p))
    n = dr.normalize(_vec(mi, mi.Normal3f, transform_normal(to_local, si.n)))
    sn = dr.normalize(_vec(mi, mi.Normal3f, transform_normal(to_local, si.sh_frame.n)))
    ss = _vec(mi, mi.Vector3f, transform_vector(to_world, si.sh_frame.s))
    ss = dr.normalize(ss - sn * dr.dot(ss, sn))  # Gram-Schmidt: exact frames under shear too
    frame = mi.Frame3f(ss, dr.cross(sn, ss), sn)
    si.p = dr.select(on_body, p, si.p)
    si.n = dr.select(on_body, n, si.n)
    si.sh_frame = dr.select(on_body, frame, si.sh_frame)
    si.dp_du = dr.select(on_body, _vec(mi, mi.Vector3f, transform_vector(to_world, si.dp_du)),
                         si.dp_du)
    si.dp_dv = dr.select(on_body, _vec(mi, mi.Vector3f, transform_vector(to_world, si.dp_dv)),
                         si.dp_dv)
    # The hit parameter t is the same in both frames (affine maps keep ray parameters);
    # the incident direction is recomputed from the world ray.
    si.wi = dr.select(si.is_valid(), si.to_local(-ray.d), si.wi)
    return si


def occluded(mi, static_scene, frames: BodyFrames | None, ray, active):
    """Shadow-ray test against the static scene and every body at the lanes' times."""
    import drjit as dr

    blocked = static_scene.ray_test(ray, active)
    if frames is None:
        return blocked
    for body, box, inv in zip(frames.bodies, frames.boxes, frames.to_local):
        box_hit, box_near, box_far = box.ray_intersect(ray)
        test = active & ~blocked & box_hit & (box_near <= ray.maxt) & (box_far >= 0)
        lo = _vec(mi, mi.Point3f, transform_point(inv, ray.o))
        ld = _vec(mi, mi.Vector3f, transform_vector(inv, ray.d))
        local_ray = mi.Ray3f(lo, ld, ray.maxt, ray.time, ray.wavelengths)
        blocked |= body.scene.ray_test(local_ray, test)
    return blocked
