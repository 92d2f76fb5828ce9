"""A capture's camera geometry: ``camera.json`` (intrinsics, lens
distortion, pose, resolution, units) and ``pointcloud.ply`` (the camera's depth
unprojected into the world).

Conventions are OpenCV's: camera axes x right, y down, z forward; pixel (u, v) covers
[u, u + 1] x [v, v + 1] with its centre at (u + 0.5, v + 0.5); a pose maps camera to world
(its columns: the right, down and forward axes and the centre). Mitsuba's own camera frame
is x left, y up: ``pose @ diag(-1, -1, 1, 1)`` is the sensor's to_world.
"""

from __future__ import annotations

import numpy as np

#: OpenCV's camera axes from Mitsuba's (x left, y up -> x right, y down); its own inverse
MITSUBA_TO_OPENCV = np.diag([-1.0, -1.0, 1.0, 1.0])
#: camera.json's conventions, said once
CONVENTION = ("OpenCV: camera x right, y down, z forward; pixel (u, v) centre at (u + 0.5, "
              "v + 0.5), (0, 0) the top-left corner; poses map camera to world (columns: "
              "right, down, forward axes and the centre); Brown-Conrady distortion "
              "(k1, k2, p1, p2, k3) of normalized coordinates as OpenCV's; depth.npy is the "
              "range along each pixel's (distorted) ray")
UNITS = {"K": "px", "distortion_k1_k2_p1_p2_k3": "1", "pose_camera_to_world":
         "m (translation; the rotation is unitless)", "time_s": "s", "window_s": "s",
         "resolution": "px"}


def camera_pose(scene, time: float) -> np.ndarray:
    """Camera-to-world (4x4, OpenCV axes, unit axes: a sensor's scale, an orthographic
    camera's extent, is left out) of ``scene``'s sensor at absolute ``time`` (s)."""
    from ..integrators.camera import rest_frame

    frame = rest_frame(scene.sensor)
    if scene.sensor_motion is not None:
        frame = scene.sensor_motion.relative_matrix(time) @ frame
    frame[:3, :3] = frame[:3, :3] / np.linalg.norm(frame[:3, :3], axis=0)
    return frame @ MITSUBA_TO_OPENCV


def intrinsics(scene) -> dict:
    """K, the lens distortion and the resolution of ``scene``'s pinhole (another sensor,
    an orthographic one: K None and its ``projection`` named)."""
    import mitsuba as mi

    from ..integrators.camera import is_pinhole, pinhole_intrinsics

    width, height = (int(v) for v in scene.sensor.film().size())
    out = {"resolution": [width, height], "projection": scene.sensor.class_name(),
           "distortion_k1_k2_p1_p2_k3": list(scene.lens_distortion or (0.0,) * 5),
           "convention": CONVENTION, "K": None}
    if is_pinhole(scene.sensor):
        fov = float(mi.traverse(scene.sensor)["x_fov"][0])
        out.update(K=pinhole_intrinsics(width, height, fov).tolist(), fov_x_deg=fov)
    return out


def camera_geometry(scene, time: float, frames=()) -> dict:
    """camera.json's content: :func:`intrinsics`, the pose at ``time`` (mid-exposure,
    where the truth is) and, per raw frame, ``frames`` = [(name, (start, end) s)] its
    window and its pose at the window's middle."""
    out = intrinsics(scene)
    out.update(time_s=float(time), pose_camera_to_world=camera_pose(scene, time).tolist(),
               units=dict(UNITS))
    if frames:
        out["frames"] = [{"name": name, "window_s": [float(a), float(b)],
                          "time_s": 0.5 * (a + b),
                          "pose_camera_to_world": camera_pose(scene, 0.5 * (a + b)).tolist()}
                         for name, (a, b) in frames]
    return out


