"""Motion-compensated antithetic pairs: a path-space antithetic mapping (supplementary
section 4).

Random-number replay pairs a sample x = (film position, t0, rest of the path) with
T_r(x) = (same film position, t1, same rest): near a moving silhouette one sample meets
the body and the other the wall behind it, and the pair no longer cancels. The motion
mapping T_m keeps the primal's first hit point fixed on its body (in the body's own
frame; static surfaces are a body that does not move) and aims the partner's camera
ray at where that point is at t1:

    T_m(pos0, t0, rest) = (pos1, t1, rest),   pos1 = film position of the point at t1.

T_m is an involution where it is *valid* (V): the primal hits a surface, pos1 lies in
the support of the pixel's reconstruction filter, and the camera ray through pos1 at t1
meets the same point first. Its Jacobian is J = |d pos1 / d pos0| = D(t1) / D(t0), D
the film area per unit body area (``PinholeProjection.film_density``).

Estimator (per pair; W the density of the film positions: the filter for the
``importance`` film; for the ``splat`` film the pixel's own cell, uniform, the filter
then being part of the integrand, which each lane evaluates at its own position):
with the balance heuristic between the primal and the mapped strategy (section 4.1),
whose weights for x and T_m(x) are the same number w = W0 / (W0 + J W1),

    <I> = w (f(x) + J (W1 / W0) f(T_m x)) / p(x)  ->  lane scales 2 w and 2 w J W1 / W0

(so that the mean over the two lanes is the pair estimate; J = 1, W1 = W0 gives the
plain pair average). Where V fails the partner falls back to replay, which covers
what T_m cannot reach. For the two together to count every sample once (the trap of
section 4.2 is two mappings that overlap), a replayed partner z = T_r(x) counts only
when z itself is not the image of a valid mapping, i.e. when V(T_r x) fails too: then
the pair is a plain replay pair (scales 1, 1); otherwise the primal counts alone
(scales 2, 0). Every sample y is then weighted once in total:

    V(y):                 w(y) + (1 - w(y))                = 1
    not V(y), not V(T_r y): 1/2 + 1/2                     = 1
    not V(y), V(T_r y):     1                              = 1

T_r and T_m must be involutions: shifted antithetic with shift 1/2, or mirrored.
"""

from __future__ import annotations

import drjit as dr

from ..scene.bodies import BodyFrames, body_transforms, nearest_hit
from ..scene.motion import determinant3, transform_normal, transform_point, transformed_ray

#: a mapped ray meets "the same point" within this fraction of the distance to it
SAME_POINT_TOLERANCE = 1e-4


class _Hit:
    """A camera ray's first hit, with the point in the frame of the scene it is in."""

    def __init__(self, mi, static, frames, ray, active, skip_idle=False):
        self.mi = mi
        self.pi, self.winner = nearest_hit(mi, static, frames, ray, active, skip_idle,
                                           coherent=True)
        self.valid = active & self.pi.is_valid()
        to_local, _ = body_transforms(mi, frames, self.winner)
        self.local_ray = transformed_ray(mi, to_local, ray, ray.maxt)  # t is kept
        self.local = [self.local_ray.o[i] + self.pi.t * self.local_ray.d[i] for i in range(3)]
        self.distance = self.pi.t  # camera ray directions are unit vectors

    def same_point(self, other) -> object:
        """Whether ``other`` (a hit at another time) met this hit's point."""
        Vector3f = self.mi.Vector3f
        gap = dr.norm(Vector3f(*self.local) - Vector3f(*other.local))
        return (self.valid & other.valid & (self.winner == other.winner)
                & (gap <= SAME_POINT_TOLERANCE * self.distance))


def _world(mi, frames, winner, local):
    _, to_world = body_transforms(mi, frames, winner)
    return transform_point(to_world, local), to_world


