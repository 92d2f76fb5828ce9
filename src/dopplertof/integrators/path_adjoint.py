"""The adjoint pass of reverse-mode gradients by path replay
(:func:`dopplertof.diff.gradient` with ``method="path"``, the default where it runs).

A lane's value is a sum of contributions C_j, one per emitter hit and light sample of
its path. The primal pass gives each lane that sum M and the sum M_L of the
contributions' derivatives with respect to their path lengths
(``trace(layout, length_derivative=True)``). This pass traces the same paths again
(the same random numbers, nothing attached) and, at each vertex, differentiates only
what is local to it, weighted by the lane's adjoint delta (d loss / d lane value):

* the segment that reaches the vertex: its length adds to the path length of every
  contribution at or after the vertex, delta . (M_L - prefix) x length;
* the vertex's own emitter hit and light sample: their emission, BSDF value, light
  sample weight and modulation weight;
* the BSDF sample that continues the path: every contribution after the vertex scales
  with the BSDF value times |cos| toward it, delta . (M - prefix') x Phi / detach(Phi).

Where motion is differentiated, every vertex follows its ray, as in forward mode and
the trajectory method: the camera ray's first hit the attached camera ray, every later
one the ray from the vertex before it along the sampled direction, that direction
turning with the body of the vertex it leaves. The vertex before is attached through
its tangents (d position / d each motion parameter, detached loop state: 3 numbers
per parameter), which each vertex passes on to the next (the first order of a ray's
hit on a moving surface, :func:`follow_ray`), so that nothing attached crosses an
iteration and memory does not grow with the path's length. On flat-faced bodies this
is the trajectory's derivative per sample; on curved ones, whose shading frames turn
as a vertex slides, the trajectory's directions turn with the frame and these with
the body, and where a light can be both hit and sampled the MIS weights are held at
their traced values (the trajectory differentiates them): unbiased estimators of the
same derivative either way (tests/test_gradient.py).
"""

from __future__ import annotations

import drjit as dr

from ..scene.bodies import nearest_hit, surface_interaction
from ..scene.motion import vec3
from .path_steps import (LoopSettings, advance, contributions, length_derivatives, lit_at,
                         sample_light, shade, survive, vertex_numbers)


class AttachedLane:
    """What a lane's vertices are attached with: the motion parameters whose tangents
    the loop carries (d x / d parameter of every place and direction, detached), and
    each parameter's change from its detached value, broadcast to the lanes once per
    vertex (:meth:`start_vertex`), so that every attached quantity x of the vertex is
    x + sum over parameters of its tangent times that change (:meth:`with_tangents`),
    and the gradient of a parameter leaves each lane once per vertex."""

    def __init__(self, mi, setup, start, motion: bool):
        self.mi, self.setup = mi, setup
        self.time = start.time
        self.camera_origin = dr.detach(start.ray.o)  #: where the camera ray leaves the lens
        self.light_frames = start.light_frames  #: the lights' frames (not differentiated)
        self.emitters_hit = emitters_hit(mi, setup.scene.static)  #: (emitters_hit)
        #: whether a shading normal turns as a hit slides over its surface (curved_shapes)
        self.curved = motion and curved_shapes(mi, setup.scene)
        #: the attached motion components, (owner, kind, variable): owner k for body k,
        #: -1 for the camera; kind "v" (linear) or "w" (angular); each vertex carries
        #: d position / d variable for each
        self.parameters = [(owner, kind, variable) for owner, motion_k in self._owned_motions()
                           for kind, _, variable in motion_k.attached_components()]
        self.steps = []  #: this vertex's changes of the parameters (start_vertex)
        self.moving = motion and bool(self.parameters)  #: whether the loop carries tangents
        #: what the vertices' interactions hold (a curved surface's normal derivatives)
        self.hit_flags = (mi.RayFlags.All | mi.RayFlags.dNSdUV if self.curved else mi.RayFlags.All)

    def _owned_motions(self):
        """(owner, motion) of every motion with velocity parameters (VelocityMotion):
        owner k for body k, -1 for the camera."""
        setup = self.setup
        owners = [(k, body.motion) for k, body in enumerate(setup.scene.bodies)]
        owners.append((-1, getattr(setup.camera, "motion", None)))
        return [(k, m) for k, m in owners if hasattr(m, "attached_components")]

    def start_vertex(self, active):
        """Each parameter's change from its detached value (zero, attached), one wide
        variable per parameter for this vertex (called inside the loop body, where
        gradients are enabled)."""
        self.steps = [dr.select(active, variable - dr.detach(variable), 0.0)
                      for _, _, variable in self.parameters]

    def _motions(self):
        """{owner: (motion, its turn rates at the lanes' times)} for the motions with
        attached components (owner k: body k, -1: the camera)."""
        return {k: (m, m.turn_rates(self.mi, self.time)) for k, m in self._owned_motions()}

    def tangents_at(self, x, owner):
        """Per parameter, d x / d parameter (detached Vector3f) of the material point at
        world ``x`` of the scene ``owner`` names (per lane: body k, or len(bodies) for the
        static scene; -1: the camera's origin), zero for the parameters of the others."""
        mi = self.mi
        values = {k: iter(m.point_velocities(mi, self.time, x, rates))
                  for k, (m, rates) in self._motions().items()}
        return [dr.select(owner == k, vec3(mi, mi.Vector3f, next(values[k])), mi.Vector3f(0.0))
                for k, _, _ in self.parameters]

    def turn_rates(self, owner):
        """Per parameter, the rate rho (detached Vector3f) at which the body ``owner``
        names (per lane) turns with it (VelocityMotion.turn_rates); None for a linear
        component (no turn)."""
        mi = self.mi
        rates = {k: iter(r) for k, (_, r) in self._motions().items()}
        out = []
        for k, kind, _ in self.parameters:
            rho = next(rates[k])
            out.append(None if kind == "v" else
                       dr.select(owner == k, vec3(mi, mi.Vector3f, rho), mi.Vector3f(0.0)))
        return out

    def turn_tangents(self, d, owner):
        """Per parameter, d d / d parameter (detached) of a direction ``d`` fixed in the
        frame of the body ``owner`` names: rho x d (None where it does not turn)."""
        return turned(self.turn_rates(owner), d)

    def with_tangents(self, x, tangents):
        """``x`` (detached: a point or a direction) plus its tangents times this
        vertex's parameter changes (:meth:`start_vertex`): the value of x, the
        derivative it was carried with (None tangents: none)."""
        for step, t in zip(self.steps, tangents):
            if t is not None:
                x = x + t * step
        return x


