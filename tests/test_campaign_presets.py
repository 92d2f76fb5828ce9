"""Camera presets that describe no real camera are refused in one line naming the file
and the key; an illuminator lights only its field of view; the capture's outputs and
its Python API refuse what they cannot use (fault campaign of 2026-12-07)."""

from __future__ import annotations

import math
import os

import numpy as np
import pytest

from test_cameras import run_cli

PRESETS = os.path.join(os.path.dirname(__file__), os.pardir, "src", "dopplertof", "cameras",
                       "presets")


def azure_text(old: str, new: str) -> str:
    """The shipped azure-kinect preset with one line edited."""
    with open(os.path.join(PRESETS, "azure-kinect.toml"), encoding="utf-8") as f:
        text = f.read()
    assert old in text, old
    return text.replace(old, new, 1)


def write(tmp_path, text: str, name: str = "camera.toml") -> str:
    path = tmp_path / name
    path.write_text(text)
    return str(path)


# ---- Values no camera has ------------------------------------------------------------------

@pytest.mark.parametrize("old, new, wanted", [
    # radians typed as degrees
    ("fov_deg = [75.0, 65.0]", "fov_deg = [1.31, 1.13]", "illuminator.fov_deg out of range"),
    ("pixel_pitch_um = 3.5", "pixel_pitch_um = 1e300", "optics.pixel_pitch_um out of range"),
    ("pixel_pitch_um = 3.5", "pixel_pitch_um = 1e-300", "optics.pixel_pitch_um out of range"),
    ("read_noise_electrons = 5.0", "read_noise_electrons = 1e300",
     "sensor.read_noise_electrons out of range"),
    ("dark_current_electrons_per_s = 100.0", "dark_current_electrons_per_s = 1e300",
     "sensor.dark_current_electrons_per_s out of range"),
    ("gain_electrons_per_dn = 1.25", "gain_electrons_per_dn = 1e-300",
     "sensor.gain_electrons_per_dn out of range"),
    ("min_range_m = 0.5", "min_range_m = 10.0", "reconstruction.min_range_m = 10 is not below"),
    # a 16-bit ADC whose offset leaves no room above a dark pixel's noise
    ("offset_dn = 32768.0", "offset_dn = 65534.0", "sensor.offset_dn = 65534 leaves a pixel"),
    ("offset_dn = 32768.0", "offset_dn = 0.0", "sensor.offset_dn = 0 leaves a pixel"),
    # extreme pincushion: monotonic, but the fixed-point inverse does not converge
    ("distortion = [0.0, 0.0, 0.0, 0.0, 0.0]", "distortion = [9.9, 9.9, 0, 0, 9.9]",
     "optics.distortion = [9.9, 9.9, 0, 0, 9.9]: its inverse does not converge"),
    # extreme barrel: the rays fold back before the image's corner
    ("distortion = [0.0, 0.0, 0.0, 0.0, 0.0]", "distortion = [-9.9, 0, 0, 0, 0]",
     "optics.distortion = [-9.9, 0, 0, 0, 0]: the radial map"),
])
def test_a_preset_no_camera_has_is_refused_in_one_line(tmp_path, old, new, wanted):
    from dopplertof.cameras import load_preset
    from dopplertof.cameras.preset import PresetError

    path = write(tmp_path, azure_text(old, new))
    with pytest.raises(PresetError) as caught:
        load_preset(path)
    message = str(caught.value)
    assert message.startswith(path + ": ") and wanted in message and "\n" not in message


def test_the_cameras_command_refuses_it_with_exit_2(tmp_path):
    path = write(tmp_path, azure_text("pixel_pitch_um = 3.5", "pixel_pitch_um = 1e300"))
    done = run_cli("cameras", path)
    assert done.returncode == 2 and "Traceback" not in done.stderr
    assert "optics.pixel_pitch_um out of range" in done.stderr and path in done.stderr


def test_moderate_distortion_and_the_shipped_presets_still_load(tmp_path):
    from dopplertof.cameras import load_preset, preset_names

    for name in preset_names():
        load_preset(name)
    lens = "distortion = [-0.25, 0.06, 0.002, -0.003, 0.01]"  # tests/test_capture_geometry.py
    load_preset(write(tmp_path, azure_text("distortion = [0.0, 0.0, 0.0, 0.0, 0.0]", lens)))


def test_the_distortion_check_inverts_what_it_accepts():
    """Over an accepted lens, the inverse maps every image point back onto itself (to
    float64 rounding after the fixed-point steps: far under the thousandth of a pixel
    the check allows)."""
    from dopplertof.integrators.camera import LensDistortion

    lens = LensDistortion([-0.25, 0.06, 0.002, -0.003, 0.01], 64, 58, 75.0)
    assert lens.problem(64, 58) is None
    xd, yd = np.meshgrid(np.linspace(-0.5, 0.5, 9) * lens.sx, np.linspace(-0.5, 0.5, 9) * lens.sy)
    bx, by = lens.forward(*lens.inverse(xd, yd))
    assert np.hypot(bx - xd, by - yd).max() * 64 / lens.sx <= LensDistortion.INVERSE_TOLERANCE_PX


