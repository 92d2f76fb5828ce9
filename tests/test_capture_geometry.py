"""Issue 41: every capture folder holds camera.json (K, distortion, poses, resolution,
units) and, with --pointcloud, pointcloud.ply, read here with plyfile.

Conventions written out (what the files promise, docs/cameras.md): OpenCV camera axes
(x right, y down, z forward); the ray of pixel (u, v) passes through (u + 0.5, v + 0.5),
normalize(inv(K) [u + 0.5, v + 0.5, 1]) without distortion; a pose maps camera to world,
x_world = R x_camera + t."""

import json

import numpy as np
import pytest

plyfile = pytest.importorskip("plyfile")

from test_cameras import SCENE_XML  # noqa: E402

#: the camera moves along +x at SPEED m/s; a plane at z = 3 turned 30 degrees about y
SPEED = 1.0
TILTED_PLANE = (SCENE_XML  # (test_cameras' plane, turned, seen by a moving camera)
                .replace('<float name="fov" value="6"/>', '<float name="fov" value="20"/>')
                .replace('<transform name="to_world"><lookat origin="0, 0, 0" target="0, 0, 1" '
                         'up="0, 1, 0"/></transform>',
                         '<animation name="to_world"><transform time="0"><lookat origin="0, 0, 0" '
                         'target="0, 0, 1" up="0, 1, 0"/></transform><transform time="0.1">'
                         '<lookat origin="0.1, 0, 0" target="0.1, 0, 1" up="0, 1, 0"/>'
                         '</transform></animation>')
                .replace('name="width" value="4"', 'name="width" value="7"')
                .replace('name="height" value="4"', 'name="height" value="5"')
                .replace('angle="180"', 'angle="210"'))
#: the plane's normal and a point on it
NORMAL, ON_PLANE = np.array([np.sin(np.radians(210)), 0.0, np.cos(np.radians(210))]), np.array(
    [0.0, 0.0, 3.0])


def _rays(camera):
    """Pixel-centre rays by the conventions above (no distortion)."""
    width, height = camera["resolution"]
    u, v = np.meshgrid(np.arange(width) + 0.5, np.arange(height) + 0.5)
    rays = np.stack([u, v, np.ones_like(u)], -1) @ np.linalg.inv(np.array(camera["K"])).T
    return rays / np.linalg.norm(rays, axis=-1, keepdims=True)


def _world(camera, pose, depth, rays):
    pose = np.asarray(pose)
    return (depth[..., None] * rays) @ pose[:3, :3].T + pose[:3, 3]


def test_capture_writes_camera_json_and_a_pointcloud_plyfile_reads(tmp_path, capsys):
    from dopplertof.cli import main

    scene = tmp_path / "plane.xml"
    scene.write_text(TILTED_PLANE)
    out = tmp_path / "out"
    assert main(["capture", str(scene), "--spp", "4", "-o", str(out), "--quiet",
                 "--pointcloud"]) == 0
    camera = json.loads((out / "camera.json").read_text())
    assert camera["resolution"] == [7, 5] and camera["units"]["K"] == "px"
    assert camera["distortion_k1_k2_p1_p2_k3"] == [0.0] * 5 and "frames" not in camera
    pose = np.array(camera["pose_camera_to_world"])
    # mid-exposure: the camera has moved SPEED * t; OpenCV axes: x right (world -x, the
    # camera looks down +z with +y up), y down, z forward
    np.testing.assert_allclose(pose[:3, 3], [SPEED * camera["time_s"], 0, 0], atol=1e-6)
    np.testing.assert_allclose(pose[:3, :3], np.diag([-1.0, -1.0, 1.0]), atol=1e-6)
    rays = _rays(camera)
    truth = np.load(out / "depth_gt.npy").astype(np.float64)
    on_plane = (_world(camera, pose, truth, rays) - ON_PLANE) @ NORMAL
    np.testing.assert_allclose(on_plane, 0.0, atol=2e-5)
    cloud = plyfile.PlyData.read(str(out / "pointcloud.ply"))["vertex"]
    names = [p.name for p in cloud.properties]
    assert names == ["x", "y", "z", "nx", "ny", "nz", "radial_velocity", "radial_velocity_gt",
                     "amplitude", "valid"]
    depth = np.load(out / "depth.npy").astype(np.float64)
    valid = np.isfinite(depth).ravel()
    assert valid.sum() > 20 and np.array_equal(cloud["valid"] == 1, valid)
    xyz = np.stack([cloud[a] for a in "xyz"], -1)
    np.testing.assert_allclose(xyz[valid], _world(camera, pose, depth, rays).reshape(-1, 3)[valid],
                               rtol=1e-5, atol=1e-5)
    np.testing.assert_array_equal(cloud["radial_velocity_gt"],
                                  np.load(out / "velocity_gt.npy").ravel().astype(np.float32))
    normals = np.stack([cloud[a] for a in ("nx", "ny", "nz")], -1)
    inside = np.isfinite(normals).all(-1)
    assert inside.sum() > 5  # (a plane: its points' normal, towards the camera)
    np.testing.assert_allclose(normals[inside] @ NORMAL, 1.0, atol=0.05)


