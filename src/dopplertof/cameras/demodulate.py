"""The camera's own depth reconstruction: N-phase arctangent per frequency, wiggling.

Raw frames k of one modulation frequency, at sensor phase steps psi_k, measure (as the
renderer's homodyne captures do, docs/camera.md) x_k = B + A cos(phi + psi_k) for a
sinusoidal correlation, phi = 4 pi f d / c. Writing x_k = B + a cos psi_k + b sin psi_k
(a = A cos phi, b = -A sin phi), the least-squares fit over the frames gives (B, a, b)
for any three or more distinct phase steps (for equally spaced ones it is the N-phase
DFT), so

    phi = atan2(-b, a),   amplitude A = hypot(a, b),   d = c phi / (4 pi f).

Wiggling. With a non-sinusoidal correlation C (modulation.correlation) the frames are
x_k = B + A' C(phi + psi_k): the fit's phase phi_hat(phi) differs from phi by a periodic
error, so depth error depends on distance. :func:`phase_table` computes phi_hat over one
period from the correlation (noise-free, analytic) for the frequency's own phase steps;
:func:`calibrate` inverts it (the calibration table a camera ships), and
:func:`wiggling_error` gives the depth error against distance without it.
"""

from __future__ import annotations

import functools
import math

import numpy as np

from ..modulation import SPEED_OF_LIGHT, correlation
from ..tof.reconstruct import ReconstructionError


def fit_matrix(phase_steps_rad) -> np.ndarray:
    """(3, K) matrix M with (B, a, b) = M x for raw frames x at ``phase_steps_rad``."""
    psi = np.asarray(phase_steps_rad, np.float64)
    design = np.stack([np.ones_like(psi), np.cos(psi), np.sin(psi)], axis=1)
    if np.linalg.matrix_rank(design) < 3:
        raise ReconstructionError("the N-phase fit needs at least 3 distinct phase steps")
    return np.linalg.pinv(design)


def n_phase(frames, phase_steps_rad):
    """(phase in [0, 2 pi), amplitude, offset B) of raw frames (K, H, W) at their steps."""
    m = fit_matrix(phase_steps_rad)
    x = np.asarray(frames, np.float64)
    offset, a, b = (np.tensordot(m[i], x, axes=(0, 0)) for i in range(3))
    return np.mod(np.arctan2(-b, a), 2 * math.pi), np.hypot(a, b), offset


def phase_jacobian(frames, phase_steps_rad) -> np.ndarray:
    """(K, H, W): d phase / d x_k of :func:`n_phase` (for first-order noise)."""
    m = fit_matrix(phase_steps_rad)
    x = np.asarray(frames, np.float64)
    a = np.tensordot(m[1], x, axes=(0, 0))
    b = np.tensordot(m[2], x, axes=(0, 0))
    norm = a * a + b * b
    # phi = atan2(-b, a): d phi = (b da - a db) / (a^2 + b^2); inf without a signal
    with np.errstate(divide="ignore", invalid="ignore"):
        return (b[None] * m[1][:, None, None] - a[None] * m[2][:, None, None]) / norm[None]


def depth_from_phase(phase, frequency_hz: float) -> np.ndarray:
    """d = c phi / (4 pi f), in [0, c / (2 f)) (m)."""
    return SPEED_OF_LIGHT * np.asarray(phase, np.float64) / (4 * math.pi * frequency_hz)


@functools.lru_cache(maxsize=None)
def phase_table(waveform: str, phase_steps_deg: tuple, points: int = 4096):
    """(true phase over one period, the N-phase fit's phase of noise-free frames
    unwrapped and less its value at true phase 0, that value): the wiggling of this
    waveform and these phase steps."""
    true = np.linspace(0.0, 2 * math.pi, points + 1)
    steps = np.radians(np.asarray(phase_steps_deg, np.float64))
    frames = np.stack([correlation(waveform, true + s) for s in steps])
    measured, _, _ = n_phase(frames, steps)
    measured = np.unwrap(measured)
    return true, measured - measured[0], float(measured[0])