def turned(rates, d):
    """Per rate rho (None: no turn), rho x d."""
    return [None if rho is None else dr.cross(rho, d) for rho in rates]


def curved_shapes(mi, scene) -> bool:
    """Whether a shading normal of the scene's shapes (static or a body's) varies over
    its surface: a shape other than a rectangle, a disk or a mesh, or a mesh whose
    vertex normals differ from its faces' normals."""
    import numpy as np

    shapes = list(scene.static.shapes()) + [s for b in scene.bodies for s in b.scene.shapes()]
    for shape in shapes:
        if shape.class_name() in ("Rectangle", "Disk") or (
                shape.is_mesh() and not shape.has_vertex_normals()):
            continue
        if not shape.is_mesh():
            return True
        faces = np.asarray(shape.face_indices(dr.arange(mi.UInt32, shape.face_count())))
        points = np.asarray(shape.vertex_position(dr.arange(mi.UInt32, shape.vertex_count())))
        normals = np.asarray(shape.vertex_normal(dr.arange(mi.UInt32, shape.vertex_count())))
        a, b, c = (points[:, faces[k]] for k in range(3))
        face_normal = np.cross(b - a, c - a, axis=0)
        face_normal /= np.maximum(np.linalg.norm(face_normal, axis=0), 1e-30)
        if any(np.min(np.abs(np.sum(normals[:, faces[k]] * face_normal, axis=0))) < 1.0 - 1e-6
               for k in range(3)):
            return True
    return False


def emitters_hit(mi, scene) -> bool:
    """Whether a path can hit one of ``scene``'s emitters (not only point, spot or
    directional lights)."""
    return any(not mi.has_flag(e.flags(), mi.EmitterFlags.DeltaPosition)
               and not mi.has_flag(e.flags(), mi.EmitterFlags.DeltaDirection)
               for e in scene.emitters())


def follow_ray(origin_tangents, direction_tangents, t, d, n, surface):
    """The tangents of the hit, at distance ``t``, of a ray from an origin with
    ``origin_tangents`` along ``d`` with ``direction_tangents`` (None: fixed), on a
    surface through the hit with normal ``n`` whose material point there has
    ``surface`` tangents: the first order of the ray's intersection with the moving
    tangent plane (exact for the position), x' = o' + t d' + d t',
    t' = n . (surface - o' - t d') / n . d."""
    cos = dr.dot(n, d)
    cos = dr.select(dr.abs(cos) > 1e-12, cos, 1e-12)
    out = []
    for o, turn, s in zip(origin_tangents, direction_tangents, surface):
        along = o if turn is None else o + t * turn
        out.append(along + d * (dr.dot(n, s - along) / cos))
    return out


