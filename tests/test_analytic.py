"""Unbiasedness against exact quadrature references (tests/analytic.py).

Statistics: the one-pixel renders here are nearly deterministic (film positions and
times are low-discrepancy sets): measured over 40 other seeds, their relative standard
deviation is below 2e-6 (homodyne, 8 comparisons; rtol 2e-3), 3.3e-6 (heterodyne, 5;
rtol 1e-2) and 1.6e-6 (waveforms, 8; rtol 3e-3), so every tolerance is over 2000
standard deviations: no false failures to speak of. What they can fail on is a bias: a
relative one of the tolerance (0.2-1%). The tests with standard errors over seeds
state their own rates.
"""

import numpy as np
import pytest

import dopplertof
from analytic import homodyne_amplitude, plane_scene, reference
from bounds import mean_rounding_bound, student_bound


def render_plane(z0, v, spp=1 << 14, seeds=(0,), **integrator):
    scene = dopplertof.load_dict(plane_scene(z0, v, spp=spp, integrator=integrator))
    values = np.array([dopplertof.render(scene, seed=s)[0, 0, 0] for s in seeds])
    return values


def assert_close(values, expected, rel, abs_tol):
    """``abs_tol``: at least the rounding of a pixel's 2^14 float32 samples
    (bounds.mean_rounding_bound: 1.3e-6 at the homodyne amplitude 0.025 of these planes),
    the floor where the value nears zero."""
    got = float(np.mean(values))
    assert abs(got - expected) <= rel * abs(expected) + abs_tol, (got, expected)


@pytest.mark.parametrize("offset", [0.0, 0.25, 0.5, 0.6])
@pytest.mark.parametrize("velocity", [0.0, 40.0])
def test_homodyne_phase_sign(offset, velocity):
    # The sign of the phase: theta = psi + omega_g L / c with psi = 2 pi offset.
    expected = reference(5.0, velocity, hetero_offset=offset)
    values = render_plane(5.0, velocity, hetero_frequency=0.0, hetero_offset=offset)
    assert_close(values, expected, rel=2e-3, abs_tol=2e-6)


@pytest.mark.parametrize("velocity", [-60.0, -15.0, 0.0, 15.0, 60.0])
def test_heterodyne_doppler(velocity):
    expected = reference(4.0, velocity, hetero_frequency=1.0)
    values = render_plane(4.0, velocity, hetero_frequency=1.0)
    if velocity == 0.0:
        assert abs(expected) < 1e-12  # a full beat period integrates to zero
        # the render's value is then a float32 mean of 2^14 samples that cancel, each at
        # most the homodyne amplitude in size: within the rounding bound of that mean
        # (bounds.mean_rounding_bound), not a fixed 2e-7 (0.15 of that bound; measured
        # -2.9e-10)
        assert abs(float(np.mean(values))) <= mean_rounding_bound(
            homodyne_amplitude(4.0, 0.0), 1 << 14)
    else:
        # receding (v > 0) and approaching give opposite signs relative to homodyne
        homodyne = reference(4.0, velocity, hetero_frequency=0.0)
        assert np.sign(expected * homodyne) == np.sign(velocity)
        assert_close(values, expected, rel=1e-2,  # (the floor: the rounding of 2^14 samples)
                     abs_tol=mean_rounding_bound(homodyne_amplitude(4.0, velocity), 1 << 14))


@pytest.mark.parametrize("waveform", ["sinusoidal", "rectangular", "triangular", "trapezoidal"])
def test_waveforms_low_pass(waveform):
    for offset in (0.1, 0.35):
        expected = reference(3.0, 25.0, waveform=waveform, hetero_frequency=0.5,
                             hetero_offset=offset)
        values = render_plane(3.0, 25.0, wave_function_type=waveform, hetero_frequency=0.5,
                              hetero_offset=offset)
        assert_close(values, expected, rel=3e-3, abs_tol=3e-6)


