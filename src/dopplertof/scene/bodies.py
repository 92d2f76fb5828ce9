"""Rigidly moving bodies and ray queries against the static scene plus every body.

Stock Mitsuba 3 has no per-ray motion of shapes, and every lane of a D-ToF render has
its own time. Each moving body therefore lives in an ``mi.Scene`` of its own, at its
reference pose; a ray at time t is tested against the static scene and, moved by the
inverse of the body's motion at t, against each body. The nearest hit wins, and its
surface interaction is computed once, with the ray of the scene that won, then moved
back to world space (docs/design.md section 3). A ray tests each body's own bounding
box in the body's frame at the lane's time, so that rays that cannot hit it skip it.

This module is the one place that knows how motion is traced, so that upstream
instance motion can replace it when Mitsuba ships it; the per-lane transforms it, the
lights and the camera apply are in :mod:`.motion`. Every query of a Mitsuba scene (the
static one or a body's) goes through :class:`SceneQueries` (``QUERIES``), so that tracing
one scene per kernel (the OptiX fallback, docs/design.md section 3) is a swap of that
one object.
"""

from __future__ import annotations

import contextlib
from dataclasses import dataclass, field

import numpy as np

from .motion import (Motion, opaque_tree, select_transform, transform_normal, transform_point,
                     transform_vector, transformed_ray, vec3)


@dataclass
class MovingBody:
    """Shapes that share one animation, loaded at the reference pose (first keyframe)."""

    scene: object = field(repr=False)  #: mi.Scene holding only this body's shapes
    motion: Motion = field(repr=False)
    names: tuple  #: ids of the shapes, for messages
    _swept: dict = field(default_factory=dict, repr=False)

    def local_bbox(self):
        """mi.ScalarBoundingBox3f of the body at its reference pose, padded a little
        against rounding in the ray transform."""
        import mitsuba as mi

        bb = self.scene.bbox()
        lo, hi = np.array(bb.min, dtype=np.float64), np.array(bb.max, dtype=np.float64)
        pad = 1e-4 * np.linalg.norm(hi - lo) + 1e-6
        return mi.ScalarBoundingBox3f(mi.ScalarPoint3f(*(lo - pad)), mi.ScalarPoint3f(*(hi + pad)))

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
        self.boxes = [opaque_box(mi, b.swept_bbox(t_start, t_end)) for b in self.bodies]
        self.local_boxes = [opaque_box(mi, b.local_bbox()) for b in self.bodies]
        self.to_world, self.to_local = [], []
        for body in self.bodies:
            rel, inv = body.motion.relative(time)
            self.to_world.append(rel)
            self.to_local.append(inv)


def opaque_box(mi, box):
    """A ScalarBoundingBox3f as a Dr.Jit BoundingBox3f of opaque corners: the kernels
    that test rays against it read its corners as parameters, so that a new window or
    motion (a new swept box) compiles no new kernel."""
    def corner(p):
        return mi.Point3f(*opaque_tree(mi.Float, [float(p[i]) for i in range(3)]))

    return mi.BoundingBox3f(corner(box.min), corner(box.max))


class SceneQueries:
    """The one door through which a ray query meets a Mitsuba scene (static or a body's).

    This one asks each scene in the kernel that traces the rays, so that a pass is one
    kernel with every scene in it, and lets the bodies be visited by a symbolic call
    over their scenes (``dispatch``). Several OptiX pipelines in one kernel are what
    Mitsuba's CUDA variants may refuse (Mitsuba issue 1349); the fallback, one scene
    per kernel, is a subclass of this one set as ``QUERIES`` (docs/design.md section 3).
    """

    #: whether the bodies may be visited by one symbolic call over their scenes
    dispatch = True

    def preliminary(self, scene, ray, coherent, active):
        """Nearest preliminary intersection of ``ray`` with ``scene``."""
        return scene.ray_intersect_preliminary(ray, coherent, active)

    def interaction(self, mi, scene, ray, coherent, active):
        """Nearest surface interaction (all fields) of ``ray`` with ``scene``."""
        return scene.ray_intersect(ray, mi.RayFlags.All, coherent, active)

    def blocked(self, scene, ray, active):
        """Whether ``scene`` blocks the segment ``ray`` (a shadow ray)."""
        return scene.ray_test(ray, active)


