"""FMCW lidar (issue 43): the chirp's parameters, the beat spectra of a moving plane at
their closed-form frequencies, range and velocity from the peaks, the energy of the
spectra, a spinning sphere's Doppler spread against its angular velocity, the command
and its folder."""

import json
import math
import os
import re

import numpy as np
import pytest
from analytic import FOV, INTENSITY, RHO, plane_scene
from bounds import FLOAT32_UNIT, rounding_bound

import dopplertof
from dopplertof.cli import main
from dopplertof.fmcw import Chirp, FMCWError, fmcw, spectrum_peaks
from dopplertof.fmcw_settings import FMCWSettings
from dopplertof.tof.ground_truth import ground_truth

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SPHERE = os.path.join(ROOT, "examples", "translating_sphere.xml")
EXPOSURE = 0.0015  # plane_scene's


@pytest.mark.parametrize("values,message", [
    ({"bandwidth": 0.0}, "bandwidth B must be > 0"),
    ({"bandwidth": -1e9}, "bandwidth B must be > 0"),
    ({"chirp_time": 0.0}, "chirp_time T must be > 0"),
    ({"bins": 1}, "bins M must be an integer >= 2"),
    ({"bins": 2.5}, "bins M must be an integer >= 2"),
    ({"wavelength": 199e-9}, "wavelength must be within 200 nm - 20 um"),
    ({"wavelength": 20.1e-6}, "wavelength must be within"),
    ({"bandwidth": math.nan}, "bandwidth must be a finite number"),
])
def test_bad_chirp_parameters_are_refused_in_one_line(values, message):
    with pytest.raises(FMCWError) as info:
        Chirp(**values)
    assert message in str(info.value) and "\n" not in str(info.value)


def test_range_and_velocity_invert_the_beats():
    chirp = Chirp(wavelength=1550e-9, bandwidth=2e9, chirp_time=5e-6, bins=8)
    f_up, f_down = chirp.beats(2 * 7.25, 2 * -1.5)
    assert f_up - f_down == pytest.approx(2 * (2 * -1.5) / 1550e-9)
    assert chirp.range_and_velocity(f_up, f_down) == pytest.approx((7.25, -1.5), rel=1e-12)
    assert chirp.frequencies()[[0, 1, 7]] == pytest.approx([0.0, 2e5, 1.4e6])


def test_peaks_are_found_strongest_first_at_their_split_beats():
    """Two beats split linearly between bins (the splat's rule), at 3.25 and 9.6 bins:
    found at exactly those, the stronger first; a third asked for is NaN."""
    chirp = Chirp(bandwidth=1e9, chirp_time=1e-6, bins=16)
    spectrum = np.zeros(16)
    for position, power in ((3.25, 1.0), (9.6, 2.0)):
        low = int(position)
        spectrum[low] += power * (1 - (position - low))
        spectrum[low + 1] += power * (position - low)
    beats, heights = spectrum_peaks(spectrum, chirp, count=3)
    assert beats[:2] == pytest.approx([9.6e6, 3.25e6], rel=1e-12)
    assert np.isnan(beats[2]) and heights[2] == 0 and heights[0] > heights[1] > 0


def _plane(z0, velocity, spp=16, res=1, chirp=None):
    """The moving plane's FMCW frame, and the plane's distance at the traced time."""
    scene = dopplertof.load_dict(plane_scene(z0, velocity, exposure=EXPOSURE, res=res, spp=spp))
    chirp = chirp or Chirp(bandwidth=1e9, chirp_time=10e-6, bins=64)
    result = fmcw(scene, chirp, spp=spp)
    assert result.summary["time_s"] == pytest.approx(0.5 * EXPOSURE)
    return result, chirp, z0 + velocity * 0.5 * EXPOSURE


@pytest.mark.parametrize("velocity", [0.5, -0.8])
def test_a_moving_plane_beats_at_the_closed_form_frequencies(velocity):
    """Up and down peaks within one bin of (B/T) 2d/c +- 2v/lambda; range and velocity
    within 1% of the truth and of the closed form (v > 0 receding: f_up > f_down)."""
    result, chirp, distance = _plane(3.0, velocity)
    f_up, f_down = chirp.beats(2 * distance, 2 * velocity)
    assert abs(result.peaks[0, 0, 0] - f_up) < chirp.bin_width
    assert abs(result.peaks[0, 0, 1] - f_down) < chirp.bin_width
    peak_bins = np.argmax(result.spectrum[0, 0], axis=-1)
    assert abs(peak_bins[0] - f_up / chirp.bin_width) <= 1
    assert abs(peak_bins[1] - f_down / chirp.bin_width) <= 1
    assert (result.peaks[0, 0, 0] > result.peaks[0, 0, 1]) == (velocity > 0)
    assert result.range[0, 0] == pytest.approx(distance, rel=0.01)
    assert abs(result.range[0, 0] - distance) < chirp.record()["range_per_bin_m"]
    assert result.velocity[0, 0] == pytest.approx(velocity, rel=0.01)
    assert result.range_gt[0, 0] == pytest.approx(distance, rel=1e-4)
    assert result.velocity_point[0, 0] == pytest.approx(velocity, rel=1e-3)


