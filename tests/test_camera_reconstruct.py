"""Velocity and depth reconstruction formulas (NumPy only): signs, exactness, calibration."""

import math

import numpy as np
import pytest

from dopplertof.tof import reconstruct as rec
from dopplertof.modulation import SPEED_OF_LIGHT, WAVEFORMS, correlation

OMEGA_G = 2 * math.pi * 30e6
EXPOSURE = 0.0015


def model(waveform="sinusoidal", h=1.0, omega_g=OMEGA_G):
    return rec.CaptureModel(omega_g, EXPOSURE, h, waveform)


def brute_force_capture(waveform, distance_mid, velocity, offset, h, n=200_000):
    """Low-pass capture of one path by plain midpoint quadrature of the definition:
    (1/T) * integral of C(omega_d t + psi + omega_g L(t) / c), L = 2 d(t)."""
    t = (np.arange(n) + 0.5) / n * EXPOSURE
    distance = distance_mid + velocity * (t - EXPOSURE / 2)
    theta = (2 * math.pi * h / EXPOSURE) * t + 2 * math.pi * offset \
        + OMEGA_G * 2 * distance / SPEED_OF_LIGHT
    return float(np.mean(correlation(waveform, theta)))


@pytest.mark.parametrize("waveform", WAVEFORMS)
def test_mean_correlation_matches_brute_force(waveform):
    m = model(waveform)
    for distance, velocity, offset, het in [(3.1, 25.0, 0.0, False), (1.7, -40.0, 0.25, True),
                                            (4.4, 7.0, 0.6, True)]:
        phase_mid = OMEGA_G * 2 * distance / SPEED_OF_LIGHT
        got = rec.model_captures(m, phase_mid, velocity, offset, het)
        want = brute_force_capture(waveform, distance, velocity, offset, 1.0 if het else 0.0)
        assert got == pytest.approx(want, abs=2e-7)


@pytest.mark.parametrize("waveform", WAVEFORMS)
@pytest.mark.parametrize("h", [1.0, 2.0, -1.0])
def test_ratio_is_the_same_closed_form_for_every_waveform_and_depth(waveform, h):
    """The calibration curve computed from the correlation equals
    Delta_omega / (omega_d + Delta_omega) at every phase (integer h, zero-mean C)."""
    m = model(waveform, h)
    phase = np.linspace(0, 2 * math.pi, 41)[:, None]
    velocity = np.array([-300.0, -60.0, -5.0, 0.0, 5.0, 60.0, 300.0])[None, :]
    curve = rec.model_ratio(m, phase, velocity)
    assert np.allclose(curve, rec.ratio_from_velocity(velocity, m), rtol=0, atol=1e-12)
    assert np.allclose(rec.velocity_from_ratio(curve, m), velocity, rtol=1e-9, atol=1e-9)


def test_sign_receding_gives_positive_ratio_and_velocity():
    m = model()
    for velocity in (3.0, 50.0):
        for phase in np.linspace(0.1, 6.0, 7):
            H = [rec.model_captures(m, phase, velocity, o, False) for o in (0, 0.25)]
            E = [rec.model_captures(m, phase, velocity, o, True) for o in (0, 0.25)]
            r, _ = rec.combined_ratio(H, E)
            assert r > 0  # heterodyne and homodyne agree in sign when the distance grows
            assert rec.velocity_from_ratio(r, m) == pytest.approx(velocity, rel=1e-9)
            H2 = [rec.model_captures(m, phase, -velocity, o, False) for o in (0, 0.25)]
            E2 = [rec.model_captures(m, phase, -velocity, o, True) for o in (0, 0.25)]
            assert rec.combined_ratio(H2, E2)[0] < 0