class OneScenePerKernel(SceneQueries):
    """The OptiX fallback: each scene query is a kernel of its own (its inputs evaluated
    before it, its output after), the bodies traced each in turn, so that no kernel
    holds two scenes' pipelines. Needs evaluated loops and calls (Dr.Jit cannot
    evaluate inside a symbolic loop): set it with :func:`one_scene_per_kernel`."""

    dispatch = False

    def preliminary(self, scene, ray, coherent, active):
        return _alone(lambda: super(OneScenePerKernel, self).preliminary(
            scene, ray, coherent, active), ray, active)

    def interaction(self, mi, scene, ray, coherent, active):
        return _alone(lambda: super(OneScenePerKernel, self).interaction(
            mi, scene, ray, coherent, active), ray, active)

    def blocked(self, scene, ray, active):
        return _alone(lambda: super(OneScenePerKernel, self).blocked(scene, ray, active),
                      ray, active)


def _alone(query, *inputs):
    """``query()`` in a kernel of its own: its inputs evaluated first, its output then."""
    import drjit as dr

    dr.eval(*inputs)
    out = query()
    dr.eval(out)
    return out


#: the scene queries every trace below goes through (swap it to change how scenes are
#: traced: one kernel for all, or one scene per kernel)
QUERIES = SceneQueries()


@contextlib.contextmanager
def one_scene_per_kernel():
    """Inside the block, renders trace one scene per kernel (:class:`OneScenePerKernel`,
    with Dr.Jit's loops and calls evaluated, not symbolic); as before after it."""
    global QUERIES
    import drjit as dr

    saved = QUERIES
    with dr.scoped_set_flag(dr.JitFlag.SymbolicLoops, False), \
            dr.scoped_set_flag(dr.JitFlag.SymbolicCalls, False):
        QUERIES = OneScenePerKernel()
        try:
            yield
        finally:
            QUERIES = saved


def _dispatched(n: int) -> bool:
    """Whether ``n`` bodies are visited by a symbolic call rather than each in turn."""
    return QUERIES.dispatch and 1 < n <= MAX_DISPATCHED_BODIES


#: above this many bodies, a lane's candidate bodies no longer fit one 32-bit mask and
#: every body is tested in turn
MAX_DISPATCHED_BODIES = 32


#: variants whose Ray3f Mitsuba's ScalarBoundingBox3f binding refuses
_SLAB_VARIANTS = set()


def box_intersect(mi, box, ray):
    """(hit, near, far): a bounding box (BoundingBox3f, or ScalarBoundingBox3f)
    against JIT rays. Mitsuba binds that class once per float type, with the
    first-loaded variant's Ray3f: a spectral render after an RGB one in the same
    process gets a TypeError from it and the same slab test written out here instead
    (the binding stays first: its kernel is measurably faster with many bodies)."""
    import drjit as dr

    if mi.variant() not in _SLAB_VARIANTS:
        try:
            return box.ray_intersect(ray)
        except TypeError:
            _SLAB_VARIANTS.add(mi.variant())
    lo = [box.min[i] for i in range(3)]
    hi = [box.max[i] for i in range(3)]
    hit = mi.Bool(True)
    near = mi.Float(-dr.inf)
    far = mi.Float(dr.inf)
    for i in range(3):
        o, d = ray.o[i], ray.d[i]
        hit &= (d != 0.0) | ((o > lo[i]) & (o < hi[i]))
        rcp = dr.rcp(d)
        t1, t2 = (lo[i] - o) * rcp, (hi[i] - o) * rcp
        near = dr.maximum(near, dr.minimum(t1, t2))
        far = dr.minimum(far, dr.maximum(t1, t2))
    return hit & (far >= near), near, far


def _box_distances(mi, dr, frames, ray, active, upto):
    """Per body, where the ray enters its bounding box (inf: missed or beyond ``upto``).
    The box is the body's own, at its reference pose, met by the ray moved into the
    body's frame at the lane's time: exact, and tighter than a box swept over the
    exposure in world space (affine maps keep ray parameters, so distances compare)."""
    out = []
    for box, inv in zip(frames.local_boxes, frames.to_local):
        hit, near, far = box_intersect(mi, box, transformed_ray(mi, inv, ray, ray.maxt))
        near = dr.maximum(near, 0.0)
        out.append(dr.select(active & hit & (far >= 0) & (near <= upto), near, dr.inf))
    return out


def _transform_by_index(mi, dr, index, transforms):
    return select_transform(mi, dr, [index == k for k in range(len(transforms))], transforms)


def _body_hits_each(mi, dr, frames, ray, active, pi, best_t, coherent):
    """Test every body in turn (one body, or too many for the dispatch below)."""
    winner = mi.UInt32(len(frames.bodies))
    for k, (body, box, inv) in enumerate(zip(frames.bodies, frames.boxes, frames.to_local)):
        box_hit, box_near, box_far = box_intersect(mi, box, ray)
        test = active & box_hit & (box_near < best_t) & (box_far >= 0)
        pib = QUERIES.preliminary(
            body.scene, transformed_ray(mi, inv, ray, dr.minimum(ray.maxt, best_t)), coherent,
            test)
        closer = test & pib.is_valid() & (pib.t < best_t)
        pi = dr.select(closer, pib, pi)
        best_t = dr.select(closer, pib.t, best_t)
        winner = dr.select(closer, k, winner)
    return pi, winner


