"""Motion-compensated antithetic pairs (integrators/antithetic_map.py): unbiased against
exact references, in agreement with replay pairs, and refused where it cannot work.

Statistics: the 5 plane comparisons (16 seeds each) and the 3 region comparisons on the
published scene (12 seeds per mapping) hold |t| under the Student quantile that gives
the 8 a family-wise false-failure rate of 1e-4 (Bonferroni; 15 and 11 degrees of
freedom: about 6.4 and 7.5). Measured over 30 other seeds: the plane values' relative
standard deviation is 0.8-1.3% per render at one beat (7e-5-1.3e-4 homodyne), their
mean's difference from the quadrature consistent with zero (at most 1.5 of its own
standard errors), so a bias of 3% fails the heterodyne comparisons (0.1% the
homodyne ones). (4 standard errors of 8 seeds, as before, is a Student tail of 5e-3 per
comparison.)
"""

import numpy as np
import pytest

import dopplertof
from analytic import plane_scene, reference
from bounds import student_bound
from conftest import PUBLISHED
from dopplertof.sampling import FULL_CORRELATION

MOTION = dict(time_sampling_method="antithetic", path_correlation_depth=FULL_CORRELATION,
              antithetic_mapping="motion")
PLANE_SEEDS = range(16)
REGION_SEEDS = range(1, 13)
FAMILY_FALSE_FAILURE = 1e-4
COMPARISONS = 5 + 3


def render_seeds(scene_dict, seeds, params):
    scene = dopplertof.load_dict(scene_dict)
    return np.array([dopplertof.render(scene, seed=s, params=params)[0, 0, 0] for s in seeds])


def assert_unbiased(values, exact):
    se = values.std(ddof=1) / np.sqrt(len(values))
    assert se > 0
    assert se < 0.05 * abs(exact)  # informative (measured: 0.2-0.35% at one beat)
    bound = student_bound(FAMILY_FALSE_FAILURE, COMPARISONS, len(values) - 1)
    assert abs(values.mean() - exact) < bound * se, (values.mean(), exact, se, bound)


@pytest.mark.parametrize("method", ["antithetic", "antithetic_mirror"])
@pytest.mark.parametrize("hetero_frequency,offset", [(1.0, 0.0), (0.0, 0.2)])
def test_fast_plane_matches_quadrature(method, hetero_frequency, offset):
    """A plane receding at 300 m/s: its points move across the film by up to 10% of the
    pixel during the exposure, so pairs are mapped to other film positions (Jacobian
    about 0.9) and fall back to replay near the pixel's edges."""
    v = 300.0
    exact = reference(4.0, v, hetero_frequency=hetero_frequency, hetero_offset=offset)
    values = render_seeds(plane_scene(4.0, v, spp=1 << 12), PLANE_SEEDS,
                          dict(MOTION, time_sampling_method=method,
                               hetero_frequency=hetero_frequency, hetero_offset=offset))
    assert_unbiased(values, exact)


def test_moving_camera_matches_quadrature():
    """A static plane seen by a camera (and its light) approaching at 200 m/s: static
    points move on the film, through the camera's motion."""
    exact = reference(4.0, 0.0, hetero_frequency=1.0, camera_velocity=200.0)
    values = render_seeds(plane_scene(4.0, 0.0, spp=1 << 12, camera_velocity=200.0),
                          PLANE_SEEDS, dict(MOTION, hetero_frequency=1.0))
    assert_unbiased(values, exact)