def test_an_auto_exposed_preset_refuses_the_sections_it_would_ignore(tmp_path):
    from dopplertof.cameras import load_preset
    from dopplertof.cameras.preset import PresetError

    with open(os.path.join(PRESETS, "opt8241.toml"), encoding="utf-8") as f:
        text = f.read()
    extra = ("\n[illuminator]\npower_w = 1.0\nwavelength_nm = 850.0\nfov_deg = [70.0, 60.0]\n"
             "offset_m = [0.0, 0.0, 0.0]\n[conditions]\nambient_irradiance_uw_cm2_nm = 90.0\n")
    path = write(tmp_path, text + extra)
    with pytest.raises(PresetError, match=r"\[illuminator\] and \[conditions\] would be "
                                          r"ignored") as caught:
        load_preset(path)
    assert str(caught.value).startswith(path)


def test_load_preset_names_its_argument_on_a_wrong_type():
    from dopplertof.cameras import load_preset

    for value in (None, 42):
        with pytest.raises(TypeError, match="camera preset: a packaged preset's name"):
            load_preset(value)


# ---- The illuminator lights its field of view only -------------------------------------------

def test_a_light_covering_the_view_stays_the_point_light_it_was():
    """An illuminator whose field holds the view: the same point light, byte for byte."""
    from dopplertof.cameras import load_preset
    from dopplertof.cameras.radiometry import illuminator_xml, radiant_intensity

    preset = load_preset("azure-kinect-wfov-binned")  # 120 x 120 deg over a square view
    intensity = radiant_intensity(preset.illuminator)
    assert illuminator_xml(preset) == (
        f'<emitter type="point" id="camera_illuminator"><rgb name="intensity" '
        f'value="{intensity!r}"/><transform name="to_world"><translate x="-0.0" '
        'y="-0.0" z="0.0"/></transform><animation name="to_world" '
        'follow="sensor"/></emitter>')


def test_the_confined_light_is_the_rectangle_of_its_field():
    """The spot light of light_xml gives I / d^2 at directions inside the h x v pyramid
    and nothing outside: the texture's arithmetic is float32, so a direction is judged
    by the side of the edge it lies on farther than float32's relative step."""
    import dopplertof
    import drjit as dr
    import mitsuba as mi

    from dopplertof.cameras.radiometry import light_xml

    dopplertof.set_variant()
    h, v, intensity = 40.0, 25.0, 3.0
    xml = light_xml(intensity, [h, v], "").replace(
        '<animation name="to_world" follow="sensor"/>', "")  # (dopplertof's own loader)
    emitter = mi.load_string(f'<scene version="3.0.0">{xml}</scene>').emitters()[0]
    n = 101
    s = np.linspace(-1.0, 1.0, n)
    x, y = (a.ravel() for a in np.meshgrid(s, s))
    it = dr.zeros(mi.Interaction3f, n * n)
    it.p = mi.Point3f(x, y, np.ones(n * n))
    _, weight = emitter.sample_direction(it, mi.Point2f(0.5, 0.5))
    radiant = np.array(weight)[0] * (x * x + y * y + 1)
    tan_h, tan_v = math.tan(math.radians(h / 2)), math.tan(math.radians(v / 2))
    step = 1e-5  # well over float32's 6e-8 relative rounding of the texture coordinates
    inside = (np.abs(x) < tan_h - step) & (np.abs(y) < tan_v - step)
    outside = (np.abs(x) > tan_h + step) | (np.abs(y) > tan_v + step)
    assert inside.sum() > 0 and outside.sum() > 0
    assert np.all(radiant[outside] == 0)
    # I / d^2 times d^2 in float32: within a few float32 steps of I
    assert np.allclose(radiant[inside], intensity, rtol=8 * 2.0**-24 * 4, atol=0)


