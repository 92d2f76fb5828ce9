"""Camera streams (`dopplertof animate --camera`): a preset's depth frames at its frame
rate on one clock, a camera moved by a TUM RGB-D trajectory, groundtruth.txt, resuming,
and bad trajectories.

Tolerances, from float32 arithmetic (eps = 2^-23, the unit roundoff 2^-24): the truth
traces float32 rays, so a hit point is off by a few ulps of its coordinates; depths here
are under 4 m (ulp 4.8e-7 m) and stored as float32: 8 ulps at 4 m (8 eps 4 m = 3.8e-6 m)
bound the depth. The radial velocity ds/dt = n . (u - u_c) / (n . d) reads the hit point
through the sphere's normal n = (p - centre) / R: a point off by 4 eps s (s <= 4 m) tilts
n by at most 4 eps s / R (R = 0.6 m: under 27 eps), and the pixels compared have
|n . d| >= 0.5, so the velocity is off by at most about 2 x 27 eps |u - u_c| plus its
float32 rounding: 64 eps |u - u_c| bounds it. Trajectory poses are float64 arithmetic
(tens of roundings on numbers of order 1: 1e-12).
"""

import json
import os
import shutil
from decimal import Decimal

import numpy as np
import pytest

#: the sphere: radius (m) and constant velocity (m/s), centre at the origin at t = 0
RADIUS, SPHERE_VELOCITY = 0.6, np.array([0.0, 0.0, 1.0])
#: the wall: the plane z = WALL_Z facing +z
WALL_Z = -1.0
#: the camera's straight trajectory: position at the first stamp and velocity (m/s),
#: looking down -z (OpenCV axes: x right = world x, y down = world -y)
CAMERA_START, CAMERA_VELOCITY = np.array([0.0, 0.0, 2.5]), np.array([0.3, 0.1, -0.5])
LOOKING_DOWN_Z = np.diag([1.0, -1.0, -1.0])
#: a TUM file's first stamp (Unix time, as the TUM RGB-D benchmark's are)
FIRST_STAMP = Decimal("1305031102.175304")
EPS32 = 2.0 ** -23

SCENE_XML = f"""<scene version="3.0.0">
    <integrator type="dopplertof"><integer name="max_depth" value="2"/></integrator>
    <sensor type="perspective">
        <transform name="to_world"><lookat origin="0, 0, 2.5" target="0, 0, 0" up="0, 1, 0"/></transform>
        <sampler type="independent"><integer name="sample_count" value="4"/></sampler>
        <film type="hdrfilm"><integer name="width" value="8"/><integer name="height" value="6"/>
            <rfilter type="box"/></film>
    </sensor>
    <bsdf type="diffuse" id="grey"><rgb name="reflectance" value="0.6"/></bsdf>
    <shape type="rectangle" id="wall">
        <transform name="to_world"><scale value="4"/><translate z="{WALL_Z}"/></transform>
        <ref id="grey"/>
    </shape>
    <shape type="sphere" id="ball">
        <animation name="to_world">
            <transform time="0"><scale value="{RADIUS}"/></transform>
            <transform time="1"><scale value="{RADIUS}"/><translate z="1"/></transform>
        </animation>
        <ref id="grey"/>
    </shape>
</scene>
"""


# ---- TUM files, written and read from the format's definition ------------------------------
# "timestamp tx ty tz qx qy qz qw" per line, '#' lines are comments; the quaternion is
# the camera's orientation (scalar last), the position its optical centre.

def quaternion_of(angle: float, axis) -> tuple:
    """(qx, qy, qz, qw) of a rotation by ``angle`` about the unit ``axis``."""
    s = np.sin(angle / 2)
    return (axis[0] * s, axis[1] * s, axis[2] * s, np.cos(angle / 2))


def write_trajectory(path, stamps, positions, quaternions) -> None:
    with open(path, "w") as f:
        f.write("# timestamp tx ty tz qx qy qz qw\n")
        for stamp, p, q in zip(stamps, positions, quaternions):
            f.write(" ".join([str(stamp)] + [repr(float(v)) for v in list(p) + list(q)]) + "\n")


