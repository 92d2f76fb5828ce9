"""Predicted per-pixel precision (camera/precision.py) against repetition, the delta
method against finite differences, first-order failures, trust masks, CLI errors.

Statistics: each comparison is the median over >= 64 pixels of predicted / measured
standard deviation, the measured one from 32 repetitions (31 degrees of freedom: about
13% per pixel) and the predicted one averaged over the 32 repetitions. The median's own
noise is about 1.25 x 13% / sqrt(pixels) <= 2.1% (< 3%), so a 10% tolerance is more than
4.5 of its standard deviations: a false failure rate below 1e-5 per comparison (measured
over 6 other seeds: the ratio's standard deviation is 1.6% for the Monte Carlo check on
the plane and 0.9% for the sensor check on the demo scene, 5.8 and 11 of them). Three
checks of 2 comparisons (velocity, depth): below 6e-5 for the file. The other tests
compare the same random numbers two ways (deterministic) or have margins of 50 standard
deviations (the first-order failure's dim and bright pixels).
"""

import math
import os
import subprocess
import sys

import numpy as np
import pytest

import dopplertof
from analytic import plane_scene
from dopplertof.tof import NoiseModel, capture
from dopplertof.tof import precision as prec
from dopplertof.tof.validation import repetition_check
from dopplertof.tof import reconstruct as rec
from dopplertof.tof.capture import _reconstruct
from dopplertof.demo import demo_scene_path

def plane(res=8, light_off=False, rfilter="box"):
    d = plane_scene(4.0, 10.0, spp=64, res=res)
    d["sensor"]["film"]["rfilter"] = {"type": rfilter}
    if light_off:  # a light 0.6 m beside the camera: the measurement is L'/2, not v
        d["light"]["position"] = [0.6, 0.0, 0.0]
    return dopplertof.load_dict(d)


def assert_within_10_percent(check, pixels=64):
    for key in ("velocity", "depth"):
        assert check[key]["pixels"] >= pixels, check
        assert abs(check[key]["predicted_over_measured_median"] - 1) < 0.10, check


@pytest.mark.slow
def test_monte_carlo_prediction_on_the_moving_plane():
    assert_within_10_percent(repetition_check(plane(), 32, 4, "mc", progress=False))


@pytest.mark.slow
def test_monte_carlo_and_sensor_with_a_light_off_the_camera_and_a_splatting_filter():
    # tent filter: every sample splats into 3x3 pixels, neighbours are correlated
    scene = plane(light_off=True, rfilter="tent")
    assert_within_10_percent(repetition_check(
        scene, 32, 4, "total", noise=NoiseModel(full_well=2e6, gain=500), progress=False))


def test_sensor_prediction_on_the_demo_scene():
    scene = dopplertof.load_file(demo_scene_path(), {"res": 16, "spp": 16})
    assert_within_10_percent(repetition_check(scene, 16, 2, "sensor", progress=False),
                             pixels=100)


def _finite_difference(captures, model, unwrap, calibration, name, step):
    up, down = dict(captures), dict(captures)
    up[name] = captures[name] + step
    down[name] = captures[name] - step
    a = _reconstruct(up, model, unwrap, 0.0, calibration)
    b = _reconstruct(down, model, unwrap, 0.0, calibration)
    return (a.velocity - b.velocity) / (2 * step), (a.depth - b.depth) / (2 * step)


@pytest.mark.parametrize("waveform, unwrap", [("sinusoidal", None), ("sinusoidal", 25.0),
                                              ("rectangular", None)])
def test_delta_method_against_finite_differences(waveform, unwrap):
    scene = plane(res=4)
    result = capture(scene, spp=32, seed=1, mc_batches=2, unwrap_frequency=unwrap,
                     params={"wave_function_type": waveform}, progress=False)
    s = result.summary
    model = rec.CaptureModel(s["modulation"]["omega_g_rad_s"], s["modulation"]["exposure_s"],
                             1.0, waveform)
    calibration = s["velocity"]["calibration"]
    rendered = {k: v.astype(np.float64) for k, v in result.rendered.items()}
    clean = _reconstruct(rendered, model, unwrap, 0.0, calibration)
    jv, jd, _ = prec.jacobians(rendered, model, unwrap, calibration, clean.depth)
    for name in rendered:
        step = 1e-4 * np.abs(rendered["homodyne_0"]).max()
        fv, fd = _finite_difference(rendered, model, unwrap, calibration, name, step)
        scale_v, scale_d = np.abs(fv).max() + 1e-30, np.abs(fd).max() + 1e-30
        np.testing.assert_allclose(jv.get(name, 0 * fv), fv, atol=2e-3 * scale_v + 1e-12)
        np.testing.assert_allclose(jd.get(name, 0 * fd), fd, atol=2e-3 * scale_d + 1e-15)