def owner_of(mi, winner, n_bodies: int):
    """The owner (AttachedLane.parameters) of the scene ``winner`` names: body k, or
    ``n_bodies`` for the static scene."""
    return dr.select(winner < n_bodies, mi.Int32(winner), mi.Int32(n_bodies))


class Followed:
    """A vertex's tangents where motion is differentiated (:func:`followed_vertex`)."""

    def __init__(self, owner, origin_tangents, direction_tangents, tangents, slides):
        self.owner = owner  #: the scene the vertex is on (owner_of)
        self.origin_tangents = origin_tangents  #: its ray's origin's, per parameter
        self.direction_tangents = direction_tangents  #: its ray's direction's (None: fixed)
        self.tangents = tangents  #: the hit's (follow_ray)
        self.slides = slides  #: the hit's move over its surface, hit's minus material point's


@dr.syntax
def adjoint_paths(mi, setup, layout, streams, start, delta, total, total_dl, motion=True,
                  lit=None):
    """Trace each lane's path again and back-propagate ``delta`` (d loss / d lane value)
    through each vertex's local terms; ``total``, ``total_dl``, ``lit``: the primal
    pass's M, M_L and light sample bits (lit_bits; None: shadow rays are traced). The
    gradients are the loop's side effects (``dr.eval()`` runs it, once)."""
    static, modulation = setup.scene.static, setup.modulation_weight
    settings = LoopSettings(mi, setup, modulation.F)  # (a plain object: not loop state)
    t_rel, ray, frames = start.t_rel, start.ray, (start.frames, start.light_frames)
    attached = AttachedLane(mi, setup, start, motion)
    u_first = [streams.first_hit_2d(k, layout.group, layout.index, setup.groups_per_pixel)
               for k in (0, 1)]  # (the first hit's light and BSDF samples)

    # ---- Loop state (all detached) ----
    prefix = mi.Spectrum(0.0)  # the contributions so far
    prefix_dl = mi.Spectrum(0.0)  # their derivatives with respect to their path lengths
    beta = mi.Spectrum(start.ray_weight)  # path throughput
    length = modulation.F(start.camera_offset)  # path length so far (m)
    depth = mi.UInt32(0)  # surface hits so far (scattering vertices)
    going = mi.UInt32(dr.select(start.active, 1, 0))  # whether the path goes on (1)
    prev_si = dr.zeros(mi.Interaction3f)  # previous vertex, for emitter MIS
    prev_bsdf_pdf = mi.Float(1.0)  # solid-angle pdf of the last BSDF sample
    prev_bsdf_delta = mi.UInt32(1)  # whether that sample was a delta lobe (1)
    eta = mi.Float(1.0)  # relative index of refraction along the path
    origin = mi.Point3f(0.0)  # the last scattering vertex, where the ray starts (moving)
    origin_owner = mi.Int32(-1)  # the scene it is on (owner_of; -1: the camera)
    tangents = [mi.Vector3f(0.0) for _ in attached.parameters if attached.moving]  # d origin
    while dr.hint(going != 0, max_iterations=settings.max_iterations,
                  label="dopplertof_adjoint"):
        # ---- The vertex, traced as the primal pass traced it ----
        active = going != 0
        pi, winner = nearest_hit(mi, static, frames[0], ray, active, coherent=depth == 0)
        si = surface_interaction(mi, static, frames[0], ray, pi, winner, active,
                                 attached.hit_flags)
        numbers = vertex_numbers(streams, depth, *u_first)
        path = (ray, beta, length, depth, active, prev_si, prev_bsdf_pdf,
                prev_bsdf_delta != 0, eta)
        v = shade(mi, settings, path, frames, si, numbers, lit_at(lit, depth))
        hit_contribution, light_contribution = contributions(modulation, v, t_rel)
        # ---- Its tangents (where motion is differentiated): its ray's and its own ----
        followed = followed_vertex(mi, attached, (si, winner), ray, depth,
                                   (origin_owner, tangents))

        # ---- Its local terms, attached, back-propagated at once ----
        suffix = (total - prefix, total_dl - prefix_dl,
                  total - prefix - hit_contribution - light_contribution)
        _back_propagate(mi, attached.setup, attached, (delta, active), (si, ray, v, numbers,
                        beta, t_rel), suffix, (depth, origin, followed), settings.bsdf_ctx)
        prefix += hit_contribution  # (summed as the primal pass sums them)
        prefix += light_contribution
        prefix_dl += length_derivatives(modulation, v, t_rel)

        # ---- The vertex's place and tangents, for the next one's ray ----
        origin, origin_owner, tangents = _next_place(si, v, followed, (origin, origin_owner,
                                                                       tangents))
        # ---- Continue the path (as the primal pass) ----
        ray, beta, length, depth, _, prev_si, prev_bsdf_pdf, delta_lobe, eta = advance(
            mi, path, si, v)
        prev_bsdf_delta = mi.UInt32(dr.select(delta_lobe, 1, 0))
        beta, going = survive(mi, v, beta, eta, depth, settings.rr_depth, numbers[3])


