"""Exact per-pixel truth from the analytic motion: depth and radial velocity.

For each pixel the ray from the camera centre through the pixel centre is traced once,
against the static scene and every body at its pose at mid-exposure (the renderer's
own :func:`dopplertof.scene.bodies.intersect`). At the hit p with geometric normal n,
on a body whose relative motion is Rel(t):

* depth: |p - o|, the distance from the camera centre o along the ray (m);
* surface velocity u = dRel/dt (t_mid) Rel(t_mid)^-1 p, by a central difference of the
  analytic motion in float64 (dt = 1e-6 of the exposure);
* radial velocity, what the modulation phase follows: the rate of change of the
  distance s along the fixed ray to the surface, ds/dt = (u . n) / (d . n) (d the ray
  direction). From n(t) . (o + s(t) d - q(t)) = 0 for a point q moving with the
  surface: the terms from the turning normal cancel at q = p, so this holds for
  rotating bodies too. It differs from u . d (also returned) when a surface slides
  along itself.

With a moving camera (an <animation> on the sensor) the ray is the pixel's ray at
mid-exposure and velocities are relative to the camera: see :func:`ground_truth`.

Pixels that hit nothing are NaN. Static surfaces seen by a static camera move at 0.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


@dataclass
class GroundTruth:
    depth: np.ndarray  #: (H, W) float64, m from the camera centre along the pixel-centre ray
    velocity: np.ndarray  #: (H, W) radial velocity ds/dt = (u . n) / (d . n), m/s, > 0 receding
    velocity_point: np.ndarray  #: (H, W) u . d, the hit point's velocity along the ray, m/s
    body: np.ndarray  #: (H, W) int: index of the body hit, -1 static, -2 nothing
    direction: np.ndarray  #: (H, W, 3) ray directions (unit)
    normal: np.ndarray  #: (H, W, 3) geometric normals at the hits
    time: float  #: the absolute time of the truth (mid-exposure), s
    camera_origin: np.ndarray  #: (3,) camera centre, m
    #: (H, W) bool: footprints that see more than one surface (:func:`mixed_footprints`);
    #: None until a capture sets it
    mixed: np.ndarray | None = None


def camera_origin(scene) -> np.ndarray:
    from ..integrators.camera import rest_frame

    return rest_frame(scene.sensor)[:3, 3].copy()


def camera_forward(scene, camera, time: float) -> np.ndarray:
    """The sensor's viewing direction at ``time`` (unit, world space)."""
    from ..integrators.camera import rest_forward

    forward = rest_forward(scene.sensor)
    if camera is not None:
        forward = camera.relative_matrix(time)[:3, :3] @ forward
    return forward / np.linalg.norm(forward)


def mid_exposure(scene, params=None) -> tuple[float, float, float]:
    """(start, mid, end) of the exposure in absolute scene time (s)."""
    params = scene.params if params is None else params
    exposure = params.exposure(scene.shutter_interval)
    start = scene.shutter_open
    return start, start + 0.5 * exposure, start + exposure


def velocity_field(motion, time: float, exposure: float) -> np.ndarray:
    """The 4x4 matrix V (float64) that maps a world point moving with ``motion``, where
    it is at ``time``, to its velocity (m/s): V = dRel/dt Rel^-1, dRel/dt by a central
    difference of the analytic relative transform (dt = 1e-6 of ``exposure``)."""
    dt = 1e-6 * exposure
    now_inverse = np.linalg.inv(motion.relative_matrix(time))
    rate = (motion.relative_matrix(time + dt) - motion.relative_matrix(time - dt)) / (2 * dt)
    return rate @ now_inverse


def body_velocity(motion, points: np.ndarray, time: float, exposure: float) -> np.ndarray:
    """Velocity (m/s) of world points ``points`` (N, 3) moving with ``motion`` at ``time``,
    by a central difference of the analytic relative transform (float64)."""
    homogeneous = np.concatenate([points, np.ones((len(points), 1))], axis=1)
    return (homogeneous @ velocity_field(motion, time, exposure).T)[:, :3]


