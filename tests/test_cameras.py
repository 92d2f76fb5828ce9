"""Real camera presets (dopplertof.cameras): preset files, raw frames in their own time
windows, the sensor pipeline, N-phase depth, unwrapping over N frequencies, wiggling."""

import math
import subprocess
import sys

import numpy as np
import pytest

from analytic import plane_scene, reference

C = 299_792_458.0


# ---- Helpers ---------------------------------------------------------------------------

SENSOR = dict(quantum_efficiency=0.4, full_well_electrons=20000.0, read_noise_electrons=5.0,
              dark_current_electrons_per_s=100.0, adc_bits=12, gain_electrons_per_dn=5.0,
              offset_dn=2048.0, well_fill=0.5, ambient_photons_per_s=0.0)


def _toml_value(v):
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, str):
        return f'"{v}"'
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    return repr(v)


def preset_text(frames, waveform="sinusoidal", unwrapping=None, max_range=None,
                calibration=True, contrast=0.8, sensor=None, drop=(), extra=""):
    """A preset's TOML text; ``frames``: (MHz, phase deg, integration s, start s[, h])."""
    freqs = {f[0] for f in frames if len(f) < 5 or f[4] == 0}
    unwrapping = unwrapping or ("wrap-search" if len(freqs) > 1 else "none")
    max_range = max_range or (C / (2e6 * min(freqs)) if len(freqs) == 1 else 20.0)
    sections = {
        "": dict(name="test", description="a test camera", sources=["tests"]),
        "optics": dict(resolution=[16, 16], fov_deg=20.0, pixel_pitch_um=10.0),
        "modulation": dict(waveform=waveform, contrast=contrast),
        "sensor": {**SENSOR, **(sensor or {})},
        "reconstruction": dict(unwrapping=unwrapping, max_range_m=max_range,
                               wiggling_calibration=calibration, min_amplitude_dn=1.0),
    }
    lines = []
    for section, values in sections.items():
        if section:
            lines.append(f"[{section}]")
        lines += [f"{k} = {_toml_value(v)}" for k, v in values.items()
                  if f"{section}.{k}".lstrip(".") not in drop]
    for f in frames:
        lines += ["[[frames]]", f"frequency_mhz = {f[0]!r}", f"phase_deg = {f[1]!r}",
                  f"integration_s = {f[2]!r}", f"start_s = {f[3]!r}"]
        if len(f) > 4:
            lines.append(f"hetero_frequency = {f[4]!r}")
    return "\n".join(lines) + "\n" + extra


def write_preset(tmp_path, *args, **kwargs):
    path = tmp_path / "camera.toml"
    path.write_text(preset_text(*args, **kwargs))
    return str(path)


def four_phase(frequency, integration=5e-4, spacing=1e-3, start=0.0):
    return [(frequency, p, integration, start + i * spacing)
            for i, p in enumerate((0.0, 90.0, 180.0, 270.0))]


def run_cli(*args):
    return subprocess.run([sys.executable, "-m", "dopplertof.cli", *args],
                          capture_output=True, text=True, timeout=600)


# ---- Presets as data ---------------------------------------------------------------------

def test_every_packaged_preset_loads_with_its_sources():
    from dopplertof import cameras

    names = cameras.preset_names()
    for wanted in ("kinect-v2", "azure-kinect", "azure-kinect-nfov-binned", "opt8241",
                   "mlx75027", "pmd-argos3d-p320", "paper-dtof"):
        assert wanted in names
    kinect = cameras.load_preset("kinect-v2")
    assert len(kinect.frames) == 9 and kinect.frequencies_mhz == (16.0, 80.0, 120.0)
    assert cameras.load_preset("mlx75027").frames.__len__() <= 8
    assert cameras.load_preset("paper-dtof").heterodyne
    for name in names:
        text = open(cameras.load_preset(name).source_file).read()
        # every number line carries a comment: its source or "inferred"
        for line in text.splitlines():
            if "=" in line and not line.startswith(("#", "[", "name", "description",
                                                    "sources", "noise_calibration", '"')) and \
                    not line.startswith(("frequency_mhz", "phase_deg", "integration_s",
                                         "start_s", "hetero_frequency")):
                assert "#" in line, f"{name}: no source comment: {line}"


