"""The adjoint pass of reverse-mode gradients by path replay
(:func:`dopplertof.diff.gradient` with ``method="path"``).

A lane's value is a sum of contributions C_j, one per emitter hit and light sample of
its path. The primal pass gives each lane that sum M and the sum M_L of the
contributions' derivatives with respect to their path lengths
(``trace(layout, length_derivative=True)``). This pass traces the same paths again
(the same random numbers, nothing attached) and, at each vertex, differentiates only
what is local to it, weighted by the lane's adjoint delta (d loss / d lane value):

* the segment that reaches the vertex: its length adds to the path length of every
  contribution at or after the vertex, delta . (M_L - prefix) x length;
* the transition into the vertex (the previous vertex's BSDF value toward it and the
  geometry term): every contribution at or after the vertex scales with it,
  delta . (M - prefix) x Phi / detach(Phi);
* the vertex's own emitter hit and light sample: their emission, BSDF value, light
  sample weight and modulation weight.

The camera ray's vertices (before the first bounce) follow the camera ray, since a
pixel integrates over film positions; the vertices after the first bounce keep their
places on their surfaces (x(theta) = T_theta(t) T_theta0(t)^-1 x for a body's points,
static points stay): both are the integrand's derivatives at fixed random numbers, so
nothing propagates along a path, and memory does not grow with its length. Forward
mode (and the trajectory method) let every vertex follow its ray instead: the two
agree in expectation, and per sample wherever no vertex after the first bounce moves
(reflectances, emission, the modulation; light samples, which are points on the
lights either way). For the motion of indirectly lit bodies they differ per sample,
and this one is far noisier: the derivative of the geometry term 1/r^2 between two
vertices grows without bound where they meet (docs/differentiable.md, "Path replay").
"""

from __future__ import annotations

from dataclasses import dataclass

import drjit as dr

from ..scene.bodies import BodyFrames, nearest_hit, surface_interaction
from ..scene.motion import select_transform, transform_point, transform_vector, vec3
from .path_steps import (advance, contributions, length_derivatives, loop_settings,
                         sample_light, shade, survive, vertex_numbers)


class AttachedLane:
    """What a lane's vertices are re-attached with, recomputed inside the loop from its
    detached inputs (so that gradients reach the width-1 parameters directly, not
    per-lane copies of them): the camera ray at the lane's film position and time,
    the bodies' frames at its time, and their detached frames."""

    def __init__(self, mi, setup, start, motion: bool):
        self.mi, self.setup = mi, setup
        self.motion = motion  #: whether anything the vertices' places depend on is attached
        self.time, self.position, self.lens = start.time, start.film_position, start.lens
        self.frames = start.frames  #: detached BodyFrames (None without bodies)
        self.light_frames = start.light_frames  #: the lights' frames (not differentiated)
        self.emitters_hit = emitters_hit(mi, setup.scene.static)  #: (emitters_hit)

    def camera_ray(self):
        """(attached camera ray, attached path length from the lens to its origin)."""
        ray, _, offset = self.setup.camera.ray(self.position, self.time, *self.lens)
        return ray, offset

    def pose(self):
        """(the bodies' attached frames at the lanes' times, their moves): per body the
        attached rigid map from its detached pose to its attached one, (R, b): x -> R x
        + b (R None: a translation), by which its points, normals and frames move (a
        VelocityMotion's linear part is a rotation times a fixed base, so R is a
        rotation). (None, None) without bodies."""
        setup = self.setup
        if self.frames is None:
            return None, None
        moved = BodyFrames(self.mi, setup.scene.bodies, self.time, setup.shutter_open,
                           setup.shutter_open + setup.modulation.exposure)
        moves = []
        for (A, b), (IA, ib) in zip(moved.to_world, self.frames.to_local):
            R = None if A is None and IA is None else _matmul3(A, IA)
            moves.append((R, transform_point((A, b), ib)))
        return moved, moves

    def move_of(self, moves, winner):
        """Per lane, the move of the scene ``winner`` names (identity: static)."""
        if moves is None:
            return None
        return select_transform(self.mi, dr, [winner == k for k in range(len(moves))], moves)


def emitters_hit(mi, scene) -> bool:
    """Whether a path can hit one of ``scene``'s emitters (not only point, spot or
    directional lights)."""
    return any(not mi.has_flag(e.flags(), mi.EmitterFlags.DeltaPosition)
               and not mi.has_flag(e.flags(), mi.EmitterFlags.DeltaDirection)
               for e in scene.emitters())


def _matmul3(A, B):
    """A B of 3x3 linear parts (None: the identity)."""
    if A is None or B is None:
        return B if A is None else A
    return [[A[i][0] * B[0][j] + A[i][1] * B[1][j] + A[i][2] * B[2][j] for j in range(3)]
            for i in range(3)]