def test_propagation_with_correlated_captures_against_brute_force():
    """J Sigma J^T from the renders equals the spread of the reconstructions of
    slightly scaled render deviations (brute force, no Jacobian), cross terms included."""
    scene = plane(res=4)
    result = capture(scene, spp=64, seed=3, mc_batches=8, progress=False)
    s = result.summary
    model = rec.CaptureModel(s["modulation"]["omega_g_rad_s"], s["modulation"]["exposure_s"],
                             1.0)
    rendered = {k: v.astype(np.float64) for k, v in result.rendered.items()}
    # batches: rebuild them from the summary's batch seeds
    from dopplertof.render import render_result

    batches = {}
    base = scene.params
    for record in s["captures"]:
        if record["kind"] == "radiance":
            continue
        spec = [c for c in dopplertof.tof.plan_captures(30.0, 1.0) if c.name == record["name"]][0]
        batches[record["name"]] = np.stack([render_result(
            scene, spp=64, seed=b, params=spec.params(base)).image.mean(-1)
            for b in record["batch_seeds"]])
    jv, jd, _ = prec.jacobians(rendered, model)
    predicted = prec.mc_variance(jv, batches)
    eps = 1e-3
    brute = []
    for b in range(8):
        moved = {k: rendered[k] + eps * (batches[k][b] - batches[k].mean(0)) for k in rendered}
        brute.append((_reconstruct(moved, model, None, 0.0, "none").velocity
                      - _reconstruct(rendered, model, None, 0.0, "none").velocity) / eps)
    brute = np.sum(np.square(brute), axis=0) / 7
    np.testing.assert_allclose(predicted, brute, rtol=1e-2)
    np.testing.assert_allclose(np.sqrt(predicted), result.uncertainty.velocity_std_mc,
                               rtol=1e-4)


def test_first_order_failure_is_marked_not_mispredicted():
    rng = np.random.default_rng(0)
    shape = (4, 4)
    level = np.where(np.arange(16).reshape(shape) < 8, 1.0, 0.01)  # half the pixels dim
    mean = {f"homodyne_{o:g}": level * np.cos(1.0 + 2 * math.pi * o) for o in rec.DEPTH_OFFSETS}
    mean.update({f"heterodyne_{o:g}": 3e-3 * mean[f"homodyne_{o:g}"]
                 for o in rec.VELOCITY_OFFSETS})
    # renders scattered by 0.02: 2% of the bright amplitude, twice the dim one
    batches = {n: m + 0.02 * rng.standard_normal((8,) + shape) for n, m in mean.items()}
    rendered = {n: b[0] for n, b in batches.items()}
    model = rec.CaptureModel(2 * math.pi * 30e6, 1.5e-3, 1.0)
    u = prec.predict(rendered, batches, model)
    dim = level < 0.5
    assert np.all(np.isinf(u.velocity_std[dim])) and np.all(u.first_order_failed[dim])
    assert np.all(np.isfinite(u.velocity_std[~dim])) and not u.first_order_failed[~dim].any()


def test_trust_masks_and_their_counts():
    scene = dopplertof.load_file(demo_scene_path(), {"res": 16, "spp": 16})
    free = capture(scene, spp=16, seed=0, noise=NoiseModel(), mc_batches=2, progress=False)
    limit = float(np.nanmedian(free.uncertainty.velocity_std))
    masked = capture(scene, spp=16, seed=0, noise=NoiseModel(), max_velocity_std=limit,
                     max_depth_std=0.01, mc_batches=2, progress=False)
    std = masked.uncertainty.velocity_std
    was = np.isfinite(free.velocity)
    expect = was & ~(std <= limit)
    assert expect.any() and (was & ~expect).any()
    assert np.all(np.isnan(masked.velocity[expect]))
    np.testing.assert_array_equal(masked.velocity[was & ~expect], free.velocity[was & ~expect])
    key = rec.INVALID_REASONS[rec.TOO_UNCERTAIN].split(" (")[0]
    assert masked.summary["velocity"]["nan_pixels"][key] == int(expect.sum())
    limits = masked.summary["precision"]["limits"]
    assert limits["masked_pixels"]["velocity"] == int(expect.sum())
    assert limits["masked_pixels"]["depth"] == masked.summary["depth"]["nan_pixels"][key]
    assert np.all(masked.depth_gt[np.isfinite(masked.depth)] >= 0)
    assert np.all(masked.uncertainty.depth_std[np.isfinite(masked.depth)] <= 0.01)