@pytest.mark.parametrize("drop, change, message", [
    (("sensor.full_well_electrons",), None, "missing key sensor.full_well_electrons"),
    ((), ("read_noise_electrons", "read_nosie_electrons"),
     "unknown key sensor.read_nosie_electrons, did you mean 'read_noise_electrons'?"),
    ((), ("adc_bits = 12", 'adc_bits = "twelve"'), "sensor.adc_bits must be an integer"),
    ((), ("contrast = 0.8", "contrast = 1.5"), "modulation.contrast out of range"),
    ((), ("frequency_mhz = 30.0\nphase_deg = 270.0", "frequency_mhz = 30.0\nphse_deg = 270.0"),
     "unknown key frames[3].phse_deg, did you mean 'phase_deg'?"),
])
def test_a_bad_preset_file_is_one_line_naming_the_key(tmp_path, drop, change, message):
    from dopplertof.cameras import PresetError, load_preset

    text = preset_text(four_phase(30.0), drop=drop)
    if change:
        assert change[0] in text
        text = text.replace(change[0], change[1], 1)
    path = tmp_path / "mine.toml"
    path.write_text(text)
    with pytest.raises(PresetError) as info:
        load_preset(str(path))
    assert message in str(info.value) and str(path) in str(info.value)
    assert "\n" not in str(info.value)


def test_sequences_the_reconstruction_cannot_use_are_refused(tmp_path):
    from dopplertof.cameras import PresetError, load_preset

    two = [(30.0, 0.0, 1e-3, 0.0), (30.0, 180.0, 1e-3, 1e-3)]
    with pytest.raises(PresetError, match="30 MHz has 2 distinct phase step"):
        load_preset(write_preset(tmp_path, two))
    with pytest.raises(PresetError, match="'wrap-search' needs two or more"):
        load_preset(write_preset(tmp_path, four_phase(30.0), unwrapping="wrap-search"))


def test_cameras_command_lists_prints_and_suggests(tmp_path):
    listing = run_cli("cameras")
    assert listing.returncode == 0 and "kinect-v2" in listing.stdout
    one = run_cli("cameras", "opt8241")
    assert one.returncode == 0 and "60 MHz, phase 90 deg" in one.stdout
    own = run_cli("cameras", write_preset(tmp_path, four_phase(20.0)))
    assert own.returncode == 0 and "20 MHz" in own.stdout
    bad = run_cli("cameras", "kinnect-v2")
    assert bad.returncode == 2 and "did you mean 'kinect-v2'?" in bad.stderr
    assert len(bad.stderr.strip().splitlines()) == 1
    # issue 42: --list, as examples/dataset.toml and the config's help say
    assert run_cli("cameras", "--list").stdout == listing.stdout
    both = run_cli("cameras", "--list", "opt8241")
    assert both.returncode == 2 and both.stderr.strip() == (
        "dopplertof: error: --list takes no NAME: give one or the other")


def _compared(name, error, velocity):
    """A camera's result as write_camera_comparison reads it (plain arrays)."""
    from types import SimpleNamespace

    depth_gt = np.full(error.shape, 3.0)
    summary = {"errors": {"depth_m": {"median": 0.01}}, "mixed_footprints": 2,
               "noise": {"saturated_pixels": 0},
               "depth": {"masked_pixels": {"unwrapping failed": 3, "saturated": 0}}}
    return SimpleNamespace(preset=SimpleNamespace(name=name), depth=depth_gt + error,
                           depth_gt=depth_gt, velocity_gt=np.ones(error.shape),
                           reconstruction=SimpleNamespace(amplitude=np.ones(error.shape),
                                                          velocity=velocity),
                           summary=summary)


def test_the_comparison_hatches_masked_pixels_and_writes_its_numbers(tmp_path):
    """issue 42: masked pixels were white, the colour of zero range error; the numbers
    were nowhere but on the terminal."""
    import json

    from PIL import Image

    from dopplertof.cameras.figures import write_camera_comparison

    error = np.zeros((12, 16))
    error[:, :8] = np.nan  # half masked
    velocity = np.where(np.isnan(error), np.nan, 1.0)
    path = tmp_path / "compare.png"
    numbers = write_camera_comparison(path, [_compared("a", error, velocity),
                                             _compared("b", np.zeros((12, 16)), None)], "t")
    pixels = np.asarray(Image.open(path).convert("RGB")).reshape(-1, 3)
    magenta = np.all(pixels == (255, 0, 255), axis=1).sum()
    assert magenta > 100, magenta
    written = json.loads((tmp_path / "compare.json").read_text())
    assert written == numbers and [c["camera"] for c in written["cameras"]] == ["a", "b"]
    assert [c["masked_pixels"] for c in written["cameras"]] == [96, 0]
    assert written["cameras"][0]["errors"] == {"depth_m": {"median": 0.01}}
    # each mask's count (issue 42, 2026-12-03: tools/check_doc_numbers.py reads the unwrap
    # failures of docs/cameras.md's table there)
    assert written["cameras"][1]["masked_by"] == {"unwrapping failed": 3, "saturated": 0}


