"""Exact references by quadrature for a diffuse plane moving along the optical axis.

Camera at the origin looking along +z, a point light of intensity I at the camera,
a diffuse plane of albedo rho facing the camera at depth z(t) = z0 + v t. For a
direction d = (a, b, 1) / |(a, b, 1)| through the film point (a, b) of the near
plane (uniform over the pixel's square), the plane is hit at range r = z / d_z,
its radiance toward the camera is rho I d_z^3 / (pi z^2) (the light's cosine and
inverse square law) and the path length is 2 r. The pixel value is the mean over
the film square and the exposure of radiance * g1 * C(theta) (low-pass) or of
radiance * s(t) g(t - 2r/c) (full waveform).
"""

from __future__ import annotations

import math

import numpy as np

from dopplertof.modulation import SPEED_OF_LIGHT, correlation

RHO = 0.5
INTENSITY = 10.0
FOV = 4.0  # degrees: one pixel covering [-s, s]^2 on the z=1 plane, s = tan(fov/2)


def plane_scene(z0: float, velocity: float, exposure: float = 0.0015, spp: int = 4096,
                integrator: dict | None = None, res: int = 1, camera_velocity: float = 0.0,
                light_velocity: float | None = None) -> dict:
    """The moving-plane scene as a dopplertof dict scene.

    ``camera_velocity`` moves the camera along +z, with the light on it unless
    ``light_velocity`` moves the light along z on its own.
    """
    import mitsuba as mi

    import dopplertof

    T = mi.ScalarTransform4f
    plane = lambda z: T().translate([0, 0, z]).rotate([0, 1, 0], 180).scale(50)  # noqa: E731
    camera = lambda z: T().look_at(origin=[0, 0, z], target=[0, 0, z + 1], up=[0, 1, 0])  # noqa: E731
    scene = {
        "type": "scene",
        "integrator": {"type": "dopplertof", "max_depth": 2, **(integrator or {})},
        "sensor": {
            "type": "perspective", "fov": FOV, "near_clip": 0.01,
            "to_world": T().look_at(origin=[0, 0, 0], target=[0, 0, 1], up=[0, 1, 0]),
            "shutter_open": 0.0, "shutter_close": exposure,
            "film": {"type": "hdrfilm", "width": res, "height": res,
                     "rfilter": {"type": "box"}, "pixel_format": "rgb"},
            "sampler": {"type": "independent", "sample_count": spp},
        },
        "light": {"type": "point", "position": [0, 0, 0],
                  "intensity": {"type": "rgb", "value": INTENSITY}},
        "white": {"type": "diffuse", "reflectance": {"type": "rgb", "value": RHO}},
        "plane": {"type": "rectangle", "bsdf": {"type": "ref", "id": "white"},
                  "to_world": dopplertof.Animation([(0.0, plane(z0)),
                                                    (exposure, plane(z0 + velocity * exposure))])},
    }
    if camera_velocity:
        scene["sensor"]["to_world"] = dopplertof.Animation(
            [(0.0, camera(0.0)), (exposure, camera(camera_velocity * exposure))])
    if light_velocity is not None:
        scene["light"] = {"type": "point", "intensity": {"type": "rgb", "value": INTENSITY},
                          "to_world": dopplertof.Animation(
                              [(0.0, T()), (exposure, T().translate([0, 0, light_velocity
                                                                     * exposure]))])}
    elif camera_velocity:
        scene["light"] = {"type": "point", "intensity": {"type": "rgb", "value": INTENSITY},
                          "to_world": dopplertof.Animation.follow_sensor()}
    return scene


def _film_grid(n_space, film=None):
    """Quadrature nodes (A, B) over the pixel's film on the z = 1 plane, their weights W
    (summing to 1) and the ray directions' z components. ``film``: the pixel's film
    weights as ((a, wa), (b, wb)), nodes in units of the half-width s of the whole film
    and weights summing to one (``filtered_axis``); by default Gauss-Legendre over the
    1-pixel film [-s, s]^2 (its mean)."""
    s = math.tan(math.radians(FOV) / 2)
    if film is None:
        xs, ws = np.polynomial.legendre.leggauss(n_space)
        film = ((xs, ws / 2), (xs, ws / 2))  # mean over [-s, s]
    (xa, wa), (xb, wb) = film
    A, B = np.meshgrid(s * np.asarray(xa), s * np.asarray(xb), indexing="ij")
    return A, B, np.outer(wa, wb), 1 / np.sqrt(A**2 + B**2 + 1)