def read_trajectory(path) -> list:
    """[(stamp as Decimal, position (3,), quaternion (x, y, z, w))] of a TUM file."""
    rows = []
    for line in open(path).read().splitlines():
        if not line.strip() or line.startswith("#"):
            continue
        fields = line.split()
        assert len(fields) == 8, line
        values = np.array([float(v) for v in fields[1:]])
        rows.append((Decimal(fields[0]), values[:3], values[3:]))
    return rows


def rotation_of(q) -> np.ndarray:
    """The rotation matrix of a unit quaternion (x, y, z, w), written out."""
    x, y, z, w = q
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


def straight_trajectory(path, seconds: float = 1.0) -> None:
    """The camera from CAMERA_START at CAMERA_VELOCITY, a pose every 0.1 s."""
    steps = int(round(seconds * 10))
    write_trajectory(path, [FIRST_STAMP + Decimal(i) / 10 for i in range(steps + 1)],
                     [CAMERA_START + CAMERA_VELOCITY * (i / 10) for i in range(steps + 1)],
                     [(1.0, 0.0, 0.0, 0.0)] * (steps + 1))


# ---- Closed forms ----------------------------------------------------------------------------

def closed_form_truth(rays, centre, camera_velocity, sphere_centre, spin=np.zeros(3)):
    """(depth, radial velocity ds/dt along each pixel's ray, on_sphere, margin) of the
    unit world rays ``rays`` (H, W, 3) from ``centre``: the nearer of the sphere and the
    wall; ds/dt from differentiating the hit's equation (sphere |c + s d - S|^2 = R^2,
    wall z = WALL_Z) with the camera moving at ``camera_velocity`` and turning at
    ``spin`` (rad/s, d' = spin x d)."""
    oc = centre - sphere_centre
    b = rays @ oc
    disc = b * b - (oc @ oc - RADIUS ** 2)
    on_sphere = disc > 0
    s_sphere = -b - np.sqrt(np.maximum(disc, 0.0))
    s_wall = (WALL_Z - centre[2]) / rays[..., 2]
    on_wall = np.all(np.abs(centre + s_wall[..., None] * rays)[..., :2] <= 4.0, axis=-1)
    depth = np.where(on_sphere, s_sphere, np.where(on_wall & (s_wall > 0), s_wall, np.nan))
    point = centre + depth[..., None] * rays
    normal = np.where(on_sphere[..., None], (point - sphere_centre) / RADIUS, [0.0, 0.0, 1.0])
    velocity = np.where(on_sphere[..., None], SPHERE_VELOCITY, 0.0)
    turning = np.cross(spin, rays)
    radial = (np.sum(normal * (velocity - camera_velocity), -1)
              - depth * np.sum(normal * turning, -1)) / np.sum(normal * rays, -1)
    return depth, radial, on_sphere, np.abs(disc)


def check_truth(depth_gt, velocity_gt, rays, centre, camera_velocity, sphere_centre,
                spin=np.zeros(3)) -> int:
    """The truth against the closed form away from the sphere's silhouette and the wall's
    edges; returns the number of sphere pixels compared."""
    depth, radial, on_sphere, margin = closed_form_truth(rays, centre, camera_velocity,
                                                         sphere_centre, spin)
    clear = margin > 0.05 * RADIUS ** 2  # (not at the silhouette, where a ray grazes)
    assert (np.isfinite(depth[clear]) & ~on_sphere[clear]).sum() >= 10  # the wall
    np.testing.assert_allclose(depth_gt[clear], depth[clear], rtol=0, atol=8 * EPS32 * 4.0)
    scale = np.linalg.norm(SPHERE_VELOCITY - camera_velocity) + np.linalg.norm(camera_velocity) \
        + np.linalg.norm(spin) * 4.0
    np.testing.assert_allclose(velocity_gt[clear], radial[clear], rtol=0,
                               atol=64 * EPS32 * scale)
    return int(on_sphere[clear].sum())