def test_the_comparison_captions_each_panel_with_its_masked_pixels(tmp_path, monkeypatch):
    """issue 42 item 3 (2026-12-04): the figure said nothing of how many pixels each panel
    masks, nor why (the counts were only in FIG.json): the range error's title gives the
    masked pixels of all and each mask's count that is not 0, the velocity's its NaN."""
    import matplotlib.text

    from dopplertof.cameras import figures

    texts = []
    save = figures.image_files.save_figure

    def keep_texts(fig, path, *rest):
        texts.extend(t.get_text() for t in fig.findobj(matplotlib.text.Text))
        return save(fig, path, *rest)

    monkeypatch.setattr(figures.image_files, "save_figure", keep_texts)
    error = np.zeros((12, 16))
    error[:, :8] = np.nan
    velocity = np.where(np.isnan(error), np.nan, 1.0)
    figures.write_camera_comparison(tmp_path / "compare.png",
                                    [_compared("a", error, velocity),
                                     _compared("b", np.zeros((12, 16)), None)], "t")
    joined = [" ".join(text.split()) for text in texts]
    assert ("a: range error (m) masked (hatched): 96 of 192 px: unwrapping failed 3"
            in joined), joined
    assert "b: range error (m) masked (hatched): 0 of 192 px: unwrapping failed 3" in joined
    assert "a: radial velocity (m/s) NaN (hatched): 96 px" in joined
    assert figures.masked_caption(np.zeros((2, 2)), {"saturated": 0}) == \
        "masked (hatched): 0 of 4 px"


# ---- Unwrapping over N frequencies --------------------------------------------------------

def test_unwrapping_three_frequencies_recovers_depth_and_flags_failures():
    from dopplertof.cameras.unwrap import unambiguous_range, unwrap_likelihood

    freqs = (16e6, 80e6, 120e6)
    assert unambiguous_range(freqs) == pytest.approx(C / (2 * 8e6))
    rng = np.random.default_rng(1)
    # (a depth within the finest wrap of the unambiguous range's end is as likely a few
    # centimetres below zero: flagged ambiguous, rightly, so the truths stop short of it)
    truth = rng.uniform(0.2, 17.5, 200_000)
    for sigma, fails_at_most in ((0.005, 0.0), (0.03, 0.5)):
        sigmas = [sigma * 120e6 / f for f in freqs]
        wrapped = [np.mod(truth + rng.normal(0, s, truth.shape), C / (2 * f))
                   for s, f in zip(sigmas, freqs)]
        result = unwrap_likelihood(wrapped, [np.full(truth.shape, s * s) for s in sigmas],
                                   freqs, 18.75)
        ok = ~result.failed
        assert result.failed.mean() <= fails_at_most
        # not flagged: right within noise, never a wrap off
        error = np.mod(result.depth[ok] - truth[ok] + 9.0, result.unambiguous_range) - 9.0
        assert np.max(np.abs(error)) < 10 * sigma  # (modulo the unambiguous range)
        assert np.all(np.isnan(result.depth[result.failed]))
    assert result.failed.any()  # the noisy case does fail somewhere, flagged


def test_two_frequency_likelihood_agrees_with_the_tof_unwrapping():
    from dopplertof.cameras.unwrap import unwrap_likelihood
    from dopplertof.tof.reconstruct import unwrap_two_frequencies

    rng = np.random.default_rng(2)
    truth = rng.uniform(0.1, 28.0, 5000)  # (short of the 29.98 m range's end: see above)
    wrapped = [np.mod(truth, C / (2 * f)) for f in (30e6, 25e6)]
    ours = unwrap_likelihood(wrapped, [np.full(truth.shape, 1e-4)] * 2, (30e6, 25e6))
    theirs = unwrap_two_frequencies(wrapped[0], 30e6, wrapped[1], 25e6)
    assert not ours.failed.any()
    np.testing.assert_allclose(ours.depth, theirs, atol=1e-9)
    np.testing.assert_allclose(ours.depth, truth, atol=1e-9)


# ---- The sensor pipeline --------------------------------------------------------------------

