"""What a camera reports from its raw DN: range, amplitude, masks, velocity.

Per modulation frequency, the N-phase fit of its homodyne frames (:mod:`.demodulate`;
frames of unequal integration times scaled to the group's longest) gives a phase, an
amplitude (DN) and a wrapped depth, calibrated for wiggling when the preset says the
camera does; two frequencies or more are unwrapped (:mod:`.unwrap`). Masks: saturated
(any frame of the pixel), low confidence (the smallest amplitude below the preset's
``min_amplitude_dn``), unwrapping failed, and the footprints that mix surfaces (given by
the capture: :func:`dopplertof.tof.ground_truth.mixed_footprints`, the reason
``tof.reconstruct.MIXED_FOOTPRINT`` of dopplertof's capture) and the pixels outside the
illuminator's field (given by the capture: no light of the camera's own reaches them); the
depth is NaN under any of them. Heterodyne
frames give velocity as dopplertof's capture does (:mod:`dopplertof.tof.reconstruct`).

The predicted depth variance (first order, from the sensor's predicted variance of each
raw frame, :mod:`.sensor`) sits beside it: ``depth_variance``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..modulation import SPEED_OF_LIGHT
from ..tof import reconstruct as tof_rec
from . import demodulate
from .sensor import to_rendered_units
from .unwrap import LIKELIHOOD_GAP, unwrap_likelihood


#: summary.json's name of the pixels outside the illuminator's field
UNLIT = "outside the illuminator's field"


@dataclass
class FrequencyPhase:
    """The N-phase result of one modulation frequency."""

    frequency_mhz: float
    frames: tuple  #: indices of its raw frames
    phase: np.ndarray  #: (H, W) rad in [0, 2 pi), calibrated when the camera calibrates
    amplitude: np.ndarray  #: (H, W) DN (at the group's longest integration)
    depth: np.ndarray  #: (H, W) wrapped depth (m)
    depth_variance: np.ndarray  #: (H, W) predicted (m^2)


@dataclass
class CameraReconstruction:
    depth: np.ndarray  #: (H, W) radial range (m), NaN where masked
    amplitude: np.ndarray  #: (H, W) the smallest of the frequencies' amplitudes (DN)
    saturated: np.ndarray  #: (H, W) bool
    low_confidence: np.ndarray  #: (H, W) bool
    unwrap_failed: np.ndarray  #: (H, W) bool
    depth_variance: np.ndarray  #: (H, W) predicted variance of ``depth`` (m^2)
    frequencies: list  #: FrequencyPhase per frequency
    range_m: float  #: the range the depth covers (unambiguous range searched, or the wrap)
    method: str
    #: chi^2 by which the best wrap must beat any other (None: one frequency, no unwrapping)
    unwrap_likelihood_gap: float | None = None
    velocity: np.ndarray | None = None  #: (H, W) m/s with heterodyne frames
    depth_z: np.ndarray | None = field(default=None)  #: (H, W), set by the capture
    #: (H, W) bool: footprints that mix surfaces, masked (all False when kept)
    mixed: np.ndarray | None = None
    #: (H, W) bool: outside the camera's range: nearer than reconstruction.min_range_m by
    #: more than three predicted standard deviations, or unwrapped beyond max_range_m
    out_of_range: np.ndarray | None = None
    #: (H, W) bool: the camera's edge filter (reconstruction.edge_range_m): the depths
    #: around the pixel span more than that (flying pixels between two surfaces)
    edge: np.ndarray | None = None
    #: (H, W) bool: pixels wholly outside the field the camera's illuminator lights
    #: (radiometry.outside_field): no light of its own reaches them
    unlit: np.ndarray | None = None

    @property
    def masked(self) -> np.ndarray:
        """(H, W) bool: the pixels under any mask (NaN in depth and velocity)."""
        masked = self.saturated | self.low_confidence | self.unwrap_failed
        if self.edge is not None:
            masked = masked | self.edge
        if self.out_of_range is not None:
            masked = masked | self.out_of_range
        if self.unlit is not None:
            masked = masked | self.unlit
        return masked if self.mixed is None else masked | self.mixed

    def mask(self, attribute: str) -> np.ndarray:
        """(H, W) bool: the mask ``attribute`` (:data:`dopplertof.outputs.MASKS`); all
        False where it was not computed (None: no pixel outside the illuminator's field,
        no edge filter...)."""
        mask = getattr(self, attribute)
        return np.zeros(self.depth.shape, bool) if mask is None else np.asarray(mask, bool)

    def describe(self) -> dict:
        mixed = 0 if self.mixed is None else int(self.mixed.sum())
        return {"file": "depth.npy", "method": self.method, "range_m": self.range_m,
                "unwrap_likelihood_gap": self.unwrap_likelihood_gap,
                "frequencies_MHz": [g.frequency_mhz for g in self.frequencies],
                "masked_pixels": {"saturated": int(self.saturated.sum()),
                                  "low confidence": int(self.low_confidence.sum()),
                                  "unwrapping failed": int(self.unwrap_failed.sum()),
                                  "edge filter": 0 if self.edge is None
                                  else int(self.edge.sum()),
                                  "outside the range": 0 if self.out_of_range
                                  is None else int(self.out_of_range.sum()),
                                  UNLIT: 0 if self.unlit is None else int(self.unlit.sum()),
                                  tof_rec.reason_name(tof_rec.MIXED_FOOTPRINT): mixed},
                "units": "radial range in m from the camera centre (depth_z.npy: along the "
                         "optical axis); amplitude in DN"}


def frequency_phase(readout, preset, frequency_mhz: float) -> FrequencyPhase:
    """The N-phase fit of the homodyne frames at ``frequency_mhz``."""
    ks = tuple(k for k, f in enumerate(preset.frames)
               if f.homodyne and f.frequency_mhz == frequency_mhz)
    steps = tuple(preset.frames[k].phase_deg for k in ks)
    times = np.array([preset.frames[k].integration_s for k in ks])
    scale = (times.max() / times)[:, None, None]
    x = (readout.raw[list(ks)].astype(np.float64) - preset.sensor["offset_dn"]) * scale
    phase, amplitude, _ = demodulate.n_phase(x, np.radians(steps))
    jacobian = demodulate.phase_jacobian(x, np.radians(steps))
    phase_variance = np.sum(jacobian**2 * readout.variance[list(ks)] * scale**2, axis=0)
    if preset.reconstruction["wiggling_calibration"] and preset.waveform != "sinusoidal":
        slope = demodulate.calibration_slope(phase, preset.waveform, steps)
        phase = demodulate.calibrate(phase, preset.waveform, steps)
        phase_variance = phase_variance * slope**2
    f_hz = frequency_mhz * 1e6
    per_radian = SPEED_OF_LIGHT / (4 * math.pi * f_hz)
    return FrequencyPhase(frequency_mhz, ks, phase, amplitude,
                          demodulate.depth_from_phase(phase, f_hz),
                          per_radian**2 * phase_variance)


def reconstruct(readout, preset, mixed=None, unlit=None) -> CameraReconstruction:
    """The camera's depth (and velocity with heterodyne frames) from its readout;
    ``mixed`` ((H, W) bool or None): the footprints that mix surfaces, masked too;
    ``unlit`` likewise: the pixels outside the illuminator's field."""
    groups = [frequency_phase(readout, preset, f) for f in preset.frequencies_mhz]
    max_range = preset.reconstruction["max_range_m"]
    saturated = readout.saturated.any(axis=0)
    amplitude = np.min([g.amplitude for g in groups], axis=0)
    low_confidence = ~(amplitude >= max(preset.reconstruction["min_amplitude_dn"], 1e-12))
    min_snr = preset.reconstruction["min_snr"]
    if min_snr > 0:  # an amplitude under min_snr of its noise: the phase noise > 1 / min_snr
        phase_std = np.max([np.sqrt(g.depth_variance) * 4 * math.pi * g.frequency_mhz * 1e6
                            / SPEED_OF_LIGHT for g in groups], axis=0)
        low_confidence |= ~(phase_std * min_snr <= 1.0)
    gap = None
    if len(groups) >= 2:
        unwrapped = unwrap_likelihood([g.depth for g in groups],
                                      [g.depth_variance for g in groups],
                                      [g.frequency_mhz * 1e6 for g in groups], max_range)
        depth, failed, variance = unwrapped.depth, unwrapped.failed, unwrapped.variance
        beyond, gap = unwrapped.beyond, LIKELIHOOD_GAP
        range_m = min(unwrapped.unambiguous_range, max_range)
        method = (f"N-phase least-squares fit per frequency, unwrapped by maximum likelihood "
                  f"over wrap counts of {len(groups)} frequencies (inverse-variance mean; "
                  f"flagged where a wrong wrap comes within chi^2 {LIKELIHOOD_GAP:g} or the "
                  "frequencies disagree beyond their noise)")
    else:  # one frequency: the wrapped depth, flagged beyond the range the camera reports
        depth, failed = groups[0].depth, np.zeros(saturated.shape, bool)
        beyond = depth > max_range
        range_m = min(max_range, tof_rec.wrap_distance(groups[0].frequency_mhz * 1e6))
        variance = groups[0].depth_variance
        method = "N-phase least-squares fit, one frequency (wraps at the range)"
    if preset.reconstruction["wiggling_calibration"] and preset.waveform != "sinusoidal":
        method += "; wiggling calibration table applied"
    mixed = np.zeros(saturated.shape, bool) if mixed is None else np.asarray(mixed, bool)
    result = CameraReconstruction(depth, amplitude, saturated, low_confidence, failed,
                                  variance, groups, float(range_m), method, gap,
                                  mixed=mixed, unlit=None if unlit is None
                                  else np.asarray(unlit, bool))
    # nearer than the operating range by more than three predicted standard deviations
    nearest = preset.reconstruction["min_range_m"] - 3 * np.sqrt(variance)
    # a depth that no other mask explains is NaN where no wrap count lies within the range
    # searched (every candidate beyond it): outside the range too
    unexplained = ~np.isfinite(depth) & ~result.masked
    result.out_of_range = (depth < nearest) | beyond | unexplained  # (NaN compares False)
    result.edge = edge_filter(np.where(result.masked, np.nan, depth),
                              preset.reconstruction["edge_range_m"])
    masked = result.masked
    result.depth = np.where(masked, np.nan, depth)
    if preset.heterodyne:
        result.velocity = np.where(masked, np.nan, heterodyne_velocity(readout, preset, result))
    return result


