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

from ..scene.bodies import BodyFrames, nearest_hit, surface_interaction
from ..scene.motion import vec3
from .path_steps import (advance, contributions, length_derivatives, loop_settings,
                         sample_light, shade, survive, vertex_numbers)


class AttachedLane:
    """What a lane's vertices are re-attached with, recomputed inside the loop from its
    detached inputs (so that gradients reach the width-1 parameters directly, not
    per-lane copies of them): the camera ray at the lane's film position and time,
    the bodies' frames at its time, and their detached frames; and the motion
    parameters whose tangents the loop carries (:meth:`tangents_at`)."""

    def __init__(self, mi, setup, start, motion: bool):
        self.mi, self.setup = mi, setup
        self.motion = motion  #: whether anything the vertices' places depend on is attached
        self.time, self.position, self.lens = start.time, start.film_position, start.lens
        self.frames = start.frames  #: detached BodyFrames (None without bodies)
        self.light_frames = start.light_frames  #: the lights' frames (not differentiated)
        self.emitters_hit = emitters_hit(mi, setup.scene.static)  #: (emitters_hit)
        #: the attached motion components, (owner, variable): owner k for body k, -1 for
        #: the camera; each vertex carries d position / d variable for each
        self.parameters = [(owner, variable) for owner, motion_k in self._owned_motions()
                           for _, _, variable in motion_k.attached_components()]

    def _owned_motions(self):
        """(owner, motion) of every motion with velocity parameters (VelocityMotion):
        owner k for body k, -1 for the camera."""
        setup = self.setup
        owners = [(k, body.motion) for k, body in enumerate(setup.scene.bodies)]
        owners.append((-1, getattr(setup.camera, "motion", None)))
        return [(k, m) for k, m in owners if hasattr(m, "attached_components")]

    def camera_ray(self):
        """(attached camera ray, attached path length from the lens to its origin)."""
        ray, _, offset = self.setup.camera.ray(self.position, self.time, *self.lens)
        return ray, offset

    def pose(self):
        """The bodies' attached frames at the lanes' times (None without bodies)."""
        setup = self.setup
        if self.frames is None:
            return None
        return BodyFrames(self.mi, setup.scene.bodies, self.time, setup.shutter_open,
                          setup.shutter_open + setup.modulation.exposure)

    def _motions(self):
        """{owner: (motion, its turn rates at the lanes' times)} for the motions with
        attached components (owner k: body k, -1: the camera)."""
        return {k: (m, m.turn_rates(self.mi, self.time)) for k, m in self._owned_motions()}

    def _per_parameter(self, owner, values):
        """Per parameter, its owner's entry of ``values`` ({owner: iterator of
        3-vectors}) where ``owner`` (per lane) is that parameter's owner, else zero."""
        mi = self.mi
        return [dr.select(owner == k, vec3(mi, mi.Vector3f, next(values[k])), mi.Vector3f(0.0))
                for k, _ in self.parameters]

    def tangents_at(self, x, owner):
        """Per parameter, d x / d parameter (detached Vector3f) of the material point at
        world ``x`` of the scene ``owner`` names (per lane: body k, or len(bodies) for the
        static scene; -1: the camera's origin), zero for the parameters of the others."""
        motions = self._motions()
        return self._per_parameter(owner, {
            k: iter(m.point_velocities(self.mi, self.time, x, rates))
            for k, (m, rates) in motions.items()})

    def turn_tangents(self, d, owner):
        """Per parameter, d d / d parameter (detached) of a direction ``d`` fixed in the
        frame of the body ``owner`` names: rho x d (VelocityMotion.turn_rates)."""
        mi = self.mi
        return self._per_parameter(owner, {
            k: iter(dr.cross(vec3(mi, mi.Vector3f, rho), d) for rho in rates)
            for k, (_, rates) in self._motions().items()})

    def with_tangents(self, x, tangents):
        """``x`` (detached: a point or a direction) plus its tangents times each
        parameter's change from its detached value: the value of x, the derivative it
        was carried with."""
        for (_, variable), t in zip(self.parameters, tangents):
            x = x + t * (variable - dr.detach(variable))
        return x


def emitters_hit(mi, scene) -> bool:
    """Whether a path can hit one of ``scene``'s emitters (not only point, spot or
    directional lights)."""
    return any(not mi.has_flag(e.flags(), mi.EmitterFlags.DeltaPosition)
               and not mi.has_flag(e.flags(), mi.EmitterFlags.DeltaDirection)
               for e in scene.emitters())