def test_the_spectra_hold_the_pixel_radiance():
    """Each chirp's spectrum sums to the pixel's radiance, rho I d_z^3 / (pi z^2)
    averaged over the pixel (a point light at the camera, a diffuse plane at z)."""
    result, _, z = _plane(2.0, 0.3, spp=64)
    s = math.tan(math.radians(FOV) / 2)
    a = np.linspace(-s, s, 401)
    A, B = np.meshgrid(a, a)
    d_z = 1.0 / np.sqrt(1.0 + A ** 2 + B ** 2)
    expected = float(np.mean(RHO * INTENSITY * d_z ** 3 / (math.pi * z ** 2)))
    sums = result.spectrum[0, 0].astype(np.float64).sum(axis=-1)
    assert sums == pytest.approx([expected, expected], rel=2e-3)


def test_a_plane_beyond_the_last_bin_has_no_peak():
    """Beats past the last bin are dropped: no spectrum, NaN range and velocity."""
    result, chirp, _ = _plane(3.0, 0.5, chirp=Chirp(bandwidth=1e9, chirp_time=10e-6, bins=8))
    assert 6.0 > chirp.max_path_length
    assert not result.spectrum.any()
    assert np.isnan(result.range).all() and np.isnan(result.velocity).all()


def _spinning_sphere(omega: float, res: int, spp: int) -> dict:
    """A unit sphere 4 m in front of the camera spinning about +y at ``omega`` rad/s."""
    import mitsuba as mi

    T = mi.ScalarTransform4f
    pose = lambda t: T().translate([0, 0, 4]).rotate([0, 1, 0], math.degrees(omega * t))  # noqa: E731
    scene = plane_scene(10.0, 0.0, exposure=EXPOSURE, res=res, spp=spp)
    scene["sensor"]["fov"] = 30.0
    scene["sphere"] = {"type": "sphere", "bsdf": {"type": "ref", "id": "white"},
                       "to_world": dopplertof.Animation([(0.0, pose(0.0)),
                                                         (EXPOSURE, pose(EXPOSURE))])}
    del scene["plane"]
    return scene


def test_a_spinning_sphere_spreads_its_doppler_by_its_angular_velocity():
    """Each pixel's velocity is its surface point's velocity along the ray,
    omega (y x (p - c)) . d, from the sphere's angular velocity alone, within half the
    change of that closed form to the pixel's neighbours (a footprint averages over its
    pixel) plus one bin's velocity; the spread across the sphere follows omega."""
    omega, centre = 2.0, np.array([0.0, 0.0, 4.0])
    scene = dopplertof.load_dict(_spinning_sphere(omega, res=32, spp=16))
    chirp = Chirp(bandwidth=10e9, chirp_time=40e-6, bins=2048)
    result = fmcw(scene, chirp, spp=16)
    truth = ground_truth(scene)  # (its depths and ray directions: the hit points)
    p = truth.depth[..., None] * truth.direction
    u = omega * np.cross([0.0, 1.0, 0.0], p - centre)
    closed_form = np.sum(u * truth.direction, axis=-1)
    on = np.isfinite(truth.depth) & (truth.body == 0)
    assert result.velocity_point[on] == pytest.approx(closed_form[on], abs=1e-3)
    # pixels wholly on the sphere (their neighbours too)
    inner = on & np.roll(on, 1, 0) & np.roll(on, -1, 0) & np.roll(on, 1, 1) & np.roll(on, -1, 1)
    step = np.max([np.abs(np.roll(closed_form, k, axis) - closed_form)
                   for k in (1, -1) for axis in (0, 1)], axis=0)
    bound = 0.5 * step + chirp.record()["velocity_per_bin_m_s"]
    error = np.abs(result.velocity - closed_form)
    assert inner.sum() > 400 and (error[inner] < bound[inner]).all()
    # the angular velocity fitted to the measured velocities (they are linear in omega)
    fitted = omega * np.polyfit(closed_form[inner], result.velocity[inner], 1)[0]
    assert fitted == pytest.approx(omega, rel=0.015)  # (0.991 omega: footprints average)
    assert np.ptp(result.velocity[inner]) > 3.0  # (omega R = 2 m/s at the limbs)