def test_error_bars_cost_no_accuracy_and_say_their_cost():
    """With mc_batches the reported captures are the plain captures, bitwise (afb2c4e
    reported the mean of B batches of spp / B samples: the starter sphere's median
    velocity error 0.021 -> 0.103 m/s at 256 spp); the error bars' render time is stated."""
    scene = plane(res=4)
    plain = capture(scene, spp=16, seed=2, progress=False)
    bars = capture(scene, spp=16, seed=2, mc_batches=2, progress=False)
    for name, image in plain.captures.items():
        np.testing.assert_array_equal(bars.captures[name], image)
    np.testing.assert_array_equal(bars.velocity, plain.velocity)
    cost = bars.summary["precision"]["cost"]
    assert cost["renders_per_capture"] == 2 and cost["error_bar_render_seconds"] > 0
    assert cost["render_time_factor"] > 1
    assert "error bars: 2 independent renders" in prec.format_precision(bars.summary)
    assert all(r["batch_seeds"][0] == 2 and len(set(r["batch_seeds"])) == 2
               for r in bars.summary["captures"])


def test_summary_files_and_bitwise_images(tmp_path):
    scene = plane(res=4)
    result = capture(scene, spp=16, seed=0, mc_batches=2, progress=False)
    again = capture(scene, spp=16, seed=0, mc_batches=2, progress=False)
    np.testing.assert_array_equal(result.captures["heterodyne_0"], again.captures["heterodyne_0"])
    plain = capture(scene, spp=16, seed=0, progress=False)
    assert plain.uncertainty is None and "precision" not in plain.summary
    paths = result.write(tmp_path)
    for name in ("velocity_std_mc", "depth_std_mc", "velocity_std_sensor", "depth_std_sensor",
                 "velocity_std", "depth_std"):
        assert os.path.join(tmp_path, f"{name}.npy") in paths
    assert os.path.exists(tmp_path / "velocity_std.png")
    se = np.load(tmp_path / "heterodyne_0_std_mc.npy")
    assert se.shape == (4, 4) and np.all(se > 0)
    p = result.summary["precision"]
    assert p["mc_batches"] == 2 and len(p["bodies"]) == 1
    assert p["bodies"][0]["velocity_m_s"]["predicted_std_median"] > 0
    assert p["overall"]["velocity_m_s"]["measured_error_spread"] > 0


@pytest.mark.parametrize("kwargs, message", [
    (dict(mc_batches=1), "mc_batches must be an integer >= 2"),
    (dict(mc_batches=2.5), "mc_batches must be an integer >= 2"),
    (dict(max_velocity_std=-1.0), "max_velocity_std must be a positive number"),
    (dict(max_depth_std=float("nan")), "max_depth_std must be a positive number"),
])
def test_bad_precision_settings(kwargs, message):
    with pytest.raises(ValueError, match=message):
        capture(plane(res=2), spp=16, progress=False, **kwargs)


def _cli(*args):
    return subprocess.run([sys.executable, "-m", "dopplertof.cli", *args],
                          capture_output=True, text=True)


def test_capture_cli_bad_batches_writes_nothing(tmp_path):
    out = tmp_path / "out"
    r = _cli("capture", demo_scene_path(), "-o", str(out), "--spp", "16",
             "--max-velocity-std", "0")
    assert r.returncode == 2 and r.stderr.count("\n") == 1
    assert "max_velocity_std must be a positive number" in r.stderr
    assert not out.exists() or not any(out.iterdir())


def test_capture_cli_writes_the_maps_and_counts_the_mask(tmp_path):
    out = tmp_path / "out"
    r = _cli("capture", demo_scene_path(), "-o", str(out), "-D", "res=8", "--spp", "16",
             "--mc-batches", "2", "--noise", "--max-velocity-std", "50", "--quiet")
    assert r.returncode == 0, r.stderr
    assert "precision overall" in r.stdout
    assert "NaN where the predicted std exceeds 50 m/s" in r.stdout
    for name in ("velocity_std", "velocity_std_sensor", "depth_std_mc"):
        assert (out / f"{name}.npy").exists() and (out / f"{name}.png").exists()
    std = np.load(out / "velocity_std.npy")
    velocity = np.load(out / "velocity.npy")
    assert np.all(std[np.isfinite(velocity)] <= 50)
