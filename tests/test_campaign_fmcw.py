"""The FMCW lidar's bad inputs and its folded beats (the reliability campaign's FMCW
rows, docs/reliability.md; docs/fmcw.md sections 3 and 5): a unit mistake in the chirp, a
key given twice, an option that does nothing, Python arguments of the wrong type, an
empty output folder and one that holds another output are refused in one line before
anything is written; NumPy numbers are numbers; a frame whose beats can fold says so."""

import hashlib
import json
import math
import os
import re

import numpy as np
import pytest
from analytic import plane_scene

import dopplertof
from dopplertof import file_formats, io
from dopplertof.cli import main
from dopplertof.fmcw import Chirp, FMCWError, fmcw
from dopplertof.modulation import SPEED_OF_LIGHT

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SPHERE = os.path.join(ROOT, "examples", "translating_sphere.xml")
EXPOSURE = 0.0015  # plane_scene's
SMALL = Chirp(bandwidth=1e9, chirp_time=10e-6, bins=64)


def _plane(z0=3.0, velocity=0.5, res=1, spp=4):
    return dopplertof.load_dict(plane_scene(z0, velocity, exposure=EXPOSURE, res=res, spp=spp))


def _sphere_with(tmp_path, lines: str, name="bad.xml") -> str:
    """examples/translating_sphere.xml with ``lines`` added to its integrator (its
    line 14)."""
    text = open(SPHERE).read().replace('<integrator type="dopplertof">',
                                       '<integrator type="dopplertof">' + lines, 1)
    path = tmp_path / name
    path.write_text(text)
    return str(path)


def _digests(folder) -> dict:
    return {name: hashlib.sha256((folder / name).read_bytes()).hexdigest()
            for name in sorted(os.listdir(folder))}


def _refused(capsys, code, *words):
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and "Traceback" not in err, err
    for word in words:
        assert word in err, err
    return err


# ---- The chirp: a sweep far below its carrier, a duration between 1 ns and 1 s ----

@pytest.mark.parametrize("values,message", [
    ({"bandwidth": 4e18}, "bandwidth B is in Hz: got 4e+18 Hz, above the optical carrier "
                          "c/lambda = 193.4 THz"),
    ({"bandwidth": 2.5e12}, "over 1% of the optical carrier"),
    ({"bandwidth": 1e-3}, "under the 1 MHz minimum"),
    ({"chirp_time": 1e-12}, "chirp_time T is in s: got 1e-12 s, under the 1 ns minimum"),
    ({"chirp_time": 1e6}, "over the 1 s maximum"),
])
def test_a_chirp_out_of_its_physical_range_is_refused(values, message):
    """PA19, PA21: a sweep over a hundredth of the carrier c/lambda (193.4 THz at
    1550 nm) or under 1 MHz, a chirp under 1 ns or over 1 s."""
    with pytest.raises(FMCWError) as info:
        Chirp(**values)
    assert message in str(info.value) and "\n" not in str(info.value)
    assert SPEED_OF_LIGHT / 1550e-9 == pytest.approx(193.4e12, rel=1e-3)


@pytest.mark.parametrize("option,value,message", [
    ("--bandwidth", "4e9", "--bandwidth is in GHz: got 4e+09 GHz = 4e+18 Hz, above the "
                           "optical carrier"),
    ("--bandwidth", "1e-300", "--bandwidth is in GHz: got 1e-300 GHz"),
    ("--chirp-time", "1e-5", "--chirp-time is in us: got 1e-05 us = 1e-11 s, under the 1 ns"),
    ("--chirp-time", "1e300", "--chirp-time is in us: got 1e+300 us"),
])
def test_a_unit_mistake_in_an_option_exits_2_before_the_scene_loads(
        tmp_path, capsys, option, value, message):
    """FO04, FO06, FO33, FO34: named in the option's unit; nothing written."""
    out = tmp_path / "out"
    code = main(["fmcw", str(tmp_path / "missing.xml"), "-o", str(out), option, value])
    _refused(capsys, code, message)
    assert not out.exists()