# ---- The stream ------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def stream(tmp_path_factory):
    """Three frames of azure-kinect (30 fps) at 8x6, 4 spp, along the straight trajectory."""
    from dopplertof.experiments.stream import run_stream

    root = tmp_path_factory.mktemp("stream")
    (root / "scene.xml").write_text(SCENE_XML)
    straight_trajectory(root / "trajectory.txt")
    summary = run_stream(root / "scene.xml", root / "out", 3, "azure-kinect",
                         trajectory=root / "trajectory.txt", resolution=(8, 6), spp=4,
                         workers=1, progress=False)
    assert summary.ok and summary.done == 3, summary
    return root


def test_each_frame_follows_the_trajectory_on_one_clock(stream):
    from dopplertof.cameras.preset import load_preset
    from dopplertof.tof.geometry import pixel_rays

    preset = load_preset("azure-kinect")
    assert preset.frame_rate_hz == 30.0
    index = json.loads((stream / "out" / "stream.json").read_text())
    assert index["fps"] == 30.0 and index["frame_count"] == 3 and len(index["frames"]) == 3
    ends = [f.start_s + f.integration_s for f in preset.frames]
    mid = 0.5 * (preset.frames[0].start_s + max(ends))
    for k, entry in enumerate(index["frames"]):
        folder = stream / "out" / entry["folder"]
        summary = json.loads((folder / "summary.json").read_text())
        geometry = json.loads((folder / "camera.json").read_text())
        # raw frame j of frame k exposes from k / F + start_j (the scene's t0 is 0)
        for frame, record in zip(preset.frames, summary["frames"]):
            assert record["window_s"][0] == pytest.approx(k / 30 + frame.start_s, abs=1e-15)
        t = summary["ground_truth_time_s"]
        assert t == pytest.approx(k / 30 + mid, abs=1e-15) and entry["truth_time_s"] == t
        assert Decimal(entry["timestamp"]) == (FIRST_STAMP + Decimal(repr(k / 30 + mid))
                                               ).quantize(Decimal("1e-9"))
        centre = CAMERA_START + CAMERA_VELOCITY * t
        pose = np.asarray(geometry["pose_camera_to_world"])
        np.testing.assert_allclose(pose[:3, :3], LOOKING_DOWN_Z, atol=1e-12)
        np.testing.assert_allclose(pose[:3, 3], centre, atol=1e-12)
        rays = pixel_rays(geometry) @ LOOKING_DOWN_Z.T
        assert check_truth(np.load(folder / "depth_gt.npy"),
                           np.load(folder / "velocity_gt.npy"), rays, centre,
                           CAMERA_VELOCITY, SPHERE_VELOCITY * t) >= 4
        assert set(entry["errors"]) >= {"depth_m", "depth_z_m"}
    # each frame draws its own sensor noise
    assert len({e["noise_seed"] for e in index["frames"]}) == 3


def test_groundtruth_round_trips_through_a_tum_reader(stream):
    index = json.loads((stream / "out" / "stream.json").read_text())
    rows = read_trajectory(stream / "out" / "groundtruth.txt")
    assert len(rows) == 3
    for (stamp, position, quaternion), entry in zip(rows, index["frames"]):
        assert stamp == Decimal(entry["timestamp"])
        t = float(stamp - FIRST_STAMP)  # the trajectory's clock: its first stamp is t0 = 0
        assert t == pytest.approx(entry["truth_time_s"], abs=1e-9)
        np.testing.assert_allclose(position, CAMERA_START + CAMERA_VELOCITY
                                   * entry["truth_time_s"], atol=1e-12)
        assert np.linalg.norm(quaternion) == pytest.approx(1.0, abs=1e-12)
        np.testing.assert_allclose(rotation_of(quaternion), LOOKING_DOWN_Z, atol=1e-12)
        np.testing.assert_allclose(rotation_of(quaternion), np.asarray(
            entry["pose_camera_to_world"])[:3, :3], atol=1e-12)