class PairedCameraRays:
    """Per lane: its camera ray, first hit and weight; see the module notes.

    ``t0``/``t1``: absolute times of the pair's primal (index 0) and partner (index 1);
    ``pos``: the pair's shared film position; ``center``: the pixel centre (normalized
    film coordinates); ``window``: the crop window seen from the centre (pixels, lo and
    hi); ``crop_size``: (width, height) of the crop window in pixels (film positions
    are normalized over it).
    """

    def __init__(self, mi, scene, camera, projection, film_sampler, pos, center, window,
                 crop_size, t0, t1, index, lens, exposure_interval):
        static, bodies = scene.static, scene.bodies
        frames = {0: BodyFrames(mi, bodies, t0, *exposure_interval) if bodies else None,
                  1: BodyFrames(mi, bodies, t1, *exposure_interval) if bodies else None}
        times = {0: t0, 1: t1}

        def filter_weight(p):
            return film_sampler.weight(mi, mi.Vector2f((p.x - center.x) * crop_size[0],
                                                       (p.y - center.y) * crop_size[1]),
                                       *window)

        def hit_at(p, k, active, skip_idle=True):
            ray = camera.ray(p, times[k], *lens)
            return ray, _Hit(mi, static, frames[k], ray[0], active, skip_idle)

        def follow(hit, k, active):
            """T_m: the film position of ``hit``'s point at time k, the camera ray and hit
            there, and whether that hit is the same point (V)."""
            p, _ = _world(mi, frames[k], hit.winner, hit.local)
            p_film, in_front = projection.film_position(p, times[k])
            ray, hit_k = hit_at(p_film, k, active & hit.valid & in_front
                                & (filter_weight(p_film) > 0.0))
            return p_film, ray, hit_k, hit.same_point(hit_k)

        # ---- Primal x: the shared film position at t0; its point followed to t1 ----
        ray0, hit0 = hit_at(pos, 0, mi.Bool(True), skip_idle=False)
        pos1, ray1, hit1, valid = follow(hit0, 1, mi.Bool(True))

        # ---- Fallback: replay T_r(x), and whether that sample is itself mapped ----
        ray_r, hit_r = hit_at(pos, 1, ~valid)
        _, _, _, replay_is_mapped = follow(hit_r, 0, ~valid)

        # ---- Jacobian of the film-position map, D(t1) / D(t0) ----
        si0 = hit0.pi.compute_surface_interaction(hit0.local_ray, mi.RayFlags.Minimal, valid)
        n_local = [si0.n[i] for i in range(3)]
        density = []
        for k in (0, 1):
            p, to_world = _world(mi, frames[k], hit0.winner, hit0.local)
            to_local, _ = body_transforms(mi, frames[k], hit0.winner)
            density.append(projection.film_density(
                p, transform_normal(to_local, n_local), determinant3(to_world[0]), times[k]))
        J = density[1] / density[0]  # finite except at grazing angles (measure zero)
        W0, W1 = filter_weight(pos), filter_weight(pos1)
        w = W0 / (W0 + J * W1)  # balance heuristic: the same for x and T_m(x)

        # ---- This lane's share ----
        primal = index == 0
        use1 = ~primal & valid
        self.ray, self.weight, self.offset = (dr.select(primal, a, dr.select(use1, b, c))
                                              for a, b, c in zip(ray0, ray1, ray_r))
        self.position = dr.select(primal, pos, dr.select(use1, pos1, pos))  # film
        self.pi = dr.select(primal, hit0.pi, dr.select(use1, hit1.pi, hit_r.pi))
        self.winner = dr.select(primal, hit0.winner,
                                dr.select(use1, hit1.winner, hit_r.winner))
        scale_mapped = dr.select(primal, 2.0 * w, 2.0 * w * J * W1 / W0)
        scale_replay = dr.select(replay_is_mapped, dr.select(primal, 2.0, 0.0), 1.0)
        self.scale = dr.select(valid, scale_mapped, scale_replay)
