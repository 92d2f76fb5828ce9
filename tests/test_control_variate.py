"""time_sampling_method="control_variate" (integrators/control_variate.py): the analytic
integral as a control variate for one sampled time per path.

What it must be: unbiased where the analytic mode is not (the exact quadrature of the
moving plane, including a plane whose value is far from linear in time, a moving camera
and a moving light), the analytic mode itself where nothing moves (the sampled path is
then the model's, up to float32 rounding), in agreement with the sampled methods on the
starter scenes (a spinning cube, a moving camera, a light off the camera); its refusal of
the waveforms the closed form does not cover is tests/test_analytic_mode.py's.

Statistics: the plane tests compare the mean of 16 seeds with the quadrature, |t| under
the Student bound (15 dof) that gives the file's 5 plane cases together a false-failure
rate of 1e-4, plus 2e-4 of the value for the quadrature's own error (its rule is exact
to about 1e-6 here). The starter scenes compare three image regions' means of 12 seeds
of each method, |t| under the Student bound (11 dof) for 3 scenes x 3 regions at 1e-4;
the published scene three regions of 6 seeds against the deep reference (5 dof) at 1e-4.
"""

import os

import numpy as np
import pytest

import dopplertof
from analytic import plane_scene, reference
from bounds import rounding_bound, student_bound

HERE = os.path.dirname(os.path.abspath(__file__))
EXAMPLES = os.path.join(HERE, "..", "examples")

PLANE_CASES = [  # (z0, velocity, hetero_frequency, camera_velocity, light_velocity)
    (4.0, 30.0, 1.0, 0.0, None),
    (1.0, 1.5 / 0.0015, 0.0, 0.0, None),  # 1 m to 2.5 m: 1/z^2 falls 6x, far from linear
    (2.0, -400.0, 1.0, 0.0, None),
    (3.0, 0.0, 1.0, 200.0, None),  # the camera (and the light on it) moves
    (3.0, 0.0, 1.0, 0.0, -300.0),  # the light moves on its own
]
PLANE_SEEDS = range(16)
PLANE_T = student_bound(1e-4, len(PLANE_CASES), len(PLANE_SEEDS) - 1)


def _plane_values(case, method, spp=64):
    z0, v, h, camera_velocity, light_velocity = case
    scene = dopplertof.load_dict(plane_scene(
        z0, v, spp=spp, camera_velocity=camera_velocity, light_velocity=light_velocity,
        integrator=dict(time_sampling_method=method, hetero_frequency=h)))
    return np.array([dopplertof.render(scene, seed=s)[0, 0, 0] for s in PLANE_SEEDS],
                    np.float64)


@pytest.mark.parametrize("case", PLANE_CASES)
def test_unbiased_on_the_moving_plane(case):
    """The mean of 16 seeds against the exact quadrature, within the Student bound."""
    z0, v, h, camera_velocity, light_velocity = case
    exact = reference(z0, v, hetero_frequency=h, camera_velocity=camera_velocity,
                      light_velocity=light_velocity)
    values = _plane_values(case, "control_variate")
    se = values.std(ddof=1) / np.sqrt(len(values))
    t = abs(values.mean() - exact) / (se + 2e-4 * abs(exact) / PLANE_T)
    assert t < PLANE_T, (values.mean(), exact, se)


def test_unbiased_where_the_analytic_mode_is_far_off():
    """On the plane receding from 1 m to 2.5 m the analytic mode misses the exact value
    by more than 10% (tests/test_analytic_mode.py); the control variate built on it does
    not (the test above), and its noise is small enough to tell the two apart."""
    case = PLANE_CASES[1]
    exact = reference(case[0], case[1], hetero_frequency=case[2])
    analytic = _plane_values(case, "analytic").mean()
    values = _plane_values(case, "control_variate")
    se = values.std(ddof=1) / np.sqrt(len(values))
    assert abs(analytic - exact) > 0.1 * abs(exact)
    assert abs(analytic - exact) > 20 * se, (analytic, exact, se)