def follow_ray(origin_tangents, direction_tangents, t, d, n, surface):
    """The tangents of the hit, at distance ``t``, of a ray from an origin with
    ``origin_tangents`` along ``d`` with ``direction_tangents``, on a surface through
    the hit with normal ``n`` whose material point there has ``surface`` tangents: the
    first order of the ray's intersection with the moving tangent plane (exact for the
    position), x' = o' + t d' + d t', t' = n . (surface - o' - t d') / n . d."""
    cos = dr.dot(n, d)
    cos = dr.select(dr.abs(cos) > 1e-12, cos, 1e-12)
    out = []
    for o, turn, s in zip(origin_tangents, direction_tangents, surface):
        along = o + t * turn
        out.append(along + d * (dr.dot(n, s - along) / cos))
    return out


def owner_of(mi, winner, n_bodies: int):
    """The owner (AttachedLane.parameters) of the scene ``winner`` names: body k, or
    ``n_bodies`` for the static scene."""
    return dr.select(winner < n_bodies, mi.Int32(winner), mi.Int32(n_bodies))


@dr.syntax
def adjoint_paths(mi, setup, layout, streams, start, delta, total, total_dl, motion=True):
    """Trace each lane's path again and back-propagate ``delta`` (per lane: d loss / d
    lane value) through each vertex's local terms; ``total``, ``total_dl``: the primal
    pass's M and M_L; ``motion``: whether any motion is attached (else the vertices stay
    as traced). The gradients are the loop's side effects (``dr.eval()`` runs it;
    evaluating a loop value as well would run the loop a second time)."""
    static, modulation = setup.scene.static, setup.modulation_weight
    t_rel, ray, frames, light_frames = start.t_rel, start.ray, start.frames, start.light_frames
    attached = AttachedLane(mi, setup, start, motion)
    u_first = [streams.first_hit_2d(k, layout.group, layout.index, setup.groups_per_pixel)
               for k in (0, 1)]  # (the first hit's light and BSDF samples)
    moving = motion and bool(attached.parameters)

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
    tangents = [mi.Vector3f(0.0) for _ in attached.parameters if moving]  # d origin / d each
    bsdf_ctx = mi.BSDFContext()
    max_depth, max_iterations, rr_depth, hide_direct_emitters = loop_settings(mi, setup)
    while dr.hint(going != 0, max_iterations=max_iterations, label="dopplertof_adjoint"):
        # ---- The vertex, traced as the primal pass traced it ----
        active = going != 0
        pi, winner = nearest_hit(mi, static, frames, ray, active, coherent=depth == 0)
        si = surface_interaction(mi, static, frames, ray, pi, winner, active)
        numbers = vertex_numbers(streams, depth, *u_first)
        v = shade(mi, static, frames, light_frames, ray, si, active, depth, beta, length,
                  prev_si, prev_bsdf_pdf, prev_bsdf_delta != 0, numbers, max_depth,
                  hide_direct_emitters, modulation.F, bsdf_ctx)
        hit_contribution, light_contribution = contributions(modulation, v, t_rel)

        # ---- Its local terms, attached, back-propagated at once ----
        with dr.resume_grad():
            after = total - prefix - hit_contribution - light_contribution
            local = _local_terms(mi, setup, attached, (si, pi, winner), ray, v, numbers,
                                 beta, t_rel, (total - prefix, total_dl - prefix_dl, after),
                                 (depth, origin, origin_owner, tangents), bsdf_ctx)
            dr.backward_from(_dot(delta, local), flags=dr.ADFlag.AllowNoGrad)
        prefix += hit_contribution  # (summed as the primal pass sums them)
        prefix += light_contribution
        prefix_dl += length_derivatives(modulation, v, t_rel)

        # ---- The vertex's place and tangents, for the next one's ray ----
        origin, origin_owner, tangents = _next_place(
            mi, attached, (si, winner, ray, v, depth), (origin, origin_owner, tangents), moving)
        # ---- Continue the path (as the primal pass) ----
        length = v.length_hit
        ray, beta, eta, prev_si, prev_bsdf_pdf, delta_lobe, depth = advance(
            mi, si, ray, v, beta, eta, prev_si, prev_bsdf_pdf, prev_bsdf_delta != 0, depth)
        prev_bsdf_delta = mi.UInt32(dr.select(delta_lobe, 1, 0))
        beta, going = survive(mi, v, beta, eta, depth, rr_depth, numbers[3])