def ground_truth(scene, params=None) -> GroundTruth:
    """Depth and radial velocity at mid-exposure for every pixel of ``scene``'s film."""
    start, mid, end = mid_exposure(scene, params)
    width, height = (int(v) for v in scene.sensor.film().crop_size())
    camera = scene.sensor_motion
    p, n, ray_o, d, body = _trace_pixel_centres(scene, width, height, start, mid, end)
    hit = body > -2
    # ---- Depth: from the camera centre at mid-exposure (or its plane) ----
    centre = camera_origin(scene)
    if camera is not None:
        centre = (camera.relative_matrix(mid) @ np.append(centre, 1.0))[:3]
    origin = centre
    if ray_o is not None:
        # rays from different points (orthographic): each pixel's distance is measured
        # from where its ray crosses the camera's plane, as the renderer's path lengths
        forward = camera_forward(scene, camera, mid)
        origin = ray_o - (((ray_o - centre) @ forward) / (d @ forward))[:, None] * d
    depth = np.where(hit, np.linalg.norm(p - origin, axis=-1), np.nan)
    # ---- Velocities relative to the camera ----
    radial, point = _relative_velocities(scene, camera, body, p, n, d, origin, depth,
                                         mid, end - start)
    shape2 = (height, width)
    return GroundTruth(depth.reshape(shape2), radial.reshape(shape2), point.reshape(shape2),
                       body.reshape(shape2), d.reshape(height, width, 3),
                       n.reshape(height, width, 3), mid, centre)


def _as_numpy(v) -> np.ndarray:
    """A Dr.Jit 3-vector of N lanes as an (N, 3) float64 array."""
    return np.stack([np.asarray(v[i], dtype=np.float64) for i in range(3)], axis=-1)


#: film offsets (pixels) of the rays tried again where the pixel-centre ray hits nothing:
#: a centre ray can pass exactly through the crease of two meshes (the demo's
#: truth had a NaN at pixel (2, 125), on the closed box's edge where the ceiling meets a
#: wall); a ten-thousandth of a pixel to each side finds the surface there
CRACK_NUDGES = ((0.0, 0.0), (1e-4, 0.0), (-1e-4, 0.0), (0.0, 1e-4), (0.0, -1e-4))


def _trace_pixel_centres(scene, width: int, height: int, start: float, mid: float,
                         end: float):
    """The width x height pixel-centre rays of the camera at mid-exposure against the
    scene at its pose then: hit points p and geometric normals n (N, 3), the rays'
    origins (N, 3) where they differ between pixels (not a pinhole) else None, unit
    directions d (N, 3), and per pixel the body hit (index, -1 static, -2 nothing)."""
    import drjit as dr

    from ..backend import require_variant
    from ..integrators.camera import is_pinhole

    mi = require_variant()
    pinhole = is_pinhole(scene.sensor)
    out = None
    for nudge in CRACK_NUDGES:
        ray, si, body = _trace(mi, scene, *_pixel_centres(mi, width, height, mid, nudge),
                               start, end)
        dr.eval(si.p, si.n, ray.d, body)
        p, n = _as_numpy(si.p), _as_numpy(si.n)
        d = np.broadcast_to(_as_numpy(ray.d), p.shape).copy()  # (parallel rays: one direction)
        d /= np.linalg.norm(d, axis=-1, keepdims=True)
        ray_o = None if pinhole else np.broadcast_to(_as_numpy(ray.o), p.shape).copy()
        traced = [p, n, ray_o, d, np.asarray(body, dtype=np.int64)]
        if out is None:
            out = traced
        else:  # a centre ray that missed takes the nudged ray's hit
            filled = (out[4] == -2) & (traced[4] != -2)
            for kept, new in zip(out, traced):
                if kept is not None:
                    kept[filled] = new[filled]
        if not np.any(out[4] == -2):
            break
    return tuple(out)


