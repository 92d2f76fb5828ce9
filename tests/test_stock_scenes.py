"""Stock Mitsuba 3 scenes through a camera preset: meshes found through ``<path>`` from
any current folder, a scene in millimetres read with ``-D unit=mm``, a bitmap texture,
a stock integrator; the preset's field of view said, or kept (``--keep-view``); a scene
whose extent disagrees with the preset's range warned about. The scenes (tests/data/stock,
written for these tests) are captured by the CLI from another folder than theirs, and
their depth checked against the exact truth the capture writes."""

import json
import math
import os
import subprocess
import sys

import numpy as np
import pytest

import dopplertof
from dopplertof.scene import SceneError

STOCK = os.path.join(os.path.dirname(os.path.abspath(__file__)), "data", "stock")
PATHS, MILLIMETRES, TEXTURED = (os.path.join(STOCK, name, "scene.xml")
                                for name in ("paths", "millimetres", "textured"))
#: every scene: the camera at z = 3 m looking down -z at a wall at z = 0; what moves
#: approaches the camera at 1 m/s from t = 0
CAMERA_Z, SPEED = 3.0, 1.0
#: float32 depths near 3 m: a few units in the last place (2**-22 m each)
ULP = 2.0 ** -22
#: the median |error| / predicted std of a Gaussian (sensor noise, which depth_std
#: predicts): 0.674; twice that allows for the Monte Carlo noise of 4 spp it leaves out
MEDIAN_Z = 2 * 0.6745


def capture(scene, out, cwd, *args):
    """``dopplertof capture SCENE --camera azure-kinect`` at 16x16, 4 spp, run in
    ``cwd``; (summary, camera.json, stderr)."""
    proc = subprocess.run([sys.executable, "-m", "dopplertof.cli", "capture", scene,
                           "--camera", "azure-kinect", "--res", "16x16", "--spp", "4",
                           "-P", "max_depth=2", "-o", str(out), "--quiet", *args],
                          capture_output=True, text=True, timeout=300, cwd=cwd,
                          env={**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)})
    assert proc.returncode == 0, proc.stderr
    with open(out / "summary.json") as f:
        summary = json.load(f)
    with open(out / "camera.json") as f:
        camera = json.load(f)
    return summary, camera, proc.stderr


def _cosines(camera):
    """cos of each pixel centre's ray to the optical axis (no distortion)."""
    K = np.asarray(camera["K"])
    width, height = camera["resolution"]
    u, v = np.meshgrid(np.arange(width) + 0.5, np.arange(height) + 0.5)
    return 1.0 / np.sqrt(((u - K[0, 2]) / K[0, 0]) ** 2 + ((v - K[1, 2]) / K[1, 1]) ** 2 + 1)


def check_depth(out, summary, camera, moving_depth):
    """The truth the capture wrote is the scene's geometry in metres (the wall at 3 m,
    what moves where ``moving_depth(cos, t)`` says, to float32 rounding), and the
    camera's depth agrees with it within its predicted noise."""
    truth = np.load(out / "depth_gt.npy").astype(np.float64)
    truth_z = np.load(out / "depth_gt_z.npy").astype(np.float64)
    cosines = _cosines(camera)
    wall = truth_z > 2.5
    assert wall.sum() > 0.5 * wall.size
    np.testing.assert_allclose(truth_z[wall], CAMERA_Z, rtol=0, atol=4 * ULP)
    np.testing.assert_allclose(truth[wall], CAMERA_Z / cosines[wall], rtol=8 * 2.0 ** -24)
    if moving_depth is not None:
        expected = moving_depth(cosines[~wall], summary["ground_truth_time_s"])
        assert (~wall).sum() >= 4
        np.testing.assert_allclose(truth[~wall], expected, rtol=0, atol=1e-5)
    depth, std = np.load(out / "depth.npy"), np.load(out / "depth_std.npy")
    valid = np.isfinite(depth)
    assert valid.sum() >= 0.1 * valid.size, summary["depth"]["masked_pixels"]
    z = np.abs(depth[valid] - truth[valid]) / std[valid]
    assert np.median(z) < MEDIAN_Z, np.median(z)


@pytest.fixture()
def elsewhere(tmp_path):
    folder = tmp_path / "elsewhere"
    folder.mkdir()
    return folder


def test_meshes_through_path_captured_from_another_folder(tmp_path, elsewhere):
    """A 0.6 m OBJ panel at z = 1 m + t (1 m/s) before an OBJ wall, both from
    ../common through <path>, under a stock path integrator (its defaults, a note)."""
    out = tmp_path / "out"
    summary, camera, err = capture(PATHS, out, elsewhere)
    assert ("<integrator type=\"path\"> (its max_depth 2 is not read: -P max_depth=2 "
            "gives it) is not a D-ToF integrator: using the D-ToF defaults") in err
    check_depth(out, summary, camera,
                lambda cos, t: (CAMERA_Z - 1.0 - SPEED * t) / cos)
    assert "warnings" not in summary


