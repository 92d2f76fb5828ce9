"""What a D-ToF camera reports: radial velocity and depth from its captures.

Pure NumPy: every function takes scalar sensor images (H, W) and the modulation, and
knows nothing of the renderer. Conventions are those of :mod:`dopplertof.modulation`
(design.md sections 1 and 4); ``docs/camera.md`` derives every formula below.

A capture at sensor offset o (psi = 2 pi o) of a single path whose length grows
linearly, L(t) = L0 + L' t, measures the low-pass value

    I(o) = g1 rho (1/T) integral_0^T C(a + Omega t) dt,   a = 2 pi o + omega_g L0 / c,
    Omega = omega_d + Delta_omega,   Delta_omega = omega_g L' / c.

With P an antiderivative of C this is g1 rho [P(a + Omega T) - P(a)] / (Omega T).

Velocity. Every correlation C of :mod:`dopplertof.modulation` is 2 pi periodic with
zero mean, so P(x + 2 pi h) = P(x) for an integer number h of beat periods per
exposure, and the heterodyne (omega_d T = 2 pi h) and homodyne (omega_d = 0)
captures at the same offset share the numerator:

    E / H = Delta_omega T / (omega_d T + Delta_omega T) = Delta_omega / (omega_d + Delta_omega)

for every phase a and every waveform. Hence Delta_omega = omega_d r / (1 - r),
L' = c Delta_omega / omega_g, and the radial velocity is v = L' / 2 (a colocated
camera and light: the path goes there and back). v > 0: the distance grows.

The velocity-to-ratio curve of any waveform, computed from its correlation by
:func:`model_ratio`, therefore equals this closed form at every depth (the tests check
it). A non-integer h would make the ratio depend on depth through the static term
P(a + 2 pi h) - P(a), with a slope in phase some 10^3 times its slope in velocity
(1 m/s ~ 0.1 mm of depth): such captures are refused rather than inverted.

Offsets 0 and 1/4 are combined by least squares (:func:`combined_ratio`), which
cancels the first-order effect of a brightness change during the exposure for
sinusoids. What depends on depth is that brightness effect: for non-sinusoidal
waveforms it stays first order. :func:`velocity_inverse_square` calibrates it for a
surface under a colocated point light, brightness (d_mid / d(t))^2, with a model
computed from :func:`dopplertof.modulation.correlation` (:func:`single_path_ratio`).

Depth. The four homodyne captures at o = 0, 1/4, 1/2, 3/4 of a static path give,
for the sinusoid C = cos / 2, H(o) = A cos(phi + 2 pi o) with phi = omega_g L / c:
H(0) - H(1/2) = 2 A cos phi and H(3/4) - H(1/4) = 2 A sin phi, so

    phi = atan2(H(3/4) - H(1/4), H(0) - H(1/2)),   depth = L / 2 = c phi / (2 omega_g),

which wraps at c / (2 f_g). For a path moving during the exposure this is the phase
at mid-exposure. Other waveforms give a distorted atan2 that is calibrated with the
same correlation (:func:`phase_calibration`).
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np

from ..modulation import SPEED_OF_LIGHT, WAVEFORMS, correlation

#: sensor offsets (in periods) of the homodyne captures used for depth
DEPTH_OFFSETS = (0.0, 0.25, 0.5, 0.75)

#: sensor offsets shared by the homodyne and heterodyne captures used for velocity
VELOCITY_OFFSETS = (0.0, 0.25)

#: default fraction of the image's 99th percentile under which a signal is "too weak"
DEFAULT_MIN_SIGNAL_FRACTION = 0.01

#: why a velocity or depth pixel is NaN (code -> explanation), 0 = valid
INVALID_REASONS = {
    1: "homodyne signal too weak (below min_signal_fraction of the image's 99th "
       "percentile): nothing seen, or too little light to divide by",
    2: "heterodyne/homodyne ratio outside the range the model can invert",
    3: "a tap saturated (full well or ADC maximum)",
    4: "predicted standard deviation above the trust limit (max_velocity_std or "
       "max_depth_std)",
    5: "footprint mixes surfaces (during the exposure the filter footprint sees two "
       "bodies, a body and the static scene or the background, or an occluding edge: a "
       "silhouette pixel, whose captures mix two surfaces' phases and brightness); from "
       "the scene's geometry (ground_truth.mixed_footprints), kept with keep_mixed_pixels",
}
VALID, WEAK_SIGNAL, OUT_OF_RANGE, SATURATED, TOO_UNCERTAIN, MIXED_FOOTPRINT = 0, 1, 2, 3, 4, 5


def reason_name(code: int) -> str:
    """The short name of a reason code (its explanation up to the first parenthesis or
    colon): summary.json's keys and the previews' captions."""
    return INVALID_REASONS[code].split(" (")[0].split(":")[0]


def reason_counts(reasons) -> dict:
    """{short name: pixels} of every reason code present in ``reasons`` (valid left out)."""
    counts = {}
    for code in INVALID_REASONS:
        n = int(np.sum(np.asarray(reasons) == code))
        if n:
            counts[reason_name(code)] = n
    return counts


class ReconstructionError(ValueError):
    """Captures or settings from which nothing can be reconstructed."""


@dataclass(frozen=True)
class CaptureModel:
    """The modulation of a set of captures, in SI units (what reconstruction needs)."""

    omega_g: float  #: illumination angular frequency (rad/s)
    exposure: float  #: T (s)
    hetero_frequency: float  #: h: beat periods per exposure of the heterodyne captures
    waveform: str = "sinusoidal"

    def __post_init__(self):
        if self.waveform not in WAVEFORMS:
            raise ReconstructionError(f"unknown waveform {self.waveform!r}: expected one of "
                                      f"{', '.join(WAVEFORMS)}")
        if not (self.omega_g > 0 and math.isfinite(self.omega_g)):
            raise ReconstructionError(f"omega_g must be > 0, got {self.omega_g}")
        if not (self.exposure > 0 and math.isfinite(self.exposure)):
            raise ReconstructionError(f"exposure must be > 0 s, got {self.exposure}")
        h = self.hetero_frequency
        needs = ("velocity needs heterodyne captures with a non-zero integer hetero_frequency "
                 f"(beat periods per exposure, e.g. 1 or 2), got {h:g}")
        if h == 0:
            raise ReconstructionError(
                f"{needs}: 0 is homodyne (sensor and light at one frequency), which carries "
                "no velocity; the capture renders the homodyne images itself")
        if not math.isfinite(h) or abs(h - round(h)) > 1e-9:
            raise ReconstructionError(
                f"{needs}: with a fraction of a period the heterodyne/homodyne ratio depends "
                "on depth")
        if abs(_antiderivative_table(self.waveform)[2]) > 1e-9:
            raise ReconstructionError(f"the correlation of waveform {self.waveform!r} has a "
                                      "non-zero mean: the ratio inversion does not hold")

    @classmethod
    def of(cls, modulation, hetero_frequency: float) -> "CaptureModel":
        """The captures of a render's modulation (``params.Modulation``: the one
        description of the renderer's modulation) with heterodyne captures at
        ``hetero_frequency`` beat periods per exposure."""
        return cls(modulation.omega_g, modulation.exposure, hetero_frequency,
                   modulation.waveform)

    @property
    def omega_d(self) -> float:
        """omega_s - omega_g of the heterodyne captures (rad/s)."""
        return 2 * math.pi * self.hetero_frequency / self.exposure

    @property
    def frequency_hz(self) -> float:
        return self.omega_g / (2 * math.pi)

    @property
    def wrap_distance(self) -> float:
        """Depth at which the homodyne phase wraps: c / (2 f_g) (m)."""
        return wrap_distance(self.frequency_hz)

    def velocity_per_delta_omega(self) -> float:
        """v / Delta_omega = c / (2 omega_g) (m/s per rad/s)."""
        return SPEED_OF_LIGHT / (2 * self.omega_g)


def wrap_distance(frequency_hz: float) -> float:
    """c / (2 f): the depth at which a homodyne phase of frequency f wraps (m)."""
    return SPEED_OF_LIGHT / (2 * frequency_hz)


# ---- Waveform integrals --------------------------------------------------------

_ANTIDERIVATIVE_POINTS = 1 << 16


@functools.lru_cache(maxsize=None)
def _antiderivative_table(waveform: str):
    """(theta grid on [0, 2 pi], periodic part of P, mean of C) for P' = C."""
    theta = np.linspace(0.0, 2 * math.pi, _ANTIDERIVATIVE_POINTS + 1)
    values = correlation(waveform, theta)
    steps = 0.5 * (values[1:] + values[:-1]) * np.diff(theta)
    P = np.concatenate([[0.0], np.cumsum(steps)])
    mean = P[-1] / (2 * math.pi)
    return theta, P - mean * theta, mean