def test_agrees_with_replay_on_the_published_scene():
    """Global illumination, two bodies, tent filter: motion and replay pairs give the
    same image regions within the Student bound (module docstring) of their combined
    standard error over seeds (Welch's degrees of freedom at least 11)."""
    scene = dopplertof.load_file(PUBLISHED, {"resx": 24, "resy": 24}).with_params(
        hetero_frequency=1.0)

    def regions(mapping):
        out = []
        for seed in REGION_SEEDS:
            img = dopplertof.render(scene, spp=32, seed=seed, params=dict(
                MOTION, antithetic_mapping=mapping)).mean(axis=-1)
            out.append([img.mean(), img[12:, 12:].mean(), img[:, :12].mean()])
        out = np.array(out)
        return out.mean(axis=0), out.std(axis=0, ddof=1) / np.sqrt(len(out))

    (m1, s1), (m2, s2) = regions("motion"), regions("replay")
    combined = np.sqrt(s1**2 + s2**2)
    assert np.all(combined > 0)
    bound = student_bound(FAMILY_FALSE_FAILURE, COMPARISONS, len(REGION_SEEDS) - 1)
    assert np.all(np.abs(m1 - m2) < bound * combined), (m1, m2, combined, bound)


def test_projection_inverts_camera_rays():
    """World point of a camera ray -> film position: back where the ray started, on a
    non-square film with a crop window."""
    import mitsuba as mi

    from dopplertof.integrators.camera import PinholeProjection

    sensor = mi.load_dict({
        "type": "perspective", "fov": 35, "near_clip": 0.1,
        "to_world": mi.ScalarTransform4f().look_at(origin=[1, 2, 3], target=[0, 0.5, -1],
                                                   up=[0, 1, 0]),
        "film": {"type": "hdrfilm", "width": 64, "height": 40, "crop_offset_x": 8,
                 "crop_offset_y": 4, "crop_width": 32, "crop_height": 20}})
    projection = PinholeProjection(mi, sensor, None, 0.1)
    rng = np.random.default_rng(3)
    pos = mi.Point2f(rng.uniform(0.1, 0.9, 50), rng.uniform(0.1, 0.9, 50))
    ray, _ = sensor.sample_ray(mi.Float(0.0), 0.5, pos, mi.Point2f(0.5, 0.5))
    p = ray(mi.Float(rng.uniform(1, 10, 50)))
    back, in_front = projection.film_position([p.x, p.y, p.z], mi.Float(0.0))
    assert np.all(np.array(in_front))
    np.testing.assert_allclose(np.array(back), np.array(pos), atol=2e-5)


@pytest.mark.parametrize("params,message", [
    (dict(time_sampling_method="uniform"), "antithetic or antithetic_mirror"),
    (dict(time_sampling_method="auto"), "antithetic or antithetic_mirror"),
    (dict(antithetic_shift=0.3), "antithetic_shift 0.5"),
    (dict(path_correlation_depth=0), "path_correlation_depth >= 1"),
    (dict(time_correlate_number=4), "time_correlate_number=2"),
    (dict(antithetic_mapping="warp"), "unknown antithetic_mapping 'warp'"),
])
def test_bad_combinations_are_errors(params, message):
    scene = dopplertof.load_dict(plane_scene(4.0, 10.0, spp=64))
    with pytest.raises(ValueError, match=message):
        dopplertof.render(scene, params=dict(MOTION, **params))


def test_needs_a_pinhole_camera():
    d = plane_scene(4.0, 10.0, spp=64)
    d["sensor"]["type"] = "thinlens"
    d["sensor"]["aperture_radius"] = 0.01
    d["sensor"]["focus_distance"] = 4.0
    scene = dopplertof.load_dict(d)
    with pytest.raises(ValueError, match="pinhole perspective sensor, got ThinLensCamera"):
        dopplertof.render(scene, params=MOTION)


def test_same_seed_same_image_whatever_the_pass_size():
    scene = dopplertof.load_file(PUBLISHED, {"resx": 12, "resy": 10})
    params = dict(MOTION, hetero_frequency=1.0)
    a = dopplertof.render(scene, spp=64, seed=3, params=params)
    b = dopplertof.render(scene, spp=64, seed=3, params=params, pass_chunks=1)
    assert np.abs(a).max() > 0 and np.array_equal(a, b)