def test_velocity_scale():
    # Delta_omega = omega_g L' / c with L' = 2 v: v = c Delta_omega / (2 omega_g)
    m = model()
    assert m.velocity_per_delta_omega() == pytest.approx(SPEED_OF_LIGHT / (2 * OMEGA_G))
    assert m.omega_d == pytest.approx(2 * math.pi / EXPOSURE)
    # one beat period per exposure, 30 MHz, 1.5 ms: r ~ 2 f_g v T / c = 3.0e-4 per m/s
    assert rec.ratio_from_velocity(1.0, m) == pytest.approx(2 * 30e6 * EXPOSURE / SPEED_OF_LIGHT,
                                                            rel=1e-3)


@pytest.mark.parametrize("waveform", WAVEFORMS)
def test_four_phase_depth_sign_and_calibration(waveform):
    m = model(waveform)
    distance = np.linspace(0.05, 4.9, 50)
    phase = 2 * OMEGA_G * distance / SPEED_OF_LIGHT
    homodyne = {o: correlation(waveform, phase + 2 * math.pi * o) for o in rec.DEPTH_OFFSETS}
    depth, recovered, _, reasons = rec.homodyne_depth(homodyne, m)
    assert np.all(reasons == rec.VALID)
    assert np.allclose(depth, distance, atol=1e-6)
    if waveform == "sinusoidal":  # the textbook formula, no calibration
        raw, amplitude = rec.four_phase_raw(*(homodyne[o] for o in rec.DEPTH_OFFSETS))
        assert np.allclose(raw, phase, atol=1e-12)
        assert np.allclose(amplitude, 0.5)
        # swapping the differences' signs (a wrong convention) would not recover it
        wrong = np.mod(np.arctan2(homodyne[0.25] - homodyne[0.75], homodyne[0] - homodyne[0.5]),
                       2 * math.pi)
        assert not np.allclose(wrong, phase, atol=1e-3)
    else:  # the raw atan2 is distorted by the harmonics
        raw, _ = rec.four_phase_raw(*(homodyne[o] for o in rec.DEPTH_OFFSETS))
        assert np.max(np.abs(raw - phase)) > 1e-3


def test_wrap_distance():
    assert model().wrap_distance == pytest.approx(SPEED_OF_LIGHT / (2 * 30e6))
    assert model().wrap_distance == pytest.approx(4.9965, abs=1e-4)


def test_two_frequency_unwrapping():
    rng = np.random.default_rng(1)
    f1, f2 = 30e6, 25e6
    assert rec.unambiguous_range(f1, f2) == pytest.approx(SPEED_OF_LIGHT / (2 * 5e6))
    truth = rng.uniform(0.0, 29.0, 2000)
    # noise 1 cm: the unwrapped depth's error (the frequency-squared weighted mean of
    # both) has a standard deviation of 0.72 cm, so 5 cm is 6.9 of them for the largest
    # of 2000 (1e-8), and over 300 other seeds it is 2.6 cm in the median, at most 3.6 cm
    d1 = np.mod(truth, rec.wrap_distance(f1)) + rng.normal(0, 0.01, truth.shape)
    d2 = np.mod(truth, rec.wrap_distance(f2)) + rng.normal(0, 0.01, truth.shape)
    unwrapped = rec.unwrap_two_frequencies(d1, f1, d2, f2)
    assert np.max(np.abs(unwrapped - truth)) < 0.05
    with pytest.raises(rec.ReconstructionError, match="must differ"):
        rec.unwrap_two_frequencies(d1, f1, d2, f1)


def test_non_integer_hetero_frequency_is_refused():
    with pytest.raises(rec.ReconstructionError, match="integer hetero_frequency"):
        model(h=0.5)
    with pytest.raises(rec.ReconstructionError, match="non-zero"):
        model(h=0.0)
    with pytest.raises(rec.ReconstructionError, match="unknown waveform"):
        model("saw")