@pytest.mark.parametrize("lines,message", [
    ('<float name="fmcw_bandwidth" value="4e9"/>',
     "fmcw_bandwidth is in GHz: got 4e+09 GHz = 4e+18 Hz, above the optical carrier"),
    ('<float name="fmcw_bandwidth" value="1e-12"/>',
     "fmcw_bandwidth is in GHz: got 1e-12 GHz = 0.001 Hz, under the 1 MHz minimum"),
    ('<float name="fmcw_chirp_time" value="1e-5"/>',
     "fmcw_chirp_time is in us: got 1e-05 us = 1e-11 s, under the 1 ns minimum"),
    ('<float name="fmcw_chirp_time" value="1e12"/>',
     "fmcw_chirp_time is in us: got 1e+12 us = 1e+06 s, over the 1 s maximum"),
    ('<string name="fmcw_beam" value="collimated"/>'
     '<float name="fmcw_beam_intensity" value="1e300"/>',
     "fmcw_beam_intensity must be at most 3.403e+38 W/sr"),
    ('<integer name="fmcw_bins" value="1024"/><integer name="fmcw_bins" value="64"/>',
     "'fmcw_bins' given twice in <integrator> (first '1024', then '64')"),
])
def test_a_bad_xml_chirp_exits_2_naming_the_file_line_and_key(tmp_path, capsys, lines,
                                                               message):
    """FX10, FX11, FX13, FX14, FX26, FX29; load_file raises the same line."""
    scene = _sphere_with(tmp_path, lines)
    out = tmp_path / "out"
    code = main(["fmcw", scene, "-o", str(out), "--spp", "1", "-D", "res=4"])
    _refused(capsys, code, message, f"{scene}:14:")
    assert not out.exists()
    with pytest.raises(dopplertof.SceneError, match=message.replace("(", r"\(")
                       .replace(")", r"\)").replace("+", r"\+")):
        dopplertof.load_file(scene)


def test_an_overflowing_spectrum_is_refused_not_written():
    """FX26 in Python: an intensity over float32's largest number is refused by the
    beam; nothing inf or NaN is returned."""
    with pytest.raises(ValueError, match="float32"):
        fmcw(_plane(), SMALL, spp=1, beam="collimated", beam_intensity=1e300)


def test_a_chirp_shorter_than_the_scene_s_round_trip_is_refused():
    """A plane at 3 m: its round trip 2 x 3 m / c = 20 ns; a 10 ns chirp (within the
    1 ns - 1 s range) cannot outlast its echo."""
    scene = _plane(3.0, 0.0)
    with pytest.raises(FMCWError, match="not longer than the scene's longest round trip"):
        fmcw(scene, Chirp(bandwidth=1e9, chirp_time=10e-9, bins=8), spp=1)
    assert 2 * 3.0 / SPEED_OF_LIGHT > 10e-9


# ---- A scene lit by the collimated beam alone ----

def _lightless(tmp_path, integrator_lines="") -> str:
    """The translating sphere without its point light."""
    text = re.sub(r"<emitter.*?</emitter>", "", open(SPHERE).read(), flags=re.S)
    text = text.replace('<integrator type="dopplertof">',
                        '<integrator type="dopplertof">' + integrator_lines, 1)
    path = tmp_path / "lightless.xml"
    path.write_text(text)
    return str(path)


def test_a_scene_without_emitters_is_ranged_by_the_collimated_beam(tmp_path, capsys):
    """FO31: the beam is the only light; the flood beam and the D-ToF renders still
    refuse the scene (nothing would light it)."""
    scene = _lightless(tmp_path)
    out = tmp_path / "out"
    code = main(["fmcw", scene, "-o", str(out), "--spp", "1", "-D", "res=4",
                 "--beam", "collimated", "--bins", "512", "-P", "max_depth=2"])
    assert code == 0, capsys.readouterr().err
    assert np.isfinite(np.load(out / "range.npy")).all()
    capsys.readouterr()
    code = main(["fmcw", scene, "-o", str(tmp_path / "flood"), "--spp", "1", "-D", "res=4"])
    _refused(capsys, code, "the scene has no emitter", "--beam collimated")
    lit = dopplertof.load_file(_lightless(tmp_path, '<string name="fmcw_beam" '
                                          'value="collimated"/>'), {"res": "4"})
    assert np.isfinite(fmcw(lit, Chirp(bins=512), spp=1).range).all()
    for render in (lambda: fmcw(lit, Chirp(bins=512), spp=1, beam="flood"),
                   lambda: dopplertof.render(lit, spp=2)):
        with pytest.raises(dopplertof.SceneError, match="the scene has no emitter"):
            render()