def test_quantization_gain_offset_and_saturation_are_exact():
    from dopplertof.cameras.sensor import read_frames

    sensor = {**SENSOR, "dark_current_electrons_per_s": 1000.0, "full_well_electrons": 5000.0}
    value = np.array([[[0.0, 0.1, -0.1, 0.2, -0.2, 0.99]]])  # rendered, (1, 1, 6)
    unmodulated = np.array([[0.2, 0.2, 0.2, 0.2, 0.2, 1.0]])
    K, T, contrast = 5e7, 1e-3, 0.8
    out = read_frames(value, unmodulated, [T], sensor, contrast, None, photons_per_unit=K)
    # the taps by hand: QE K T (g0 R +- c V) / 2 + D T
    e_a = 0.4 * K * T * (unmodulated + contrast * value[0]) / 2 + 1000.0 * T
    e_b = 0.4 * K * T * (unmodulated - contrast * value[0]) / 2 + 1000.0 * T
    ideal = (e_a - e_b) / 5.0 + 2048.0
    np.testing.assert_allclose(out.raw_ideal[0], ideal, rtol=1e-12)
    clipped_a, clipped_b = np.minimum(e_a, 5000.0), np.minimum(e_b, 5000.0)
    expected = np.clip(np.rint((clipped_a - clipped_b) / 5.0) + 2048.0, 0, 4095)
    np.testing.assert_array_equal(out.raw[0], expected)
    assert out.raw.dtype == np.uint16
    # the last pixel's tap A is past the 5000 e- well: flagged, and only it
    assert e_a[0, -1] > 5000 and out.saturated[0].tolist() == [[False] * 5 + [True]]
    # the ADC's ends flag too
    adc = read_frames(np.array([[[0.99]]]), np.array([[1.0]]), [T],
                      {**SENSOR, "gain_electrons_per_dn": 0.5}, contrast, None,
                      photons_per_unit=K)
    assert adc.raw[0, 0, 0] == 4095 and adc.saturated.all()


def test_raw_frames_of_a_plane_match_their_closed_form(tmp_path):
    import dopplertof
    from dopplertof.cameras import load_preset
    from dopplertof.cameras.capture import capture_camera

    frames = ([(20.0, p, 4e-4, i * 5e-4) for i, p in enumerate((0.0, 120.0, 240.0))]
              + [(50.0, p, 2e-4, 1.5e-3 + i * 3e-4) for i, p in enumerate((0.0, 90.0, 180.0, 270.0))])
    preset = load_preset(write_preset(tmp_path, frames, max_range=5.9))
    scene = dopplertof.load_dict(plane_scene(4.0, 0.0, exposure=3e-3, spp=1024, res=1))
    result = capture_camera(scene, preset, noise=False, progress=False)
    K = result.readout.photons_per_unit
    for k, (f, phase, T, _) in enumerate(frames):
        v = reference(4.0, 0.0, exposure=T, w_g=f, hetero_offset=phase / 360.0)
        expected = 0.8 * 0.4 * K * T * v / 5.0 + 2048.0  # c QE K T V / gain + offset
        amplitude = 0.8 * 0.4 * K * T * reference(4.0, 0.0, exposure=T, w_g=f) / 5.0
        assert abs(result.readout.raw_ideal[k, 0, 0] - expected) < 2e-3 * abs(amplitude) + 1e-3
        assert result.raw[k, 0, 0] == np.clip(np.rint(result.readout.raw_ideal[k, 0, 0]), 0, 4095)
    assert abs(result.depth[0, 0] - result.depth_gt[0, 0]) < 2e-3


# ---- Rendering raw frames in their own time windows -----------------------------------------

def test_a_shutter_window_renders_as_a_scene_loaded_with_that_shutter():
    import dopplertof

    moving = plane_scene(3.0, 40.0, exposure=4e-3, spp=16, res=4)
    scene = dopplertof.load_dict(moving)
    later = dict(moving, sensor=dict(moving["sensor"], shutter_open=1e-3, shutter_close=2e-3))
    params = {"w_g": 30.0, "hetero_frequency": 0.0, "time": 1e-3}
    a = dopplertof.render(scene.with_shutter(1e-3, 1e-3), seed=3, params=params, progress=False)
    b = dopplertof.render(dopplertof.load_dict(later), seed=3, params=params, progress=False)
    c = dopplertof.render(scene, seed=3, params=params, progress=False)
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a, c)  # the window moved the plane