def analytic_approximation(z0: float, velocity: float, *, exposure=0.0015, w_g=30.0,
                           hetero_frequency=0.0, hetero_offset=0.0, g1=0.5, n_space=12,
                           n_time=96) -> float:
    """The pixel value of ``time_sampling_method="analytic"`` (static camera and light),
    by quadrature of its definition: per film point, the paths at t = 0 and t = T give
    lengths L1, L2 and values C1, C2; the value is the mean over the exposure of
    C1 (1 + (C2/C1 - 1) t/T) g1 0.5 cos(omega_d t + psi + omega_g L(t) / c) with L(t)
    linear from L1 to L2 (numerical in t, independent of the renderer's closed form)."""
    A, B, W, dz = _film_grid(n_space)
    k = 2 * math.pi * w_g * 1e6 / SPEED_OF_LIGHT
    omega_d = 2 * math.pi * hetero_frequency / exposure
    psi = 2 * math.pi * hetero_offset
    z1, z2 = z0, z0 + velocity * exposure
    L1, L2 = 2 * z1 / dz, 2 * z2 / dz  # camera to plane and back (light at the camera)
    C1 = RHO * INTENSITY * dz**3 / (math.pi * z1**2)
    C2 = RHO * INTENSITY * dz**3 / (math.pi * z2**2)
    xt, wt = np.polynomial.legendre.leggauss(n_time)
    total = 0.0
    for t, w in zip(exposure * (xt + 1) / 2, wt / 2):
        s = t / exposure
        theta = omega_d * t + psi + k * (L1 + (L2 - L1) * s)
        total += w * np.sum(W * C1 * (1 + (C2 / C1 - 1) * s) * g1 * 0.5 * np.cos(theta))
    return float(total)


def reference(z0: float, velocity: float, *, exposure=0.0015, w_g=30.0, hetero_frequency=0.0,
              hetero_offset=0.0, waveform="sinusoidal", g0=0.5, g1=0.5, low_pass=True,
              n_space=12, n_time=96, camera_velocity=0.0, light_velocity=None,
              film=None) -> float:
    """The exact pixel value by Gauss-Legendre quadrature (tensor rule); ``film`` as in
    :func:`_film_grid`."""
    A, B, W, dz = _film_grid(n_space, film)
    omega_g = 2 * math.pi * w_g * 1e6
    omega_d = 2 * math.pi * hetero_frequency / exposure
    psi = 2 * math.pi * hetero_offset
    total = 0.0
    if low_pass:
        xt, wt = np.polynomial.legendre.leggauss(n_time)
        times = exposure * (xt + 1) / 2
        wts = wt / 2
    else:  # resolve every modulation period: composite midpoint rule
        n = int(w_g * 1e6 * exposure * 24)
        times = (np.arange(n) + 0.5) * exposure / n
        wts = np.full(n, 1.0 / n)
    for t, wt in zip(times, wts):
        cam = camera_velocity * t
        light = cam if light_velocity is None else light_velocity * t
        r_cam = (z0 + velocity * t - cam) / dz
        px, py, pz = A * dz * r_cam, B * dz * r_cam, z0 + velocity * t
        r_light = np.sqrt(px**2 + py**2 + (pz - light) ** 2)
        cos_light = (pz - light) / r_light
        radiance = RHO * INTENSITY * cos_light / (math.pi * r_light**2)
        L = r_cam + r_light
        if low_pass:
            m = g1 * correlation(waveform, omega_d * t + psi + omega_g * L / SPEED_OF_LIGHT)
        else:
            from dopplertof.modulation import wave

            m = wave(waveform, (omega_g + omega_d) * t + psi) * (
                g0 + g1 * wave(waveform, omega_g * (t - L / SPEED_OF_LIGHT)))
        total += wt * np.sum(W * radiance * m)
    return float(total)


def homodyne_amplitude(z0: float, velocity: float, **motion) -> float:
    """The size every sample of the plane's pixel stays within, heterodyne or not: the
    homodyne signal's amplitude, hypot of its values at offsets 0 and 1/4."""
    return math.hypot(*(reference(z0, velocity, hetero_frequency=0.0, hetero_offset=o,
                                  **motion) for o in (0.0, 0.25)))


def filter_1d(kind: str, x):
    """Mitsuba's reconstruction filters on one axis (default radii), x in pixels."""
    x = np.abs(x)
    if kind == "box":
        return (x < 0.5).astype(float)
    if kind == "tent":
        return np.maximum(0.0, 1.0 - x)
    sigma, radius = 0.5, 2.0
    return np.maximum(0.0, np.exp(-x**2 / (2 * sigma**2)) - np.exp(-radius**2 / (2 * sigma**2)))


def filtered_axis(kind: str, res: int, k: int, nodes: int = 8):
    """Film weights on one axis of pixel ``k`` of a ``res``-pixel film: the filter
    around the pixel's centre restricted to the film [0, res], normalized, as nodes in
    units of the film's half-width and weights summing to one (Gauss-Legendre on every
    half pixel, where the filters are smooth)."""
    radius = {"box": 0.5, "tent": 1.0, "gaussian": 2.0}[kind]
    centre = k + 0.5
    lo, hi = max(0.0, centre - radius), min(float(res), centre + radius)
    xs, ws = np.polynomial.legendre.leggauss(nodes)
    edges = np.arange(lo, hi + 1e-9, 0.5)
    x = np.concatenate([(a + b) / 2 + (b - a) / 2 * xs for a, b in zip(edges, edges[1:])])
    w = np.concatenate([(b - a) / 2 * ws for a, b in zip(edges, edges[1:])])
    w = w * filter_1d(kind, x - centre)
    return 2 * x / res - 1, w / w.sum()
