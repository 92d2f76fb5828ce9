"""Camera rays at a lane's time, and (pinhole cameras) the way back: world point to film.

Rays start at the lens point of the sensor's pose at the lane's time (a moving camera
is its rest pose moved by its motion). Path lengths are measured from the lens point,
not from the near clip plane where Mitsuba's perspective rays start.
"""

from __future__ import annotations

import math

import numpy as np

from ..scene.motion import opaque_tree, transform_point, transform_vector, transformed_ray

#: the sensor plugin whose rays all leave one point (the pinhole)
PINHOLE_CLASS = "PerspectiveCamera"


def is_pinhole(sensor) -> bool:
    return sensor.class_name() == PINHOLE_CLASS


def rest_frame(sensor) -> np.ndarray:
    """The sensor's rest pose, camera to world (4x4, float64): its centre is column 3,
    its viewing direction column 2 (Mitsuba's cameras look along local +z)."""
    return np.array(sensor.world_transform().matrix, dtype=np.float64).reshape(4, 4, -1)[..., 0]


def rest_forward(sensor) -> np.ndarray:
    """The sensor's viewing direction at rest (unit, world space)."""
    forward = rest_frame(sensor)[:3, 2]
    return forward / np.linalg.norm(forward)


def pinhole_intrinsics(width: int, height: int, fov_x_deg: float) -> np.ndarray:
    """K (3x3, pixels) of a pinhole whose horizontal field of view is ``fov_x_deg``: pixel
    (i, j) covers [i, i + 1] x [j, j + 1], its centre at (i + 0.5, j + 0.5)."""
    import math

    focal = 0.5 * width / math.tan(math.radians(fov_x_deg) / 2)
    return np.array([[focal, 0.0, 0.5 * width], [0.0, focal, 0.5 * height], [0.0, 0.0, 1.0]])


