"""Velocities fitted through the renderer (dopplertof.diff.fit and `dopplertof fit`).

One small capture of the demo scene (48x48, 64 spp per capture) serves every test. The
fit is deterministic for a seed (its renders take fixed seeds): from a start 50% wrong
the fitted radial velocities were measured within 2% of the truth on this capture
(-10.16 for -9.98, +9.87 for +9.94) (the demo capture: within 1%, see
docs/differentiable.md). That was luck: with the captures of 15 other seeds the fitted
radial velocities are off by 6.4% RMS (7.2% for seeds 5-15, at most 14.5%; the fit's
reported uncertainty, about 0.6 m/s, is 1.5x too small at this size), so the 10% bound
asserted before failed 3 of 15 legitimate changes of seed. The bound is 35%: 5 of those
standard deviations (a false-failure rate of about 1e-6 per body, 1e-4 if the RMS were
8.5%); a fit that stays at its start (50% off) or moves the wrong way still fails it.
"""

import json
import os

import numpy as np
import pytest


@pytest.fixture(scope="module")
def capture_dir(tmp_path_factory):
    import dopplertof
    from dopplertof.demo import demo_scene_path

    dopplertof.set_variant("llvm_ad_rgb")
    folder = tmp_path_factory.mktemp("capture")
    scene = dopplertof.load_file(demo_scene_path(), {"res": 48, "spp": 64})
    dopplertof.capture(scene, spp=64, seed=0, progress=False).write(str(folder))
    return str(folder)


def _truths(folder):
    with open(os.path.join(folder, "summary.json")) as f:
        return [b["velocity_gt_median_m_s"] for b in json.load(f)["bodies"]]


@pytest.mark.slow  # a whole fit (about 15 s); the CLI test below keeps the module in the fast tier
def test_fit_recovers_radial_velocities_from_a_start_half_wrong(capture_dir, tmp_path):
    from dopplertof.diff.fit import fit, write_fit

    truth = _truths(capture_dir)
    result = fit(capture_dir, start={0: [0.0, 0.0, 5.0], 1: [0.0, 0.0, -5.0]}, spp=32,
                 iterations=4, block=4)
    for k, body in enumerate(result.bodies):
        start = body["start_radial_velocity_m_s"]
        assert abs(start / truth[k] - 1) > 0.4  # the start is far off
        assert abs(body["radial_velocity_m_s"] / truth[k] - 1) < 0.35, (body, truth)
        assert body["radial_velocity_uncertainty_m_s"] > 0
        assert len(body["linear_velocity_m_s"]) == 3
    assert result.history[-1]["loss"] < result.history[0]["loss"]
    paths = write_fit(result, str(tmp_path / "fit"))
    with open(paths[0]) as f:
        saved = json.load(f)
    assert {"bodies", "iterations", "loss"} <= set(saved)
    assert {"name", "radial_velocity_m_s", "linear_velocity_m_s",
            "angular_velocity_rad_s"} <= set(saved["bodies"][0])
    assert os.path.getsize(paths[1]) > 1000  # the convergence plot


def test_closed_form_start_inverts_radial_velocities():
    """The start's least squares recovers a translation from its own radial field."""
    from types import SimpleNamespace

    from dopplertof.diff.fit import closed_form_velocity

    rng = np.random.default_rng(1)
    n = rng.normal(size=(5, 5, 3))
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    d = rng.normal(size=(5, 5, 3))
    d /= np.linalg.norm(d, axis=-1, keepdims=True)
    u = np.array([1.0, -2.0, 3.0])
    radial = (n @ u) / np.sum(d * n, -1)
    truth = SimpleNamespace(normal=n, direction=d)
    assert np.allclose(closed_form_velocity(truth, radial, np.ones((5, 5), bool)), u)


def test_cli_fit_writes_fit_json(capture_dir, tmp_path, capsys):
    from dopplertof.cli import main

    out = tmp_path / "fit"
    rc = main(["fit", capture_dir, "-o", str(out), "--spp", "8", "--iterations", "1",
               "--quiet"])
    assert rc == 0
    assert (out / "fit.json").exists() and (out / "convergence.png").exists()
    assert "radial" in capsys.readouterr().out


@pytest.mark.parametrize("case", ["missing", "not_a_capture", "bad_start", "output_file"])
def test_cli_fit_bad_input_is_one_line_exit_2_and_writes_nothing(case, capture_dir,
                                                                 tmp_path, capsys):
    from dopplertof.cli import main

    capture, out = capture_dir, tmp_path / "fit"
    extra = []
    if case == "missing":
        capture = str(tmp_path / "nowhere")
    elif case == "not_a_capture":
        capture = str(tmp_path)
    elif case == "bad_start":
        extra = ["--start", "0=1,2"]
    else:
        out = tmp_path / "taken"
        out.write_text("keep")
    rc = main(["fit", capture, "-o", str(out), "--quiet"] + extra)
    err = capsys.readouterr().err
    assert rc == 2
    assert err.count("\n") == 1 and "Traceback" not in err and err.startswith("dopplertof")
    if case == "output_file":
        assert out.read_text() == "keep"
    else:
        assert not out.exists()