def test_equals_the_analytic_mode_where_nothing_moves():
    """A static plane: P1, P2 and the sampled path are one path, f = g at every time, and
    the estimate is the analytic one up to float32 rounding. Per sample, f's phase
    omega_d t + psi + k L (under 16 rad here) is summed in float32 (4 roundings of at
    most 16 eps each) and both weights round their cosine and products (a few eps):
    |f - g| < 72 eps of the sample's amplitude A, the pixel's A from the homodyne
    quadratures; the pixel's float32 sums of 64 samples add Higham and Mary's bound."""
    scene = {m: dopplertof.load_dict(plane_scene(
        3.0, 0.0, spp=64, integrator=dict(time_sampling_method=m, hetero_frequency=1.0)))
        for m in ("analytic", "control_variate")}
    image = {m: dopplertof.render(s, seed=3)[0, 0, 0] for m, s in scene.items()}
    amplitude = np.hypot(*(reference(3.0, 0.0, hetero_offset=o) for o in (0.0, 0.25)))
    eps = float(np.finfo(np.float32).eps)
    bound = 72 * eps * amplitude + rounding_bound(3 * amplitude, 3 * 64)
    assert abs(image["control_variate"] - image["analytic"]) < bound, (image, bound)
    assert abs(image["analytic"]) < 1e-3 * amplitude  # (one beat: the static plane's 0)


STARTERS = ("rotating_cube.xml", "moving_camera.xml", "light_off_camera.xml")
STARTER_SEEDS = range(1, 13)
STARTER_T = student_bound(1e-4, 3 * len(STARTERS), len(STARTER_SEEDS) - 1)