class LensDistortion:
    """Brown-Conrady distortion of a pinhole's rays, OpenCV's model.

    In normalized image coordinates (x, y) = ((u - c_x) / f, (v - c_y) / f) of pixel
    coordinates (u, v) (x right, y down; K of focal length f = W / (2 tan(fov_x / 2))
    and centre (W / 2, H / 2)), an undistorted ray (x, y) images at

        x_d = x (1 + k1 r^2 + k2 r^4 + k3 r^6) + 2 p1 x y + p2 (r^2 + 2 x^2)
        y_d = y (1 + k1 r^2 + k2 r^4 + k3 r^6) + p1 (r^2 + 2 y^2) + 2 p2 x y,  r^2 = x^2 + y^2.

    A pixel of the distorted image is rendered with the ray of the undistorted position
    that images there: :meth:`undistort` inverts the map by fixed-point iteration."""

    ITERATIONS = 20  #: fixed-point steps (converged to float32 for |k1 r^2| under 0.3)
    INVERSE_TOLERANCE_PX = 1e-3  #: the inverse's largest reprojection error over an image

    def __init__(self, coefficients, width: int, height: int, fov_x_deg: float):
        self.k1, self.k2, self.p1, self.p2, self.k3 = (float(c) for c in coefficients)
        focal = pinhole_intrinsics(width, height, fov_x_deg)[0, 0]
        self.sx, self.sy = width / focal, height / focal

    def undistort(self, mi, pos):
        """Film positions (normalized, [0, 1]^2) of the distorted image -> those of the
        pinhole whose rays image there."""
        x, y = self.inverse((pos.x - 0.5) * self.sx, (pos.y - 0.5) * self.sy)
        return mi.Point2f(x / self.sx + 0.5, y / self.sy + 0.5)

    def inverse(self, xd, yd):
        """The undistorted normalized coordinates (x, y) that image at (xd, yd) (Dr.Jit
        or NumPy arrays): :data:`ITERATIONS` fixed-point steps."""
        x, y = xd, yd
        for _ in range(self.ITERATIONS):
            r2 = x * x + y * y
            radial = 1 + r2 * (self.k1 + r2 * (self.k2 + r2 * self.k3))
            x = (xd - (2 * self.p1 * x * y + self.p2 * (r2 + 2 * x * x))) / radial
            y = (yd - (self.p1 * (r2 + 2 * y * y) + 2 * self.p2 * x * y)) / radial
        return x, y

    def forward(self, x, y):
        """Where the undistorted normalized coordinates (x, y) image (the model above)."""
        r2 = x * x + y * y
        radial = 1 + r2 * (self.k1 + r2 * (self.k2 + r2 * self.k3))
        return (x * radial + 2 * self.p1 * x * y + self.p2 * (r2 + 2 * x * x),
                y * radial + self.p1 * (r2 + 2 * y * y) + 2 * self.p2 * x * y)

    def problem(self, width: int, height: int) -> str | None:
        """Why the map cannot be inverted over the width x height image, or None: the
        radial map r_d(r) = r (1 + k1 r^2 + k2 r^4 + k3 r^6) must rise monotonically
        until it reaches the image's corner radius (else rays fold back and no ray
        images at the corners), and the fixed-point inverse must reproduce every pixel
        edge and centre of the image to within :data:`INVERSE_TOLERANCE_PX`."""
        half_x, half_y = 0.5 * self.sx, 0.5 * self.sy
        corner = math.hypot(half_x, half_y)
        # r_d over r in steps of a thousandth of the corner radius, up to 100 times it
        r = np.arange(1, 100001) * (corner / 1000)
        r2 = r * r
        rd = r * (1 + r2 * (self.k1 + r2 * (self.k2 + r2 * self.k3)))
        reached = np.nonzero(rd >= corner)[0]
        end = reached[0] if reached.size else r.size
        if reached.size == 0 or np.any(np.diff(rd[:end + 1]) <= 0):
            return (f"the radial map r (1 + k1 r^2 + k2 r^4 + k3 r^6) does not rise "
                    f"monotonically to the image's corner radius {corner:.3g} (normalized "
                    "coordinates): rays fold back and the image cannot be undistorted")
        xd = np.linspace(-half_x, half_x, 2 * int(round(width)) + 1)
        yd = np.linspace(-half_y, half_y, 2 * int(round(height)) + 1)
        xd, yd = np.meshgrid(xd, yd)
        with np.errstate(all="ignore"):
            x, y = self.inverse(xd, yd)
            bx, by = self.forward(x, y)
            error = np.hypot(bx - xd, by - yd) * width / self.sx
        worst = float(np.nanmax(error)) if np.isfinite(error).all() else math.inf
        if not worst <= self.INVERSE_TOLERANCE_PX:
            return (f"its inverse does not converge over the image (a pixel's ray "
                    f"reprojects {worst:.3g} px off, more than "
                    f"{self.INVERSE_TOLERANCE_PX:g}): the rendered rays would not be the "
                    "model's")
        return None

    @classmethod
    def of(cls, sensor, coefficients):
        """The distortion of a pinhole ``sensor`` (None when every coefficient is 0)."""
        import mitsuba as mi

        if coefficients is None or not any(coefficients):
            return None
        if not is_pinhole(sensor):
            raise ValueError(f"lens distortion needs a pinhole perspective sensor, got "
                             f"{sensor.class_name()}")
        width, height = (int(v) for v in sensor.film().size())
        return cls(coefficients, width, height, float(mi.traverse(sensor)["x_fov"][0]))


class Camera:
    """Camera rays of one sensor, possibly moving (``motion``: a scene Motion or None),
    through a lens with ``distortion`` (LensDistortion or None)."""

    def __init__(self, mi, sensor, motion, near_clip: float = 0.0, forward=None,
                 distortion=None):
        self.mi = mi
        self.sensor = sensor
        self.motion = motion
        self.near_clip = near_clip
        self.forward = forward  # mi.Vector3f, rest pose (None: no near clip offset)
        self.distortion = distortion

    def ray(self, pos, time, u_aperture, u_wavelength=0.5):
        """World ray through film position ``pos`` (normalized over the crop window, as
        Mitsuba's sensors take it) at absolute ``time`` (``u_wavelength`` picks the
        wavelengths in spectral variants),
        its importance weight, and the path length from the lens point to its origin."""
        import drjit as dr

        if self.distortion is not None:
            pos = self.distortion.undistort(self.mi, pos)
        ray, weight = self.sensor.sample_ray(time, u_wavelength, pos, u_aperture)
        offset = (self.near_clip / dr.dot(ray.d, self.forward) if self.forward is not None
                  else self.mi.Float(0.0))
        if self.motion is not None:  # the ray of the rest pose, moved to the lane's time
            ray = transformed_ray(self.mi, self.motion.relative(time)[0], ray, ray.maxt,
                                  normalize=True)
        return ray, weight, offset