def _body_hits_dispatched(mi, dr, frames, ray, active, pi, best_t, coherent):
    """Visit the bodies whose boxes the ray enters (each body's own box, met by the ray in
    the body's frame at the lane's time: _box_distances), nearest first, until the
    next box starts beyond the nearest hit. Each visit is one symbolic call that runs only
    the body scenes present in a SIMD packet, so the cost follows what rays meet rather
    than the number of bodies."""
    n = len(frames.bodies)
    entry = _box_distances(mi, dr, frames, ray, active, dr.inf)
    targets = [lambda r, coherent, active, body=body:
               QUERIES.preliminary(body.scene, r, coherent, active)
               for body in frames.bodies]

    def nearest_untested(tested):
        k_best, d_best = mi.UInt32(n), mi.Float(dr.inf)
        for k, d in enumerate(entry):
            closer = (((tested >> k) & 1) == 0) & (d < d_best)
            d_best = dr.select(closer, d, d_best)
            k_best = dr.select(closer, k, k_best)
        return k_best, d_best

    def more(tested, winner, pi, best_t):
        return active & (nearest_untested(tested)[1] < best_t)

    def visit(tested, winner, pi, best_t):
        k, d = nearest_untested(tested)
        go = active & (d < best_t)
        tested = dr.select(go, tested | (mi.UInt32(1) << k), tested)
        local = transformed_ray(mi, _transform_by_index(mi, dr, k, frames.to_local), ray,
                           dr.minimum(ray.maxt, best_t))
        pib = dr.switch(k, targets, local, coherent, active=go)
        closer = go & pib.is_valid() & (pib.t < best_t)
        return (tested, dr.select(closer, k, winner), dr.select(closer, pib, pi),
                dr.select(closer, pib.t, best_t))

    _, winner, pi, _ = dr.while_loop((mi.UInt32(0), mi.UInt32(n), pi, best_t), more, visit,
                                     label="dopplertof_bodies", max_iterations=n)
    return pi, winner


def _static_preliminary(mi, dr, static_scene, ray, active, skip_idle: bool, coherent):
    """Preliminary hit in the static scene. ``skip_idle`` puts the query in a loop of one
    iteration, so that SIMD packets without an active lane skip the Embree call (a
    masked query still costs one per packet)."""
    if not skip_idle:
        return QUERIES.preliminary(static_scene, ray, coherent, active)

    def pending(done, pi):
        return active & ~done

    def query(done, pi):
        return mi.Bool(True), QUERIES.preliminary(static_scene, ray, coherent, active & ~done)

    _, pi = dr.while_loop((mi.Bool(False), dr.zeros(mi.PreliminaryIntersection3f)), pending,
                          query, label="dopplertof_static", max_iterations=1)
    return pi


def nearest_hit(mi, static_scene, frames: BodyFrames | None, ray, active,
                skip_idle: bool = False, coherent=False):
    """Nearest preliminary hit of world rays at their lanes' times, and which scene it is
    in: body index k, or ``len(bodies)`` for the static scene. The hit parameter t is
    the world ray's (affine maps keep ray parameters). ``coherent`` (a mask) tells
    Embree that the rays are coherent (camera rays)."""
    import drjit as dr

    n = len(frames.bodies) if frames is not None else 0
    pi = _static_preliminary(mi, dr, static_scene, ray, active, skip_idle, coherent)
    # A default (zero) intersection has t = 0: only active lanes with a hit are valid.
    pi.t = dr.select(active & (pi.t != 0.0), pi.t, dr.inf)
    if n == 0:
        return pi, mi.UInt32(0)
    best_t = dr.select(pi.is_valid(), pi.t, dr.inf)
    hits = _body_hits_dispatched if _dispatched(n) else _body_hits_each
    return hits(mi, dr, frames, ray, active, pi, best_t, mi.Bool(coherent))


def body_transforms(mi, frames: BodyFrames | None, winner):
    """Per lane, (to_local, to_world) of the scene ``winner`` names (identity: static)."""
    import drjit as dr

    n = len(frames.bodies) if frames is not None else 0
    if n == 0:
        identity = (None, [mi.Float(0.0)] * 3)
        return identity, identity
    won = [winner == k for k in range(n)]
    return (select_transform(mi, dr, won, frames.to_local),
            select_transform(mi, dr, won, frames.to_world))