def _pixel_centres(mi, width: int, height: int, time: float, nudge=(0.0, 0.0)):
    """(film positions, times) of the width x height pixel centres (moved by ``nudge``
    pixels) at ``time``, normalized over the crop window as Mitsuba's sensors take them."""
    import drjit as dr

    from ..scene.motion import lane_times

    index = dr.arange(mi.UInt32, width * height)
    position = mi.Point2f((mi.Float(index % width) + (0.5 + nudge[0])) / width,
                          (mi.Float(index // width) + (0.5 + nudge[1])) / height)
    return position, lane_times(mi, time, width * height)


def trace_pixels(scene, time: float, params=None, nudge=(0.0, 0.0)) -> dict:
    """The pixel-centre rays (moved by ``nudge`` pixels) of a static camera against the
    scene posed at ``time``: (H, W) arrays ``body`` (index, -1 static, -2 nothing) and
    ``depth`` (m from the camera centre, NaN: no hit), (H, W, 3) ``point``, ``normal``
    (geometric), ``shading_normal`` and ``direction`` (unit). For the truth over the
    exposure (:mod:`.exposure_truth`)."""
    import drjit as dr

    from ..backend import require_variant

    mi = require_variant()
    start, _, end = mid_exposure(scene, params)
    width, height = (int(v) for v in scene.sensor.film().crop_size())
    ray, si, body = _trace(mi, scene, *_pixel_centres(mi, width, height, time, nudge),
                           start, end)
    dr.eval(si.p, si.n, si.sh_frame.n, ray.d, body)
    p = _as_numpy(si.p)
    d = np.broadcast_to(_as_numpy(ray.d), p.shape).copy()
    d /= np.linalg.norm(d, axis=-1, keepdims=True)
    body = np.asarray(body, dtype=np.int64)
    depth = np.where(body > -2, np.linalg.norm(p - camera_origin(scene), axis=-1), np.nan)
    shape2, shape3 = (height, width), (height, width, 3)
    return {"body": body.reshape(shape2), "depth": depth.reshape(shape2),
            "point": p.reshape(shape3), "normal": _as_numpy(si.n).reshape(shape3),
            "shading_normal": _as_numpy(si.sh_frame.n).reshape(shape3),
            "direction": d.reshape(shape3)}


def radial_velocity_at(scene, hit: dict, time: float, exposure: float) -> np.ndarray:
    """(H, W) radial velocity (u . n) / (d . n) at ``time`` of the hits of
    :func:`trace_pixels` (a static camera; NaN where the ray hits nothing)."""
    shape2 = hit["body"].shape
    flat = {k: v.reshape(-1, 3) if v.ndim == 3 else v.ravel() for k, v in hit.items()}
    radial, _ = _relative_velocities(scene, None, flat["body"], flat["point"], flat["normal"],
                                     flat["direction"], camera_origin(scene), flat["depth"],
                                     time, exposure)
    return radial.reshape(shape2)


def surface_albedo(scene, params=None) -> np.ndarray:
    """(H, W) the diffuse reflectance (mean over channels) of the surface each pixel
    centre sees at mid-exposure, what ambient light reflects (cameras/radiometry.py); 0
    for BSDFs without a diffuse part, NaN where the ray hits nothing."""
    import drjit as dr

    from ..backend import require_variant

    mi = require_variant()
    start, mid, end = mid_exposure(scene, params)
    width, height = (int(v) for v in scene.sensor.film().crop_size())
    ray, si, _ = _trace(mi, scene, *_pixel_centres(mi, width, height, mid), start, end)
    valid = si.is_valid()
    reflectance = si.bsdf(ray).eval_diffuse_reflectance(si, valid)
    dr.eval(reflectance, valid)
    channels = np.asarray(reflectance, np.float64).reshape(-1, width * height)
    value = channels.mean(axis=0)
    value = np.where(np.asarray(valid, bool), value, np.nan)
    return value.reshape(height, width)


def _trace(mi, scene, position, time, start: float, end: float):
    """The camera's rays through film positions ``position`` at the lanes' times against
    the scene posed then: (rays, surface interactions, the body hit per lane: index, -1
    static, -2 nothing)."""
    import drjit as dr

    from ..integrators.camera import Camera, LensDistortion
    from ..scene.bodies import BodyFrames, intersect

    lens = LensDistortion.of(scene.sensor, scene.lens_distortion)
    ray, _, _ = Camera(mi, scene.sensor, scene.sensor_motion,
                       distortion=lens).ray(position, time,
                                                                  mi.Point2f(0.5, 0.5))
    frames = BodyFrames(mi, scene.bodies, time, start, end) if scene.bodies else None
    si = intersect(mi, scene.static, frames, ray, mi.Bool(True))
    body = dr.select(si.is_valid(), mi.Int32(-1), mi.Int32(-2))
    for k, moving in enumerate(scene.bodies):
        for shape in moving.scene.shapes():
            # (an opaque pointer: a shape's registry id is no literal of the kernel)
            body = dr.select(si.is_valid() & (si.shape == dr.opaque(mi.ShapePtr, shape)),
                             k, body)
    return ray, si, body


#: spacing of the footprint samples (pixels) of :func:`mixed_footprints`: a quarter pixel,
#: 5 x 5 over the box filter's pixel (edge to edge), 17 x 17 over a radius-2 gaussian's
FOOTPRINT_SPACING = 0.25

#: at most this many rays per footprint kernel (rows of pixels at a time): a few hundred MB
FOOTPRINT_LANES = 1 << 22

#: neighbouring footprint samples on one body whose depths differ by more than this
#: fraction of the nearer see an occluding edge, not one surface: on a continuous
#: surface they differ by about the samples' angle x tan(incidence), under 20% up to 87
#: degrees of incidence at 16 pixels over 40 degrees of field of view (88.6 at 64)
FOOTPRINT_DEPTH_JUMP = 0.2


def mixed_footprints(scene, params=None) -> np.ndarray:
    """(H, W) bool: the pixels whose filter footprint sees more than one surface during
    the exposure. At the exposure's start, middle and end, the rays through a grid of
    samples :data:`FOOTPRINT_SPACING` apart over the film filter's reach (the box
    filter's: the pixel, edges included) hit different bodies (a moving body and the
    static scene, another body, or nothing), or neighbouring samples' depths jump by
    more than :data:`FOOTPRINT_DEPTH_JUMP` (an occluding edge, of one body or of the
    static scene). Such a pixel's captures mix two surfaces' phases and brightness: its
    velocity and depth are neither surface's (a silhouette of the starter sphere reads
    -500 to -900 m/s). Shapes of one motion meeting at a crease (two walls in a corner)
    are one surface here: one velocity and a continuous depth, as a curved surface."""
    from ..integrators.film import _filter_of

    width, height = (int(v) for v in scene.sensor.film().crop_size())
    reach = _filter_of(scene.sensor.film())[1]
    samples = int(math.ceil(2 * reach / FOOTPRINT_SPACING - 1e-9)) + 1
    offsets = np.linspace(-reach, reach, samples)
    rows = max(1, FOOTPRINT_LANES // (width * samples * samples))
    mixed = np.zeros((height, width), bool)
    for first in range(0, height, rows):  # ---- a block of rows at a time ----
        last = min(height, first + rows)
        mixed[first:last] = _mixed_rows(scene, params, width, height, first, last, offsets)
    return mixed


def _mixed_rows(scene, params, width: int, height: int, first: int, last: int, offsets):
    """:func:`mixed_footprints` of the pixel rows first .. last - 1 ((rows, W) bool), with
    the footprint samples at ``offsets`` (pixels) from the pixel centre in x and y."""
    import drjit as dr

    from ..backend import aligned_host_array, require_variant
    from ..scene.motion import lane_times

    mi = require_variant()
    samples = len(offsets)
    # ---- Film positions: every pixel's grid of footprint samples, pixel-major ----
    sx, sy = (a.ravel() for a in np.meshgrid(offsets, offsets))
    py, px = (a.ravel() for a in np.mgrid[first:last, 0:width] + 0.5)
    x = ((px[:, None] + sx[None, :]) / width).ravel()
    y = ((py[:, None] + sy[None, :]) / height).ravel()
    position = mi.Point2f(mi.Float(aligned_host_array(x, np.float32)),
                          mi.Float(aligned_host_array(y, np.float32)))
    # ---- Traced at the exposure's start, middle and end ----
    mixed = np.zeros(px.size, bool)
    start, _, end = mid_exposure(scene, params)
    for instant in (start, 0.5 * (start + end), end):
        _, si, body = _trace(mi, scene, position, lane_times(mi, instant, x.size),
                             start, end)
        dr.eval(si.t, body)
        body = np.asarray(body, np.int64).reshape(-1, sx.size)
        mixed |= body.min(axis=1) != body.max(axis=1)
        depth = np.where(body > -2, np.asarray(si.t, np.float64).reshape(body.shape), np.nan)
        mixed |= _depth_jump(depth.reshape(-1, samples, samples))
    return mixed.reshape(last - first, width)


def _depth_jump(depth) -> np.ndarray:
    """(N,) bool: an (N, S, S) grid of depths per pixel (NaN: nothing hit) has two
    neighbouring samples, along a row or a column, more than FOOTPRINT_DEPTH_JUMP of the
    nearer apart."""
    jump = np.zeros(depth.shape[0], bool)
    with np.errstate(invalid="ignore"):
        for a, b in ((depth[:, 1:, :], depth[:, :-1, :]), (depth[:, :, 1:], depth[:, :, :-1])):
            step = np.abs(a - b) > FOOTPRINT_DEPTH_JUMP * np.fmin(a, b)
            jump |= step.reshape(depth.shape[0], -1).any(axis=1)
    return jump


def _relative_velocities(scene, camera, body, p, n, d, origin, depth, mid: float,
                         exposure: float):
    """Per pixel, relative to the camera: the radial velocity ds/dt of the distance s
    (``depth``) along the ray and the hit point's velocity along the ray u . d (NaN
    where the ray hits nothing)."""
    hit = body > -2
    u = np.zeros_like(p)
    for k, moving in enumerate(scene.bodies):
        on = body == k
        if on.any():
            u[on] = body_velocity(moving.motion, p[on], mid, exposure)
    # A moving camera: relative to it, with its origin moving at u_o and the pixel's ray
    # turning at d' = W d, the distance s along the ray changes at
    # (n . (u - u_o) - s n . d') / (n . d)  (the terms of a turning normal cancel at the hit).
    u_origin = np.zeros(3)
    d_rate = np.zeros_like(d)
    if camera is not None:
        u_origin = body_velocity(camera, np.atleast_2d(origin), mid, exposure)
        u_origin = u_origin[0] if origin.ndim == 1 else u_origin
        d_rate = body_velocity(camera, origin + d, mid, exposure) - u_origin
    s_along = np.where(hit, depth, 0.0)[:, None]
    with np.errstate(divide="ignore", invalid="ignore"):
        radial = (np.sum((u - u_origin) * n, axis=-1) - np.sum(s_along * d_rate * n, axis=-1)) \
            / np.sum(d * n, axis=-1)
    radial = np.where(hit, radial + 0.0, np.nan)  # + 0.0: no -0 on static surfaces
    point = np.where(hit, np.sum((u - u_origin) * d, axis=-1) + 0.0, np.nan)
    return radial, point


#: a light is at the camera when its position is within this fraction of the scene's
#: size (the diagonal of the static scene's bounding box with the camera in it)
COLOCATION_FRACTION = 1e-4


def scene_size(scene) -> float:
    """The diagonal of the bounding box of the static scene and the camera centre (m;
    1 when it has no extent)."""
    box = scene.static.bbox()
    origin = camera_origin(scene)
    lo, hi = origin.copy(), origin.copy()
    if box.valid():
        lo = np.minimum(lo, np.asarray(box.min, np.float64).reshape(3))
        hi = np.maximum(hi, np.asarray(box.max, np.float64).reshape(3))
    size = float(np.linalg.norm(hi - lo))
    return size if size > 0 else 1.0


def emitter_position(emitter):
    """The world position (3,) of a light that has one (a point light's ``position``, a
    spot light's to_world origin), else None (area and environment lights)."""
    import mitsuba as mi

    params = mi.traverse(emitter)
    if "position" in params:
        return np.array(params["position"], dtype=np.float64).reshape(-1)[:3]
    if emitter.class_name() == "SpotLight" and "to_world" in params:
        matrix = np.array(params["to_world"].matrix, dtype=np.float64).reshape(4, 4)
        return matrix[:3, 3].copy()
    return None


def light_colocation(scene, tolerance: float | None = None) -> dict:
    """Whether every emitter is a point or spot light at the camera centre (then the path
    length is twice the distance and v = L' / 2 exactly), within ``tolerance`` (m;
    default :data:`COLOCATION_FRACTION` of :func:`scene_size`)."""
    origin = camera_origin(scene)
    if tolerance is None:
        tolerance = COLOCATION_FRACTION * scene_size(scene)
    lights = []
    for emitter in scene.static.emitters():
        entry = {"type": emitter.class_name()}
        position = emitter_position(emitter)
        if position is not None:
            entry["offset_from_camera_m"] = float(np.linalg.norm(position - origin))
        lights.append(entry)
    colocated = all(e.get("offset_from_camera_m", np.inf) <= tolerance for e in lights)
    return {"colocated": bool(colocated), "lights": lights, "tolerance_m": float(tolerance)}