def material_interaction(mi, si, move):
    """``si`` (world, detached) as a material point of its body, moved with it by
    ``move`` (AttachedLane.move_of; None: nothing moves)."""
    if move is None:
        return si
    si = mi.SurfaceInteraction3f(si)
    si.p = vec3(mi, mi.Point3f, transform_point(move, si.p))
    si.n = vec3(mi, mi.Normal3f, transform_vector(move, si.n))
    si.sh_frame = mi.Frame3f(vec3(mi, mi.Vector3f, transform_vector(move, si.sh_frame.s)),
                             vec3(mi, mi.Vector3f, transform_vector(move, si.sh_frame.t)),
                             vec3(mi, mi.Normal3f, transform_vector(move, si.sh_frame.n)))
    return si


def material_point(mi, p, move):
    """A world point ``p`` (detached) moved with its body by ``move``."""
    return p if move is None else vec3(mi, mi.Point3f, transform_point(move, p))


def tangent_point(mi, moved, n, move, camera_ray):
    """A camera-ray vertex as the camera ray's hit of its moving tangent plane (exact to
    first order, as the vertex follows the ray): ``moved``, its point moved with its
    body (material_point), ``n`` its geometric normal, moved here by ``move``."""
    normal = n if move is None else vec3(mi, mi.Normal3f, transform_vector(move, n))
    t = dr.dot(normal, moved - camera_ray.o) / dr.dot(normal, camera_ray.d)
    return camera_ray.o + t * camera_ray.d


@dr.syntax
def adjoint_paths(mi, setup, layout, streams, start, delta, total, total_dl, motion=True):
    """Trace each lane's path again and back-propagate ``delta`` (per lane, the
    variant's Spectrum: d loss / d lane value) through each vertex's local terms;
    ``total`` and ``total_dl`` are the primal pass's sums M and M_L; ``motion``: whether
    any motion (a body's, the camera's) is attached (else the vertices stay as traced).
    Returns nothing: the gradients are the loop's side effects (``dr.eval()`` runs it;
    evaluating a loop value as well would run the loop a second time)."""
    static = setup.scene.static
    modulation = setup.modulation_weight
    t_rel, ray, frames, light_frames = start.t_rel, start.ray, start.frames, start.light_frames
    attached = AttachedLane(mi, setup, start, motion)
    u_em_first = streams.first_hit_2d(0, layout.group, layout.index, setup.groups_per_pixel)
    u_dir_first = streams.first_hit_2d(1, layout.group, layout.index, setup.groups_per_pixel)

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
    last = LastVertex.zeros(mi)  # the last scattering vertex (none yet)
    before = LastVertex.zeros(mi)  # the one before it
    bsdf_ctx = mi.BSDFContext()

    max_depth, max_iterations, rr_depth, hide_direct_emitters = loop_settings(mi, setup)
    while dr.hint(going != 0, max_iterations=max_iterations, label="dopplertof_adjoint"):
        active = going != 0
        # ---- The vertex, traced as the primal pass traced it ----
        pi, winner = nearest_hit(mi, static, frames, ray, active, coherent=depth == 0)
        si = surface_interaction(mi, static, frames, ray, pi, winner, active)
        numbers = vertex_numbers(streams, depth, u_em_first, u_dir_first)
        v = shade(mi, static, frames, light_frames, ray, si, active, depth, beta, length,
                  prev_si, prev_bsdf_pdf, prev_bsdf_delta != 0, numbers, max_depth,
                  hide_direct_emitters, modulation.F, bsdf_ctx)

        # ---- Its local terms, attached, back-propagated at once ----
        with dr.resume_grad():
            local = _local_terms(mi, setup, attached, (si, pi, winner), v, numbers, depth,
                                 beta, t_rel, (total - prefix, total_dl - prefix_dl), last,
                                 before, bsdf_ctx)
            dr.backward_from(_dot(delta, local), flags=dr.ADFlag.AllowNoGrad)
        hit_contribution, light_contribution = contributions(modulation, v, t_rel)
        prefix += hit_contribution  # (summed as the primal pass sums them)
        prefix += light_contribution
        prefix_dl += length_derivatives(modulation, v, t_rel)

        # ---- Continue the path (as the primal pass) ----
        bounced = v.valid & ~v.through
        before = dr.select(bounced, last, before)
        last = dr.select(bounced, LastVertex.of(mi, si, pi, winner, depth), last)
        length = v.length_hit
        ray, beta, eta, prev_si, prev_bsdf_pdf, delta_lobe, depth = advance(
            mi, si, ray, v, beta, eta, prev_si, prev_bsdf_pdf, prev_bsdf_delta != 0, depth)
        prev_bsdf_delta = mi.UInt32(dr.select(delta_lobe, 1, 0))
        beta, going = survive(mi, v, beta, eta, depth, rr_depth, numbers[3])


