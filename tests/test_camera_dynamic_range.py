"""The sensor's dynamic-range scheme (sensor.shutters) and kinect-v2 against Fankhauser et
al.'s Kinect v2 noise curve (benchmarks/camera_accuracy.py prints the same side by side)."""

import math
from dataclasses import replace

import numpy as np
import pytest

from dopplertof import cameras
from dopplertof.cameras.preset import PresetError, preset_path
from dopplertof.cameras.sensor import read_frames, shutter_fractions, to_rendered_units

SENSOR = {"quantum_efficiency": 0.5, "full_well_electrons": 1000.0,
          "read_noise_electrons": 3.0, "dark_current_electrons_per_s": 0.0, "adc_bits": 16,
          "gain_electrons_per_dn": 0.5, "offset_dn": 32768.0, "well_fill": 0.9,
          "ambient_photons_per_s": 0.0, "shutters": [1.0, 0.5, 0.25]}


def test_a_pixel_takes_the_longest_shutter_under_the_fill():
    """Limit 0.9 x 1000 = 900 e- on the brightest tap of any frame: 800 keeps the whole
    integration, 1800 fits at exactly 1/2, 1801 and 3600 need 1/4, 5000 gets the
    shortest (and will saturate)."""
    peaks = np.array([800.0, 1800.0, 1801.0, 3600.0, 5000.0])
    means = [(peaks, 0.5 * peaks), (0.25 * peaks, 0.1 * peaks)]
    assert shutter_fractions(means, SENSOR).tolist() == [1.0, 0.5, 0.25, 0.25, 0.25]
    assert shutter_fractions(means, dict(SENSOR, shutters=[1.0])) is None


def _frames(level):
    """Two raw frames (K=2, 1 x N) whose taps carry (e_A, e_B) = K T (g0 R +- c V) / 2 QE."""
    rendered = np.stack([np.full((1, level.size), 0.3), np.full((1, level.size), -0.2)])
    return rendered * level, np.ones((1, level.size)) * level


def test_one_shutter_reads_as_before():
    rendered, unmodulated = _frames(np.linspace(1.0, 8.0, 64))
    without = {k: v for k, v in SENSOR.items() if k != "shutters"}
    for sensor in (without, dict(SENSOR, shutters=[1.0])):
        a = read_frames(rendered, unmodulated, [1e-3, 1e-3], sensor, 0.7,
                        np.random.Generator(np.random.PCG64(3)), photons_per_unit=2e5)
        b = read_frames(rendered, unmodulated, [1e-3, 1e-3], without, 0.7,
                        np.random.Generator(np.random.PCG64(3)), photons_per_unit=2e5)
        assert a.shutter is None
        assert np.array_equal(a.raw, b.raw) and np.array_equal(a.variance, b.variance)


def test_a_shuttered_pixel_scales_its_electrons_and_units_undo_it():
    """Every electron scales by the pixel's shutter s: the ideal differential by s, the
    predicted variance to (s (e_A + e_B) + 2 r^2) / g^2 + 1/12, and the rendered units
    are the same values whatever the shutter (to rounding of the float sums, 1e-12)."""
    level = np.array([1.0, 3.0, 7.0])
    rendered, unmodulated = _frames(level)
    photons, exposure = 2e5, 1e-3  # QE K T = 100 e- per unit
    one = dict(SENSOR, shutters=[1.0])
    full = read_frames(rendered, unmodulated, [exposure] * 2, one, 0.7,
                       photons_per_unit=photons)
    shut = read_frames(rendered, unmodulated, [exposure] * 2, SENSOR, 0.7,
                       photons_per_unit=photons)
    # brightest tap 0.5 x 100 x level x (1 + 0.7 x 0.3) = 60.5 level: 60.5, 181.5, 423.5
    # e- under 900 at s = 1; raise the level by 8: 484, 1452, 3388 -> 1, 1/2, 1/4
    bright = read_frames(rendered * 8, unmodulated * 8, [exposure] * 2, SENSOR, 0.7,
                         photons_per_unit=photons)
    assert shut.shutter.tolist() == [[1.0, 1.0, 1.0]]
    assert bright.shutter.tolist() == [[1.0, 0.5, 0.25]]
    s = bright.shutter
    unshut = read_frames(rendered * 8, unmodulated * 8, [exposure] * 2, one, 0.7,
                         photons_per_unit=photons)
    g, r = SENSOR["gain_electrons_per_dn"], SENSOR["read_noise_electrons"]
    differential = (unshut.raw_ideal - SENSOR["offset_dn"]) * g
    assert np.allclose((bright.raw_ideal - SENSOR["offset_dn"]) * g, s * differential,
                       rtol=1e-12, atol=1e-9)
    taps = (unshut.variance - 1.0 / 12.0) * g**2 - 2 * r**2  # e_A + e_B unshuttered
    assert np.allclose(bright.variance, (s * taps + 2 * r**2) / g**2 + 1.0 / 12.0,
                       rtol=1e-12)
    assert np.allclose(to_rendered_units(bright.raw_ideal, bright, SENSOR),
                       to_rendered_units(unshut.raw_ideal, unshut, one), rtol=1e-12)
    assert np.allclose(to_rendered_units(full.raw_ideal, full, one),
                       rendered, rtol=1e-12)


