"""Doppler shift of the geometric path against the actual photon path (supplementary Sec. 1).

A camera and a light at the same place see a surface receding at speed v (d(t) = d0 + v t).
The renderer uses the *geometric* path, built with the scene at the time of observation:
its round-trip delay is 2 d(t) / c (Eq. 1), a Doppler shift of 2 omega_g v / c (Eq. 3).  A
real photon meets the surface while it moves: delay 2 d / (c + v) (Eq. 6), shift
2 omega_g v / (c + v) (Eq. 7).  The two differ by 2 omega_g v^2 / (c (c + v)) = O(v^2/c^2)
against a shift of O(v/c): for any terrestrial speed the geometric path is exact enough.
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import brentq

from ..modulation import SPEED_OF_LIGHT


def geometric_doppler_shift(omega_g, speed):
    """Eq. (3): 2 omega_g v / c (rad/s), for a receding speed v (m/s)."""
    return 2.0 * np.asarray(omega_g) * np.asarray(speed) / SPEED_OF_LIGHT


def photon_doppler_shift(omega_g, speed):
    """Eq. (7): 2 omega_g v / (c + v) (rad/s)."""
    speed = np.asarray(speed)
    return 2.0 * np.asarray(omega_g) * speed / (SPEED_OF_LIGHT + speed)


def doppler_shift_difference(omega_g, speed):
    """Eq. (3) minus Eq. (7) in closed form, 2 omega_g v^2 / (c (c + v)), free of cancellation."""
    speed = np.asarray(speed)
    return 2.0 * np.asarray(omega_g) * speed**2 / (SPEED_OF_LIGHT * (SPEED_OF_LIGHT + speed))


def geometric_delay(t, d0, speed):
    """Eq. (1): round trip 2 d(t) / c with the surface frozen at observation time t (s)."""
    return 2.0 * (d0 + speed * t) / SPEED_OF_LIGHT


def photon_delay(t, d0, speed):
    """Round-trip time of the photon observed at time t, found by root finding.

    The photon reflects at the time t_r where light leaving the surface reaches the camera
    at t: c (t - t_r) = d0 + v t_r.  By symmetry of the two legs (Eq. 4; constancy of c)
    it left the light at t_r - (t - t_r), so the delay is 2 (t - t_r).  Solved with
    Brent's method, not with Eq. (5), so that it checks Eqs. (5)-(7).
    """
    def light_cone(t_r):
        return SPEED_OF_LIGHT * (t - t_r) - (d0 + speed * t_r)

    # the reflection lies within one camera-surface light time (< 1 s for any d0 here)
    reflection = brentq(light_cone, t - 1.0, t, xtol=1e-300, rtol=4 * np.finfo(float).eps,
                        maxiter=500)
    return 2.0 * (t - reflection)


def doppler_shift_from_delay(delay, omega_g, speed, d0=10.0, baseline=1.0):
    """omega_g * d(delay)/dt: the frequency shift of cos(omega_g (t - delay(t))).

    The delay is linear in t for constant v, so a long baseline gives the slope to
    rounding precision.  The surface must stay in front of the camera over the baseline
    (for an approaching surface, d0 > |v| * baseline).
    """
    start, end = 0.0, baseline
    if min(d0 + speed * start, d0 + speed * end) <= 0.0:
        raise ValueError("the surface reaches the camera within the baseline: "
                         "increase d0 or shorten the baseline")
    return omega_g * (delay(end, d0, speed) - delay(start, d0, speed)) / baseline