def test_a_millimetre_scene_is_one_flag(tmp_path, elsewhere):
    """mm read as metres: the extent warning; with -D unit=mm the wall is at 3 m and the
    300 mm ball, centred 1 m + t from the wall, where its geometry puts it."""
    out = tmp_path / "out"
    summary, camera, err = capture(MILLIMETRES, out, elsewhere, "-D", "unit=mm")
    assert "warnings" not in summary

    def on_ball(cos, t):  # a ray at angle theta from the axis meets the ball at
        centre, radius = CAMERA_Z - 1.0 - SPEED * t, 0.3
        sin2 = 1 - cos ** 2
        return centre * cos - np.sqrt(radius ** 2 - centre ** 2 * sin2)

    check_depth(out, summary, camera, on_ball)
    as_metres, _, err = capture(MILLIMETRES, tmp_path / "metres", elsewhere)
    warning, = as_metres["warnings"]
    assert "differ by more than 100 times" in warning and "-D unit=mm" in warning
    assert "warning" in err and "differ by more than 100 times" in err


def test_a_textured_scene(tmp_path, elsewhere):
    """A bitmap texture beside the scene (20% and 80% squares) found from elsewhere."""
    out = tmp_path / "out"
    summary, camera, _ = capture(TEXTURED, out, elsewhere)
    check_depth(out, summary, camera, None)
    amplitude = np.load(out / "amplitude.npy")
    # the two albedos: the brightest pixels about 4 times the darkest (same distances)
    assert np.nanpercentile(amplitude, 90) > 2.5 * np.nanpercentile(amplitude, 10)


# ---- Units, in the loader ---------------------------------------------------------------

def _text(path):
    with open(path) as f:
        return f.read()


def test_unit_scales_geometry_camera_and_velocity(tmp_path):
    """-D unit=mm and <default name="unit" value="mm"/> give the same scene: the camera
    3 m from the wall, the ball's 300 mm radius 0.3 m, its 1000 mm/s 1 m/s; the preset's
    illuminator (its offset in metres) on the camera."""
    import mitsuba as mi

    from dopplertof.cameras.scene_view import load_scene_for_camera
    from dopplertof.cameras.preset import load_preset

    dopplertof.set_variant()
    preset = load_preset("azure-kinect")
    flag = load_scene_for_camera(MILLIMETRES, preset, (4, 4), {"unit": "mm"})
    declared_file = tmp_path / "declared.xml"
    declared_file.write_text(_text(MILLIMETRES).replace(
        '<default name="spp"', '<default name="unit" value="mm"/><default name="spp"'))
    declared = load_scene_for_camera(str(declared_file), preset, (4, 4))
    for scene in (flag, declared):
        to_world = np.asarray(scene.sensor.world_transform().matrix, np.float64).reshape(4, 4)
        np.testing.assert_allclose(to_world[:3, 3], [0, 0, CAMERA_Z], rtol=1e-6)
        light, = scene.static.emitters()
        values = mi.traverse(light)  # (a point light, or a spot confined to its field)
        position = (np.asarray(values["position"]).reshape(-1) if "position" in values else
                    np.asarray(values["to_world"].matrix, np.float64).reshape(4, 4)[:3, 3])
        np.testing.assert_allclose(position, [0, 0, CAMERA_Z], rtol=1e-6)
        np.testing.assert_allclose(np.abs(np.linalg.det(to_world[:3, :3])), 1.0, rtol=1e-5)
        box = scene.bodies[0].scene.bbox()
        np.testing.assert_allclose(np.asarray(box.max) - np.asarray(box.min), 0.6, rtol=1e-5)
        motion = scene.bodies[0].motion
        start, end = (np.asarray(motion.times, np.float64)[k] for k in (0, -1))
        moved = [motion.world_matrix(t)[2, 3] for t in (start, end)]
        assert (moved[1] - moved[0]) / (end - start) == pytest.approx(SPEED, rel=1e-5)
        wall = scene.static.bbox()
        assert float(wall.max[0] - wall.min[0]) == pytest.approx(10.0, rel=1e-6)


def _lit_plane(scale, light):
    """A grey plane 3 x ``scale`` before the camera, lit by ``light`` (formatted with
    its distance ``d``, 0.9 of the camera's), in units of 1 / ``scale`` m."""
    return f"""<scene version="3.0.0">
    <sensor type="perspective"><float name="fov" value="40"/>
        <transform name="to_world"><lookat origin="0, 0, {3 * scale}" target="0, 0, 0"
                                           up="0, 1, 0"/></transform>
        <sampler type="independent"><integer name="sample_count" value="4"/></sampler>
        <film type="hdrfilm"><integer name="width" value="8"/><integer name="height"
                                                                  value="8"/></film></sensor>
    {light.format(d=2.7 * scale)}
    <shape type="rectangle"><transform name="to_world"><scale value="{5 * scale}"/></transform>
        <bsdf type="diffuse"><rgb name="reflectance" value="0.5"/></bsdf></shape>
</scene>"""