def antiderivative(waveform: str, theta) -> np.ndarray:
    """P(theta) with P' = C (the waveform's correlation) and P(0) = 0."""
    grid, periodic, mean = _antiderivative_table(waveform)
    theta = np.asarray(theta, dtype=np.float64)
    return np.interp(np.mod(theta, 2 * math.pi), grid, periodic) + mean * theta


def mean_correlation(waveform: str, start, sweep) -> np.ndarray:
    """(1 / sweep) * integral of C over [start, start + sweep]: a capture whose phase
    moves linearly by ``sweep`` radians during the exposure, per unit g1 rho."""
    start = np.asarray(start, dtype=np.float64)
    sweep = np.asarray(sweep, dtype=np.float64)
    small = np.abs(sweep) < 1e-6
    safe = np.where(small, 1.0, sweep)
    integral = (antiderivative(waveform, start + safe) - antiderivative(waveform, start)) / safe
    return np.where(small, correlation(waveform, start + 0.5 * sweep), integral)


# ---- Depth ------------------------------------------------------------------------

def four_phase_raw(h0, h25, h50, h75):
    """atan2 phase in [0, 2 pi) and amplitude of four homodyne captures (offsets
    0, 1/4, 1/2, 3/4). The amplitude is hypot of the two differences over 2 (the
    amplitude A of H(o) = A cos(phi + 2 pi o) for a sinusoid)."""
    x = np.asarray(h0, np.float64) - np.asarray(h50, np.float64)
    y = np.asarray(h75, np.float64) - np.asarray(h25, np.float64)
    return np.mod(np.arctan2(y, x), 2 * math.pi), 0.5 * np.hypot(x, y)