def test_the_fmcw_command_writes_its_folder(tmp_path, capsys):
    out = tmp_path / "out"
    code = main(["fmcw", SPHERE, "-o", str(out), "--spp", "4", "-D", "res=8",
                 "--bandwidth", "10", "--chirp-time", "10", "--bins", "512",
                 "-P", "max_depth=2", "--returns", "2"])
    assert code == 0
    shapes = {name: np.load(out / f"{name}.npy").shape
              for name in ("spectrum", "frequencies", "range", "velocity", "range_gt",
                           "velocity_point", "returns_range", "returns_velocity")}
    assert shapes == {"spectrum": (8, 8, 2, 512), "frequencies": (512,), "range": (8, 8),
                      "velocity": (8, 8), "range_gt": (8, 8), "velocity_point": (8, 8),
                      "returns_range": (8, 8, 2), "returns_velocity": (8, 8, 2)}
    assert all((out / f"{name}.png").stat().st_size > 0
               for name in ("range", "range_gt", "velocity", "velocity_point"))
    points = np.load(out / "points.npy")
    assert points.shape[1] == 5 and 64 <= len(points) <= 128
    summary = json.loads((out / "summary.json").read_text())
    assert "issue" not in summary and summary["chirp"]["bins"] == 512
    errors = summary["errors"]
    assert errors["range_m"]["pixels"] == 64
    assert errors["range_m"]["median_abs"] < 0.02
    assert errors["velocity_m_s"]["median_abs"] < 0.1  # the sphere at -10 m/s, the wall at 0
    sphere, static = summary["regions"]
    assert sphere["velocity_gt_median_m_s"] < -9.0 and static["velocity_gt_median_m_s"] == 0
    assert sphere["velocity_m_s"]["median_abs"] < 0.1 and sphere["pixels"] > 4
    velocity = np.load(out / "velocity.npy")
    assert np.nanmin(velocity) < -9.0
    assert "wrote" in capsys.readouterr().out


def test_bad_chirp_options_exit_2_in_one_line(tmp_path, capsys):
    code = main(["fmcw", SPHERE, "-o", str(tmp_path / "out"), "--bins", "1"])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and "bins M must be" in err
    assert not (tmp_path / "out").exists()


# ---- The chirp and the beam in the scene's XML (issue 43, 2026-12-03) ----

XML_CHIRP = {"fmcw_wavelength": ("float", "1064"), "fmcw_bandwidth": ("float", "10"),
             "fmcw_chirp_time": ("float", "5"), "fmcw_bins": ("integer", "512")}
XML_CHIRP_SI = Chirp(wavelength=1064e-9, bandwidth=10e9, chirp_time=5e-6, bins=512)


def _sphere_with(tmp_path, values: dict, name="chirp.xml") -> str:
    """examples/translating_sphere.xml with ``values`` ({name: (tag, value)}) added to
    its integrator, written to ``tmp_path``; the file's path."""
    lines = "".join(f'<{tag} name="{key}" value="{value}"/>'
                    for key, (tag, value) in values.items())
    text = open(SPHERE).read().replace('<integrator type="dopplertof">',
                                       '<integrator type="dopplertof">' + lines, 1)
    path = tmp_path / name
    path.write_text(text)
    return str(path)


@pytest.mark.parametrize("beam", ["flood", "collimated"])
def test_a_chirp_in_the_xml_gives_the_spectrum_of_the_same_chirp_in_python(tmp_path, beam):
    """The scene's fmcw_* parameters (nm, GHz, us, bins, beam, W/sr) make the frame of
    the same chirp and beam passed in Python (to float32 rounding: atomic adds), and an
    argument given in Python overrides the scene's; the D-ToF renders ignore them."""
    values = dict(XML_CHIRP, fmcw_beam=("string", beam),
                  fmcw_beam_intensity=("float", "3"))
    scene = dopplertof.load_file(_sphere_with(tmp_path, values), {"res": "8"})
    plain = dopplertof.load_file(SPHERE, {"res": "8"})
    from_xml = fmcw(scene, spp=4)
    from_python = fmcw(plain, XML_CHIRP_SI, spp=4, beam=beam, beam_intensity=3.0)
    assert from_xml.spectrum.shape == (8, 8, 2, 512) and from_xml.spectrum.any()
    # the same samples summed, at most in another order: a bin is a sum of non-negative
    # powers, one per lane and vertex that lands in it (4 spp x max_depth 2 x 2 shares
    # at most), within twice their sum's rounding bound of each other (measured: bitwise)
    bound = 2 * rounding_bound(1.0, 4 * 2 * 2)
    assert np.all(np.abs(from_xml.spectrum - from_python.spectrum)
                  <= bound * np.maximum(from_xml.spectrum, from_python.spectrum))
    assert from_xml.summary["chirp"] == from_python.summary["chirp"]
    assert from_xml.summary["beam"] == from_python.summary["beam"]
    override = fmcw(scene, Chirp(bins=64), spp=1, beam="flood")
    assert override.spectrum.shape[-1] == 64 and override.summary["beam"]["kind"] == "flood"
    # (the D-ToF renders' and checkpoints' keys: the image-defining parameters' repr)
    assert scene.params == plain.params and "fmcw" not in repr(scene.params)
    assert scene.modality_settings["fmcw"] == FMCWSettings(
        wavelength=1064.0, bandwidth=10.0, chirp_time=5.0, bins=512, beam=beam,
        beam_intensity=3.0)