def surface_interaction(mi, static_scene, frames: BodyFrames | None, ray, pi, winner, active,
                        flags=None):
    """The world-space surface interaction of a preliminary hit from :func:`nearest_hit`
    (``flags``: Mitsuba's RayFlags, ``All`` by default; with ``dNSdUV`` the shading
    normal's derivatives are in world space too)."""
    import drjit as dr

    flags = mi.RayFlags.All if flags is None else flags
    if frames is None or not frames.bodies:
        return pi.compute_surface_interaction(ray, flags, active)
    n = len(frames.bodies)
    to_local, to_world = body_transforms(mi, frames, winner)
    hit_ray = transformed_ray(mi, to_local, ray, ray.maxt)  # the world ray where static won
    si = pi.compute_surface_interaction(hit_ray, flags, active)

    # ---- Back to world space (identity for static hits) ----
    on_body = winner < n
    p = vec3(mi, mi.Point3f, transform_point(to_world, si.p))
    nrm = dr.normalize(vec3(mi, mi.Normal3f, transform_normal(to_local, si.n)))
    sn_moved = vec3(mi, mi.Normal3f, transform_normal(to_local, si.sh_frame.n))
    sn = dr.normalize(sn_moved)
    ss = vec3(mi, mi.Vector3f, transform_vector(to_world, si.sh_frame.s))
    ss = dr.normalize(ss - sn * dr.dot(ss, sn))  # Gram-Schmidt: exact frames under shear too
    frame = mi.Frame3f(ss, dr.cross(sn, ss), sn)
    if mi.has_flag(flags, mi.RayFlags.dNSdUV):  # d normalize(m) = (I - n n^T) dm / |m|
        for name in ("dn_du", "dn_dv"):
            dm = vec3(mi, mi.Vector3f, transform_normal(to_local, getattr(si, name)))
            moved = (dm - sn * dr.dot(sn, dm)) / dr.norm(sn_moved)
            setattr(si, name, dr.select(on_body, moved, getattr(si, name)))
    si.p = dr.select(on_body, p, si.p)
    si.n = dr.select(on_body, nrm, si.n)
    si.sh_frame = dr.select(on_body, frame, si.sh_frame)
    si.dp_du = dr.select(on_body, vec3(mi, mi.Vector3f, transform_vector(to_world, si.dp_du)),
                         si.dp_du)
    si.dp_dv = dr.select(on_body, vec3(mi, mi.Vector3f, transform_vector(to_world, si.dp_dv)),
                         si.dp_dv)
    # The incident direction is recomputed from the world ray.
    si.wi = dr.select(si.is_valid(), si.to_local(-ray.d), si.wi)
    return si


def intersect(mi, static_scene, frames: BodyFrames | None, ray, active, coherent=False):
    """Nearest surface interaction (world space) of world rays at their lanes' times."""
    if frames is None or not frames.bodies:
        return QUERIES.interaction(mi, static_scene, ray, coherent, active)
    pi, winner = nearest_hit(mi, static_scene, frames, ray, active, coherent=coherent)
    return surface_interaction(mi, static_scene, frames, ray, pi, winner, active)


def occluded(mi, static_scene, frames: BodyFrames | None, ray, active):
    """Shadow-ray test against the static scene and every body at the lanes' times."""
    import drjit as dr

    blocked = QUERIES.blocked(static_scene, ray, active)
    if frames is None or not frames.bodies:
        return blocked
    n = len(frames.bodies)
    if not _dispatched(n):
        for body, box, inv in zip(frames.bodies, frames.boxes, frames.to_local):
            box_hit, box_near, box_far = box_intersect(mi, box, ray)
            test = active & ~blocked & box_hit & (box_near <= ray.maxt) & (box_far >= 0)
            blocked |= QUERIES.blocked(body.scene, transformed_ray(mi, inv, ray, ray.maxt), test)
        return blocked

    # ---- Dispatch: visit only the bodies whose own boxes the segment crosses ----
    entry = _box_distances(mi, dr, frames, ray, active, ray.maxt)
    pending = mi.UInt32(0)
    for k, d in enumerate(entry):
        pending |= dr.select(dr.isfinite(d), mi.UInt32(1 << k), 0)
    targets = [lambda r, active, body=body: QUERIES.blocked(body.scene, r, active)
               for body in frames.bodies]

    def more(pending, blocked):
        return active & ~blocked & (pending != 0)

    def visit(pending, blocked):
        go = active & ~blocked & (pending != 0)
        k = dr.tzcnt(pending)
        pending = dr.select(go, pending & ~(mi.UInt32(1) << k), pending)
        k = dr.minimum(k, n - 1)
        local = transformed_ray(mi, _transform_by_index(mi, dr, k, frames.to_local), ray, ray.maxt)
        return pending, blocked | dr.switch(k, targets, local, active=go)

    _, blocked = dr.while_loop((pending, blocked), more, visit, label="dopplertof_shadow",
                               max_iterations=n)
    return blocked