def test_weak_signal_is_nan_with_reason():
    m = model()
    zero = np.zeros((3, 4))
    bright = np.ones((3, 4)) * 0.3
    bright[0, 0] = 0.0
    homodyne = {0.0: bright, 0.25: zero}
    heterodyne = {0.0: bright * 1e-3, 0.25: zero}
    v, reasons = rec.reconstruct_velocity(homodyne, heterodyne, m)
    assert np.isnan(v[0, 0]) and reasons[0, 0] == rec.WEAK_SIGNAL
    assert np.all(np.isfinite(v.ravel()[1:])) and np.all(reasons.ravel()[1:] == rec.VALID)
    with pytest.raises(rec.ReconstructionError, match="offsets 0.25"):
        rec.reconstruct_velocity({0.0: bright}, heterodyne, m)


def test_least_squares_cancels_linear_brightness_change_for_sinusoids():
    """A brightness change with no Doppler shift (v = 0, falloff q): the sinusoid's
    combined ratio has no first-order term; a square wave's has one."""
    phase = np.linspace(0.0, 2 * math.pi, 25)
    zero = np.zeros_like(phase)
    for q, expect_small in ((5.0, True), (-5.0, True)):
        r_sin = rec.single_path_ratio(model(), phase, zero, np.full_like(phase, q))
        r_rect = rec.single_path_ratio(model("rectangular"), phase, zero, np.full_like(phase, q))
        # second order only: 3 q^2 T^2 / (2 pi^2) ~ 1e-5 for the sinusoid
        assert np.max(np.abs(r_sin)) < 3 * q * q * EXPOSURE**2 / (2 * math.pi**2) * 1.2
        assert np.max(np.abs(r_rect)) > 20 * np.max(np.abs(r_sin))


def test_second_order_brightness_bias_of_the_exact_inversion():
    """Uncalibrated, an approaching/receding surface under a colocated light is biased by
    3 c T v / (4 pi^2 f_g d^2) (relative): 2.3% at 1 m and 20 m/s."""
    m = model()
    for distance, velocity in ((1.0, 20.0), (2.0, -40.0), (1.5, 60.0)):
        phase = np.linspace(0.0, 2 * math.pi, 9)
        r = rec.single_path_ratio(m, phase, np.full_like(phase, velocity),
                                  np.full_like(phase, velocity / distance))
        bias = rec.velocity_from_ratio(r, m) / velocity - 1
        predicted = 3 * SPEED_OF_LIGHT * EXPOSURE * velocity / (4 * math.pi**2 * 30e6
                                                                * distance**2)
        assert np.allclose(bias, predicted, rtol=0.1), (bias, predicted)


UNCALIBRATED_ERROR_AT_LEAST = {"rectangular": 0.03, "trapezoidal": 0.03, "triangular": 0.005}


@pytest.mark.parametrize("waveform", WAVEFORMS)
def test_inverse_square_calibration_inverts_the_single_path_model(waveform):
    m = model(waveform)
    phase = np.linspace(0.0, 2 * math.pi, 31)
    for distance in (1.5, 3.0, 4.8):
        for velocity in (-60.0, -8.0, 8.0, 60.0):
            r = rec.single_path_ratio(m, phase, np.full_like(phase, velocity),
                                      np.full_like(phase, velocity / distance))
            v = rec.velocity_inverse_square(r, phase, np.full_like(phase, distance), m)
            assert np.max(np.abs(v / velocity - 1)) < 0.004, (distance, velocity)
            if waveform in UNCALIBRATED_ERROR_AT_LEAST:
                # without it the brightness change biases the result at some depths
                exact = rec.velocity_from_ratio(r, m)
                assert np.max(np.abs(exact / velocity - 1)) > UNCALIBRATED_ERROR_AT_LEAST[waveform]


def test_unknown_calibration_is_an_error():
    with pytest.raises(rec.ReconstructionError, match="unknown velocity calibration"):
        rec.resolve_calibration("magic", "sinusoidal")
    assert rec.resolve_calibration("auto", "sinusoidal") == "none"
    assert rec.resolve_calibration("auto", "rectangular") == "inverse-square"