def test_the_command_takes_its_options_over_the_xml_and_the_xml_over_the_defaults(
        tmp_path, capsys):
    """Each parameter on its own: --bins over -P fmcw_bins over the scene's fmcw_bins;
    the scene's bandwidth where no option gives one; the default wavelength where
    neither does."""
    scene = _sphere_with(tmp_path, {"fmcw_bandwidth": ("float", "10"),
                                    "fmcw_bins": ("integer", "512")})
    common = ["--spp", "1", "-D", "res=4", "-P", "max_depth=2"]
    for extra, bins in (([], 512), (["-P", "fmcw_bins=128"], 128),
                        (["-P", "fmcw_bins=128", "--bins", "64"], 64)):
        out = tmp_path / f"out{bins}"
        assert main(["fmcw", scene, "-o", str(out), *common, *extra]) == 0
        chirp = json.loads((out / "summary.json").read_text())["chirp"]
        assert (chirp["bins"], chirp["bandwidth_GHz"], chirp["wavelength_nm"]) == (
            bins, 10, 1550)
    capsys.readouterr()


@pytest.mark.parametrize("key,tag,value,message", [
    ("fmcw_bandwidth", "float", "0", "fmcw_bandwidth must be > 0 GHz, got 0"),
    ("fmcw_bandwidth", "float", "-2", "fmcw_bandwidth must be > 0 GHz, got -2"),
    ("fmcw_chirp_time", "float", "0", "fmcw_chirp_time must be > 0 us, got 0"),
    ("fmcw_bins", "integer", "1", "fmcw_bins must be >= 2, got 1"),
    ("fmcw_bins", "float", "2.5", "parameter 'fmcw_bins' must be an integer"),
    ("fmcw_wavelength", "float", "150", "fmcw_wavelength must be within 200 - 20000 nm"),
    ("fmcw_wavelength", "float", "25000", "fmcw_wavelength must be within 200 - 20000 nm"),
    ("fmcw_beam", "string", "laser", "unknown fmcw_beam 'laser': expected one of flood, "
                                     "collimated"),
    ("fmcw_beam_intensity", "float", "0", "fmcw_beam_intensity must be > 0 W/sr"),
    ("fmcw_bandwith", "float", "4", "unknown parameter 'fmcw_bandwith', did you mean "
                                    "'fmcw_bandwidth'?"),
])
def test_a_bad_xml_chirp_exits_2_in_one_line_naming_the_file_and_the_key(
        tmp_path, capsys, key, tag, value, message):
    scene = _sphere_with(tmp_path, {key: (tag, value)}, name="bad.xml")
    code = main(["fmcw", scene, "-o", str(tmp_path / "out"), "--spp", "1"])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1, err
    assert message in err and key in err and f"{scene}:14:" in err, err
    with pytest.raises(dopplertof.SceneError, match=re.escape(message)):
        dopplertof.load_file(scene)