def _plane_through(tmp_path, frames, z0, velocity, span, **preset_args):
    import dopplertof
    from dopplertof.cameras import load_preset
    from dopplertof.cameras.capture import capture_camera

    preset = load_preset(write_preset(tmp_path, frames, **preset_args))
    scene = dopplertof.load_dict(plane_scene(z0, velocity, exposure=span, spp=32, res=8))
    return preset, capture_camera(scene, preset, noise=False, progress=False)


def test_motion_between_raw_frames_gives_the_closed_form_depth_error(tmp_path):
    from dopplertof.cameras.demodulate import n_phase
    from dopplertof.tof.reconstruct import mean_correlation

    f, v, span = 30.0, 60.0, 3.5e-3
    frames = four_phase(f, integration=5e-4, spacing=1e-3)
    preset, result = _plane_through(tmp_path, frames, 2.0, v, span)
    # each frame sees the plane where it is in its own window: range r(t) = z(t) / cos
    cosine = result.depth_gt_z / result.depth_gt
    mid = 0.5 * (0.0 + 3.5e-3)
    z_mid = result.depth_gt_z
    k_phase = 4 * math.pi * f * 1e6 / C
    predicted_frames = []
    for _, phase, T, start in frames:
        z_start = z_mid + v * (start - mid)
        a = k_phase * z_start / cosine + math.radians(phase)
        brightness = (z_mid / (z_start + 0.5 * v * T)) ** 2
        predicted_frames.append(brightness * mean_correlation("sinusoidal", a,
                                                              k_phase * v * T / cosine))
    phase, _, _ = n_phase(np.stack(predicted_frames), np.radians([p[1] for p in frames]))
    predicted = C * phase / (4 * math.pi * f * 1e6)
    error_predicted = predicted - result.depth_gt
    measured = result.depth - result.depth_gt
    assert np.median(np.abs(error_predicted)) > 0.01  # a real artefact ...
    np.testing.assert_allclose(measured, error_predicted, atol=1.5e-3)  # ... as predicted


def test_noise_spread_of_raw_frames_and_depth_matches_the_model(tmp_path):
    from dopplertof.cameras.reconstruct import reconstruct
    from dopplertof.cameras.sensor import read_frames
    from dopplertof.tof.precision import spread_ratio

    frames = four_phase(40.0) + four_phase(50.0, start=4e-3)
    preset, clean = _plane_through(tmp_path, frames, 4.0, 0.0, 8e-3, max_range=14.9,
                                   sensor={"gain_electrons_per_dn": 2.0})
    unmodulated = 0.5 * clean.radiance.mean(axis=-1)
    raws, depths, variances = [], [], []
    for seed in range(48):
        readout = read_frames(clean.rendered, unmodulated, [f[2] for f in frames],
                              preset.sensor, preset.contrast, np.random.default_rng(seed))
        recon = reconstruct(readout, preset)
        raws.append(readout.raw.astype(np.float64))
        depths.append(recon.depth)
        variances.append(recon.depth_variance)
    raws = np.stack(raws)
    for k in range(len(frames)):
        ratio, pixels = spread_ratio(readout.variance[k], raws[:, k])
        assert pixels == 64 and abs(ratio - 1) < 0.1, (k, ratio)
    ratio, pixels = spread_ratio(np.mean(variances, axis=0), np.stack(depths))
    assert pixels == 64 and abs(ratio - 1) < 0.1, ratio


def test_a_plane_beyond_every_single_frequency_range_unwraps_through_kinect_v2(tmp_path):
    import dopplertof
    from dopplertof.cameras.capture import capture_camera

    scene = dopplertof.load_dict(plane_scene(7.0, 0.0, exposure=0.02, spp=16, res=8))
    result = capture_camera(scene, "kinect-v2", progress=False)
    assert 7.0 > C / (2 * 80e6) and 7.0 > C / (2 * 120e6)
    ok = np.isfinite(result.depth)
    assert ok.mean() > 0.95
    std = np.sqrt(result.reconstruction.depth_variance)
    assert np.all(np.abs(result.depth[ok] - result.depth_gt[ok]) < 5 * std[ok] + 2e-3)


# ---- Wiggling ----------------------------------------------------------------------------------