def test_a_shuttered_pixel_draws_the_predicted_variance():
    """20000 pixels of one level, taking shutter 1/4: the sample variance of the raw DN is
    the predicted one within 5 standard errors (sqrt(2 / N) = 1%, so 5%)."""
    n = 20000
    rendered, unmodulated = _frames(np.full(n, 56.0))
    readout = read_frames(rendered, unmodulated, [1e-3] * 2, SENSOR, 0.7,
                          np.random.Generator(np.random.PCG64(11)), photons_per_unit=2e5)
    assert np.all(readout.shutter == 0.25) and not readout.saturated.any()
    for k in range(2):
        sample = np.var(readout.raw[k].astype(np.float64), ddof=1)
        predicted = float(np.mean(readout.variance[k]))
        assert abs(sample / predicted - 1) < 5 * math.sqrt(2 / n)


@pytest.mark.parametrize("shutters, why", [([0.5, 0.25], "from 1"), ([1.0, 0.5, 0.5], "longest"),
                                           ([1.0, 0.0], "fractions"), ([], "fractions")])
def test_bad_shutters_are_refused(tmp_path, shutters, why):
    text = open(preset_path("opt8241"), encoding="utf-8").read()
    path = tmp_path / "bad.toml"
    path.write_text(text.replace("[sensor]\n", f"[sensor]\nshutters = {shutters!r}\n"),
                    encoding="utf-8")
    with pytest.raises(PresetError) as e:
        cameras.load_preset(path)
    assert "sensor.shutters" in str(e.value) and "\n" not in str(e.value)


# ---- kinect-v2 against Fankhauser et al. 2015 ------------------------------------------------

def fankhauser_mm(z, angle_deg=0.0):
    theta = math.radians(angle_deg)
    return 1.5 - 0.5 * z + 0.3 * z * z + 0.1 * z**1.5 * theta**2 / (math.pi / 2 - theta) ** 2


WALLS = ((1.0, 0.0), (2.0, 0.0), (3.0, 0.0), (4.0, 0.0), (2.0, 60.0))


def test_fankhausers_model_at_the_walls():
    """The quoted values: 1.3, 1.7, 2.7, 4.3 mm head-on; x1.66 at 60 deg, 2 m."""
    assert [round(fankhauser_mm(z), 1) for z, _ in WALLS[:4]] == [1.3, 1.7, 2.7, 4.3]
    assert fankhauser_mm(2.0, 60.0) / fankhauser_mm(2.0) == pytest.approx(1.66, abs=0.01)


def test_kinect_v2_first_order_noise_follows_fankhauser():
    """First-order noise (no draws) of small renders within the issue's 25% of the curve:
    a calibration check (two constants fitted at 1 and 4 m, three walls predicted)."""
    from dopplertof.cameras.accuracy import predicted_random, render_wall

    preset = cameras.load_preset("kinect-v2")
    assert preset.absolute and preset.noise_calibrated and len(preset.sensor["shutters"]) > 1
    for distance, angle in WALLS:
        wall = render_wall(preset, distance, 0.9, crop=8, spp=4, angle_deg=angle)
        ratio = predicted_random(wall) * 1e3 / fankhauser_mm(distance, angle)
        assert 0.75 <= ratio <= 1.25, (distance, angle, ratio)


@pytest.mark.slow
def test_kinect_v2_measured_noise_follows_fankhauser():
    """Monte Carlo as benchmarks/camera_accuracy.py (32 draws): within 25%, >= 95% valid."""
    from dopplertof.cameras.accuracy import wall_accuracy

    for distance, angle in WALLS:
        r = wall_accuracy("kinect-v2", distance, 0.9, seeds=32, crop=16, spp=8,
                          angle_deg=angle)
        assert 0.75 <= r.random_m * 1e3 / fankhauser_mm(distance, angle) <= 1.25
        assert r.valid >= 0.95


def test_the_shutters_make_the_floor():
    """Without its shutters (one, the full integration) kinect-v2 saturates at 1 m: the
    near floor is the dynamic-range scheme's."""
    from dopplertof.cameras.accuracy import render_wall

    preset = cameras.load_preset("kinect-v2")
    single = replace(preset, sensor=dict(preset.sensor, shutters=[1.0]))
    wall = render_wall(preset, 1.0, 0.9, crop=4, spp=2)
    assert not wall.light.read(preset, None)[0].saturated.any()
    assert wall.light.read(single, None)[0].saturated.all()


def test_a_capture_writes_its_shutters(tmp_path):
    """kinect-v2's frame of a near wall: shutter.npy is each pixel's fraction, and the
    summary counts the pixels of each."""
    import json

    from dopplertof.cameras.accuracy import render_wall
    from dopplertof.cameras.output import write_camera_result

    wall = render_wall(cameras.load_preset("kinect-v2"), 1.0, 0.9, crop=4, spp=2)
    write_camera_result(wall, tmp_path / "out")
    shutter = np.load(tmp_path / "out" / "shutter.npy")
    assert np.array_equal(shutter, wall.readout.shutter.astype(np.float32))
    counts = json.loads((tmp_path / "out" / "summary.json").read_text())[
        "noise"]["radiometry"]["pixels_per_shutter"]
    assert sum(counts.values()) == shutter.size
    assert set(counts) == {f"{f:.6g}" for f in np.unique(wall.readout.shutter)}
    assert np.all(shutter < 1)  # a white wall at 1 m fills more than the well unshuttered