@pytest.mark.parametrize("moving", ["camera", "light", "camera with its beam"])
def test_a_moving_camera_or_light_shifts_the_beats_by_its_own_rate(moving):
    """A static plane 3 m ahead: the camera (its light on it, or a collimated beam from
    it) approaching at 0.6 m/s reads -0.6 m/s; a light alone moving toward the plane at
    0.6 m/s shortens the light's leg only: dL/dt = -0.6 m/s, velocity -0.3 m/s (half the
    path's rate)."""
    camera, light = (0.0, 0.6) if moving == "light" else (0.6, None)
    scene = dopplertof.load_dict(plane_scene(3.0, 0.0, exposure=EXPOSURE, res=1, spp=16,
                                             camera_velocity=camera, light_velocity=light))
    chirp = Chirp(bandwidth=1e9, chirp_time=10e-6, bins=64)
    result = fmcw(scene, chirp, spp=16, beam="collimated" if "beam" in moving else "flood")
    t0 = 0.5 * EXPOSURE
    if moving != "light":
        f_up, f_down = chirp.beats(2 * (3.0 - camera * t0), -2 * camera)
        expected = -camera
    else:  # the light leaves the camera for the plane: its leg is 3 - v t0 long
        f_up, f_down = chirp.beats(3.0 + 3.0 - light * t0, -light)
        expected = -0.5 * light
    assert result.peaks[0, 0] == pytest.approx([f_up, f_down], abs=0.05 * chirp.bin_width)
    assert result.velocity[0, 0] == pytest.approx(expected, rel=0.01)


def test_the_street_example_reads_the_car_and_the_pedestrian():
    """examples/fmcw_street.xml with the chirp its integrator carries (4 GHz over 10 us,
    1024 bins): the car's pixels read its approach (about -10 m/s along the rays) and
    the walls stand still."""
    scene = dopplertof.load_file(os.path.join(ROOT, "examples", "fmcw_street.xml"),
                                 {"res": "24", "spp": "8"})
    result = fmcw(scene, spp=8)
    assert result.summary["chirp"]["bandwidth_GHz"] == 4 and result.spectrum.shape[-1] == 1024
    truth = ground_truth(scene)
    car, walker = truth.body == 0, truth.body == 1
    assert car.sum() > 10 and walker.sum() > 3
    error = np.abs(result.velocity - result.velocity_point)
    assert np.median(result.velocity_point[car]) < -9.5
    assert np.median(error[car]) < 0.1 and np.median(error[walker]) < 0.1
    assert np.nanmedian(np.abs(result.velocity[truth.body == -1])) < 0.01


def _mirror_scene(spp: int) -> dict:
    """One 4-degree pixel: its left half sees a diffuse plane 4 m ahead, its right half a
    mirror 2 m ahead that sends it back to a diffuse wall 1 m behind the camera (the
    point light at the camera lights both)."""
    import mitsuba as mi

    T = mi.ScalarTransform4f
    scene = plane_scene(4.0, 0.0, exposure=EXPOSURE, res=1, spp=spp)
    scene["integrator"]["max_depth"] = 3
    facing = lambda x, z: T().translate([x, 0, z]).rotate([0, 1, 0], 180).scale([0.5, 1, 1])  # noqa: E731
    scene["plane"] = {"type": "rectangle", "bsdf": {"type": "ref", "id": "white"},
                      "to_world": facing(-0.5, 4.0)}
    scene["mirror"] = {"type": "rectangle", "bsdf": {"type": "conductor"},
                       "to_world": facing(0.5, 2.0)}
    scene["wall"] = {"type": "rectangle", "bsdf": {"type": "ref", "id": "white"},
                     "to_world": T().translate([0, 0, -1]).scale(2)}
    return scene


def test_a_mirror_adds_a_peak_at_its_longer_path():
    """Two peaks in each chirp: the plane's at L = 8 m and the mirrored path's at
    L = 2 + 3 + 1 = 6 m (camera, mirror, wall, light), at their closed-form beats (both
    static: up and down agree); the mirrored one is the stronger (its wall is 1 m from
    the light) and the pixel's range reads its 3 m."""
    scene = dopplertof.load_dict(_mirror_scene(spp=64))
    chirp = Chirp(bandwidth=1e9, chirp_time=10e-6, bins=64)
    result = fmcw(scene, chirp, spp=64)
    for spectrum in result.spectrum[0, 0]:
        local = [m for m in range(1, chirp.bins - 1)
                 if spectrum[m] > spectrum[m - 1] and spectrum[m] >= spectrum[m + 1]]
        strongest = sorted(local, key=lambda m: -spectrum[m])[:2]
        expected = [chirp.beats(6.0, 0.0)[0], chirp.beats(8.0, 0.0)[0]]
        assert np.abs(np.array(strongest) * chirp.bin_width - expected).max() <= chirp.bin_width
    assert result.range[0, 0] == pytest.approx(3.0, abs=0.5 * chirp.record()["range_per_bin_m"])
    assert result.velocity[0, 0] == pytest.approx(0.0, abs=1e-6)
    # two returns: the mirrored path's, then the plane's; each a point along the pixel's ray
    two = fmcw(scene, chirp, spp=64, returns=2)
    assert two.returns_range[0, 0] == pytest.approx([3.0, 4.0], abs=0.5 * chirp.record()[
        "range_per_bin_m"])
    assert two.returns_velocity[0, 0] == pytest.approx([0.0, 0.0], abs=1e-6)
    assert two.points.shape == (2, 5)
    assert two.points[:, :3] == pytest.approx(two.returns_range[0, 0][:, None] * [0, 0, 1],
                                               abs=1e-6)
    assert two.points[0, 4] > two.points[1, 4] > 0  # (peak heights, strongest first)