def test_wiggling_error_is_the_render_and_the_calibration_removes_it(tmp_path):
    from dopplertof.cameras.demodulate import wiggling_error

    frames = four_phase(40.0, integration=2e-4, spacing=2e-4)
    depths = {}
    for calibrated in (False, True):
        _, result = _plane_through(tmp_path, frames, 2.3, 0.0, 1e-3, waveform="rectangular",
                                   calibration=calibrated)
        depths[calibrated] = result.depth - result.depth_gt
    predicted = wiggling_error("rectangular", (0, 90, 180, 270), 40e6,
                               result.depth_gt)
    assert np.median(np.abs(predicted)) > 5e-3
    np.testing.assert_allclose(depths[False], predicted, atol=1e-3)
    assert np.max(np.abs(depths[True])) < 1e-3
    assert np.max(np.abs(wiggling_error("rectangular", (0, 90, 180, 270), 40e6,
                                        np.linspace(0, 3.7, 500), calibrated=True))) < 1e-6


def test_wiggling_figure_and_calibration_tables_from_the_command_line(tmp_path):
    import json

    figure = tmp_path / "wiggle.png"
    done = run_cli("cameras", "opt8241", "--wiggling", str(figure))
    assert done.returncode == 0, done.stderr
    numbers = json.loads((tmp_path / "wiggle.json").read_text())
    # rectangular 4-phase at 60 and 48 MHz: centimetres of wiggling, removed by the table
    assert numbers["max_abs_error_uncalibrated_m"] > 0.01
    assert numbers["calibration_applied"] and numbers["max_abs_error_reported_m"] < 1e-6
    table = numbers["calibration_tables"]["60"]
    assert len(table["measured_phase_rad"]) == len(table["true_phase_rad"]) == 257
    assert figure.stat().st_size > 0
    bad = run_cli("cameras", "--wiggling", str(figure))
    assert bad.returncode == 2 and "--wiggling needs a camera NAME" in bad.stderr


# ---- Heterodyne presets -------------------------------------------------------------------------

def test_paper_dtof_renders_todays_captures_and_gives_velocity():
    from dataclasses import replace

    import dopplertof
    from dopplertof.cameras.capture import capture_camera
    from dopplertof.cameras.reconstruct import heterodyne_velocity

    scene = dopplertof.load_dict(plane_scene(3.0, -20.0, exposure=1.5e-3, spp=16, res=4))
    camera = capture_camera(scene, "paper-dtof", seed=2, noise=False, progress=False)
    today = dopplertof.capture(scene, seed=2, params={"time": 1.5e-3}, progress=False)
    names = ["homodyne_0", "homodyne_0.25", "homodyne_0.5", "homodyne_0.75",
             "heterodyne_0", "heterodyne_0.25"]
    for k, name in enumerate(names):  # the same renders, bitwise
        np.testing.assert_array_equal(camera.rendered[k].astype(np.float32),
                                      today.rendered[name])
    # without rounding to DN the camera's velocity is today's (the units undone exactly) ...
    unrounded = replace(camera.readout, raw=camera.readout.raw_ideal)
    np.testing.assert_allclose(
        heterodyne_velocity(unrounded, camera.preset, camera.reconstruction), today.velocity,
        rtol=1e-6, atol=1e-6)
    # ... and rounding costs about a tenth of a DN of a heterodyne signal of a few DN
    assert np.nanmedian(np.abs(camera.reconstruction.velocity - today.velocity)) < 1.0
    assert np.nanmedian(camera.reconstruction.velocity) == pytest.approx(-20.0, rel=0.08)


# ---- The command line ------------------------------------------------------------------------

SCENE_XML = """<scene version="3.0.0">
    <integrator type="dopplertof"><integer name="max_depth" value="2"/></integrator>
    <sensor type="perspective">
        <float name="fov" value="6"/>
        <transform name="to_world"><lookat origin="0, 0, 0" target="0, 0, 1" up="0, 1, 0"/></transform>
        <float name="shutter_open" value="0"/><float name="shutter_close" value="0.02"/>
        <sampler type="independent"><integer name="sample_count" value="8"/></sampler>
        <film type="hdrfilm"><integer name="width" value="4"/><integer name="height" value="4"/>
            <rfilter type="box"/></film>
    </sensor>
    <emitter type="point"><point name="position" x="0" y="0" z="0"/><rgb name="intensity" value="10"/></emitter>
    <shape type="rectangle"><bsdf type="diffuse"/>
        <transform name="to_world"><scale value="50"/><rotate y="1" angle="180"/><translate z="3"/></transform>
    </shape>
</scene>
"""


