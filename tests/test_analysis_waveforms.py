"""Supplementary Sec. 2: low-pass correlations recomputed from the raw waveforms."""

import math

import numpy as np
import pytest

from dopplertof import modulation
from dopplertof.analysis import (
    correlation_from_fourier_series,
    numeric_correlation,
    pulse_correlation,
    trapezoid_sensor_wave,
)

# includes every corner of the closed forms (multiples of pi/4)
THETAS = np.linspace(-2 * math.pi, 4 * math.pi, 241)


@pytest.mark.parametrize("name", modulation.FULL_WAVEFORMS)
def test_quadrature_of_raw_waveforms_matches_closed_form(name):
    numeric = numeric_correlation(name, THETAS)
    assert np.max(np.abs(numeric - modulation.correlation(name, THETAS))) < 1e-12


@pytest.mark.parametrize("name, peak", [("sinusoidal", 0.5), ("rectangular", 1.0),
                                        ("triangular", 1.0 / 3.0)])
def test_correlation_peak_is_the_mean_square(name, peak):
    # C(0) = mean of wave^2 over a period; C(pi) = -C(0) for these half-wave symmetric waves
    assert numeric_correlation(name, np.array(0.0)) == pytest.approx(peak, abs=1e-13)
    assert numeric_correlation(name, np.array(math.pi)) == pytest.approx(-peak, abs=1e-13)


def test_fourier_series_eq10_converges_to_closed_forms():
    harmonics = 256
    errors = {name: np.max(np.abs(correlation_from_fourier_series(name, THETAS, harmonics)
                                  - modulation.correlation(name, THETAS)))
              for name in modulation.WAVEFORMS}
    assert errors["sinusoidal"] < 1e-12
    assert errors["triangular"] < 1e-7          # a_n b_n ~ 1/n^4: tail ~ 1/N^3
    # rectangular: a_n = 4/(n pi) for odd n, the tail sum_{n > N, odd} 8/(n pi)^2 ~ 4/(pi^2 N)
    assert errors["rectangular"] < 1.01 * 4.0 / (math.pi**2 * harmonics)
    # trapezoid x delta: a_n b_n ~ 1/n^2 as well, so first order in 1/N
    assert errors["trapezoidal"] < 1.01 * 4.0 / (math.pi**2 * harmonics)
    doubled = np.max(np.abs(correlation_from_fourier_series("trapezoidal", THETAS, 2 * harmonics)
                            - modulation.correlation("trapezoidal", THETAS)))
    assert 1.8 < errors["trapezoidal"] / doubled < 2.2


def test_trapezoid_sensor_wave_is_the_renderer_correlation():
    assert np.array_equal(trapezoid_sensor_wave(THETAS),
                          modulation.correlation("trapezoidal", THETAS))
    values = trapezoid_sensor_wave(np.array([0.0, 0.25, 0.5, 0.75, 1.0, 1.5]) * math.pi)
    assert np.allclose(values, [1.0, 1.0, 0.0, -1.0, -1.0, 0.0], atol=1e-15)


@pytest.mark.parametrize("width", [0.2, 0.02, 0.002])
def test_narrow_light_pulse_tends_to_the_sensor_sample(width):
    # Averaging a piecewise-linear wave of slope 4/pi over a window w errs by at most
    # (4/pi) w / 8 = w / (2 pi), reached with the window centred on a corner.
    numeric = pulse_correlation(THETAS, width)
    error = np.abs(numeric - modulation.correlation("trapezoidal", THETAS))
    assert np.max(error) <= width / (2 * math.pi) * (1 + 1e-9)
    assert np.max(error) >= 0.9 * width / (2 * math.pi)  # the corners are on the grid
