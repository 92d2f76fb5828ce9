"""Modulation waveforms and their low-pass cross-correlations.

One definition serves the renderer (Dr.Jit arrays) and the analysis (NumPy arrays):
every function takes the array namespace ``xp`` (``numpy`` or ``drjit``) that holds
``cos``, ``floor``, ``minimum``, ``maximum`` and ``abs``.

Conventions (design.md section 1):

* illumination  g(t) = g0 + g1 * wave(omega_g t)
* sensor        s(t) = wave(omega_s t + psi)
* low-pass      s(t) g(t - tau) ~ g1 * C(theta),  theta = omega_d t + psi + omega_g L / c

``wave`` is a unit periodic waveform of period 2 pi with its peak at phase 0, and C is
the cross-correlation of the sensor and illumination waveforms averaged over one period.
"""

from __future__ import annotations

import math

import numpy as np

#: speed of light in vacuum, m/s
SPEED_OF_LIGHT = 299_792_458.0

#: waveform names as published; the index is the code the renderer uses
WAVEFORMS = ("sinusoidal", "rectangular", "triangular", "trapezoidal")

# Waveforms with a full-waveform (not only low-pass) form.
FULL_WAVEFORMS = ("sinusoidal", "rectangular", "triangular")


def waveform_index(name: str) -> int:
    """Index of a waveform name, or ValueError naming the valid ones."""
    try:
        return WAVEFORMS.index(name)
    except ValueError:
        raise ValueError(
            f"unknown wave_function_type {name!r}: expected one of {', '.join(WAVEFORMS)}"
        ) from None


def folded_phase(theta, xp=np):
    """c(theta) in [0, 1]: the phase distance to the nearest multiple of 2 pi, over pi."""
    p = theta * (1.0 / math.pi)
    p = p - 2.0 * xp.floor(p * 0.5)  # p in [0, 2)
    return xp.minimum(p, 2.0 - p)


def wave(name: str, phase, xp=np):
    """A unit periodic waveform (period 2 pi, peak +1 at phase 0; sinusoid cos)."""
    if name == "sinusoidal":
        return xp.cos(phase)
    if name == "rectangular":  # +1 on |phase| < pi/2, -1 elsewhere
        return xp.sign(xp.cos(phase))
    if name == "triangular":  # linear from +1 at 0 to -1 at pi
        return 1.0 - 2.0 * folded_phase(phase, xp)
    if name == "trapezoidal":
        raise ValueError(
            "wave_function_type 'trapezoidal' pairs a trapezoid sensor with a delta "
            "illumination and has no full-waveform form; use low_frequency_component_only=true"
        )
    waveform_index(name)  # raises with the list of valid names
    raise AssertionError("unreachable")


def correlation(name: str, theta, xp=np):
    """Low-pass cross-correlation C(theta) of the sensor and illumination waveforms.

    C(theta) = (1 / 2 pi) * integral over one period of  wave(x + theta) * wave(x) dx
    (for the trapezoidal pair: a trapezoid sensor against a delta illumination).
    """
    if name == "sinusoidal":
        return 0.5 * xp.cos(theta)
    c = folded_phase(theta, xp)
    if name == "rectangular":
        return 1.0 - 2.0 * c
    if name == "triangular":
        return 1.0 / 3.0 - 2.0 * c * c + (4.0 / 3.0) * c * c * c
    if name == "trapezoidal":
        return xp.minimum(xp.maximum(2.0 - 4.0 * c, -1.0), 1.0)
    waveform_index(name)
    raise AssertionError("unreachable")


def correlation_by_index(index, theta, xp):
    """C(theta) for a waveform given by an index that may be an opaque JIT variable.

    The renderer uses this so that one compiled kernel serves every waveform: all
    four closed forms are cheap, and the index selects one per lane.
    """
    result = correlation(WAVEFORMS[0], theta, xp)
    for i, name in enumerate(WAVEFORMS[1:], start=1):
        result = xp.select(index == i, correlation(name, theta, xp), result)
    return result