def test_capture_with_a_camera_writes_its_files(tmp_path):
    import json

    scene = tmp_path / "plane.xml"
    scene.write_text(SCENE_XML)
    out = tmp_path / "out"
    done = run_cli("capture", str(scene), "--camera", "pmd-argos3d-p320", "--res", "6x5",
                   "--spp", "8", "-o", str(out), "--quiet")
    assert done.returncode == 0, done.stderr
    raw = np.load(out / "raw.npy")
    assert raw.shape == (4, 5, 6) and raw.dtype == np.uint16
    assert np.load(out / "raw_ideal.npy").shape == (4, 5, 6)
    for name in ("depth", "depth_z", "amplitude", "depth_gt", "mask_saturated",
                 "mask_low_confidence", "mask_unwrap_failed"):
        assert np.load(out / f"{name}.npy").shape == (5, 6), name
    assert (out / "depth.png").exists() and (out / "raw.png").exists()
    summary = json.loads((out / "summary.json").read_text())
    assert summary["camera"]["name"] == "pmd-argos3d-p320" and summary["resolution"] == [6, 5]
    # the plane at z = 3 within the predicted noise (20 MHz, shot noise: centimetres)
    error = np.load(out / "depth_z.npy") - 3.0
    assert np.all(np.abs(error) < 5 * np.load(out / "depth_std.npy") + 1e-3)
    assert np.all(np.load(out / "depth_gt.npy") > np.load(out / "depth_gt_z.npy"))


@pytest.mark.slow
def test_one_scene_through_several_cameras_side_by_side(tmp_path):
    scene = tmp_path / "plane.xml"
    scene.write_text(SCENE_XML)
    figure = tmp_path / "compare.png"
    done = run_cli("cameras", "--compare", str(scene), "--with", "pmd-argos3d-p320,paper-dtof",
                   "--res", "5x4", "--spp", "4", "-o", str(figure))
    assert done.returncode == 0, done.stderr
    assert "through pmd-argos3d-p320: 5x4" in done.stdout and "velocity error" in done.stdout
    assert figure.stat().st_size > 0


@pytest.mark.parametrize("args, message", [
    (("--camera", "kinect-v2", "--unwrap-frequency", "20"), "drop --unwrap-frequency"),
    (("--camera", "kinect-v2", "--noise"), "drop --noise"),
    (("--res", "8x8"), "--res needs --camera"),
    (("--res", "8x8"), "without a camera the scene's film sets the resolution: -D res=N"),
    (("--camera", "kinect-v2", "--res", "8by8"), "--res must be WIDTHxHEIGHT"),
    (("--camera", "kinnect"), "did you mean 'kinect-v2'?"),
])
def test_capture_camera_option_errors_write_nothing(tmp_path, args, message):
    scene = tmp_path / "plane.xml"
    scene.write_text(SCENE_XML)
    out = tmp_path / "out"
    done = run_cli("capture", str(scene), "-o", str(out), *args)
    assert done.returncode == 2 and message in done.stderr
    assert len(done.stderr.strip().splitlines()) == 1 and not out.exists()


@pytest.mark.parametrize("kwargs, error, words", [
    # issue 39, 2026-12-03 campaign: AttributeErrors from inside, or accepted silently
    # A21: a scene file's path is loaded for the camera (issue 38); another type is named
    ({"scene": 3.5}, TypeError, "scene must be a DopplerScene"),
    ({"camera": None}, TypeError, "camera must be a preset name"),  # A23
    ({"camera": 42}, TypeError, "camera must be a preset name"),  # A24
    ({"noise_seed": -5}, ValueError, "noise_seed must be an integer in"),  # A29
    ({"noise_seed": 1.5}, TypeError, "noise_seed must be an integer"),  # A30
    ({"noise_seed": True}, TypeError, "noise_seed must be an integer"),  # A30
    ({"params": "max_depth=2"}, TypeError, "params must be a dict"),  # A32
    ({"noise": "no"}, TypeError, "noise must be True or False"),  # A33
    ({"checkpoint": 42}, TypeError, "checkpoint must be a file path"),  # A34
    ({"on_frame": "x"}, TypeError, "on_frame must be a function"),  # A35
    ({"spp": 8.7}, TypeError, "spp must be a positive integer"),
])
def test_wrong_arguments_of_capture_camera_are_named_before_any_render(kwargs, error, words):
    import dopplertof
    from dopplertof.cameras.capture import capture_camera

    dopplertof.set_variant("llvm_ad_rgb")
    call = {"scene": dopplertof.load_dict(plane_scene(4.0, 0.0, spp=4, res=2)),
            "camera": "kinect-v2", "progress": False, **kwargs}
    with pytest.raises(error, match=words):
        capture_camera(**call)