def edge_filter(depth, limit: float) -> np.ndarray:
    """(H, W) bool: the pixels whose 3 x 3 neighbourhood's reported depths (NaN ignored)
    span more than ``limit`` metres, the edge filter of a depth engine that removes
    flying pixels (0: off). A pixel that mixes two surfaces lies between them, so it and
    its neighbours across the edge go."""
    from numpy.lib.stride_tricks import sliding_window_view

    depth = np.asarray(depth, np.float64)
    if not limit > 0 or depth.ndim != 2:
        return np.zeros(depth.shape, bool)
    windows = sliding_window_view(np.pad(depth, 1, constant_values=np.nan), (3, 3))
    with np.errstate(invalid="ignore"):
        import warnings

        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)  # (all-NaN windows)
            span = np.nanmax(windows, axis=(-2, -1)) - np.nanmin(windows, axis=(-2, -1))
    return np.isfinite(depth) & (span > limit)


def heterodyne_velocity(readout, preset, recon: CameraReconstruction) -> np.ndarray:
    """Radial velocity (m/s) from the heterodyne frames and the homodyne frames of
    their frequency (offsets 0 and 1/4), as :func:`dopplertof.tof.capture` does."""
    frames = to_rendered_units(readout.raw, readout, preset.sensor)
    hetero = [k for k, f in enumerate(preset.frames) if not f.homodyne]
    first = preset.frames[hetero[0]]
    group = next(g for g in recon.frequencies if g.frequency_mhz == first.frequency_mhz)
    homodyne = {preset.frames[k].offset: frames[k] for k in group.frames}
    heterodyne = {preset.frames[k].offset: frames[k] for k in hetero}
    model = tof_rec.CaptureModel(2 * math.pi * first.frequency_mhz * 1e6, first.integration_s,
                                 first.hetero_frequency, preset.waveform)
    velocity, _ = tof_rec.reconstruct_velocity(
        homodyne, heterodyne, model, None, tof_rec.resolve_calibration("auto", preset.waveform),
        group.phase, recon.depth)
    return velocity