POINT = '<emitter type="point"><point name="position" x="0" y="0" z="{d}"/>{i}</emitter>'
SPOT = ('<emitter type="spot"><transform name="to_world"><lookat origin="0, 0, {d}" '
        'target="0, 0, 0"/></transform><float name="cutoff_angle" value="30"/>{i}</emitter>')


@pytest.mark.parametrize("light, written, scaled, ratio", [
    (POINT, '<rgb name="intensity" value="2"/>', '<rgb name="intensity" value="2e6"/>', 1),
    (SPOT, '<spectrum name="intensity" value="400:1, 700:3"/>',
     '<spectrum name="intensity" value="400:1e6, 700:3e6"/>', 1),
    (POINT, "", "", 1e-6)])
def test_a_point_lights_intensity_follows_the_unit(light, written, scaled, ratio):
    """A point or spot light's irradiance is I / r^2 with r in scene units: the same
    scene written in millimetres (its lengths 1000 times, its intensity 10^6 times:
    stock Mitsuba renders the two alike) and read with -D unit=mm renders the radiance
    of the one in metres (it was 10^6 times brighter); a light without an intensity has
    Mitsuba's 1 at 1 mm, 10^-6 of it at 1 m. The float32 geometry of the scaled scene
    rounds differently: a few units in the last place of 1 / r^2."""
    dopplertof.set_variant()
    metres = dopplertof.load_string(_lit_plane(1, light.replace("{i}", written)), {})
    millimetres = dopplertof.load_string(_lit_plane(1000, light.replace("{i}", scaled)),
                                         {"unit": "mm"})
    a, b = (dopplertof.capture(s, spp=4, seed=0, params={"max_depth": 2}, progress=False)
            for s in (metres, millimetres))
    assert a.radiance.max() > 0
    np.testing.assert_allclose(b.radiance, ratio * a.radiance, rtol=1e-5, atol=0)


def test_an_intensity_it_cannot_scale_is_one_line():
    dopplertof.set_variant()
    light = POINT.replace("{i}", '<spectrum name="intensity" filename="lamp.spd"/>')
    with pytest.raises(SceneError, match=r"the point light's 'intensity' \(<spectrum>\) "
                                         r"cannot be scaled to metres \(-D unit\)") as caught:
        dopplertof.load_string(_lit_plane(1000, light), {"unit": "mm"})
    assert len(str(caught.value).splitlines()) == 1


def test_unit_m_changes_nothing_and_a_bad_unit_is_one_line():
    from dopplertof.cameras.scene_view import load_scene_for_camera
    from dopplertof.cameras.preset import load_preset

    dopplertof.set_variant()
    preset = load_preset("azure-kinect")

    def load(**defines):
        return load_scene_for_camera(PATHS, preset, (4, 4), defines)

    plain = load()
    assert load(unit="m").fingerprint == plain.fingerprint
    assert load(unit="0.001").fingerprint != plain.fingerprint
    with pytest.raises(SceneError, match=r"scene\.xml: unit: unknown unit 'mn', did you "
                                         r"mean 'm.*known: m, dm, cm, mm"):
        load(unit="mn")


def test_a_bad_unit_from_the_cli_is_one_line_exit_2(tmp_path):
    proc = subprocess.run([sys.executable, "-m", "dopplertof.cli", "capture", MILLIMETRES,
                           "--camera", "azure-kinect", "--res", "4x4", "-D", "unit=-1",
                           "-o", str(tmp_path / "o")], capture_output=True, text=True,
                          timeout=120)
    assert proc.returncode == 2
    assert proc.stderr.count("\n") == 1 and "unit: unknown unit '-1'" in proc.stderr


# ---- The preset's view ------------------------------------------------------------------