def test_an_interrupted_stream_resumes_bitwise(stream, tmp_path):
    """Frame 1 lost its marker and a file (a kill mid-frame): the rerun renders it alone,
    and every file equals the uninterrupted run's."""
    from dopplertof.experiments.stream import run_stream

    out = tmp_path / "out"
    shutil.copytree(stream / "out", out)
    os.unlink(out / "frame_0001" / "complete.json")
    os.unlink(out / "frame_0001" / "depth.npy")
    summary = run_stream(stream / "scene.xml", out, 3, "azure-kinect",
                         trajectory=stream / "trajectory.txt", resolution=(8, 6), spp=4,
                         workers=1, progress=False)
    assert summary.ok and summary.done == 1 and summary.skipped == 2
    for k in range(3):
        for name in sorted(os.listdir(stream / "out" / f"frame_{k:04d}")):
            if name.endswith(".npy"):
                before = (stream / "out" / f"frame_{k:04d}" / name).read_bytes()
                assert (out / f"frame_{k:04d}" / name).read_bytes() == before, (k, name)
    assert (out / "groundtruth.txt").read_text() == \
        (stream / "out" / "groundtruth.txt").read_text()


def test_a_stream_has_a_video_and_with_previews_a_contact_sheet(stream, tmp_path, monkeypatch):
    """The fixture's stream wrote its video (MP4 or GIF: whichever this installation
    writes) of its 3 frames; rerun with --previews and without imageio-ffmpeg (the frames
    complete: nothing is rendered) it writes a GIF and the contact sheet instead."""
    import sys

    from PIL import Image

    from dopplertof.cli import main
    from dopplertof.videos import video_extension

    index = json.loads((stream / "out" / "stream.json").read_text())
    assert index["video"] == "video" + video_extension()
    assert (stream / "out" / index["video"]).stat().st_size > 0
    out = tmp_path / "out"
    shutil.copytree(stream / "out", out)
    monkeypatch.setitem(sys.modules, "imageio_ffmpeg", None)
    code = main(["animate", str(stream / "scene.xml"), "--camera", "azure-kinect", "--frames",
                 "3", "--res", "8x6", "--spp", "4", "--trajectory",
                 str(stream / "trajectory.txt"), "--workers", "1", "--quiet", "--previews",
                 "-o", str(out)])
    assert code == 0
    index = json.loads((out / "stream.json").read_text())
    assert index["video"] == "video.gif" and index["last_run"]["done"] == 0
    gif = Image.open(out / "video.gif")
    assert gif.n_frames == 3 and gif.info["duration"] == 30  # (1/30 s in GIF's 10 ms)
    assert not (out / "video.mp4").exists() and (out / "contact_sheet.png").is_file()
    assert Image.open(out / "contact_sheet.png").width > 3 * 160


# ---- A turning camera --------------------------------------------------------------------------