def test_a_camera_capture_gives_the_pose_of_each_raw_frame_and_its_distortion(tmp_path):
    from dopplertof.cameras.preset import load_preset
    from dopplertof.cli import main
    from dopplertof.tof.geometry import pixel_rays

    scene = tmp_path / "plane.xml"
    scene.write_text(TILTED_PLANE)
    out = tmp_path / "out"
    # the Azure Kinect's preset with a lens (barrel distortion)
    text = open(load_preset("azure-kinect").source_file).read()
    lens = "distortion = [-0.25, 0.06, 0.002, -0.003, 0.01]"
    assert "distortion = [0.0, 0.0, 0.0, 0.0, 0.0]" in text
    (tmp_path / "lens.toml").write_text(text.replace("distortion = [0.0, 0.0, 0.0, 0.0, 0.0]",
                                                     lens))
    preset = load_preset(str(tmp_path / "lens.toml"))
    assert main(["capture", str(scene), "--camera", str(tmp_path / "lens.toml"), "--res",
                 "8x6", "--spp", "2", "-o", str(out), "--quiet"]) == 0
    camera = json.loads((out / "camera.json").read_text())
    assert camera["resolution"] == [8, 6] and not (out / "pointcloud.ply").exists()
    assert camera["distortion_k1_k2_p1_p2_k3"] == list(preset.distortion)
    frames = camera["frames"]
    assert [f["name"] for f in frames] == [f"raw_{k}" for k in range(len(preset.frames))]
    for frame in frames:
        a, b = frame["window_s"]
        assert frame["time_s"] == pytest.approx(0.5 * (a + b))
        np.testing.assert_allclose(np.array(frame["pose_camera_to_world"])[:3, 3],
                                   [SPEED * frame["time_s"], 0, 0], atol=1e-6)
    assert frames[0]["time_s"] < camera["time_s"] < frames[-1]["time_s"]
    # the truth along the distorted rays (pixel_rays undoes the distortion) lies on the plane
    truth = np.load(out / "depth_gt.npy").astype(np.float64)
    points = _world(camera, camera["pose_camera_to_world"], truth, pixel_rays(camera))
    np.testing.assert_allclose((points - ON_PLANE) @ NORMAL, 0.0, atol=1e-4)
    undistorted = _world(camera, camera["pose_camera_to_world"], truth, _rays(camera))
    assert np.abs((undistorted - ON_PLANE) @ NORMAL).max() > 1e-3  # (the distortion matters)


def test_an_orthographic_capture_has_no_k_and_refuses_a_pointcloud(tmp_path, capsys):
    """camera.json of an orthographic camera: K None, its projection named, a pose with
    unit axes (the sensor's scale, its extent, left out); --pointcloud is one line,
    exit 2, before anything renders."""
    from dopplertof.cli import main

    text = TILTED_PLANE.replace('<sensor type="perspective">\n        <float name="fov" value="20"/>',
                                '<sensor type="orthographic">').replace(
        'up="0, 1, 0"/></transform>', 'up="0, 1, 0"/><scale x="0.5" y="0.5"/></transform>')
    assert 'type="orthographic"' in text and "scale" in text
    scene = tmp_path / "ortho.xml"
    scene.write_text(text)
    out = tmp_path / "out"
    assert main(["capture", str(scene), "--spp", "4", "-o", str(out), "--quiet",
                 "--pointcloud"]) == 2
    err = capsys.readouterr().err.strip()
    assert "--pointcloud needs a pinhole" in err and len(err.splitlines()) == 1
    assert not out.exists()
    assert main(["capture", str(scene), "--spp", "4", "-o", str(out), "--quiet"]) == 0
    camera = json.loads((out / "camera.json").read_text())
    assert camera["K"] is None and camera["projection"] == "OrthographicCamera"
    pose = np.array(camera["pose_camera_to_world"])
    np.testing.assert_allclose(pose[:3, :3], np.diag([-1.0, -1.0, 1.0]), atol=1e-6)