# ---- Options and arguments ----

def test_a_beam_intensity_with_the_flood_beam_is_refused(tmp_path, capsys):
    """FO12: the flood beam (the scene's lights) ignores it: the command refuses it, a
    Python call (whose loops may pass one intensity to both beams) warns."""
    out = tmp_path / "out"
    code = main(["fmcw", SPHERE, "-o", str(out), "--spp", "1", "-D", "res=4",
                 "--beam-intensity", "5"])
    _refused(capsys, code, "--beam-intensity is a collimated beam's")
    assert not out.exists()
    warned = fmcw(_plane(), SMALL, spp=1, beam_intensity=5.0)  # (Python: a warning)
    assert "beam_intensity 5.0 is a collimated beam's" in warned.summary["warnings"][0]


def test_python_arguments_of_the_wrong_type_are_named():
    """PA05, PA06, PA12, PA14: a TypeError naming the argument."""
    scene = _plane()
    with pytest.raises(TypeError, match="scene must be a DopplerScene.*load it first"):
        fmcw(SPHERE)
    with pytest.raises(TypeError, match="scene must be a DopplerScene"):
        fmcw(None)
    with pytest.raises(TypeError, match="params must be a dict"):
        fmcw(scene, SMALL, spp=1, params="fmcw_bins=3")
    with pytest.raises(TypeError, match="speckle must be True or False"):
        fmcw(scene, SMALL, spp=1, speckle="no")


def test_a_plain_mitsuba_scene_is_taken_as_a_static_one():
    """PA22: as capture and render take it."""
    import mitsuba as mi

    scene = mi.load_dict({
        "type": "scene",
        "sensor": {"type": "perspective", "fov": 30,
                   "to_world": mi.ScalarTransform4f().look_at(origin=[0, 0, 0],
                                                              target=[0, 0, 1], up=[0, 1, 0]),
                   "film": {"type": "hdrfilm", "width": 2, "height": 2},
                   "sampler": {"type": "independent", "sample_count": 2}},
        "light": {"type": "point", "position": [0, 0, 0]},
        "plane": {"type": "rectangle", "to_world": mi.ScalarTransform4f().translate(
            [0, 0, 3]).rotate([0, 1, 0], 180).scale(50)},
    })
    result = fmcw(scene, SMALL, spp=2)
    assert result.range.shape == (2, 2)  # within a range bin c/(2B) of the truth
    assert (np.abs(result.range - result.range_gt) < SMALL.record()["range_per_bin_m"]).all()


def test_numpy_numbers_are_numbers():
    """PA15, PA16, PA20: np.int64 and np.float32 taken as the numbers they hold."""
    assert Chirp(bins=np.int64(256)) == Chirp(bins=256)
    assert type(Chirp(bins=np.int64(256)).bins) is int
    wavelength = np.float32(1.55e-6)
    assert Chirp(wavelength=wavelength) == Chirp(wavelength=float(wavelength))
    result = fmcw(_plane(), SMALL, spp=1, returns=np.int64(2))
    assert result.returns_range.shape == (1, 1, 2)


# ---- The output folder ----