def _region_means(image):
    lum = np.asarray(image, np.float64).mean(axis=-1)
    h, w = lum.shape
    return np.array([lum.mean(), lum[:, : w // 2].mean(), lum[h // 2:, w // 2:].mean()])


@pytest.mark.slow
@pytest.mark.parametrize("name", STARTERS)
def test_agrees_with_sampled_time_on_the_starter_scenes(name):
    """Three regions' means of 12 seeds, against ``auto`` (antithetic pairs at one beat),
    each |t| under the Student bound."""
    dopplertof.set_variant()
    scene = dopplertof.load_file(os.path.join(EXAMPLES, name), {"res": "16"})
    estimates = {}
    for method in ("auto", "control_variate"):
        samples = np.array([_region_means(dopplertof.render(
            scene, spp=32, seed=s, params=dict(time_sampling_method=method)))
            for s in STARTER_SEEDS])
        estimates[method] = samples.mean(axis=0), samples.std(axis=0, ddof=1) / np.sqrt(
            len(STARTER_SEEDS))
    (a, sa), (b, sb) = estimates["auto"], estimates["control_variate"]
    t = np.abs(a - b) / np.sqrt(sa**2 + sb**2)
    assert np.all(t < STARTER_T), (t, a, b)


PUBLISHED_DIR = os.path.normpath(os.path.join(HERE, "..", "..", "shared", "fixtures",
                                              "published"))
PUBLISHED_SEEDS = range(1, 7)
PUBLISHED_T = student_bound(1e-4, 3, len(PUBLISHED_SEEDS) - 1)


@pytest.mark.slow
@pytest.mark.skipif(not os.path.exists(os.path.join(PUBLISHED_DIR, "deep_reference_2e17.npy")),
                    reason="needs ../shared/fixtures/published (the deep reference)")
def test_agrees_with_the_deep_reference_on_the_published_scene():
    """The published moving Cornell box at 256x256, depth 4, one beat: three regions'
    means of 6 seeds at 32 spp against the 2^17-spp reference (its own noise, 2.93e-6 per
    pixel, is below 1e-8 over a region), each |t| under the Student bound (5 dof) (the
    analytic mode's image mean is 0.81 of the reference's; the standard error here is
    about 1.3% of it)."""
    dopplertof.set_variant()
    scene = dopplertof.load_file(os.path.join(PUBLISHED_DIR, "cornell_box_moving.xml"))
    reference_image = np.load(os.path.join(PUBLISHED_DIR, "deep_reference_2e17.npy"))
    samples = np.array([_region_means(dopplertof.render(
        scene, spp=32, seed=s, params=dict(time_sampling_method="control_variate")))
        for s in PUBLISHED_SEEDS])
    mean = samples.mean(axis=0)
    se = samples.std(axis=0, ddof=1) / np.sqrt(len(PUBLISHED_SEEDS))
    expected = _region_means(reference_image)
    t = np.abs(mean - expected) / se
    assert np.all(t < PUBLISHED_T), (t, mean, expected, se)


def test_auto_takes_it_away_from_whole_beats_and_never_for_derivatives():
    """auto's rule (docs/benchmarks.md's table): pairs within 0.08 of a whole number of
    beats, the control variate from half a beat on, stratified time below; never the
    control variate for another waveform or where derivatives need sampled time."""
    from dopplertof.sampling import auto_sampling

    picks = {h: auto_sampling(h, closed_form=True)["time_sampling_method"]
             for h in (0.0, 0.4, 0.5, 0.75, 1.0, 1.05, 1.1, 2.0, 2.5, 6.5)}
    assert picks == {0.0: "stratified", 0.4: "stratified", 0.5: "control_variate",
                     0.75: "control_variate", 1.0: "antithetic", 1.05: "antithetic",
                     1.1: "control_variate", 2.0: "antithetic", 2.5: "control_variate",
                     6.5: "control_variate"}
    params = dopplertof.RenderParams(time_sampling_method="auto", hetero_frequency=2.5,
                                     time=0.001)
    assert params.resolved(0.0).time_sampling_method == "control_variate"
    assert params.resolved(0.0, sampled=True).time_sampling_method == "stratified"
    square = dopplertof.RenderParams(time_sampling_method="auto", hetero_frequency=2.5,
                                     time=0.001, wave_function_type="rectangular")
    assert square.resolved(0.0).time_sampling_method == "stratified"


def test_derivatives_of_an_auto_scene_sample_time():
    """A scene at 2.5 beats renders with the control variate, and its gradient's render
    parameters (diff/adjoint.gradient_params) resolve to sampled time."""
    from dopplertof.diff.adjoint import gradient_params
    from dopplertof.diff.render import DifferentiableScene

    scene = dopplertof.load_dict(plane_scene(4.0, 30.0, spp=16, integrator=dict(
        hetero_frequency=2.5)))
    assert scene.params.resolved(scene.shutter_interval).time_sampling_method == (
        "control_variate")
    assert gradient_params(DifferentiableScene(scene)).time_sampling_method == "stratified"


def test_a_render_leaves_the_settings_dataclasses_as_they_were():
    """The pass reads its loop's settings through a plain object: a loop that read the
    render's setup (a dataclass) took it for loop state, and Dr.Jit's traversal then
    replaced the FMCW settings' field types ('float') by the classes in place, so that
    the next FMCW scene in the process failed to load (KeyError: <class 'float'>)."""
    from dataclasses import fields

    from dopplertof.fmcw_settings import FMCWSettings

    before = [f.type for f in fields(FMCWSettings)]
    scene = dopplertof.load_dict(plane_scene(
        3.0, 30.0, spp=4, integrator=dict(time_sampling_method="control_variate")))
    dopplertof.render(scene, seed=0)
    assert [f.type for f in fields(FMCWSettings)] == before
    street = dopplertof.load_file(os.path.join(EXAMPLES, "fmcw_street.xml"), {"res": "4"})
    assert street.modality_settings["fmcw"].bandwidth == 4.0  # (the file's fmcw_bandwidth)
