"""The lidar's beam (docs/fmcw.md section 2): "flood", the scene's emitters
light the whole view (the D-ToF captures' light); or "collimated", each pixel its own beam
from the camera centre along its rays, of radiant intensity I (W/sr) within the pixel's
cone, and no other light.

A collimated beam lights the pixel's footprint: as a point light of intensity I at the
camera centre restricted to the pixel's cone. Its light reaches the pixel directly (the
first surface the pixel sees, lit at I cos / r^2: the direct return, path length twice its
distance) or through a first bounce off a point x_s of the footprint, which each lane draws
on its own: a beam ray through its own uniform film position in the pixel (stream
numbers trace.DIMENSIONS' "beam_film"), independent of the lane's path. Seen from a vertex x_k of
the path (the first surface included) x_s is a small source of radiant intensity
I a cos^3(theta) f_r(x_s) |cos_w| toward w, its irradiance I cos_s / r_s^2 times the
footprint's area per pixel r_s^2 a cos^3(theta) / cos_s (a = f^-2, a pixel's area on the
plane z = 1, theta the beam ray's angle to the camera's axis), so x_k gets that times
|cos_k| / |x_s - x_k|^2, unoccluded. (Connecting to the lane's own first hit instead would
integrate only the diagonal of the footprint's pairs: biased unless the footprint is a
point.) The path is the beam's leg (camera centre to x_s), the connection, and the lane's
path from x_k back to the camera; its rate sums the three legs' rates. Undistorted pinhole
cameras, the splat film's uniform film positions.
"""

from __future__ import annotations

import drjit as dr

from ..scene.bodies import nearest_hit, surface_interaction
from ..fmcw_settings import BEAMS, beam_intensity_problem


class Beam:
    """The beam of a render: :attr:`collimated`, its intensity and, collimated, the
    film's pixel area seen from the camera centre and the camera's forward direction."""

    def __init__(self, mi, scene, kind: str = "flood", intensity: float = 1.0,
                 time: float = 0.0):
        from ..integrators.camera import is_pinhole, pinhole_intrinsics
        from ..tof.ground_truth import camera_forward

        if kind not in BEAMS:
            raise ValueError(f"beam must be one of {', '.join(BEAMS)}, got {kind!r}")
        problem = beam_intensity_problem(intensity, "beam intensity")
        if problem:
            raise ValueError(problem)
        self.mi = mi
        self.collimated = kind == "collimated"
        self.intensity = float(intensity)
        if self.collimated:
            sensor = scene.sensor
            if not is_pinhole(sensor) or getattr(scene, "lens_distortion", None) is not None:
                raise ValueError("a collimated beam needs an undistorted pinhole camera, got "
                                 f"{sensor.class_name()}")
            width, height = (int(v) for v in sensor.film().size())
            focal = pinhole_intrinsics(width, height,
                                       float(mi.traverse(sensor)["x_fov"][0]))[0, 0]
            self.pixel_area = float(1.0 / focal ** 2)  #: a pixel's area on the plane z = 1
            self.forward = mi.Vector3f(*map(float, camera_forward(
                scene, scene.sensor_motion, time)))

    def start(self, mi, setup, layout, streams, dim: int, time, frames, fields):
        """Each lane's spot x_s (None when the beam floods), through its uniform film
        position in the pixel (the lane's numbers at dimension ``dim``): its interaction
        (wi toward the camera), velocity, the beam leg's length and rate, and the
        footprint's power per unit of f_r |cos|, I a cos^3(theta), zero where the beam
        ray hits nothing."""
        if not self.collimated:
            return None
        width, height = setup.scene.sensor.film().crop_size()
        u = streams.get_2d(0, dim)
        pos = mi.Point2f((mi.Float(layout.pixel % width) + u.x) / width,
                         (mi.Float(layout.pixel // width) + u.y) / height)
        ray, _, offset = setup.camera.ray(pos, time, mi.Point2f(0.5))
        pi, winner = nearest_hit(mi, setup.scene.static, frames, ray, mi.Bool(True))
        si = surface_interaction(mi, setup.scene.static, frames, ray, pi, winner, mi.Bool(True))
        u_spot = fields.at_surface(si.p, winner)
        cosine = dr.dot(ray.d, self.forward)
        power = dr.select(si.is_valid(), (self.intensity * self.pixel_area) * cosine * cosine
                          * cosine, 0.0)
        return (si, u_spot, offset + si.t, dr.dot(ray.d, u_spot - fields.camera), power)

    def direct(self, si, ray, v, beta, depth, rate_hit, ctx):
        """The first surface's direct return: (value, path length, rate, active)."""
        mi = self.mi
        bsdf = si.bsdf(ray)
        active = (depth == 0) & v.active_next & mi.has_flag(bsdf.flags(), mi.BSDFFlags.Smooth)
        value = beta * bsdf.eval(ctx, si, si.to_local(-ray.d), active) * (
            self.intensity / dr.square(v.length_hit))
        return value, 2.0 * v.length_hit, 2.0 * rate_hit, active

    def spot_light(self, spot, depth, max_depth, ctx):
        """What ``shade`` takes for its light sample at a hit of depth ``depth`` (None
        when the beam floods): a function ``(si, active) -> (ds, weight)`` giving the
        lane's spot x_s as a point source of radiant intensity power f_r(x_s) |cos|
        toward the hit, weight that over the squared distance; ds.pdf 0 (no shadow ray)
        where the path would have more than ``max_depth`` segments (the spot adds two),
        the footprint is empty or the hit is the spot. So ``shade``'s own shadow ray and
        BSDF evaluation serve the connection, as they serve a light sample (neither
        the scene's lights are sampled, nor a second BSDF evaluated at the hit)."""
        if not self.collimated:
            return None
        mi = self.mi
        xs, _, _, _, power = spot

        def light(si, active):
            to_spot = xs.p - si.p
            distance = dr.norm(to_spot)
            ds = dr.zeros(mi.DirectionSample3f)
            ds.p, ds.n, ds.time, ds.dist = xs.p, xs.n, si.time, distance
            ds.d = to_spot / dr.maximum(distance, 1e-30)
            lit = active & (depth + 2 < max_depth) & (power > 0.0) & (distance > 0.0)
            ds.pdf, ds.delta = dr.select(lit, 1.0, 0.0), mi.Bool(True)
            there = xs.bsdf().eval(ctx, xs, xs.to_local(-ds.d), lit)
            return ds, there * (power / dr.square(distance))

        return light

    def from_spot(self, v, spot, rate_hit, u_here):
        """Vertex ``v``'s light from the lane's spot (its light sample, drawn by
        :meth:`spot_light`; the hit moving at ``u_here``, reached at dL/dt
        ``rate_hit``): (value, path length, rate, active)."""
        _, u_spot, leg, leg_rate, _ = spot
        rate = rate_hit + dr.dot(v.em_sample.d, u_spot - u_here) + leg_rate
        return v.em_value, v.length_em + leg, rate, v.active_em
