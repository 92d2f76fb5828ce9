"""Calibrating a preset to measured wall noise (cameras.calibrate, `dopplertof cameras
BASE --calibrate TABLE.csv -o MINE.toml`), writing presets, and the noise labels."""

import dataclasses
import subprocess
import sys

import pytest

import dopplertof

from dopplertof import cameras
from dopplertof.cameras.accuracy import wall_accuracy
from dopplertof.cameras.calibration import CalibrationError, fit_table, read_table

#: the round trip's known factors: half the illuminator power, four times the read noise
POWER_FACTOR, READ_NOISE_FACTOR = 0.5, 4.0
#: the walls measured (m, albedo), all reported at the modified preset, signal levels
#: over a factor 20 (read noise from 10% to over half of a row's variance), and held out
FITTED_WALLS = ((0.7, 0.15), (1.0, 0.5), (1.5, 0.15), (2.0, 0.5), (3.0, 0.95))
HELD_OUT = ((1.2, 0.3), (2.0, 0.3), (2.5, 0.95))
SEEDS, CROP, SPP = 32, 8, 4
#: the "measurements" are Monte Carlo: a per-pixel std of 32 draws is off by
#: 1/sqrt(2 x 31) = 13% (one sigma), the median of the 16 centre pixels' by about
#: 1.25 x 13% / 4 = 4%; fitting two constants to five rows leaves about that on a
#: prediction, plus the first-order prediction's own bias against Monte Carlo (2% here).
#: 10% (the issue's bound) is about twice that.
TOLERANCE = 0.10


@pytest.fixture(scope="module")
def modified():
    dopplertof.set_variant("llvm_ad_rgb")  # (module fixtures run before conftest's)
    base = cameras.load_preset("azure-kinect")
    return dataclasses.replace(
        base, illuminator=dict(base.illuminator, power_w=base.illuminator["power_w"]
                               * POWER_FACTOR),
        sensor=dict(base.sensor, read_noise_electrons=base.sensor["read_noise_electrons"]
                    * READ_NOISE_FACTOR))


@pytest.fixture(scope="module")
def table(modified, tmp_path_factory):
    path = tmp_path_factory.mktemp("walls") / "walls.csv"
    lines = ["distance_m,albedo,random_error_mm"]
    for distance, albedo in FITTED_WALLS:
        r = wall_accuracy(modified, distance, albedo, seeds=SEEDS, crop=CROP, spp=SPP)
        assert r.valid == 1.0
        lines.append(f"{distance},{albedo},{r.random_m * 1e3!r}")
    path.write_text("\n".join(lines) + "\n")
    return path


def test_round_trip_predicts_held_out_walls(modified, table, tmp_path):
    calibration = fit_table("azure-kinect", table)
    assert set(calibration.fitted) == {"illuminator.power_w", "sensor.read_noise_electrons"}
    written = cameras.write_preset(calibration.preset, tmp_path / "mine.toml")
    mine = cameras.load_preset(written)
    assert mine.noise_calibrated and "walls.csv (5 rows)" in mine.noise_source
    text = open(written).read()
    for key in ("power_w", "read_noise_electrons"):
        line = next(x for x in text.splitlines() if x.startswith(key + " ="))
        assert line.endswith("# calibrated: fitted to walls.csv (5 rows)"), line
    for distance, albedo in HELD_OUT:
        predicted = wall_accuracy(mine, distance, albedo, seeds=2, crop=CROP, spp=SPP)
        truth = wall_accuracy(modified, distance, albedo, seeds=2, crop=CROP, spp=SPP)
        ratio = predicted.predicted_random_m / truth.predicted_random_m
        assert abs(ratio - 1) < TOLERANCE, (distance, albedo, ratio)
    # the fitted rows themselves: within the Monte Carlo scatter of the measurements
    for row, simulated in zip(calibration.rows, calibration.simulated_m):
        assert abs(simulated / row.random_m - 1) < TOLERANCE


def test_one_wall_is_refused(tmp_path):
    path = tmp_path / "one.csv"
    path.write_text("distance_m,albedo,random_error_mm\n2,0.5,3\n2,0.5,3.2\n")
    with pytest.raises(CalibrationError, match=r"one\.csv: every row measures one wall"):
        cameras.calibrate("azure-kinect", path)