@functools.lru_cache(maxsize=None)
def phase_calibration(waveform: str, points: int = 4096):
    """(true phase grid, measured atan2 phase) over one period, measured unwrapped.

    The measured phase of a waveform whose correlation is not a sinusoid differs from
    the true phase (a periodic "wiggle"); the table maps one to the other. Raises if
    the map is not strictly increasing (the waveform could not tell depths apart).
    """
    true = np.linspace(0.0, 2 * math.pi, points + 1)
    h = [correlation(waveform, true + 2 * math.pi * o) for o in DEPTH_OFFSETS]
    measured = np.unwrap(np.arctan2(h[3] - h[1], h[0] - h[2]))
    measured -= measured[0]
    if not np.all(np.diff(measured) > 0) or abs(measured[-1] - 2 * math.pi) > 1e-6:
        raise ReconstructionError(
            f"the four-phase depth of waveform {waveform!r} is not invertible")
    return true, measured


def calibrate_phase(raw_phase, waveform: str) -> np.ndarray:
    """True phase in [0, 2 pi) from the atan2 phase of :func:`four_phase_raw`."""
    raw_phase = np.asarray(raw_phase, np.float64)
    if waveform == "sinusoidal":
        return raw_phase
    true, measured = phase_calibration(waveform)
    return np.mod(np.interp(np.mod(raw_phase, 2 * math.pi), measured, true), 2 * math.pi)


def depth_from_phase(phase, omega_g: float) -> np.ndarray:
    """Depth (m) of a colocated camera and light: L / 2 = c phi / (2 omega_g)."""
    return SPEED_OF_LIGHT * np.asarray(phase, np.float64) / (2 * omega_g)


def phase_from_depth(depth, omega_g: float) -> np.ndarray:
    return np.mod(2 * omega_g * np.asarray(depth, np.float64) / SPEED_OF_LIGHT, 2 * math.pi)


def homodyne_depth(homodyne: dict, model: CaptureModel, min_signal_fraction=None):
    """Depth (m, wrapped to [0, c / (2 f_g))), phase (rad), amplitude and reason codes.

    ``homodyne`` maps the offsets 0, 0.25, 0.5, 0.75 to images.
    """
    missing = [o for o in DEPTH_OFFSETS if o not in homodyne]
    if missing:
        raise ReconstructionError(f"depth needs homodyne captures at offsets "
                                  f"{', '.join(f'{o:g}' for o in missing)}")
    raw, amplitude = four_phase_raw(*(homodyne[o] for o in DEPTH_OFFSETS))
    phase = calibrate_phase(raw, model.waveform)
    depth = depth_from_phase(phase, model.omega_g)
    reasons = np.where(_weak(amplitude, min_signal_fraction), WEAK_SIGNAL, VALID)
    depth = np.where(reasons == VALID, depth, np.nan)
    return depth, phase, amplitude, reasons