def test_the_spectra_hold_stock_mitsuba_path_radiance_at_every_pixel():
    """A static scene (a sphere before a wall, point light at the camera, two bounces):
    each chirp's spectrum sums, at every pixel, to the radiance of stock Mitsuba `path`
    (mean of the channels, box filter): |t| < 7.62 at each of the 64 pixels (16 seeds
    each; Student, 15 dof, Bonferroni over the pixels at 1e-4), the image means within
    1% (measured 0.3%)."""
    import mitsuba as mi

    scene_dict = _spinning_sphere(0.0, res=8, spp=64)
    scene_dict["sphere"]["to_world"] = mi.ScalarTransform4f().translate([0, 0, 4])
    scene_dict["plane"] = {"type": "rectangle", "bsdf": {"type": "ref", "id": "white"},
                           "to_world": mi.ScalarTransform4f().translate([0, 0, 5.5]).rotate(
                               [0, 1, 0], 180).scale(3)}
    scene_dict["integrator"]["max_depth"] = 3
    scene = dopplertof.load_dict(scene_dict)
    chirp = Chirp(bandwidth=1e9, chirp_time=10e-6, bins=128)
    seeds = 16
    ours = np.array([fmcw(scene, chirp, spp=64, seed=s).spectrum.astype(np.float64).sum(-1)
                     for s in range(seeds)])  # (seeds, H, W, 2)
    # both chirps hold all the energy: the same lane powers, split between two bins
    # (2 roundings) and summed in float32 per bin (at most 64 spp x max_depth 3 lanes per
    # bin; non-negative terms: the bins' relative error at most the bound of one sum);
    # the float64 sums over the bins add 1e-16
    bound = 2 * rounding_bound(1.0, 64 * 3 + 2)
    assert np.all(np.abs(ours[..., 0] - ours[..., 1]) <= bound * ours[..., 1])
    stock_scene = mi.load_dict({**scene_dict, "integrator": {"type": "path", "max_depth": 3}})
    stock = np.array([np.asarray(mi.render(stock_scene, spp=64, seed=100 + s)).mean(-1)
                      for s in range(seeds)])
    error = np.sqrt((ours[..., 0].var(0, ddof=1) + stock.var(0, ddof=1)) / seeds)
    t = (ours[..., 0].mean(0) - stock.mean(0)) / error
    assert np.abs(t).max() < 7.62, np.abs(t).max()
    assert ours[..., 0].mean() == pytest.approx(stock.mean(), rel=0.01)


@pytest.mark.parametrize("variant", ["llvm_ad_mono", "llvm_ad_spectral"])
def test_the_other_variants_read_the_plane(variant):
    """Monochrome and spectral variants: the same range and velocity (their colour is
    reduced as the RGB variant's: the mean of what the film would get)."""
    dopplertof.set_variant(variant)
    result, chirp, distance = _plane(3.0, 0.5)
    assert result.range[0, 0] == pytest.approx(distance, rel=0.01)
    assert result.velocity[0, 0] == pytest.approx(0.5, rel=0.01)


def test_a_frame_too_large_for_memory_is_refused_before_tracing(monkeypatch):
    from dopplertof.fmcw import trace

    monkeypatch.setattr(trace, "MAX_SPECTRUM_VALUES", 1000)
    scene = dopplertof.load_dict(plane_scene(3.0, 0.5, res=4, spp=4))
    with pytest.raises(ValueError, match="4x4 pixels x 2 chirps x 64 bins is 2,048 spectrum"):
        fmcw(scene, Chirp(bins=64), spp=4)