def test_pixels_outside_a_narrow_illuminator_get_no_light(tmp_path):
    """azure-kinect with a 20 x 20 deg illuminator (its camera sees 75 deg): a wall fills
    the view, and only the pixels inside the lit square report a depth."""
    import dopplertof
    from dopplertof.cameras import load_preset
    from dopplertof.cameras.accuracy import wall_scene_xml
    from dopplertof.cameras.capture import capture_camera
    from dopplertof.cameras.scene_view import with_illuminator
    from dopplertof.cameras.radiometry import view_tangents
    from dopplertof.scene import load_string

    dopplertof.set_variant()
    preset = load_preset(write(tmp_path, azure_text("fov_deg = [75.0, 65.0]",
                                                    "fov_deg = [20.0, 20.0]")))
    n = 16
    text = with_illuminator(wall_scene_xml(1.5, 0.5, preset.fov_deg, n, 4), preset,
                            view_tangents(preset.fov_deg, n, n))
    result = capture_camera(load_string(text, {}, source="wall"), preset, 4, 0,
                            noise=False, progress=False)
    # pixel centres' directions on the plane at unit depth; the lit square's half side
    centres = ((np.arange(n) + 0.5) / n * 2 - 1) * math.tan(math.radians(preset.fov_deg) / 2)
    half = math.tan(math.radians(10.0))
    # a pixel wholly outside: its nearest edge beyond the lit square
    pixel = 2 * math.tan(math.radians(preset.fov_deg) / 2) / n
    far = np.abs(centres) - pixel / 2 > half
    outside = far[None, :] | far[:, None]
    assert outside.sum() >= 200
    assert np.all(result.rendered[:, outside] == 0) and np.all(result.light.unmodulated[outside] == 0)
    assert not np.isfinite(result.depth[outside]).any()
    assert result.reconstruction.low_confidence[outside].all()
    # and they say why: outside the illuminator's field (exactly the pixels wholly out)
    assert np.array_equal(result.reconstruction.unlit, outside)
    assert result.summary["depth"]["masked_pixels"]["outside the illuminator's field"] == \
        outside.sum()
    lit = (np.abs(centres)[None, :] + pixel / 2 < half) & (np.abs(centres)[:, None] + pixel / 2 < half)
    assert lit.sum() > 0 and np.isfinite(result.depth[lit]).all()


def test_azure_kinects_nfov_illuminator_leaves_the_top_and_bottom_rows_unlit():
    """Microsoft gives the NFOV modes a 75 x 65 deg field of view (its illuminator's
    field in the presets), but 320 x 288 (and 640 x 576) square pixels over 75 deg
    see 2 atan(tan 37.5 deg x 288 / 320) = 69.27 deg vertically. The rows whose
    footprint lies wholly beyond 65 deg: those whose edge nearest the axis is more than
    f tan 32.5 deg = 132.84 px from the centre (f = 160 / tan 37.5 deg = 208.51 px),
    11 at the top and 11 at the bottom (7.6% of the rows); no column."""
    from dopplertof.cameras import load_preset
    from dopplertof.cameras.radiometry import outside_field
    from dopplertof.integrators.camera import pinhole_intrinsics

    for name, (w, h) in (("azure-kinect-nfov-binned", (320, 288)),
                         ("azure-kinect", (640, 576))):
        preset = load_preset(name)
        assert preset.resolution == (w, h) and preset.illuminator["fov_deg"] == [75.0, 65.0]
        unlit = outside_field(preset.illuminator["fov_deg"],
                              pinhole_intrinsics(w, h, preset.fov_deg), w, h)
        focal = 0.5 * w / math.tan(math.radians(37.5))
        per_side = math.floor(h / 2 - focal * math.tan(math.radians(32.5)))
        rows = np.flatnonzero(unlit.all(axis=1))
        assert rows.tolist() == list(range(per_side)) + list(range(h - per_side, h))
        assert not unlit[per_side:h - per_side].any()
        assert (per_side, name) in ((11, "azure-kinect-nfov-binned"), (22, "azure-kinect"))


def test_a_capture_through_the_nfov_preset_reports_its_unlit_rows_invalid(tmp_path):
    """azure-kinect-nfov-binned at 40 x 36 (its aspect): a wall fills the view, the
    illuminator lights 65 of the view's 69.27 deg, so rows 0 and 35 (wholly beyond
    it: 18 - 20/tan 37.5 deg x tan 32.5 deg = 1.4 rows a side) get none of its light
    and, with shot and read noise too, report no depth, counted in summary.json as
    outside the illuminator's field; the rows beside them, partly lit, are not."""
    import dopplertof
    from dopplertof.cameras import load_preset
    from dopplertof.cameras.accuracy import wall_scene_xml
    from dopplertof.cameras.capture import capture_camera, format_camera_summary
    from dopplertof.cameras.scene_view import scene_text_for_camera, with_illuminator
    from dopplertof.cameras.radiometry import view_tangents
    from dopplertof.scene import load_string

    dopplertof.set_variant()
    preset = load_preset("azure-kinect-nfov-binned")
    w, h = 40, 36
    text = scene_text_for_camera(wall_scene_xml(2.0, 0.5, preset.fov_deg, w, 4), w, h,
                                 preset.fov_deg, "wall")
    text = with_illuminator(text, preset, view_tangents(preset.fov_deg, w, h))
    result = capture_camera(load_string(text, {}, source="wall"), preset, 4, 0,
                            progress=False)
    unlit = result.reconstruction.unlit
    assert np.flatnonzero(unlit.any(axis=1)).tolist() == [0, h - 1] and unlit[[0, -1]].all()
    assert not np.isfinite(result.depth[unlit]).any()
    assert np.all(result.light.unmodulated[[0, -1]] == 0)
    assert np.all(result.light.unmodulated[[1, -2]] > 0)
    masked = result.summary["depth"]["masked_pixels"]
    assert masked["outside the illuminator's field"] == 2 * w
    assert f"{2 * w} px outside the illuminator's field" in format_camera_summary(
        result.summary)
    result.write(str(tmp_path / "capture"))
    assert np.array_equal(np.load(tmp_path / "capture" / "mask_unlit.npy"), unlit)