class PinholeProjection:
    """World point at a time -> normalized film position, for a pinhole perspective sensor.

    The film map is fitted to the sensor's own rays (so that it follows Mitsuba's fov,
    aspect and crop conventions): in camera coordinates a ray through film position
    (x, y) has direction proportional to ((x - b_x) / a_x, (y - b_y) / a_y, 1).
    """

    PROBES = ((0.5, 0.5), (0.9, 0.5), (0.5, 0.9), (0.2, 0.3))

    def __init__(self, mi, sensor, motion, near_clip: float):
        if not is_pinhole(sensor):
            raise ValueError(f"sensor {sensor.class_name()} is not a pinhole perspective camera")
        self.mi = mi
        self.motion = motion
        to_world = rest_frame(sensor)
        to_camera = np.linalg.inv(to_world)
        pos = mi.Point2f([p[0] for p in self.PROBES], [p[1] for p in self.PROBES])
        ray, _ = sensor.sample_ray(mi.Float(0.0), 0.5, pos, mi.Point2f(0.5, 0.5))
        d = to_camera[:3, :3] @ np.array(ray.d, dtype=np.float64).reshape(3, -1)
        slope = d[:2] / d[2]
        film = np.array(self.PROBES, dtype=np.float64).T
        a = (film[:, 1:3].diagonal() - film[:, 0]) / (slope[:, 1:3].diagonal() - slope[:, 0])
        b = film[:, 0] - a * slope[:, 0]
        if not np.allclose(a * slope[:, 3] + b, film[:, 3], atol=1e-4):
            raise ValueError("the sensor's rays do not follow a pinhole film map")
        f = to_world[:3, 2] / np.linalg.norm(to_world[:3, 2])
        # opaque values: one kernel for every camera pose and film map
        self.a, self.b, self.to_camera, self.center, self.forward = opaque_tree(
            mi.Float, [a.tolist(), b.tolist(), [to_camera[i].tolist() for i in range(3)],
                       to_world[:3, 3].tolist(), f.tolist()])
        self.near_clip = opaque_tree(mi.Float, float(near_clip))

    def _rest(self, v, time, point: bool):
        """World coordinates at ``time`` -> world coordinates of the camera's rest pose."""
        if self.motion is None:
            return v
        inverse = self.motion.relative(time)[1]
        return transform_point(inverse, v) if point else transform_vector(inverse, v)

    def film_position(self, p, time):
        """Normalized film position of world point ``p`` (list of 3) at ``time``, and
        whether the point lies in front of the near clip plane."""
        mi = self.mi
        p = self._rest(p, time, True)
        q = [sum(self.to_camera[i][k] * p[k] for k in range(3)) + self.to_camera[i][3]
             for i in range(3)]
        in_front = q[2] > self.near_clip
        z = mi.Float(q[2])
        return mi.Point2f(self.a[0] * q[0] / z + self.b[0],
                          self.a[1] * q[1] / z + self.b[1]), in_front

    def film_density(self, p, n, area_scale, time):
        """Film area per unit surface area at world point ``p`` with (unnormalized)
        world normal ``n`` at ``time``, up to a constant: |n . v| / (f . v)^3, v from the
        lens point to p, times ``area_scale`` (world area per reference area)."""
        import drjit as dr

        p = self._rest(p, time, True)
        n = self._rest(n, time, False)
        v = [p[i] - self.center[i] for i in range(3)]
        along = sum(self.forward[i] * v[i] for i in range(3))
        facing = dr.abs(sum(n[i] * v[i] for i in range(3)))
        return dr.abs(area_scale) * facing / (along * along * along)