def test_the_presets_view_is_said_and_can_be_kept(tmp_path):
    """The preset's 75 degrees replace the scene's 50 with a note; keep-view keeps the
    scene's 50 on the preset's pixels (fov_axis y: the horizontal view its aspect gives)."""
    from dopplertof.cameras.scene_view import load_scene_for_camera, preset_with_scene_view
    from dopplertof.cameras.preset import load_preset

    dopplertof.set_variant()
    preset = load_preset("azure-kinect")
    scene = load_scene_for_camera(PATHS, preset, (8, 8))
    note, = [n for n in scene.notes if "field of view" in n]
    assert "azure-kinect's 75 degree horizontal field of view replaces the scene's " \
           "sensor's (fov 50)" in note and "--keep-view" in note
    kept = preset_with_scene_view(PATHS, preset, (8, 8))
    assert kept.fov_deg == pytest.approx(50.0, rel=1e-6)
    assert not [n for n in load_scene_for_camera(PATHS, kept, (8, 8), keep_view=True).notes
                if "field of view" in n]
    vertical = tmp_path / "vertical.xml"
    vertical.write_text(_text(PATHS).replace('<path value="../common"/>',
                                             f'<path value="{STOCK}/common"/>')
                        .replace('<float name="fov" value="50"/>',
                                 '<float name="fov" value="50"/>'
                                 '<string name="fov_axis" value="y"/>'))
    width, height = 16, 8
    expected = 2 * math.degrees(math.atan(math.tan(math.radians(25)) * width / height))
    assert preset_with_scene_view(str(vertical), preset, (width, height)).fov_deg == \
        pytest.approx(expected, rel=1e-6)
    said, = [n for n in load_scene_for_camera(str(vertical), preset, (4, 4)).notes
             if "field of view" in n]
    assert "(fov 50, fov_axis y)" in said


def test_keep_view_on_the_command_line(tmp_path, elsewhere):
    out = tmp_path / "out"
    _, camera, err = capture(TEXTURED, out, elsewhere, "--keep-view")
    assert camera["fov_x_deg"] == pytest.approx(50.0, rel=1e-6)
    assert camera["K"][0][0] == pytest.approx(8 / math.tan(math.radians(25)), rel=1e-6)
    assert "field of view" not in err


# ---- Lines of the user's file through a preset -------------------------------------------

@pytest.mark.parametrize("how", [
    ["capture", "--camera", "azure-kinect", "--res", "8x7"],
    ["capture", "--camera", "kinect-v2", "--keep-view", "--res", "8x7"],
    ["animate", "--camera", "azure-kinect", "--frames", "1", "--res", "8x7",
     "--trajectory", os.path.join(os.path.dirname(STOCK), "..", "..", "examples", "stream",
                                  "trajectory.txt")]])
def test_an_error_through_a_preset_names_the_line_of_the_users_file(tmp_path, capsys, how):
    """A preset edits the scene's text before it loads (its view, its resolution, the
    illuminator, a trajectory's keyframes in place of the sensor's placement); the
    message of an error after those edits names the line of the user's file, not of the
    edited text: the stock Cornell box (a five-line comment before <scene>, an XML
    declaration), its sensor's placement spread over three lines, a misspelt shape type
    on line 42 of it (the edits dropped the comments and the blank lines: line 36)."""
    from dopplertof.cli import main

    with open(os.path.join(STOCK, "cornell", "scene.xml"), encoding="utf-8") as f:
        text = f.read()
    placed = '<transform name="to_world"><lookat'
    text = text.replace(placed, '<transform name="to_world">\n\n            <lookat', 1)
    text = text.replace('<shape type="cube"', '<shape type="cubee"', 1)
    line = text[:text.index('type="cubee"')].count("\n") + 1
    assert line == 42  # (the placement's two new lines before it)
    scene = tmp_path / "scene.xml"
    scene.write_text(text, encoding="utf-8")
    code = main([how[0], str(scene), "-D", "unit=mm", "-o", str(tmp_path / "out"), "--quiet",
                 *how[1:]])
    err = capsys.readouterr().err
    assert code == 2, err
    assert f"{scene}:{line}: failed to instantiate shape plugin of type \"cubee\"" in err, err
    assert not (tmp_path / "out").exists()


def test_a_define_that_sizes_the_film_is_said_to_be_replaced():
    """``-D res=32`` with ``--camera`` and no ``--res``: the scene's film (width and
    height ``$res``) gives way to the preset's pixels, at the preset's full size; a note
    says so and names --res. With --res (a resolution), or a define that does not size
    the film, nothing is said."""
    from dopplertof.cameras import load_preset, load_scene_for_camera

    dopplertof.set_variant()
    scene = os.path.join(os.path.dirname(STOCK), "..", "..", "examples",
                         "translating_sphere.xml")
    preset = load_preset("pmd-argos3d-p320")
    loaded = load_scene_for_camera(scene, preset, None, {"res": "32"}, keep_view=True)
    said = [n for n in loaded.notes if "-D res=32 sets the scene's film" in n]
    assert len(said) == 1 and "352x287 pixels replace: --res WIDTHxHEIGHT" in said[0]
    assert loaded.sensor.film().size().x == 352
    for resolution, defines in (((8, 6), {"res": "32"}), (None, {"spp": "4"})):
        loaded = load_scene_for_camera(scene, preset, resolution, defines, keep_view=True)
        assert not any("sets the scene's film" in n for n in loaded.notes)
