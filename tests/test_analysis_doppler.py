"""Supplementary Sec. 1: geometric path vs photon path Doppler shift."""

import math

import numpy as np
import pytest

from dopplertof.analysis import (
    doppler_shift_difference,
    doppler_shift_from_delay,
    geometric_delay,
    geometric_doppler_shift,
    photon_delay,
    photon_doppler_shift,
)
from dopplertof.modulation import SPEED_OF_LIGHT as C

OMEGA_G = 2 * math.pi * 30e6


@pytest.mark.parametrize("speed", [1e4, 1e5, 1e6, 1e7, -1e6])
def test_numerical_delays_give_eq3_and_eq7(speed):
    d0 = 10.0 if speed > 0 else 2e6  # an approaching surface must stay in front
    geometric = doppler_shift_from_delay(geometric_delay, OMEGA_G, speed, d0=d0)
    photon = doppler_shift_from_delay(photon_delay, OMEGA_G, speed, d0=d0)
    assert geometric == pytest.approx(float(geometric_doppler_shift(OMEGA_G, speed)), rel=1e-12)
    assert photon == pytest.approx(float(photon_doppler_shift(OMEGA_G, speed)), rel=1e-9)
    # the O(v^2/c^2) gap, measured from the root-found photon delay
    assert geometric - photon == pytest.approx(float(doppler_shift_difference(OMEGA_G, speed)),
                                               rel=1e-5)


def test_surface_reaching_the_camera_is_refused():
    with pytest.raises(ValueError, match="reaches the camera"):
        doppler_shift_from_delay(photon_delay, OMEGA_G, -1e6, d0=10.0)


def test_photon_delay_is_eq6():
    d0, speed, t = 7.0, 3e6, 0.25
    distance = d0 + speed * (t - photon_delay(t, d0, speed) / 2)  # surface at reflection
    # Eq. (6) with d the distance at reflection: Delta t = 2 d / c; and Eq. (5) form
    assert photon_delay(t, d0, speed) == pytest.approx(2 * distance / C, rel=1e-12)
    assert photon_delay(t, d0, speed) == pytest.approx(2 * (d0 + speed * t) / (C + speed),
                                                       rel=1e-12)


def test_difference_is_second_order_in_v_over_c():
    speeds = np.logspace(0, 4, 9)
    difference = geometric_doppler_shift(OMEGA_G, speeds) - photon_doppler_shift(OMEGA_G, speeds)
    # subtraction and the cancellation-free closed form agree
    assert np.allclose(difference, doppler_shift_difference(OMEGA_G, speeds), rtol=1e-6)
    # it is 2 omega_g (v/c)^2 (c / (c + v)): the leading O(v^2/c^2) term
    leading = 2 * OMEGA_G * (speeds / C) ** 2
    assert np.allclose(doppler_shift_difference(OMEGA_G, speeds) / leading, 1.0, atol=1e-4)
    slope_difference = np.polyfit(np.log(speeds),
                                  np.log(doppler_shift_difference(OMEGA_G, speeds)), 1)[0]
    slope_shift = np.polyfit(np.log(speeds), np.log(geometric_doppler_shift(OMEGA_G, speeds)), 1)[0]
    assert slope_difference == pytest.approx(2.0, abs=1e-4)
    assert slope_shift == pytest.approx(1.0, abs=1e-12)


def test_relative_error_negligible_for_terrestrial_speeds():
    for speed in (1.0, 30.0, 300.0):
        relative = (doppler_shift_difference(OMEGA_G, speed)
                    / geometric_doppler_shift(OMEGA_G, speed))
        assert relative == pytest.approx(speed / (C + speed), rel=1e-12)
        assert relative < 1.1e-6