def test_a_rotating_trajectory_slerps_as_the_closed_form_rotation(tmp_path):
    """The camera turns about the world's y axis at 2 rad/s (poses every 0.25 s: half a
    radian apart) while moving: between the poses its orientation is the closed-form
    rotation (SLERP of one axis is the rotation by the interpolated angle), and the
    static wall's velocity truth holds the camera's own turning."""
    import dopplertof
    from dopplertof.cameras.scene_view import load_scene_for_camera
    from dopplertof.cameras.preset import load_preset
    from dopplertof.scene.motion import Motion, rotation_quaternion
    from dopplertof.scene.trajectory import read_tum
    from dopplertof.tof.geometry import MITSUBA_TO_OPENCV, camera_geometry, pixel_rays
    from dopplertof.tof.ground_truth import ground_truth

    rate, axis = 2.0, np.array([0.0, 1.0, 0.0])

    def turned(t):  # camera to world at time t: the turn after looking down -z
        return rotation_of(quaternion_of(rate * t, axis)) @ LOOKING_DOWN_Z

    times = [0.25 * i for i in range(5)]
    quaternions = [tuple(np.roll(rotation_quaternion(turned(t)), -1)) for t in times]
    write_trajectory(tmp_path / "turn.txt", [FIRST_STAMP + Decimal(repr(t)) for t in times],
                     [CAMERA_START + CAMERA_VELOCITY * t for t in times], quaternions)
    trajectory = read_tum(tmp_path / "turn.txt")
    keyframes = trajectory.keyframes(0.1, 0.9, 0.0)
    motion = Motion(keyframes)
    for t in (0.1, 0.3, 0.5, 0.61, 0.9):
        pose = motion.world_matrix(t) @ MITSUBA_TO_OPENCV
        np.testing.assert_allclose(pose[:3, :3], turned(t), atol=1e-12)
        np.testing.assert_allclose(pose[:3, 3], CAMERA_START + CAMERA_VELOCITY * t, atol=1e-12)
    # the truth of a frame at t = 0.3 s: the wall turns past the camera
    (tmp_path / "scene.xml").write_text(SCENE_XML)
    dopplertof.set_variant("llvm_ad_rgb")
    preset = load_preset("azure-kinect")
    scene = load_scene_for_camera(tmp_path / "scene.xml", preset, (8, 6),
                                  camera_keyframes=trajectory.keyframes(0.29, 0.31, 0.0))
    scene = scene.with_shutter(0.29, 0.02)
    truth = ground_truth(scene)
    assert truth.time == pytest.approx(0.3, abs=1e-15)
    geometry = camera_geometry(scene, truth.time)
    rays = pixel_rays(geometry) @ turned(truth.time).T
    check_truth(truth.depth, truth.velocity, rays, CAMERA_START + CAMERA_VELOCITY * 0.3,
                CAMERA_VELOCITY, SPHERE_VELOCITY * 0.3, spin=rate * axis)
    # the illuminator rides with the camera: at its first keyframe, moved by its motion
    import mitsuba as mi

    (index, light_motion), = scene.light_motions
    assert light_motion is scene.sensor_motion
    position = np.array(mi.traverse(scene.static.emitters()[index])["position"]).reshape(-1)
    np.testing.assert_allclose(position, CAMERA_START + CAMERA_VELOCITY * 0.25, atol=1e-6)


# ---- The TUM files themselves ------------------------------------------------------------------

def test_tum_writer_and_reader_round_trip(tmp_path):
    from dopplertof.scene.trajectory import format_tum, pose_matrix, read_tum

    rng = np.random.default_rng(5)
    poses = []
    for _ in range(4):
        q = rng.normal(size=4)
        q /= np.linalg.norm(q)
        poses.append(pose_matrix(rng.normal(size=3), q))
    stamps = [FIRST_STAMP + Decimal(i) / 30 for i in range(4)]
    (tmp_path / "g.txt").write_text(format_tum(zip(stamps, poses)))
    rows = read_trajectory(tmp_path / "g.txt")
    for (stamp, position, quaternion), expected, pose in zip(rows, stamps, poses):
        assert stamp == expected.quantize(Decimal("1e-9"))
        assert quaternion[3] >= 0
        np.testing.assert_allclose(position, pose[:3, 3], rtol=0, atol=0)
        np.testing.assert_allclose(rotation_of(quaternion), pose[:3, :3], atol=1e-12)
    again = read_tum(tmp_path / "g.txt")
    for i, pose in enumerate(poses):
        np.testing.assert_allclose(again.pose(i), pose, atol=1e-12)


# ---- Bad input ---------------------------------------------------------------------------------

GOOD = "1305031102.0 0 0 2.5 1 0 0 0\n1305031103.0 0.3 0 2.0 1 0 0 0\n"


