"""Low-pass correlation of modulation waveforms (supplementary Sec. 2, Fig. 2).

The renderer uses the closed forms ``modulation.correlation``; here the same quantities are
recomputed from the raw periodic waveforms ``modulation.wave`` so that the two can be compared:

* by direct quadrature of the cross-correlation over one period,
  C(theta) = (1 / 2 pi) * integral_0^{2 pi} s(x + theta) g(x) dx;
* by the Fourier series of Eqs. (10)-(11), C(theta) = 1/2 * sum_n a_n b_n cos(n theta).

The trapezoidal pair (a trapezoid sensor against a delta illumination, the "Hamiltonian"
code of Gupta et al. 2018) has no raw illumination waveform; its correlation is the sensor
waveform itself sampled at theta.
"""

from __future__ import annotations

import math

import numpy as np

from .. import modulation
from .quadrature import panel_rule

TWO_PI = 2.0 * math.pi

#: Phases in [0, 2 pi) where a waveform or its slope is not smooth.  Quadrature splits there.
KINK_PHASES = {
    "sinusoidal": (),
    "rectangular": (0.5 * math.pi, 1.5 * math.pi),
    "triangular": (0.0, math.pi),
    "trapezoidal": (0.25 * math.pi, 0.75 * math.pi, 1.25 * math.pi, 1.75 * math.pi),
}


def trapezoid_sensor_wave(phase):
    """Trapezoid sensor waveform clamp(2 - 4 c, -1, 1), c the folded phase in [0, 1].

    +1 within a quarter period of the peak, -1 within a quarter period of the trough,
    linear in between.  Defined here independently of ``modulation.correlation``.
    """
    folded = modulation.folded_phase(np.asarray(phase, dtype=float))
    return np.clip(2.0 - 4.0 * folded, -1.0, 1.0)


def sensor_wave(name: str, phase):
    """The raw sensor waveform of a named pair (trapezoid for 'trapezoidal')."""
    if name == "trapezoidal":
        return trapezoid_sensor_wave(phase)
    return modulation.wave(name, np.asarray(phase, dtype=float))


def numeric_correlation(name: str, theta, order: int = 8):
    """C(theta) by quadrature of the raw waveforms over one period (Sec. 2).

    For the full waveforms the integrand is split at the corners of both factors, so the
    result is exact to rounding.  For 'trapezoidal' the illumination is a delta of unit
    mean, which picks the sensor value at theta.
    """
    theta = np.asarray(theta, dtype=float)
    if name == "trapezoidal":
        return trapezoid_sensor_wave(theta)
    kinks = np.asarray(KINK_PHASES[name], dtype=float)
    # corners of g(x) at the kinks, of s(x + theta) at kinks - theta; x scaled to [0, 1]
    breaks = np.concatenate([
        np.broadcast_to(kinks, theta.shape + kinks.shape),
        np.mod(kinks - theta[..., None], TWO_PI),
    ], axis=-1) / TWO_PI
    nodes, weights = panel_rule(breaks, order=order)
    x = TWO_PI * nodes
    product = modulation.wave(name, x + theta[..., None]) * modulation.wave(name, x)
    return np.sum(weights * product, axis=-1)


def pulse_correlation(theta, pulse_width: float, order: int = 8):
    """Trapezoid sensor against a box pulse of unit mean and width ``pulse_width`` (rad).

    As the pulse narrows towards a delta this tends to the trapezoid sampled at theta,
    with an error at most (slope 4/pi) * width / 8 near the corners.
    """
    theta = np.asarray(theta, dtype=float)
    kinks = np.asarray(KINK_PHASES["trapezoidal"])
    # The average of s over [theta - w/2, theta + w/2]; u in [0, 1] spans that window.
    start = theta - 0.5 * pulse_width
    breaks = np.mod(kinks - start[..., None], TWO_PI) / pulse_width
    nodes, weights = panel_rule(breaks, order=order, base_panels=1)
    return np.sum(weights * trapezoid_sensor_wave(start[..., None] + pulse_width * nodes), axis=-1)


def fourier_cosine_coefficients(name: str, harmonics: int, order: int = 8):
    """a_n, n = 1..harmonics, of wave(x) = sum_n a_n cos(n x) (Eq. 8), by quadrature."""
    n = np.arange(1, harmonics + 1, dtype=float)
    kinks = np.asarray(KINK_PHASES[name], dtype=float) / TWO_PI
    # two panels per period of the highest harmonic keep the rule accurate to ~1e-12
    nodes, weights = panel_rule(kinks, order=order, base_panels=max(16, 2 * harmonics))
    x = TWO_PI * nodes
    values = sensor_wave(name, x)
    return 2.0 * np.sum(weights * values * np.cos(n[:, None] * x), axis=-1)


def correlation_from_fourier_series(name: str, theta, harmonics: int = 256):
    """C(theta) = 1/2 * sum_n a_n b_n cos(n theta), Eqs. (10)-(11), truncated.

    Sensor and illumination share the waveform, so b_n = a_n; for 'trapezoidal' the delta
    illumination of unit mean has b_n = 2 for every n.  The truncation error falls like
    1/N for the rectangular pair (a_n ~ 1/n), much faster for the others.
    """
    theta = np.asarray(theta, dtype=float)
    a = fourier_cosine_coefficients(name, harmonics)
    b = np.full_like(a, 2.0) if name == "trapezoidal" else a
    n = np.arange(1, harmonics + 1, dtype=float)
    return 0.5 * np.sum(a * b * np.cos(theta[..., None] * n), axis=-1)
