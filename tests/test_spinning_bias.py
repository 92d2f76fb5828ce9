"""The velocity bias of a spinning plane (issue 24, section 8): a plane spinning about
an axis through the image centre reads about -0.07 m/s on the axis (truth 0) for +omega
and -omega. Cause: the curvature in time of the brightness of a turning surface,
cos(theta0 + omega tau), whose tau^2 term the two-offset least squares does not cancel:
v = c (-omega^2 / 2) / (omega_d omega_g) (reconstruct.brightness_curvature_bias). The
measurement separates it from the other candidates: the axis does not move (no Doppler
of any order), the bias is even in omega (no sign or time-origin convention) and
scales with omega^2."""

import math
import os

import numpy as np
import pytest

import dopplertof
from dopplertof.modulation import correlation
from dopplertof.tof import reconstruct as rec

PLANE = os.path.join(os.path.dirname(__file__), "fixtures", "spinning_plane.xml")
MODEL = rec.CaptureModel(2 * math.pi * 30e6, 0.0015, 1.0)  # the fixture's modulation


def axis_error(omega: float) -> float:
    """Median velocity error (m/s) of the two pixel columns beside the spin axis."""
    degrees = math.degrees(omega * MODEL.exposure)
    result = dopplertof.capture(dopplertof.load_file(PLANE, {"angle": degrees}))
    error = result.velocity - result.truth.velocity
    centre = error.shape[1] // 2
    return float(np.nanmedian(error[:, centre - 1:centre + 1]))


def prediction(omega: float) -> float:
    return float(rec.brightness_curvature_bias(MODEL, -0.5 * omega**2))


def test_the_bias_is_the_brightness_curvature_of_the_turning_plane():
    assert prediction(20.0) == pytest.approx(-0.0759, abs=1e-4)
    # +-40 rad/s: 4 times the bias at 20 (omega^2), the same for both signs
    for omega in (40.0, -40.0):
        assert axis_error(omega) == pytest.approx(prediction(omega), rel=0.1)
    assert axis_error(20.0) == pytest.approx(prediction(20.0), rel=0.25)
    assert abs(axis_error(0.0)) < 0.005  # the same plane at rest


@pytest.mark.parametrize("theta0", [0.0, 0.5])
def test_the_single_path_model_gives_the_closed_form(theta0):
    # brightness cos(theta0 + omega tau) by quadrature, path length constant (the axis)
    n, T = 8192, MODEL.exposure
    tau = ((np.arange(n) + 0.5) / n - 0.5) * T
    brightness = np.cos(theta0 + 40.0 * tau)
    for phase in (0.3, 1.7):
        H = [np.mean(brightness * correlation("sinusoidal", phase + 2 * math.pi * o))
             for o in rec.VELOCITY_OFFSETS]
        E = [np.mean(brightness * correlation("sinusoidal", phase + 2 * math.pi * o
                                              + MODEL.omega_d * (tau + 0.5 * T)))
             for o in rec.VELOCITY_OFFSETS]
        velocity = rec.velocity_from_ratio(rec.combined_ratio(H, E)[0], MODEL)
        # the linear term (theta0 != 0: -omega tan(theta0) tau) cancels; the tau^2 term stays
        assert velocity == pytest.approx(prediction(40.0), rel=1e-6)
