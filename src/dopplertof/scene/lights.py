"""Moving point and spot lights: next-event estimation at each lane's time.

A moving light stays in the static scene at its rest pose (its first keyframe, or the
camera's for a light that follows the camera). To sample it at time t, the shading
point is moved into the light's rest frame by the inverse of the light's motion
Rel(t), the stock emitter samples a direction there, and the sample is moved back by
Rel(t). Rigid motion keeps distances, so the sampled radiance and the path length of
the contribution stay valid. Static lights go through the same code with the identity.
"""

from __future__ import annotations

from .motion import select_transform, transform_normal, transform_point, transform_vector, vec3


class LightFrames:
    """Per-lane transforms of the moving lights at the lanes' times."""

    def __init__(self, mi, light_motions, time):
        self.indices = [index for index, _ in light_motions]
        self.to_world, self.to_local = [], []
        for _, motion in light_motions:
            rel, inv = motion.relative(time)
            self.to_world.append(rel)
            self.to_local.append(inv)


def sample_emitter_direction(mi, scene, frames: LightFrames, si, sample, active):
    """Like ``Scene.sample_emitter_direction`` without visibility, with moving lights."""
    import drjit as dr

    index, selection_weight, sample_x = scene.sample_emitter(sample.x, active)
    emitter = dr.gather(mi.EmitterPtr, scene.emitters_dr(), index, active)
    masks = [index == k for k in frames.indices]
    to_world = select_transform(mi, dr, masks, frames.to_world)
    to_local = select_transform(mi, dr, masks, frames.to_local)

    # ---- The shading point, seen from the light's rest pose ----
    ref = mi.Interaction3f(si.t, si.time, si.wavelengths,
                           vec3(mi, mi.Point3f, transform_point(to_local, si.p)),
                           dr.normalize(vec3(mi, mi.Normal3f, transform_normal(to_world, si.n))))
    ds, weight = emitter.sample_direction(ref, mi.Point2f(sample_x, sample.y), active)

    # ---- Back to the world at the lane's time ----
    ds.p = vec3(mi, mi.Point3f, transform_point(to_world, ds.p))
    ds.d = dr.normalize(vec3(mi, mi.Vector3f, transform_vector(to_world, ds.d)))
    ds.n = dr.normalize(vec3(mi, mi.Normal3f, transform_normal(to_local, ds.n)))
    ds.pdf *= scene.pdf_emitter(index, active)
    return ds, weight * selection_weight