@pytest.mark.parametrize("text, message", [
    ("distance_m,albedo\n1,0.5\n", "missing column 'random_error_mm'"),
    ("distance_m,albedo,random_err_mm\n1,0.5,3\n", "unknown column 'random_err_mm'"),
    ("distance_m,albedo,random_error_mm\n1,half,3\n", "line 2, column albedo: 'half'"),
    ("distance_m,albedo,random_error_mm\n1,1.5,3\n", "line 2, column albedo: 1.5 out of"),
    ("distance_m,albedo,random_error_mm\n1,0.5\n", "line 2 has 2 values"),
    ("distance_m,albedo,random_error_mm\n", "no measurements"),
    ("", "empty"),
])
def test_bad_tables_name_file_and_column(tmp_path, text, message):
    path = tmp_path / "t.csv"
    path.write_text(text)
    with pytest.raises(CalibrationError) as e:
        read_table(path)
    assert str(e.value).startswith(str(path)) and message in str(e.value)
    assert "\n" not in str(e.value)


def test_write_preset_round_trips_every_preset(tmp_path):
    for name in cameras.preset_names():
        preset = cameras.load_preset(name)
        again = cameras.load_preset(cameras.write_preset(preset, tmp_path / f"{name}.toml"))
        assert dataclasses.replace(again, source_file=preset.source_file) == preset


def test_noise_labels():
    for name in cameras.preset_names():
        described = cameras.load_preset(name).describe()
        assert described["noise_calibrated"] == (name.startswith("azure-kinect")
                                                 or name == "kinect-v2")
        assert described["noise_source"]
    auto = cameras.load_preset("opt8241")
    assert "relative, not the camera's" in auto.uncalibrated_note()
    assert "relative, not the camera's" in auto.exposure
    assert cameras.load_preset("kinect-v2").uncalibrated_note() is None
    assert cameras.load_preset("azure-kinect").uncalibrated_note() is None


def run(*args):
    return subprocess.run([sys.executable, "-m", "dopplertof.cli", *args],
                          capture_output=True, text=True, timeout=300)


def test_cli_refuses_without_overwriting(tmp_path):
    out = tmp_path / "mine.toml"
    out.write_text("kept")
    bad = tmp_path / "bad.csv"
    bad.write_text("distance_m,albedo,random_error_mm\n1,0.5,-3\n2,0.5,4\n")
    proc = run("cameras", "azure-kinect", "--calibrate", str(bad), "-o", str(out))
    assert proc.returncode == 2
    assert proc.stderr.strip().count("\n") == 0 and "Traceback" not in proc.stderr
    assert f"{bad}: line 2, column random_error_mm" in proc.stderr
    assert out.read_text() == "kept"
    proc = run("cameras", "azure-kinect", "--calibrate", str(bad), "-o", str(tmp_path / "x"))
    assert proc.returncode == 2 and "-o MINE.toml" in proc.stderr


def test_cli_calibrates_and_captures(table, tmp_path):
    out, figure = tmp_path / "mine.toml", tmp_path / "fit.png"
    proc = run("cameras", "azure-kinect", "--calibrate", str(table), "-o", str(out),
               "--figure", str(figure))
    assert proc.returncode == 0, proc.stderr
    assert "measured mm" in proc.stdout and "residual" in proc.stdout
    assert figure.stat().st_size > 0
    assert cameras.load_preset(out).name == "mine"
    assert run("cameras", str(out)).returncode == 0


def test_capture_summaries_carry_the_label():
    from dopplertof.cameras.accuracy import render_wall, wall_scene_xml
    from dopplertof.cameras.capture import capture_camera
    from dopplertof.scene import load_string

    summary = render_wall(cameras.load_preset("azure-kinect"), 2.0, 0.5, crop=4, spp=2).summary
    assert summary["camera"]["noise_calibrated"] is True
    assert summary["noise"]["exposure"].startswith("absolute: ")
    lit = wall_scene_xml(2.0, 0.5, 5.0, 4, 2).replace(
        "</scene>", '<emitter type="point"><point name="position" x="0" y="0" z="0"/>'
        '<rgb name="intensity" value="1"/></emitter></scene>')
    summary = capture_camera(load_string(lit, {}), "opt8241", 2, progress=False).summary
    assert summary["camera"]["noise_calibrated"] is False
    assert summary["noise"]["exposure"].startswith("auto: ")
    assert "relative, not the camera's" in summary["camera"]["noise_source"]