def unambiguous_range(f1_hz: float, f2_hz: float, max_wraps: int = 64) -> float:
    """Depth range over which two frequencies tell depths apart: c / (2 gcd(f1, f2)),
    capped at ``max_wraps`` wraps of the first frequency (m)."""
    g = math.gcd(int(round(f1_hz)), int(round(f2_hz)))
    if g == 0:
        raise ReconstructionError("frequencies must be at least 1 Hz to unwrap")
    return min(wrap_distance(g), max_wraps * wrap_distance(f1_hz))


def unwrap_two_frequencies(depth1, f1_hz: float, depth2, f2_hz: float,
                           max_range: float | None = None) -> np.ndarray:
    """Unwrapped depth from two wrapped depths (metres, each in [0, c/(2f)) ).

    Tries every wrap count n of the first frequency within the unambiguous range and
    keeps the candidate depth1 + n R1 closest to some depth2 + k R2; the result is the
    frequency-squared weighted mean of the two matched depths (the higher frequency
    is the more precise one).
    """
    if abs(f1_hz - f2_hz) < 1.0:
        raise ReconstructionError("the unwrap frequency must differ from the modulation "
                                  f"frequency (both {f1_hz / 1e6:g} MHz)")
    r1, r2 = wrap_distance(f1_hz), wrap_distance(f2_hz)
    limit = unambiguous_range(f1_hz, f2_hz) if max_range is None else max_range
    n_wraps = max(1, int(math.ceil(limit / r1 - 1e-9)))
    d1 = np.asarray(depth1, np.float64)
    d2 = np.asarray(depth2, np.float64)
    best = np.full(d1.shape, np.inf)
    chosen1 = np.full(d1.shape, np.nan)
    chosen2 = np.full(d1.shape, np.nan)
    for n in range(n_wraps):
        cand1 = d1 + n * r1
        cand2 = d2 + np.round((cand1 - d2) / r2) * r2
        residual = np.abs(cand1 - cand2)
        better = residual < best
        best = np.where(better, residual, best)
        chosen1 = np.where(better, cand1, chosen1)
        chosen2 = np.where(better, cand2, chosen2)
    w1, w2 = f1_hz**2, f2_hz**2
    return (w1 * chosen1 + w2 * chosen2) / (w1 + w2)


# ---- Velocity ---------------------------------------------------------------------

def combined_ratio(homodyne: list, heterodyne: list):
    """r = sum_i H_i E_i / sum_i H_i^2: the least-squares fit of E = r H over the
    offsets, i.e. the per-offset ratios E_i / H_i weighted by H_i^2; and the weight
    sqrt(sum_i H_i^2), the homodyne amplitude.

    For offsets 0 and 1/4 and a sinusoid this also cancels the heterodyne response
    to a change of brightness during the exposure (a surface that approaches gets
    brighter): that term is in quadrature, E_i ~ sin(a_i) where H_i ~ cos(a_i), and
    cos(a) sin(a) + cos(a + pi/2) sin(a + pi/2) = 0. Weights |H_i| would not cancel it.
    """
    H = [np.asarray(h, np.float64) for h in homodyne]
    E = [np.asarray(e, np.float64) for e in heterodyne]
    num = sum(h * e for h, e in zip(H, E))
    den = sum(h * h for h in H)
    with np.errstate(divide="ignore", invalid="ignore"):
        return num / den, np.sqrt(den)


def velocity_from_ratio(ratio, model: CaptureModel) -> np.ndarray:
    """Exact inversion of E/H = Delta_omega / (omega_d + Delta_omega) (integer h):
    v = c Delta_omega / (2 omega_g), Delta_omega = omega_d r / (1 - r). NaN for r >= 1."""
    r = np.asarray(ratio, np.float64)
    with np.errstate(divide="ignore", invalid="ignore"):
        delta_omega = model.omega_d * r / (1.0 - r)
    return np.where(r < 1.0, delta_omega * model.velocity_per_delta_omega(), np.nan)


def ratio_from_velocity(velocity, model: CaptureModel) -> np.ndarray:
    """Forward model of :func:`velocity_from_ratio` (integer h)."""
    delta_omega = np.asarray(velocity, np.float64) / model.velocity_per_delta_omega()
    return delta_omega / (model.omega_d + delta_omega)


