"""The precision study (camera/study.py, `dopplertof precision`): predictions checked by
simulation, the map, and the command line's errors for impossible ranges.

Each check compares, per pixel, the predicted sensor standard deviation (from the pilot,
rescaled to the exposure) with the spread of 32 noise draws; the median over 64 pixels
of that ratio has a noise of about 2% (see test_precision.py), against a 10% tolerance:
4 comparisons below 1e-5 each. The map's frequency-exposure ratio (rtol 5%) is off from
the 1 / (f T) scaling by -4.30% +- 0.09% over 8 other seeds: systematic (the rendered
amplitudes differ with the frequency), 7.5 of its standard deviations inside the bound.
"""

import json
import subprocess
import sys

import numpy as np
import pytest

import dopplertof
from analytic import plane_scene
from dopplertof.tof import NoiseModel
from dopplertof.tof import study
from dopplertof.tof.precision import PrecisionError


def plane():
    return dopplertof.load_dict(plane_scene(4.0, 10.0, spp=16, res=8))


@pytest.mark.slow
def test_map_is_checked_by_simulation_and_scales_with_frequency_and_exposure():
    scene = plane()
    result = study.precision_study(scene, (20.0, 60.0), (1.5e-3, 6e-3), spp=16, steps=2,
                                   mc_batches=2, progress=False)
    assert result.velocity_std.shape == (2, 2)
    v = result.velocity_std
    # sensor-limited with the auto photon scale: precision ~ 1 / (f T)
    np.testing.assert_allclose(v[0, 0] / v[1, 1], 3.0 * 4.0, rtol=0.05)
    study.check_points(scene, result, [(0, 1), (1, 0)], noise=NoiseModel(), progress=False)
    for c in result.checks:
        assert abs(c["velocity_predicted_over_measured_median"] - 1) < 0.10, c
        assert abs(c["depth_predicted_over_measured_median"] - 1) < 0.10, c


def test_fixed_photon_scale_saturates_long_exposures():
    scene = plane()
    first = study.precision_study(scene, 30.0, 1.5e-3, spp=16, mc_batches=2, progress=False)
    assert first.noise["photons_per_unit"] is None  # auto: resolved per exposure
    k = first.pilots[0].summary["noise"]["photons_per_unit"]  # the pilot's, at 1.5 ms
    result = study.precision_study(scene, 30.0, (1.5e-3, 15e-3), spp=16, steps=2,
                                   mc_batches=2, noise=NoiseModel(photons_per_unit=k),
                                   progress=False)
    assert np.isfinite(result.velocity_std[0, 0]) and np.isnan(result.velocity_std[0, 1])


@pytest.mark.parametrize("text, message", [("300:10", "empty"), ("a:b", "number or a range"),
                                           ("1:2:3", "number or a range"),
                                           ("-5", "outside")])
def test_parse_range_errors(text, message):
    with pytest.raises(PrecisionError, match=message):
        study.parse_range(text, "--w-g (MHz)", 1e-3, 1e5)


def _cli(*args):
    return subprocess.run([sys.executable, "-m", "dopplertof.cli", "precision", *args],
                          capture_output=True, text=True)


@pytest.mark.parametrize("args, message", [
    (["--w-g", "300:10", "-o", "{out}"], "range '300:10' is empty"),
    (["--exposure", "0:1e-3", "-o", "{out}"], "outside"),
    (["--w-g", "10:300"], "ranges need -o"),
    (["--w-g", "10:300", "-o", "{bad}"], "must end in .png"),
])
def test_cli_impossible_ranges(tmp_path, args, message):
    out = tmp_path / "map.png"
    out.write_bytes(b"keep")
    args = [a.format(out=out, bad=tmp_path / "map.txt") for a in args]
    from dopplertof.demo import demo_scene_path

    r = _cli(demo_scene_path(), *args)
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and message in r.stderr, r.stderr
    assert "Traceback" not in r.stderr
    assert out.read_bytes() == b"keep"


@pytest.mark.slow
def test_cli_writes_the_map_and_its_numbers(tmp_path):
    from dopplertof.demo import demo_scene_path

    out = tmp_path / "map.png"
    r = _cli(demo_scene_path(), "-D", "res=8", "--spp", "16", "--mc-batches", "2",
             "--w-g", "20:40", "--exposure", "1e-3:2e-3", "--steps", "2", "--check", "1",
             "-o", str(out), "--quiet")
    assert r.returncode == 0, r.stderr
    assert out.exists() and "check" in r.stdout
    data = json.loads((tmp_path / "map.json").read_text())
    assert len(data["velocity_std_median_m_s"]) == 2 and len(data["checks"]) == 1