def followed_vertex(mi, attached, hit, ray, depth, last):
    """The vertex's Followed tangents (None where nothing moves): its ray is the camera
    ray (from the camera's origin, its direction fixed) or the ray from the last vertex
    (``last``: its owner and tangents), its direction turning with that vertex's body;
    its hit slides along the ray on its moving surface (follow_ray)."""
    if not attached.moving:
        return None
    si, winner = hit
    origin_owner, tangents = last
    on_camera_ray = depth == 0
    camera = attached.tangents_at(attached.camera_origin, mi.Int32(-1))
    origin_tangents = [dr.select(on_camera_ray, c, t) for c, t in zip(camera, tangents)]
    turns = [None if turn is None else dr.select(on_camera_ray, mi.Vector3f(0.0), turn)
             for turn in attached.turn_tangents(dr.detach(ray.d), origin_owner)]
    owner = owner_of(mi, winner, len(attached.setup.scene.bodies))
    surface = attached.tangents_at(si.p, owner)
    hit_tangents = follow_ray(origin_tangents, turns, si.t, dr.detach(ray.d), dr.detach(si.n),
                              surface)
    return Followed(owner, origin_tangents, turns, hit_tangents,
                    [h - s for h, s in zip(hit_tangents, surface)])


def _back_propagate(mi, setup, attached, lanes, vertex, suffix, place, bsdf_ctx):
    """Back-propagate delta . the vertex's local terms (_local_terms) into the
    parameters' gradients (``lanes``: delta and whether the lane's path goes on; the
    vertex's attached values live only here)."""
    delta, active = lanes
    with dr.resume_grad():
        attached.start_vertex(active)
        local = _local_terms(mi, setup, attached, *vertex, suffix, place, bsdf_ctx)
        dr.backward_from(_dot(delta, local), flags=dr.ADFlag.AllowNoGrad)


def _next_place(si, v, followed, place):
    """(origin, its owner, its tangents) of the next ray: this vertex's where the path
    bounces off it, ``place`` (the last ones) otherwise or where nothing moves."""
    if followed is None:
        return place
    origin, origin_owner, tangents = place
    tangents = [dr.select(si.is_valid(), f, t) for f, t in zip(followed.tangents, tangents)]
    bounced = v.valid & ~v.through
    return (dr.select(bounced, si.p, origin), dr.select(bounced, followed.owner, origin_owner),
            tangents)


def _local_terms(mi, setup, attached, si, ray, v, numbers, beta, t_rel, suffix, place,
                 bsdf_ctx):
    """The vertex's local terms (Spectrum, attached): d/d theta of their dot product with
    delta is the vertex's share of d loss / d theta (see the module docstring)."""
    remaining, remaining_dl, after = suffix  # at or after this vertex; after it
    depth, origin, followed = place
    terms = mi.Spectrum(0.0)
    here, turns = si, None
    if followed is not None:  # ---- the vertex attached by its tangents ----
        turns = attached.turn_rates(followed.owner)
        here, segment = attached_vertex(mi, attached, si, ray, depth, origin, followed, turns)
        terms += dr.select(v.valid & ~v.through, remaining_dl * segment, 0.0)
    # ---- The BSDF sample that continues the path, its own emitter hit and light sample ----
    terms += _continuation_term(mi, attached, turns, si, here, v, after, bsdf_ctx)
    return terms + _own_terms(mi, setup, attached, si, here, v, numbers, beta, t_rel, bsdf_ctx)


