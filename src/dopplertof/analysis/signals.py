"""Test signals x(t) on the normalized exposure [0, 1] (T = 1), batched over parameters.

A signal is called with sample times ``t`` of shape ``batch + (n,)`` and returns x(t) of the
same shape; its parameters (arrays) broadcast against ``batch``, so one call evaluates a whole
grid of frequencies, phases or random draws.  ``breakpoints()`` lists the times in [0, 1]
where x or its slope jumps, so that quadrature can split there (see ``quadrature``).

Phase convention: like the supplementary from Eq. (23) on, ``theta`` is the phase at the
middle of the exposure, x(t) = cos(omega (t - 1/2) + theta); the phase at t = 0 is
phi = theta - omega / 2.  Averages over theta in [0, 2 pi] do not depend on this choice.
"""

from __future__ import annotations

import math

import numpy as np

from .waveforms import KINK_PHASES, sensor_wave

TWO_PI = 2.0 * math.pi


def _as_arrays(*values):
    return np.broadcast_arrays(*[np.asarray(v, dtype=float) for v in values])


class Sinusoid:
    """x(t) = cos(omega (t - 1/2) + theta): the low-pass heterodyne signal of one path."""

    def __init__(self, omega, theta):
        self.omega, self.theta = _as_arrays(omega, theta)

    def __call__(self, t):
        return np.cos(self.omega[..., None] * (t - 0.5) + self.theta[..., None])

    def breakpoints(self):
        return np.zeros(self.omega.shape + (0,))


class PeriodicWaveform:
    """x(t) = W(omega (t - 1/2) + theta) for a raw waveform W of ``waveforms.sensor_wave``."""

    def __init__(self, name: str, omega, theta):
        self.name = name
        self.omega, self.theta = _as_arrays(omega, theta)
        if np.any(self.omega <= 0.0):
            raise ValueError("PeriodicWaveform needs omega > 0")

    def __call__(self, t):
        return sensor_wave(self.name, self.omega[..., None] * (t - 0.5) + self.theta[..., None])

    def breakpoints(self):
        kinks = np.asarray(KINK_PHASES[self.name], dtype=float)
        if kinks.size == 0:
            return np.zeros(self.omega.shape + (0,))
        # Times where the phase omega (t - 1/2) + theta meets a kink + 2 pi n, for the
        # n that can fall inside [0, 1]; the others clip to an end and cost nothing.
        copies = int(np.floor(np.max(self.omega) / TWO_PI)) + 2
        omega, theta = self.omega[..., None, None], self.theta[..., None, None]
        kinks = kinks[:, None]
        first = np.ceil((theta - 0.5 * omega - kinks) / TWO_PI)
        n = first + np.arange(copies)
        times = 0.5 + (kinks - theta + TWO_PI * n) / omega
        return np.clip(times, 0.0, 1.0).reshape(self.omega.shape + (-1,))


class TruncatedAttenuatedSinusoid:
    """Eq. (26): two attenuated sinusoids joined at a discontinuity t_d.

    x(t) = cos(omega t + phi_1) / (l_1 + v_1 t)^2 for t < t_d, and the same with index 2
    after; phi_1, phi_2 are phases at t = 0 as in the supplementary.  Models a path that
    changes (an occlusion edge sweeping by) and the 1/r^2 falloff of a moving surface.
    """

    def __init__(self, omega, phi1, phi2, l1, l2, v1, v2, t_d):
        (self.omega, self.phi1, self.phi2, self.l1, self.l2,
         self.v1, self.v2, self.t_d) = _as_arrays(omega, phi1, phi2, l1, l2, v1, v2, t_d)

    def __call__(self, t):
        def piece(phi, length, speed):
            return (np.cos(self.omega[..., None] * t + phi[..., None])
                    / (length[..., None] + speed[..., None] * t) ** 2)

        before = t < self.t_d[..., None]
        return np.where(before, piece(self.phi1, self.l1, self.v1),
                        piece(self.phi2, self.l2, self.v2))

    def breakpoints(self):
        return np.clip(self.t_d, 0.0, 1.0)[..., None]