def test_an_empty_output_folder_is_refused_and_the_current_folder_untouched(
        tmp_path, capsys, monkeypatch):
    """OU16, OU16b: ``-o "$OUT"`` with OUT unset, run inside a capture's folder."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "summary.json").write_text("{}")
    before = _digests(tmp_path)
    code = main(["fmcw", SPHERE, "-o", "", "--spp", "1", "-D", "res=4"])
    _refused(capsys, code, "output folder '' is empty")
    assert _digests(tmp_path) == before


def test_a_folder_holding_another_output_is_not_overwritten(tmp_path, capsys):
    """OU16b: a capture's summary.json, velocity.npy and velocity.png (its set's
    manifest lists them) are never replaced by an FMCW frame's: the command refuses
    before rendering and the Python write at its commit; the capture's files stay as
    they were, and an FMCW frame rewrites its own folder."""
    folder = tmp_path / "capture"
    with io.output_folder(folder, "capture") as staged:
        file_formats.write_json(staged.path("summary.json"), {"kind": "capture"})
        file_formats.write_npy(staged.path("velocity.npy"), np.zeros((2, 2)))
        file_formats.write_npy(staged.path("depth.npy"), np.zeros((2, 2)))
    before = _digests(folder)
    code = main(["fmcw", SPHERE, "-o", str(folder), "--spp", "1", "-D", "res=4"])
    _refused(capsys, code, "holds the capture output that wrote velocity.npy, summary.json",
             "write into another folder")
    result = fmcw(_plane(), SMALL, spp=1)
    with pytest.raises(io.OutputError, match="the fmcw output would overwrite them"):
        result.write(folder)
    assert _digests(folder) == before
    own = tmp_path / "fmcw"
    first = result.write(own)
    assert result.write(own) == first and (own / "ambiguous.npy").exists()


@pytest.mark.parametrize("folder", [None, 42])
def test_a_folder_that_is_no_path_is_a_type_error_naming_it(folder):
    """PA23, PA24."""
    result = fmcw(_plane(), SMALL, spp=1)
    with pytest.raises(TypeError, match="the output folder must be a path"):
        result.write(folder)


# ---- Folded beats ----

def test_a_plane_faster_than_its_range_beat_folds_and_is_flagged():
    """A plane at 3 m approaching at 2 m/s with B = 1 GHz over 10 us at 1550 nm: its
    Doppler beat 2 v / lambda = 2.58 MHz exceeds its range beat (B/T) 2 d / c = 2.0 MHz
    (the unambiguous speed at 3 m is B lambda d / (c T) = 1.55 m/s), so its up beat
    crosses zero and the pair reads the range c T v / (lambda B) = 3.87 m from the
    Doppler: the summary counts it folded and ambiguous and warns; a plane receding at
    0.5 m/s is neither."""
    velocity, z0 = -2.0, 3.0
    result = fmcw(_plane(z0, velocity), SMALL, spp=4)
    d, v = z0 + velocity * 0.5 * EXPOSURE, abs(velocity)
    assert SMALL.unambiguous_speed(d) == pytest.approx(
        1e9 / 10e-6 * 1550e-9 * d / SPEED_OF_LIGHT, rel=1e-12)
    assert SMALL.unambiguous_speed(d) < v
    swapped = SPEED_OF_LIGHT * SMALL.chirp_time * v / (SMALL.wavelength * SMALL.bandwidth)
    assert abs(result.range[0, 0] - swapped) < SMALL.record()["range_per_bin_m"]
    record = result.summary["folding"]
    assert (record["folded_pixels"], record["ambiguous_pixels"]) == (1, 1)
    assert result.ambiguous.tolist() == [[True]]
    assert record["max_speed_m_s"] == pytest.approx(v, rel=1e-3)
    assert record["unambiguous_beyond_m"] == pytest.approx(
        v * SPEED_OF_LIGHT / (SMALL.slope * SMALL.wavelength), rel=1e-3)
    assert "the beats fold: 1 pixel(s)" in result.summary["warnings"][0]

    calm = fmcw(_plane(z0, 0.5), SMALL, spp=4)
    assert (calm.summary["folding"]["folded_pixels"],
            calm.summary["folding"]["ambiguous_pixels"]) == (0, 0)
    assert "warnings" not in calm.summary and not calm.ambiguous.any()


def test_an_iq_receiver_sees_the_beats_sign_and_nothing_folds():
    """The folding plane (3 m, approaching at 2 m/s) with an I/Q receiver: the down beat
    (B/T) 2 d / c + 2 |v| / lambda and the up beat, now below zero, read as signed
    frequencies over 2 M bins from -M / T, give the plane's range and velocity within a
    bin each, and nothing is folded or ambiguous; a plane that did not fold reads the
    same range and velocity from either receiver (to the centroid's rounding)."""
    from dataclasses import replace

    iq = replace(SMALL, iq=True)
    np.testing.assert_allclose(iq.frequencies(), np.arange(-64, 64) * 1e5, rtol=1e-15)
    velocity, z0 = -2.0, 3.0
    result = fmcw(_plane(z0, velocity), iq, spp=4)
    d = z0 + velocity * 0.5 * EXPOSURE
    up, down = iq.beats(2 * d, 2 * velocity)
    assert up < 0 < down  # (the up beat below zero: a real receiver folds it)
    assert result.spectrum.shape == (1, 1, 2, 128)
    record = iq.record()
    assert abs(result.range[0, 0] - d) < record["range_per_bin_m"]
    assert abs(result.velocity[0, 0] - velocity) < record["velocity_per_bin_m_s"]
    folding = result.summary["folding"]
    assert (folding["folded_pixels"], folding["ambiguous_pixels"]) == (0, 0)
    assert folding["receiver"] == "I/Q" and "warnings" not in result.summary
    assert result.summary["chirp"]["receiver"].startswith("I/Q")
    # the same plane unfolded: the same readings, but for the float32 bin position, which
    # carries the offset M = 64 with an I/Q receiver (a unit in the last place below 128:
    # 2^-16 bin; twice that per reading, of range or of velocity)
    real, both = fmcw(_plane(z0, 0.5), SMALL, spp=4), fmcw(_plane(z0, 0.5), iq, spp=4)
    assert abs(both.range[0, 0] - real.range[0, 0]) <= 2 * 2.0 ** -16 * record[
        "range_per_bin_m"]
    assert abs(both.velocity[0, 0] - real.velocity[0, 0]) <= 2 * 2.0 ** -16 * record[
        "velocity_per_bin_m_s"]
    with pytest.raises(FMCWError, match="iq must be True or False, got 'yes'"):
        Chirp(iq="yes")


def test_the_command_warns_of_folded_beats(tmp_path, capsys):
    """The translating sphere at -10 m/s with the default chirp (B = 1 GHz over 10 us):
    unambiguous only beyond 10 m/s x c T / (B lambda) = 19.3 m, farther than the scene:
    the command warns on stderr and writes the mask."""
    out = tmp_path / "out"
    assert main(["fmcw", SPHERE, "-o", str(out), "--spp", "2", "-D", "res=4",
                 "--bins", "512", "-P", "max_depth=2"]) == 0
    err = capsys.readouterr().err
    assert "dopplertof: warning: the beats fold" in err
    assert "raise B / T, or use an I/Q receiver (--iq" in err  # (what to do, both ways)
    summary = json.loads((out / "summary.json").read_text())
    assert summary["folding"]["folded_pixels"] > 0
    assert summary["folding"]["unambiguous_beyond_m"] > 19
    assert np.load(out / "ambiguous.npy").shape == (4, 4)
    assert math.isfinite(summary["folding"]["max_speed_m_s"])
    # the same frame with an I/Q receiver (--iq), at 8x8 (at 4x4 most of the ball's
    # pixels mix it with the wall, whose peaks pair with the ball's): signed beats,
    # nothing folds, no warning; the ball's median pixel reads its range within a range
    # bin (0.15 m) and its velocity within a velocity bin (0.039 m/s)
    iq = tmp_path / "iq"
    assert main(["fmcw", SPHERE, "-o", str(iq), "--spp", "2", "-D", "res=8",
                 "--bins", "512", "-P", "max_depth=2", "--iq"]) == 0
    assert "fold" not in capsys.readouterr().err
    summary = json.loads((iq / "summary.json").read_text())
    assert summary["folding"]["folded_pixels"] == summary["folding"]["ambiguous_pixels"] == 0
    assert np.load(iq / "spectrum.npy").shape == (8, 8, 2, 1024)
    assert np.load(iq / "frequencies.npy")[0] == pytest.approx(-512 / 10e-6, rel=1e-12)
    ball = next(r for r in summary["regions"] if r["name"] == "ball")
    assert ball["range_m"]["median_abs"] < summary["chirp"]["range_per_bin_m"]
    assert ball["velocity_m_s"]["median_abs"] < summary["chirp"]["velocity_per_bin_m_s"]