def calibrate(phase, waveform: str, phase_steps_deg: tuple) -> np.ndarray:
    """True phase in [0, 2 pi) from the fit's phase: the inverse of :func:`phase_table`."""
    phase = np.asarray(phase, np.float64)
    true, measured, start = phase_table(waveform, tuple(phase_steps_deg))
    if not (np.all(np.diff(measured) > 0) and abs(measured[-1] - 2 * math.pi) < 1e-6):
        raise ReconstructionError(f"the {len(phase_steps_deg)}-phase depth of waveform "
                                  f"{waveform!r} is not invertible: no calibration table")
    shifted = np.mod(phase - start, 2 * math.pi)
    return np.mod(np.interp(shifted, measured, true), 2 * math.pi)


def calibration_slope(phase, waveform: str, phase_steps_deg: tuple) -> np.ndarray:
    """d true phase / d fit phase of :func:`calibrate` at ``phase`` (the fit's phase)."""
    true, measured, start = phase_table(waveform, tuple(phase_steps_deg))
    slope = np.gradient(true, measured)
    return np.interp(np.mod(np.asarray(phase, np.float64) - start, 2 * math.pi), measured, slope)


def wiggling_error(waveform: str, phase_steps_deg, frequency_hz: float, distances,
                   calibrated: bool = False) -> np.ndarray:
    """Noise-free depth error (m) at ``distances`` (m) of one frequency's N-phase depth,
    wrapped to [-R/2, R/2) with R = c / (2 f); ``calibrated``: after the table."""
    steps = np.radians(np.asarray(phase_steps_deg, np.float64))
    d = np.asarray(distances, np.float64)
    true = 4 * math.pi * frequency_hz * d / SPEED_OF_LIGHT
    frames = np.stack([correlation(waveform, true + s) for s in steps])
    phase, _, _ = n_phase(frames, steps)
    if calibrated:
        phase = calibrate(phase, waveform, tuple(phase_steps_deg))
    wrap = SPEED_OF_LIGHT / (2 * frequency_hz)
    error = depth_from_phase(phase, frequency_hz) - np.mod(d, wrap)
    return np.mod(error + 0.5 * wrap, wrap) - 0.5 * wrap


def wiggling_curves(preset, points: int = 1000):
    """Noise-free depth error against distance over the preset's range, analytic:
    (distances, {MHz: error of that frequency's wrapped depth without calibration},
    error of the depth the camera reports without calibration, and with its own
    (calibrated when the preset applies the table)). The reported depth is the
    f^2-weighted mean of the frequencies' depths, unwrapped right."""
    distances = np.linspace(0.0, preset.reconstruction["max_range_m"], points, endpoint=False)
    per_frequency, calibrated = {}, {}
    for f in preset.frequencies_mhz:
        steps = tuple(fr.phase_deg for fr in preset.frames if fr.homodyne and fr.frequency_mhz == f)
        per_frequency[f] = wiggling_error(preset.waveform, steps, f * 1e6, distances)
        calibrated[f] = (wiggling_error(preset.waveform, steps, f * 1e6, distances, True)
                         if preset.reconstruction["wiggling_calibration"] else per_frequency[f])
    weights = {f: f**2 / sum(g**2 for g in per_frequency) for f in per_frequency}
    raw = sum(weights[f] * per_frequency[f] for f in per_frequency)
    reported = sum(weights[f] * calibrated[f] for f in per_frequency)
    return distances, per_frequency, raw, reported


def calibration_tables(preset, points: int = 256) -> dict:
    """The calibration table a camera ships, per frequency: the N-phase fit's phase
    (rad) and the true phase it maps to, over one period (what :func:`calibrate` applies)."""
    tables = {}
    for f in preset.frequencies_mhz:
        steps = tuple(fr.phase_deg for fr in preset.frames if fr.homodyne and fr.frequency_mhz == f)
        true, measured, start = phase_table(preset.waveform, steps)
        pick = np.linspace(0, len(true) - 1, points + 1).astype(int)
        tables[f"{f:g}"] = {"phase_steps_deg": list(steps),
                            "measured_phase_rad": (np.mod(measured[pick] + start, 2 * math.pi)).tolist(),
                            "true_phase_rad": true[pick].tolist()}
    return tables