@pytest.mark.parametrize("text,expected", [
    ("1305031102.5 0 0 2.5 1 0 0 0\n" + GOOD, "line 2: timestamp 1305031102.0 is before"),
    (GOOD.replace("2.0 1 0 0 0", "2.0 1 0 0.5 0"), "line 2: the quaternion"),
    ("# a comment\n1305031102.0 0 0 2.5 1 0 0 0\n1305031102.05 0 0 2.4 1 0 0 0\n",
     "but the file ends 0.05 s after it (line 3)"),
    (GOOD + "1305031104.0 0 0 2.5 1 0 0\n", "line 3: expected 8 numbers"),
])
def test_a_bad_trajectory_is_one_line_naming_the_line(tmp_path, capsys, text, expected):
    from dopplertof.cli import main

    (tmp_path / "scene.xml").write_text(SCENE_XML)
    (tmp_path / "t.txt").write_text(text)
    out = tmp_path / "out"
    code = main(["animate", str(tmp_path / "scene.xml"), "--camera", "azure-kinect",
                 "--frames", "3", "--res", "8x6", "--trajectory", str(tmp_path / "t.txt"),
                 "-o", str(out), "--quiet"])
    err = capsys.readouterr().err
    assert code == 2 and len(err.strip().splitlines()) == 1, err
    assert str(tmp_path / "t.txt") in err and expected in err, err
    assert not out.exists()


def test_a_sequence_longer_than_a_frame_is_refused(tmp_path, capsys):
    from dopplertof.cameras.preset import PresetError, load_preset, preset_path
    from dopplertof.cli import main

    (tmp_path / "scene.xml").write_text(SCENE_XML)
    code = main(["animate", str(tmp_path / "scene.xml"), "--camera", "azure-kinect",
                 "--fps", "100", "--frames", "2", "-o", str(tmp_path / "out"), "--quiet"])
    err = capsys.readouterr().err
    assert code == 2 and len(err.strip().splitlines()) == 1, err
    assert "raw frame sequence lasts 12.725 ms, longer than a depth frame at 100 fps" in err
    text = open(preset_path("azure-kinect")).read().replace("frame_rate_hz = 30.0",
                                                            "frame_rate_hz = 90.0")
    (tmp_path / "fast.toml").write_text(text)
    with pytest.raises(PresetError, match=r"fast.toml: frame_rate_hz = 90: .* 12.725 ms"):
        load_preset(tmp_path / "fast.toml")
    # a preset without a frame rate needs --fps
    code = main(["animate", str(tmp_path / "scene.xml"), "--camera", "opt8241",
                 "--frames", "2", "-o", str(tmp_path / "out"), "--quiet"])
    err = capsys.readouterr().err
    assert code == 2 and "no frame_rate_hz: give the stream's --fps" in err, err


def test_a_trajectory_for_a_camera_that_moves_already_is_refused(tmp_path, capsys):
    from dopplertof.cli import main

    moving = SCENE_XML.replace(
        '<transform name="to_world"><lookat origin="0, 0, 2.5" target="0, 0, 0" up="0, 1, 0"/></transform>',
        '<animation name="to_world"><transform time="0"><translate z="2.5"/></transform>'
        '<transform time="1"><translate z="2"/></transform></animation>')
    (tmp_path / "scene.xml").write_text(moving)
    straight_trajectory(tmp_path / "t.txt")
    code = main(["animate", str(tmp_path / "scene.xml"), "--camera", "azure-kinect",
                 "--frames", "2", "--trajectory", str(tmp_path / "t.txt"), "-o",
                 str(tmp_path / "out"), "--quiet"])
    err = capsys.readouterr().err
    assert code == 2 and len(err.strip().splitlines()) == 1, err
    assert "the scene's sensor has an <animation> of its own" in err
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("argv,expected", [
    (["--trajectory", "t.txt"], "--trajectory needs --camera"),
    (["--res", "8x8"], "without a camera the scene's film sets the resolution: -D res=N"),
    (["--camera", "azure-kinect", "--frame-period", "0.1"], "--frame-period does not apply"),
])
def test_stream_options_belong_to_streams(tmp_path, capsys, argv, expected):
    from dopplertof.cli import main

    (tmp_path / "scene.xml").write_text(SCENE_XML)
    code = main(["animate", str(tmp_path / "scene.xml"), "--frames", "2", "-o",
                 str(tmp_path / "out"), "--quiet", *argv])
    err = capsys.readouterr().err
    assert code == 2 and expected in err and len(err.strip().splitlines()) == 1, err