def model_captures(model: CaptureModel, phase_mid, velocity, offset: float, heterodyne: bool):
    """Model capture per unit g1 rho of one path: mid-exposure phase ``phase_mid`` (rad,
    omega_g L / c at mid-exposure) and radial velocity ``velocity`` (m/s)."""
    delta_omega = np.asarray(velocity, np.float64) / model.velocity_per_delta_omega()
    T = model.exposure
    start = np.asarray(phase_mid, np.float64) + 2 * math.pi * offset - 0.5 * delta_omega * T
    omega = delta_omega + (model.omega_d if heterodyne else 0.0)
    return mean_correlation(model.waveform, start, omega * T)


def model_ratio(model: CaptureModel, phase_mid, velocity,
                offsets=VELOCITY_OFFSETS) -> np.ndarray:
    """The combined ratio (:func:`combined_ratio`) that a single path would give."""
    H = [model_captures(model, phase_mid, velocity, o, False) for o in offsets]
    E = [model_captures(model, phase_mid, velocity, o, True) for o in offsets]
    return combined_ratio(H, E)[0]


# ---- Brightness calibration ----------------------------------------------------------

#: velocity calibrations: "none" inverts E/H exactly (no brightness change);
#: "inverse-square" also models the brightness change of a surface at distance d under a
#: colocated point light, (d_mid / d(t))^2; "auto": inverse-square for non-sinusoidal
#: waveforms, none for the sinusoid (whose first-order brightness term cancels)
VELOCITY_CALIBRATIONS = ("auto", "none", "inverse-square")


def single_path_ratio(model: CaptureModel, phase_mid, velocity, falloff_rate,
                      offsets=VELOCITY_OFFSETS, samples_per_period: int = 2048) -> np.ndarray:
    """The combined ratio of one path with brightness changing during the exposure, by
    midpoint quadrature of :func:`dopplertof.modulation.correlation`.

    phase_mid: omega_g L / c at mid-exposure (rad); velocity: radial velocity (m/s),
    L' = 2 v; falloff_rate: q in the brightness (1 + q tau)^-2, tau the time from
    mid-exposure (q = v / d for a colocated point light at distance d).
    """
    n = samples_per_period * max(1, int(round(abs(model.hetero_frequency))))
    T = model.exposure
    tau = ((np.arange(n) + 0.5) / n - 0.5) * T
    a = np.asarray(phase_mid, np.float64)[..., None]
    delta_omega = np.asarray(velocity, np.float64)[..., None] / model.velocity_per_delta_omega()
    brightness = (1.0 + np.asarray(falloff_rate, np.float64)[..., None] * tau) ** -2.0
    beat = model.omega_d * (tau + 0.5 * T)
    H, E = [], []
    for o in offsets:
        theta = a + 2 * math.pi * o + delta_omega * tau
        H.append(np.mean(brightness * correlation(model.waveform, theta), axis=-1))
        E.append(np.mean(brightness * correlation(model.waveform, theta + beat), axis=-1))
    return combined_ratio(H, E)[0]


#: stencil of the coefficient fit: velocity (m/s) and falloff rate (1/s)
_STENCIL_VELOCITY = 20.0
_STENCIL_RATE = 20.0


@functools.lru_cache(maxsize=8)
def inverse_square_coefficients(model: CaptureModel, phases: int = 512):
    """Phase grid and the coefficients c10, c01, c20, c11, c02 (each per phase) of
    r(v, q) ~ c10 v + c01 q + c20 v^2 + c11 v q + c02 q^2, by central differences of
    :func:`single_path_ratio` (r(0, 0) = 0 for an integer hetero_frequency)."""
    a = np.linspace(0.0, 2 * math.pi, phases + 1)
    V, Q = _STENCIL_VELOCITY, _STENCIL_RATE

    def r(v, q):
        return single_path_ratio(model, a, np.full(a.shape, v), np.full(a.shape, q))

    r0 = r(0.0, 0.0)
    rv_p, rv_m, rq_p, rq_m = r(V, 0.0), r(-V, 0.0), r(0.0, Q), r(0.0, -Q)
    c10 = (rv_p - rv_m) / (2 * V)
    c20 = (rv_p - 2 * r0 + rv_m) / (2 * V * V)
    c01 = (rq_p - rq_m) / (2 * Q)
    c02 = (rq_p - 2 * r0 + rq_m) / (2 * Q * Q)
    c11 = (r(V, Q) - r(V, -Q) - r(-V, Q) + r(-V, -Q)) / (4 * V * Q)
    return a, (c10, c01, c20, c11, c02)