# ---- The reconstruction says why a depth is NaN -------------------------------------------

def test_a_depth_no_candidate_explains_is_masked_outside_the_range(monkeypatch):
    """Where the unwrapping finds no wrap count within the range searched (every
    candidate beyond it: a range that ends at 5 cm), its depth is NaN and neither failed
    nor beyond: the reconstruction masks it outside the range."""
    import dataclasses

    from dopplertof.cameras import load_preset
    from dopplertof.cameras import reconstruct as module
    from dopplertof.cameras.sensor import read_frames

    preset = load_preset("kinect-v2")
    real = module.unwrap_likelihood

    def no_candidate(*args, **kwargs):
        found = real(*args, **kwargs)
        nothing = np.zeros(found.depth.shape, bool)
        return dataclasses.replace(found, depth=np.full(found.depth.shape, np.nan),
                                   ambiguous=nothing, inconsistent=nothing, beyond=nothing)

    monkeypatch.setattr(module, "unwrap_likelihood", no_candidate)
    shape = (4, 4)
    rendered = np.stack([np.full(shape, math.cos(math.radians(30.0 - f.phase_deg)))
                         for f in preset.frames])
    readout = read_frames(rendered, np.full(shape, 2.0), [f.integration_s for f in preset.frames],
                          preset.sensor, preset.contrast, None)
    recon = module.reconstruct(readout, preset)
    assert not (recon.saturated | recon.low_confidence | recon.unwrap_failed).any()
    assert not np.isfinite(recon.depth).any()
    assert recon.masked.all() and recon.out_of_range.all()
    assert recon.describe()["masked_pixels"]["outside the range"] == 16


# ---- Outputs and the Python API ------------------------------------------------------------

def test_an_empty_output_folder_is_refused(tmp_path):
    from dopplertof.io import OutputError, check_output_folder

    for value in ("", "  "):
        with pytest.raises(OutputError, match="is empty: name a folder"):
            check_output_folder(value)
    scene = tmp_path / "scene.xml"
    scene.write_text("<scene version='3.0.0'/>")
    work = tmp_path / "work"
    work.mkdir()
    done = run_cli("capture", str(scene), "--camera", "azure-kinect", "--res", "4x4",
                   "--spp", "1", "--quiet", "-o", "")
    assert done.returncode == 2 and "Traceback" not in done.stderr
    assert "output folder '' is empty" in done.stderr
    assert os.listdir(work) == []


def test_write_takes_only_a_bool_pointcloud(tmp_path):
    from dopplertof.cameras.capture import CameraResult

    result = CameraResult.__new__(CameraResult)
    for value in ("no", 1, None):
        with pytest.raises(TypeError, match="pointcloud must be True or False"):
            result.write(tmp_path / "out", pointcloud=value)
    assert not (tmp_path / "out").exists()


def test_ambient_irradiance_takes_numpy_integers():
    from dopplertof.cameras import load_preset
    from dopplertof.cameras.capture import _ambient_irradiance
    from dopplertof.tof.capture import CaptureError

    preset = load_preset("azure-kinect")
    assert _ambient_irradiance(preset, np.int64(5)) == 5.0
    with pytest.raises(CaptureError, match="ambient_irradiance must be a number"):
        _ambient_irradiance(preset, np.bool_(True))


def test_point_cloud_normals_of_a_single_pixel_are_nan():
    from dopplertof.tof.geometry import point_cloud

    geometry = {"K": [[1.0, 0, 0.5], [0, 1.0, 0.5], [0, 0, 1]], "resolution": [1, 1],
                "pose_camera_to_world": np.eye(4).tolist(), "distortion_k1_k2_p1_p2_k3": [0.0] * 5}
    out = point_cloud(geometry, np.ones((1, 1)), np.ones((1, 1)), None, np.zeros((1, 1)))
    assert out["valid"].tolist() == [1] and np.isnan(out["nx"]).all()
    assert out["z"][0] == pytest.approx(1.0, rel=2.0**-23)