def test_exposure_from_time_parameter_overrides_shutter():
    scene = dopplertof.load_dict(plane_scene(5.0, 30.0, exposure=0.0015, spp=1 << 12,
                                             integrator={"time": 0.001, "hetero_frequency": 1}))
    assert scene.params.modulation(scene.shutter_interval).exposure == 0.001


@pytest.mark.slow
@pytest.mark.parametrize("waveform", ["sinusoidal", "triangular"])
def test_full_waveform_matches_low_pass(waveform):
    """Full-waveform mode (float64 phases) agrees with low-pass mode and with its own
    quadrature within the Student bound (15 degrees of freedom, Bonferroni over the 2
    waveforms for a false-failure rate of 1e-4: about 5.6) of the standard error over
    16 seeds (the renders take 0.1 s; the quadrature of the full waveform 15 s).
    Measured over 20 other seeds: 10-12% relative standard deviation per render (the
    full waveform's own noise), no bias (0.3-0.4 standard errors of 6); a 20% bias fails
    it. (4 standard errors of 6 seeds, as before: 1e-2 each.)"""
    common = dict(wave_function_type=waveform, hetero_frequency=0.25, hetero_offset=0.1,
                  time_sampling_method="uniform", path_correlation_depth=0)
    full = render_plane(5.0, 40.0, spp=1 << 15, seeds=range(16),
                        low_frequency_component_only=False, **common)
    low = reference(5.0, 40.0, waveform=waveform, hetero_frequency=0.25, hetero_offset=0.1)
    exact_full = reference(5.0, 40.0, waveform=waveform, hetero_frequency=0.25,
                           hetero_offset=0.1, low_pass=False, n_space=4)
    se = full.std(ddof=1) / np.sqrt(len(full))
    assert se > 0
    assert abs(exact_full - low) < 0.02 * abs(low)  # the low-pass approximation is good
    bound = student_bound(1e-4, 2, len(full) - 1)
    assert abs(full.mean() - exact_full) < bound * se + 1e-7, (full.mean(), exact_full, se)
    # and the estimate is informative: the standard error is well below the signal
    assert se < 0.2 * abs(low)


def test_trapezoidal_full_waveform_is_an_error():
    with pytest.raises(dopplertof.SceneError, match="trapezoid"):
        dopplertof.load_dict(plane_scene(5.0, 0.0, integrator={
            "wave_function_type": "trapezoidal", "low_frequency_component_only": False}))


@pytest.mark.parametrize("camera_velocity", [0.0, 150.0])
def test_exposure_starting_later(camera_velocity):
    """An exposure that opens at 0.25 s, keyframes at 0.25 s and 0.2515 s: the same pixel as
    the same motion starting at 0 (times enter the motion absolutely, the modulation from
    the exposure start). The 1% allowance dominates: the renders' relative standard
    deviation is 2-3e-6 (measured, 30 other seeds), so 4 standard errors of 4 seeds
    (a Student tail of 3e-2 on its own) add nothing, and the 1% is over 6000 of them."""
    start = 0.25
    d = plane_scene(4.0, 40.0, spp=1 << 14, camera_velocity=camera_velocity,
                    integrator={"hetero_frequency": 1.0})
    for key in ("plane",):
        d[key]["to_world"] = dopplertof.Animation(
            [(t + start, T) for t, T in d[key]["to_world"].keyframes])
    if camera_velocity:
        d["sensor"]["to_world"] = dopplertof.Animation(
            [(t + start, T) for t, T in d["sensor"]["to_world"].keyframes])
    d["sensor"]["shutter_open"] = start
    d["sensor"]["shutter_close"] = start + 0.0015
    scene = dopplertof.load_dict(d)
    assert scene.shutter_open == start
    expected = reference(4.0, 40.0, hetero_frequency=1.0, camera_velocity=camera_velocity)
    values = np.array([dopplertof.render(scene, seed=s)[0, 0, 0] for s in range(4)])
    se = values.std(ddof=1) / np.sqrt(len(values))
    assert abs(values.mean() - expected) < 4 * se + 0.01 * abs(expected), (values, expected)