def velocity_inverse_square(ratio, phase_mid, depth, model: CaptureModel) -> np.ndarray:
    """Velocity from the combined ratio for a surface at ``depth`` (m) under a colocated
    point light: solves c20' v^2 + c10' v = r with the coefficients at the pixel's phase
    and q = v / depth (the root that tends to r / c10'). NaN where it has no root."""
    grid, coefficients = inverse_square_coefficients(model)
    phase = np.mod(np.asarray(phase_mid, np.float64), 2 * math.pi)
    c10, c01, c20, c11, c02 = (np.interp(phase, grid, c) for c in coefficients)
    depth = np.asarray(depth, np.float64)
    r = np.asarray(ratio, np.float64)
    with np.errstate(divide="ignore", invalid="ignore"):
        inv_d = np.where(depth > 0, 1.0 / depth, np.nan)
        s1 = c10 + c01 * inv_d
        s2 = c20 + c11 * inv_d + c02 * inv_d**2
        disc = s1 * s1 + 4 * s2 * r
        v = 2 * r / (s1 + np.sign(s1) * np.sqrt(disc))
    return np.where(disc >= 0, v, np.nan)


def brightness_curvature_bias(model: CaptureModel, curvature) -> np.ndarray:
    """The velocity bias (m/s) of a path whose brightness is curved in time during the
    exposure, b(tau) ~ b_mid (1 + curvature tau^2) (tau from mid-exposure, curvature in
    1/s^2), for the sinusoid: the least squares of the offsets 0 and 1/4 cancels the
    linear term of b, not this one. With omega_d T = 2 pi h the heterodyne capture's
    tau^2 term is (-1)^h 2 T / omega_d^2 cos(a) over T, so r = 2 curvature / omega_d^2
    and v = c curvature / (omega_d omega_g). A surface turning at omega under a
    colocated light, cos(theta(t)): curvature -omega^2 / 2 (docs/camera.md)."""
    return (SPEED_OF_LIGHT * np.asarray(curvature, np.float64)
            / (model.omega_d * model.omega_g))


def resolve_calibration(calibration: str | None, waveform: str) -> str:
    calibration = "auto" if calibration is None else calibration
    if calibration not in VELOCITY_CALIBRATIONS:
        raise ReconstructionError(f"unknown velocity calibration {calibration!r}: expected "
                                  f"one of {', '.join(VELOCITY_CALIBRATIONS)}")
    if calibration == "auto":
        return "none" if waveform == "sinusoidal" else "inverse-square"
    return calibration


def _weak(signal, min_signal_fraction):
    fraction = DEFAULT_MIN_SIGNAL_FRACTION if min_signal_fraction is None else min_signal_fraction
    signal = np.asarray(signal, np.float64)
    finite = signal[np.isfinite(signal)]
    reference = float(np.percentile(finite, 99)) if finite.size else 0.0
    if reference <= 0:
        return np.ones(signal.shape, bool)
    return ~(signal >= fraction * reference)


def reconstruct_velocity(homodyne: dict, heterodyne: dict, model: CaptureModel,
                         min_signal_fraction=None, calibration: str | None = None,
                         phase_mid=None, depth=None):
    """Radial velocity (m/s, > 0 receding) and reason codes (0 valid, see
    INVALID_REASONS) from homodyne and heterodyne captures at offsets 0 and 1/4.

    calibration (VELOCITY_CALIBRATIONS): "inverse-square" needs each pixel's phase and
    depth (from :func:`homodyne_depth`).
    """
    for name, caps in (("homodyne", homodyne), ("heterodyne", heterodyne)):
        missing = [o for o in VELOCITY_OFFSETS if o not in caps]
        if missing:
            raise ReconstructionError(f"velocity needs {name} captures at offsets "
                                      f"{', '.join(f'{o:g}' for o in missing)}")
    ratio, weight = combined_ratio([homodyne[o] for o in VELOCITY_OFFSETS],
                                   [heterodyne[o] for o in VELOCITY_OFFSETS])
    if resolve_calibration(calibration, model.waveform) == "inverse-square":
        if phase_mid is None or depth is None:
            raise ReconstructionError("the inverse-square velocity calibration needs the "
                                      "homodyne phase and depth of every pixel")
        velocity = velocity_inverse_square(ratio, phase_mid, depth, model)
    else:
        velocity = velocity_from_ratio(ratio, model)
    reasons = np.where(_weak(weight, min_signal_fraction), WEAK_SIGNAL,
                       np.where(np.isfinite(velocity), VALID, OUT_OF_RANGE))
    return np.where(reasons == VALID, velocity, np.nan), reasons