@dataclass
class LastVertex:
    """A scattering vertex of the path, detached, as the loop keeps it: its interaction,
    its hit and the scene it is in (to follow the camera ray again), and whether it
    lies on the camera ray (before the first bounce: 1)."""

    si: object  #: mi.SurfaceInteraction3f (world)
    pi: object  #: mi.PreliminaryIntersection3f
    winner: object  #: mi.UInt32, the scene it is in (nearest_hit)
    on_camera_ray: object  #: mi.UInt32

    @classmethod
    def zeros(cls, mi):
        return cls(dr.zeros(mi.SurfaceInteraction3f), dr.zeros(mi.PreliminaryIntersection3f),
                   mi.UInt32(0), mi.UInt32(1))

    @classmethod
    def of(cls, mi, si, pi, winner, depth):
        return cls(mi.SurfaceInteraction3f(si), mi.PreliminaryIntersection3f(pi),
                   mi.UInt32(winner), mi.UInt32(dr.select(depth == 0, 1, 0)))


def _local_terms(mi, setup, attached, hit, v, numbers, depth, beta, t_rel, suffix, last,
                 before, bsdf_ctx):
    """The vertex's local terms (Spectrum, attached): d/d theta of their dot product with
    delta is the vertex's share of d loss / d theta (see the module docstring)."""
    si, pi, winner = hit
    remaining, remaining_dl = suffix  # the contributions at or after this vertex
    terms = mi.Spectrum(0.0)
    if attached.motion:  # ---- vertices that move: attached, with the segment's length ----
        here, last_a, wi_last, segment = _moving_vertices(
            mi, setup, attached, hit, v, depth, last, before)
        terms += dr.select(v.valid & ~v.through, remaining_dl * segment, 0.0)
    else:  # ---- nothing moves: the vertices as traced ----
        here, last_a = si, mi.SurfaceInteraction3f(last.si)
        wi_last = last_a.to_world(last_a.wi)

    # ---- The transition into it, and its own emitter hit and light sample ----
    terms += _transition_term(mi, (here, last_a), wi_last, depth, v.valid, remaining,
                              bsdf_ctx)
    return terms + _own_terms(mi, setup, attached, si, here, v, numbers, beta, t_rel, bsdf_ctx)


def _moving_vertices(mi, setup, attached, hit, v, depth, last, before):
    """This vertex and the last scattering one, attached (at most one of them lies on the
    camera ray, so one interaction follows it), the direction the last one was reached
    from, and the length of the segment reaching this one (from the lens on the camera
    ray)."""
    si, pi, winner = hit
    moved, moves = attached.pose()
    camera, camera_offset = attached.camera_ray()
    on_camera_ray = depth == 0
    first = mi.PreliminaryIntersection3f(dr.select(on_camera_ray, pi, last.pi))
    followed = surface_interaction(mi, setup.scene.static, moved, camera, first,
                                   dr.select(on_camera_ray, winner, last.winner),
                                   v.valid & (depth <= 1))
    last_a = dr.select(depth == 1, followed,
                       material_interaction(mi, last.si, attached.move_of(moves, last.winner)))
    here = dr.select(on_camera_ray, followed,
                     material_interaction(mi, si, attached.move_of(moves, winner)))
    here.wi = dr.select(on_camera_ray, here.wi,
                        here.to_local(dr.normalize(last_a.p - here.p)))
    before_move = attached.move_of(moves, before.winner)
    before_moved = material_point(mi, before.si.p, before_move)
    before_a = dr.select(before.on_camera_ray != 0,
                         tangent_point(mi, before_moved, before.si.n, before_move, camera),
                         before_moved)
    wi_last = dr.select(depth == 1, -camera.d, dr.normalize(before_a - last_a.p))
    segment = dr.select(on_camera_ray,
                        setup.modulation_weight.to_float32(camera_offset)
                        + dr.norm(here.p - camera.o), dr.norm(here.p - last_a.p))
    return here, last_a, wi_last, segment


def _transition_term(mi, vertices, wi_last, depth, valid, remaining, bsdf_ctx):
    """The transition into this vertex, ``remaining`` x Phi / detach(Phi): Phi the last
    vertex's BSDF value toward it (reached from ``wi_last``, world) times the geometry
    term |cos| / r^2 at this vertex (``vertices``: this one and the last, attached)."""
    here, last_a = vertices
    to_here = here.p - last_a.p
    wo_last = dr.normalize(to_here)
    last_a.wi = last_a.to_local(wi_last)
    transition = (depth > 0) & valid
    phi = (last_a.bsdf().eval(bsdf_ctx, last_a, last_a.to_local(wo_last), transition)
           * dr.abs(dr.dot(here.n, wo_last)) / dr.squared_norm(to_here))
    base = dr.detach(phi)
    return dr.select(transition & (base > 0.0),
                     remaining * phi / dr.select(base > 0.0, base, 1.0), 0.0)


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