def _box(max_depth: int, res: int, spp: int) -> dict:
    """A box open toward the camera (its walls between z = 1 and 3, x and y within +-1),
    seen by a 90-degree camera at the origin with a point light of intensity 10 on it:
    everything the light reaches lies inside the camera's view."""
    import mitsuba as mi

    T = mi.ScalarTransform4f
    scene = plane_scene(3.0, 0.0, exposure=EXPOSURE, res=res, spp=spp)
    scene["sensor"]["fov"] = 90.0
    scene["integrator"]["max_depth"] = max_depth
    walls = {"plane": T().translate([0, 0, 3]).rotate([0, 1, 0], 180),
             "left": T().translate([-1, 0, 2]).rotate([0, 1, 0], 90),
             "right": T().translate([1, 0, 2]).rotate([0, 1, 0], -90),
             "floor": T().translate([0, -1, 2]).rotate([1, 0, 0], -90),
             "top": T().translate([0, 1, 2]).rotate([1, 0, 0], 90)}
    for name, to_world in walls.items():
        scene[name] = {"type": "rectangle", "bsdf": {"type": "ref", "id": "white"},
                       "to_world": to_world}
    return scene


def test_a_collimated_beam_returns_the_flood_light_of_its_own_footprint():
    """Direct light only: each pixel's own beam of intensity I gives the spectra of a
    point light of intensity I at the camera (the same numbers)."""
    scene = dopplertof.load_dict(_box(max_depth=2, res=6, spp=8))
    chirp = Chirp(bandwidth=1e9, chirp_time=10e-6, bins=64)
    flood = fmcw(scene, chirp, spp=8)
    beam = fmcw(scene, chirp, spp=8, beam="collimated", beam_intensity=INTENSITY)
    assert beam.spectrum.any() and beam.summary["beam"]["kind"] == "collimated"
    # the same samples through two light paths (a beam of I, a point light of I): each
    # lane's power (I / d^2 times the BSDF and cosines) and its beat position (in bins,
    # at most `bins`: the path's two segment lengths, their sum, times the bins per
    # metre, plus the Doppler term) are float32 results of at most OPS = 16 roundings
    # each, so they differ by at most OPS u relative. A lane splits its power between two
    # neighbouring bins by its position's fraction, so a position off by OPS u bins moves
    # that much of its power across; a bin then differs by at most OPS u (1 + bins) times
    # the power of it and its two neighbours (not relative to the bin alone: a bin
    # holding a sliver of its lanes' power beside full ones read 4.2e-5 apart, 37 u of
    # that power). The sums' order is the same in both (one kernel).
    ops, u = 16, FLOAT32_UNIT
    near = flood.spectrum.astype(np.float64)
    near[..., 1:] += flood.spectrum[..., :-1]
    near[..., :-1] += flood.spectrum[..., 1:]
    bound = ops * u * (1 + chirp.bins) * near
    assert np.all(np.abs(beam.spectrum.astype(np.float64) - flood.spectrum) <= bound)


def test_a_collimated_beam_reads_the_moving_plane():
    """Each pixel's own beam: the moving plane's range and velocity as with the flood."""
    scene = dopplertof.load_dict(plane_scene(3.0, -0.8, exposure=EXPOSURE, res=3, spp=16))
    chirp = Chirp(bandwidth=1e9, chirp_time=10e-6, bins=64)
    result = fmcw(scene, chirp, spp=16, beam="collimated", beam_intensity=5.0)
    assert result.range == pytest.approx(result.range_gt, rel=1e-3)
    assert result.velocity == pytest.approx(result.velocity_point, rel=1e-3)


@pytest.mark.parametrize("beam,intensity,message", [
    ("laser", 1.0, "beam must be one of flood, collimated"),
    ("collimated", 0.0, "beam intensity must be > 0 W/sr"),
    ("collimated", math.inf, "beam intensity must be > 0 W/sr"),
])
def test_bad_beams_are_refused(beam, intensity, message):
    scene = dopplertof.load_dict(plane_scene(3.0, 0.5, res=1, spp=4))
    with pytest.raises(ValueError, match=message):
        fmcw(scene, Chirp(bins=64), spp=4, beam=beam, beam_intensity=intensity)


def test_one_collimated_pixel_seeing_everything_lit_equals_the_flood():
    """One 90-degree pixel that sees everything the flood's light reaches: its beam is
    that light, so with interreflections (max_depth 3) the spectra agree in expectation:
    |t| < 5.24 on the total (Student, 15 dof, 1e-4) and on the interreflected part,
    which the connections to the spot carry (a fifth of the total here; measured
    t = -1.2 on it, the beam 5% under the flood)."""
    chirp = Chirp(bandwidth=1e9, chirp_time=10e-6, bins=64)
    totals = {}
    for depth in (2, 3):
        scene = dopplertof.load_dict(_box(max_depth=depth, res=1, spp=256))
        for kind in ("flood", "collimated"):
            totals[depth, kind] = np.array([fmcw(
                scene, chirp, spp=256, seed=s, beam=kind, beam_intensity=INTENSITY
            ).spectrum[0, 0, 0].astype(np.float64).sum() for s in range(16)])
    for part in ("total", "interreflected"):
        flood, beam = ((totals[3, k] - (totals[2, k] if part != "total" else 0))
                       for k in ("flood", "collimated"))
        t = (beam.mean() - flood.mean()) / np.sqrt((beam.var(ddof=1) + flood.var(ddof=1)) / 16)
        assert abs(t) < 5.24, (part, t, beam.mean(), flood.mean())
    interreflected = totals[3, "flood"].mean() - totals[2, "flood"].mean()
    assert interreflected > 0.1 * totals[3, "flood"].mean()