def test_a_plain_mitsuba_scene_is_captured(tmp_path):
    """A36: mi.Scene raised AttributeError 'no attribute params'; now it is the static
    DopplerScene it loads as."""
    import mitsuba as mi

    import dopplertof
    from dopplertof.cameras.capture import capture_camera

    dopplertof.set_variant("llvm_ad_rgb")
    box = mi.cornell_box()
    box["sensor"]["film"].update(width=3, height=2)
    result = capture_camera(mi.load_dict(box), "opt8241", spp=4, noise=False,
                            progress=False)
    assert result.depth.shape == (2, 3) and np.isfinite(result.depth_gt).any()


def test_keyframes_shorter_than_the_raw_frames_warn_once_naming_both_spans(tmp_path, capsys):
    """issue 42: the starter sphere's 1.5 ms of keyframes through kinect-v2's raw frames
    (about 13 ms) passed silently; the bodies stand still after their last keyframe."""
    import json
    import os

    from dopplertof.cli import main

    sphere = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))),
                          "examples", "translating_sphere.xml")
    out = tmp_path / "out"
    assert main(["capture", sphere, "--camera", "kinect-v2", "--res", "4x4", "--spp", "2",
                 "--quiet", "--noiseless", "-o", str(out)]) == 0
    warnings = [line for line in capsys.readouterr().err.splitlines() if "warning" in line]
    summary = json.loads((out / "summary.json").read_text())
    first, last = summary["sequence_s"]
    assert len(warnings) == 1 and warnings == [f"dopplertof: warning: {summary['warnings'][0]}"]
    assert "the keyframes (0 to 0.0015 s) cover" in warnings[0]
    assert f"of the raw frames ({first:g} to {last:g} s)" in warnings[0]
    assert last - first > 0.01


def _three_phase(steps):
    return [(30.0, p, 5e-4, i * 1e-3) for i, p in enumerate(steps)]


@pytest.mark.parametrize("frames, old, new, message", [
    # issue 39's 2026-12-03 campaign: presets accepted by `cameras`, then silently wrong
    (None, "frequency_mhz = 30.0", "frequency_mhz = 1e12", "frames[0].frequency_mhz out of range"),  # P05
    (None, "frequency_mhz = 30.0", "frequency_mhz = 1e6", "frames[0].frequency_mhz out of range"),  # P06
    (None, "frequency_mhz = 30.0", "frequency_mhz = 1e-9", "frames[0].frequency_mhz out of range"),  # P07
    ((0.0, 1e-6, 2e-6), None, None, "too close together to give a phase"),  # P09
    ((0.0, 180.0, 180.000001), None, None, "too close together to give a phase"),  # P10
    (None, "offset_dn = 2048.0", "offset_dn = 1e9", "past the 12-bit ADC"),  # P15
    (None, "contrast = 0.8", "contrast = 1e-300", "modulation.contrast out of range"),  # P16
    (None, "fov_deg = 20.0", "fov_deg = 179.999", "optics.fov_deg out of range"),  # P22
    (None, "max_range_m = ", "max_range_m = 1e-9 #", "reconstruction.max_range_m out of range"),  # P23
    (None, "integration_s = 0.0005", "integration_s = 1e-15", "integration_s out of range"),  # P39
    # P28: a half beat was reported as "16 MHz has 2 distinct phase step(s)", not named
    ((0.0, 120.0, 240.0), "phase_deg = 0.0\n", "phase_deg = 0.0\nhetero_frequency = 0.5\n",
     "frames[0].hetero_frequency must be an integer number of beat periods, got 0.5"),
])
def test_campaign_presets_that_passed_are_refused_naming_the_key(tmp_path, frames, old, new,
                                                                 message):
    text = preset_text(_three_phase(frames) if frames else four_phase(30.0))
    if old:
        assert old in text
        text = text.replace(old, new, 1)
    path = tmp_path / "campaign.toml"
    path.write_text(text)
    done = run_cli("cameras", str(path))
    assert done.returncode == 2 and message in done.stderr and str(path) in done.stderr
    assert len(done.stderr.strip().splitlines()) == 1


def test_one_frequency_depths_beyond_the_reported_range_are_flagged(tmp_path):
    """P23: a single-frequency camera's max_range_m was printed, not applied."""
    preset, result = _plane_through(tmp_path, four_phase(30.0), 3.0, 0.0, 4e-3,
                                    max_range=2.0)
    assert result.reconstruction.out_of_range.all() and np.isnan(result.depth).all()