def attached_vertex(mi, attached, si, ray, depth, origin, followed, rates):
    """This vertex attached by its tangents: its place (``followed.tangents``), its
    shading frame turning with its body (``rates``: its turn rates, AttachedLane.turn_rates)
    and, on a curved surface, with the normal's
    change as the hit slides (``followed.slides``), its uv sliding, the direction it is
    seen from (its ray's, turning: ``followed.direction_tangents``); and the length of
    the segment reaching it (from the camera's origin on the camera ray)."""
    start = dr.select(depth == 0, attached.camera_origin, origin)
    start = attached.with_tangents(start, followed.origin_tangents)
    here = mi.SurfaceInteraction3f(si)
    here.p = attached.with_tangents(dr.detach(si.p), followed.tangents)
    slid_uv = _uv_slides(mi, si, followed.slides)
    here.uv = attached.with_tangents(dr.detach(si.uv), slid_uv)
    here.n = attached.with_tangents(dr.detach(si.n), turned(rates, dr.detach(si.n)))
    if attached.curved:  # the frame also turns as the hit slides: n x dn
        n = dr.detach(si.sh_frame.n)
        slid = [dr.cross(n, dr.detach(si.dn_du) * uv[0] + dr.detach(si.dn_dv) * uv[1])
                for uv in slid_uv]
        rates = [w if rho is None else rho + w for rho, w in zip(rates, slid)]
    frame = si.sh_frame
    here.sh_frame = mi.Frame3f(*(attached.with_tangents(dr.detach(axis), turned(rates, axis))
                                 for axis in (frame.s, frame.t, frame.n)))
    d = dr.detach(ray.d)
    here.wi = here.to_local(-attached.with_tangents(d, followed.direction_tangents))
    return here, dr.norm(here.p - start)


def _uv_slides(mi, si, slides):
    """Per parameter, the change of uv (Point2f) of a hit sliding by ``slides`` (world,
    in the tangent plane): the least-squares solve with dp/du and dp/dv."""
    du, dv = dr.detach(si.dp_du), dr.detach(si.dp_dv)
    e, f, g = dr.dot(du, du), dr.dot(du, dv), dr.dot(dv, dv)
    det = e * g - f * f
    inverse = dr.select(det > 1e-20 * (e * g), dr.rcp(det), 0.0)
    out = []
    for r in slides:
        a, b = dr.dot(du, r), dr.dot(dv, r)
        out.append(mi.Vector2f((g * a - f * b) * inverse, (e * b - f * a) * inverse))
    return out


def _continuation_term(mi, attached, turns, si, here, v, after, bsdf_ctx):
    """The BSDF sample that continues the path from this vertex, ``after`` x Phi /
    detach(Phi): Phi the vertex's BSDF value times |cos| toward the sampled direction
    (turning with the vertex's body where it moves: ``turns``, its turn rates, None
    where nothing moves; the next vertex follows it), ``after`` the contributions after
    this vertex (every one of them scales with Phi)."""
    bounced = v.valid & ~v.through & v.active_next
    d_next = dr.detach(si.to_world(v.bs.wo))
    if turns is not None:
        d_next = attached.with_tangents(d_next, turned(turns, d_next))
    phi = here.bsdf().eval(bsdf_ctx, here, here.to_local(d_next), bounced)
    base = dr.detach(phi)
    return dr.select(bounced & (base > 0.0), after * phi / dr.select(base > 0.0, base, 1.0), 0.0)


def _own_terms(mi, setup, attached, si, here, v, numbers, beta, t_rel, bsdf_ctx):
    """The vertex's own emitter hit (where the scene has emitters to hit) and light
    sample, each with its emission, BSDF value, light sample weight and modulation
    weight attached (at the detached path length up to the vertex)."""
    static, modulation = setup.scene.static, setup.modulation_weight
    terms = mi.Spectrum(0.0)
    if attached.emitters_hit:
        emitted = si.emitter(static).eval(here, v.hit_emitter)
        terms += dr.select(v.hit_emitter, beta * v.mis_hit * emitted
                           * modulation(dr.detach(v.length_hit), t_rel), 0.0)
    ds, em_weight = sample_light(mi, static, attached.light_frames, here, numbers[0],
                                 v.active_em)
    bsdf_value = here.bsdf().eval(bsdf_ctx, here, here.to_local(ds.d), v.active_em)
    terms += dr.select(v.active_em, beta * v.mis_em * bsdf_value * em_weight
                       * modulation(dr.detach(v.length_hit) + modulation.F(ds.dist), t_rel),
                       0.0)
    return terms


def _dot(delta, value):
    """Per lane, the sum over channels of delta x value."""
    out = delta[0] * value[0]
    for c in range(1, len(value)):
        out += delta[c] * value[c]
    return out