def test_speckle_is_fully_developed_around_the_spectrum():
    """Random path phases summed coherently: each pixel's speckle power over its
    spectrum's is exponential with mean 1 and contrast 1 (fully developed speckle): over
    64 pixels x 4 seeds, the mean within 1 +- 0.31 and the contrast within 1 +- 0.44 (5 sd
    each); a static plane's up and down chirps share their phases, so their speckle."""
    ratios = []
    for seed in range(4):
        scene = dopplertof.load_dict(plane_scene(3.0, 0.0, exposure=EXPOSURE, res=8, spp=64))
        result = fmcw(scene, Chirp(bandwidth=1e9, chirp_time=10e-6, bins=64), spp=64,
                      seed=seed, speckle=True)
        # a static plane: up and down add the same amplitudes sqrt(power x share) at the
        # same phases (measured: bitwise), summed in at most another order: each of the
        # real and imaginary sums within twice its rounding bound, whose magnitude
        # sum |a_i| <= sqrt(n S) (Cauchy-Schwarz; S the bin's power, n its terms: 64 spp
        # x max_depth 2 x 2 shares at most); speckle = re^2 + im^2 then moves by at most
        # 2 sqrt(2 speckle) d + 2 d^2
        n = 64 * 2 * 2
        d = 2 * rounding_bound(1.0, n) * np.sqrt(n * result.spectrum[:, :, 0].astype(np.float64))
        speckle = result.speckle.astype(np.float64)
        bound = 2 * np.sqrt(2 * speckle.max(axis=2)) * d + 2 * d ** 2
        assert np.all(np.abs(speckle[:, :, 0] - speckle[:, :, 1]) <= bound)
        ratios.append(result.speckle[:, :, 0].astype(np.float64).sum(-1)
                      / result.spectrum[:, :, 0].astype(np.float64).sum(-1))
    ratios = np.concatenate([r.ravel() for r in ratios])
    assert ratios.mean() == pytest.approx(1.0, abs=0.31)
    assert ratios.std() / ratios.mean() == pytest.approx(1.0, abs=0.44)


def test_a_file_in_the_way_of_the_folder_exits_2_before_rendering(tmp_path, capsys):
    blocker = tmp_path / "file"
    blocker.write_text("x")
    assert main(["fmcw", SPHERE, "-o", str(blocker), "--spp", "1"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "not a folder" in err and blocker.read_text() == "x"


def test_the_fmcw_settings_are_parsed_apart_from_the_render_parameters():
    """One parser hands fmcw_* names to the lidar's settings and the rest to
    RenderParams, which knows no fmcw_* name; a misspelt name is named with the nearest
    known ones, whoever's they are."""
    from dopplertof.params import ParameterError, RenderParams
    from dopplertof.scene.parameters import parsed

    params, settings = parsed({"max_depth": "3", "fmcw_bins": "64"}, "here", RenderParams())
    assert params == RenderParams(max_depth=3) and settings["fmcw"] == FMCWSettings(bins=64)
    assert not [name for name in RenderParams.names() if name.startswith("fmcw")]
    with pytest.raises(ParameterError, match="here: unknown parameter 'fmcw_bin', did you "
                                             "mean 'fmcw_bins'"):
        parsed({"fmcw_bin": 64}, "here", RenderParams())
    with pytest.raises(ParameterError, match="unknown parameter 'fmcw_bins'"):
        RenderParams.from_mapping({"fmcw_bins": 64})


def test_a_dtof_command_refuses_an_fmcw_parameter_it_would_ignore(tmp_path, capsys):
    """-P fmcw_bins=64 on `capture`: one line naming it and whose it is, exit 2, before
    the scene loads; nothing written."""
    out = tmp_path / "out"
    code = main(["capture", str(tmp_path / "missing.xml"), "-o", str(out), "-P",
                 "fmcw_bins=64"])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1, err
    assert "fmcw_bins is the FMCW lidar's (the fmcw command, dopplertof.fmcw), not a D-ToF " \
           "render's" in err
    assert not out.exists()