def _next_place(mi, attached, vertex, place, moving: bool):
    """(origin, its owner, its tangents) of the next ray: this vertex's where the path
    bounces off it (``vertex``: its si, winner, ray, Vertex and depth), ``place`` (the
    last ones) otherwise or where nothing moves."""
    if not moving:
        return place
    si, winner, ray, v, depth = vertex
    origin, origin_owner, tangents = place
    tangents = _next_tangents(mi, attached, si, winner, ray, depth, origin_owner, tangents)
    bounced = v.valid & ~v.through
    owner = owner_of(mi, winner, len(attached.setup.scene.bodies))
    return (dr.select(bounced, si.p, origin), dr.select(bounced, owner, origin_owner), tangents)


def _next_tangents(mi, attached, si, winner, ray, depth, origin_owner, tangents):
    """The tangents of this vertex (the origin of the next ray): its hit slides along
    its ray on its moving surface (follow_ray); the ray from the last vertex, its
    direction turning with that vertex's body, or the camera ray (from the camera's
    origin, its direction fixed)."""
    on_camera_ray = depth == 0
    camera = attached.tangents_at(ray.o, mi.Int32(-1))
    origin_tangents = [dr.select(on_camera_ray, c, t) for c, t in zip(camera, tangents)]
    turns = [dr.select(on_camera_ray, mi.Vector3f(0.0), turn)
             for turn in attached.turn_tangents(dr.detach(ray.d), origin_owner)]
    surface = attached.tangents_at(si.p, owner_of(mi, winner, len(attached.setup.scene.bodies)))
    followed = follow_ray(origin_tangents, turns, si.t, dr.detach(ray.d), dr.detach(si.n),
                          surface)
    return [dr.select(si.is_valid(), f, t) for f, t in zip(followed, tangents)]


def _local_terms(mi, setup, attached, hit, ray, v, numbers, beta, t_rel, suffix, place,
                 bsdf_ctx):
    """The vertex's local terms (Spectrum, attached): d/d theta of their dot product with
    delta is the vertex's share of d loss / d theta (see the module docstring)."""
    si, pi, winner = hit
    remaining, remaining_dl, after = suffix  # at or after this vertex; after it
    depth, origin, origin_owner, tangents = place
    terms = mi.Spectrum(0.0)
    here = si
    if attached.motion:  # ---- the vertex re-attached, following its ray ----
        here, segment = _moving_vertex(mi, setup, attached, hit, ray, v, depth, origin,
                                       origin_owner, tangents)
        terms += dr.select(v.valid & ~v.through, remaining_dl * segment, 0.0)
    # ---- The BSDF sample that continues the path, its own emitter hit and light sample ----
    turning = (attached.motion, owner_of(mi, winner, len(setup.scene.bodies)))
    terms += _continuation_term(mi, attached, turning, si, here, v, after, bsdf_ctx)
    return terms + _own_terms(mi, setup, attached, si, here, v, numbers, beta, t_rel, bsdf_ctx)


def _moving_vertex(mi, setup, attached, hit, ray, v, depth, origin, origin_owner, tangents):
    """This vertex, attached: the hit of its ray (the attached camera ray on the camera
    ray, else from the last vertex, attached by its tangents, along a direction fixed
    in that vertex's body) on its surface in the bodies' attached frames; and the
    length of the segment reaching it (from the lens on the camera ray)."""
    si, pi, winner = hit
    camera, camera_offset = attached.camera_ray()
    on_camera_ray = depth == 0
    start_point = attached.with_tangents(origin, tangents)
    d = dr.detach(ray.d)
    followed_ray = mi.Ray3f(start_point, attached.with_tangents(
        d, attached.turn_tangents(d, origin_owner)), ray.maxt, ray.time, ray.wavelengths)
    ray_a = dr.select(on_camera_ray, camera, followed_ray)
    here = surface_interaction(mi, setup.scene.static, attached.pose(), ray_a, pi, winner,
                               v.valid)
    segment = dr.select(on_camera_ray,
                        setup.modulation_weight.to_float32(camera_offset)
                        + dr.norm(here.p - camera.o), dr.norm(here.p - start_point))
    return here, segment


def _continuation_term(mi, attached, turning, si, here, v, after, bsdf_ctx):
    """The BSDF sample that continues the path from this vertex, ``after`` x Phi /
    detach(Phi): Phi the vertex's BSDF value times |cos| toward the sampled direction
    (turning with the vertex's body where it moves: ``turning`` = (whether anything
    moves, the vertex's owner); the next vertex follows it), ``after`` the
    contributions after this vertex (every one of them scales with Phi)."""
    bounced = v.valid & ~v.through & v.active_next
    d_next = dr.detach(si.to_world(v.bs.wo))
    if turning[0]:
        d_next = attached.with_tangents(d_next, attached.turn_tangents(d_next, turning[1]))
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