def pixel_rays(geometry: dict) -> np.ndarray:
    """(H, W, 3) unit rays (camera axes) through the pixel centres, the lens distortion
    undone as the renderer does (:class:`dopplertof.integrators.camera.LensDistortion`)."""
    from types import SimpleNamespace

    from ..integrators.camera import LensDistortion

    width, height = geometry["resolution"]
    K = np.asarray(geometry["K"], np.float64)
    u, v = np.meshgrid((np.arange(width) + 0.5) / width, (np.arange(height) + 0.5) / height)
    film = SimpleNamespace(x=u, y=v)
    if any(geometry["distortion_k1_k2_p1_p2_k3"]):
        lens = LensDistortion(geometry["distortion_k1_k2_p1_p2_k3"], width, height,
                              geometry["fov_x_deg"])
        film = lens.undistort(SimpleNamespace(Point2f=lambda x, y: SimpleNamespace(x=x, y=y)),
                              film)
    rays = np.stack([(film.x * width - K[0, 2]) / K[0, 0],
                     (film.y * height - K[1, 2]) / K[1, 1], np.ones_like(film.x)], -1)
    return rays / np.linalg.norm(rays, axis=-1, keepdims=True)


def point_cloud(geometry: dict, depth, amplitude, velocity, velocity_gt) -> dict:
    """pointcloud.ply's columns, one vertex per pixel in row-major order (vertex k is
    pixel (k mod W, k div W)): x, y, z (world, m, the pose at mid-exposure), nx, ny, nz
    (the normal of the neighbouring points' central differences, turned towards the
    camera; NaN in an image one pixel wide or high: no neighbours to span a surface),
    radial_velocity and radial_velocity_gt (m/s, > 0 receding), amplitude and
    valid (1 where the camera reports a depth; x, y, z and the normal NaN elsewhere). A
    ValueError for a sensor without K (not a pinhole)."""
    if geometry.get("K") is None:
        raise ValueError(f"pointcloud.ply needs a pinhole perspective camera, not a "
                         f"{geometry.get('projection')}: run without --pointcloud")
    pose = np.asarray(geometry["pose_camera_to_world"], np.float64)
    depth = np.asarray(depth, np.float64)
    camera_points = depth[..., None] * pixel_rays(geometry)
    points = camera_points @ pose[:3, :3].T + pose[:3, 3]
    du, dv = _differences(camera_points, 1), _differences(camera_points, 0)
    normal = np.cross(du, dv)
    normal /= np.linalg.norm(normal, axis=-1, keepdims=True)
    normal *= np.where(np.sum(normal * camera_points, -1, keepdims=True) > 0, -1.0, 1.0)
    normal = normal @ pose[:3, :3].T
    nan = np.full(depth.shape, np.nan)
    columns = {"x": points[..., 0], "y": points[..., 1], "z": points[..., 2],
               "nx": normal[..., 0], "ny": normal[..., 1], "nz": normal[..., 2],
               "radial_velocity": nan if velocity is None else velocity,
               "radial_velocity_gt": velocity_gt, "amplitude": amplitude}
    out = {k: np.asarray(v, np.float32).ravel() for k, v in columns.items()}
    out["valid"] = np.isfinite(depth).ravel().astype(np.uint8)
    return out


def _differences(points, axis: int) -> np.ndarray:
    """The central differences of ``points`` along ``axis`` (one-sided at the ends),
    NaN where the axis has a single pixel."""
    if points.shape[axis] < 2:
        return np.full(points.shape, np.nan)
    return np.gradient(points, axis=axis)


def write_camera_files(path, geometry: dict, pointcloud: bool, depth, amplitude, velocity,
                       velocity_gt) -> None:
    """camera.json at ``path("camera.json")`` and, with ``pointcloud``, pointcloud.ply
    (binary little-endian: :func:`point_cloud` of the other arguments)."""
    from .. import file_formats

    file_formats.write_json(path("camera.json"), geometry)
    if pointcloud:
        file_formats.write_ply(path("pointcloud.ply"),
                     point_cloud(geometry, depth, amplitude, velocity, velocity_gt),
                     comment="dopplertof capture: one vertex per pixel, row-major")
