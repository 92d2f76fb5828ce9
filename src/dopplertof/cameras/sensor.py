"""A camera's sensor: from rendered raw frames to the integer DN it delivers.

Raw frame k is the renderer's homodyne (or heterodyne) capture V_k at the frame's
frequency, phase step and time window (the time-averaged correlation, docs/camera.md),
and R the time-averaged radiance over the sequence. A differential two-tap pixel
(the two-tap model of :mod:`dopplertof.tof.noise`, whose :class:`NoiseModel` sets the
photon scale and the taps' mean electrons) collects over the integration time T_k

    e_A = QE K T_k (g0 R + c V_k) / 2 + QE a T_k / 2 + D T_k,
    e_B = QE K T_k (g0 R - c V_k) / 2 + QE a T_k / 2 + D T_k

(c the demodulation contrast, K photons per second per rendered unit, a the ambient
photon rate, per pixel through an absolute preset (:mod:`.radiometry`), D the dark
current per tap). With noise, each tap draws Poisson(e) electrons
and is clipped at the full well, then Gaussian read noise is added; the ADC digitizes the
difference:

    DN_k = clip(round((e_A - e_B) / gain) + offset, 0, 2^bits - 1).

Saturated: a tap at the full well, or the ADC at either end. Without noise the same
pipeline runs on the mean electrons (``raw_ideal`` is the same before rounding and
clipping). Predicted variance of DN_k away from clipping:
(e_A + e_B + 2 read_noise^2) / gain^2 + 1/12.

Dynamic range (``sensor.shutters``, longest first, fractions of each frame's
integration): a sensor with several shutters integrates each pixel for the longest at
which its brightest tap stays under ``well_fill`` of the full well
(:func:`shutter_fractions`): e_A, e_B and the dark and ambient electrons all scale by
that fraction s, and the rendered units divide by s too, so near, bright pixels keep
about the same electrons instead of saturating (their noise levels off) while far ones
use the whole integration.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ..tof.noise import NoiseModel


@dataclass
class Readout:
    """What the sensor delivers for one raw frame sequence."""

    raw: np.ndarray  #: (K, H, W) integer DN
    raw_ideal: np.ndarray  #: (K, H, W) float DN: no noise, no rounding, no clipping
    saturated: np.ndarray  #: (K, H, W) bool
    variance: np.ndarray  #: (K, H, W) predicted variance of ``raw`` (DN^2)
    electrons_per_unit: np.ndarray  #: (K,) signal electrons (A - B) per rendered unit, c QE K T_k
    photons_per_unit: float  #: K, photons / s at a pixel per rendered unit
    #: (H, W) fraction of each frame's integration the pixel used (the dynamic-range
    #: scheme's shutter, :func:`shutter_fractions`); None: the whole of it
    shutter: np.ndarray | None = None


def noise_model(sensor: dict, seed: int = 0) -> NoiseModel:
    """The :class:`NoiseModel` of a preset's [sensor] section (photon scale automatic)."""
    return NoiseModel(photons_per_unit=None, well_fill=sensor["well_fill"],
                      quantum_efficiency=sensor["quantum_efficiency"],
                      read_noise=sensor["read_noise_electrons"],
                      full_well=sensor["full_well_electrons"],
                      gain=sensor["gain_electrons_per_dn"], bits=sensor["adc_bits"],
                      ambient=sensor["ambient_photons_per_s"], seed=seed)


def raw_dtype(bits: int):
    """The integer type of raw DN: uint16 up to 16 bits, else int32."""
    return np.uint16 if bits <= 16 else np.int32


def read_frames(rendered, unmodulated, integration_s, sensor: dict, contrast: float,
                rng: np.random.Generator | None = None,
                photons_per_unit: float | None = None, ambient_photons=None,
                shutter=None) -> Readout:
    """The sensor's readout of rendered raw frames (K, H, W) with the unmodulated light
    g0 R (H, W); ``rng`` None: no shot or read noise (rounding and clipping stay).
    ``photons_per_unit``: the photon scale (default: the brightest unmodulated pixel
    fills well_fill of the well at the longest integration). ``ambient_photons``: (H, W)
    unmodulated photons per second at each pixel (ambient light, :mod:`.radiometry`),
    shared by the two taps; with it the [sensor] section's scalar
    ambient_photons_per_s is not used. ``shutter``: (H, W) each pixel's fraction of the
    integration (another readout's, of the same scene); default the sensor's own choice
    (:func:`shutter_fractions`)."""
    model = noise_model(sensor)
    if ambient_photons is not None:
        model = replace(model, ambient=0.0)
        ambient_photons = np.asarray(ambient_photons, np.float64)
    integration_s = np.asarray(integration_s, np.float64)
    if photons_per_unit is None:
        model = model.scaled_for(unmodulated, float(integration_s.max()))
    else:
        model = replace(model, photons_per_unit=float(photons_per_unit))
    gain, offset = sensor["gain_electrons_per_dn"], sensor["offset_dn"]
    shape = np.shape(rendered)
    raw = np.zeros(shape, raw_dtype(sensor["adc_bits"]))
    ideal, variance = np.zeros(shape), np.zeros(shape)
    saturated = np.zeros(shape, bool)
    means = []
    for value, exposure in zip(rendered, integration_s):
        e_a, e_b = model.tap_means(contrast * np.asarray(value, np.float64), unmodulated,
                                   float(exposure))
        dark = sensor["dark_current_electrons_per_s"] * exposure
        if ambient_photons is not None:
            dark = dark + 0.5 * model.quantum_efficiency * ambient_photons * exposure
        means.append((e_a + dark, e_b + dark))
    if shutter is None:
        shutter = shutter_fractions(means, sensor)
    for k, (e_a, e_b) in enumerate(means):
        if shutter is not None:
            e_a, e_b = e_a * shutter, e_b * shutter
        ideal[k] = (e_a - e_b) / gain + offset
        variance[k] = (e_a + e_b + 2 * model.read_noise**2) / gain**2 + 1.0 / 12.0
        taps = [_draw_tap(e, model, rng) for e in (e_a, e_b)]
        dn = np.rint((taps[0][0] - taps[1][0]) / gain) + offset
        saturated[k] = taps[0][1] | taps[1][1] | (dn <= 0) | (dn >= model.adc_max)
        raw[k] = np.clip(dn, 0, model.adc_max)
    per_unit = contrast * model.quantum_efficiency * model.photons_per_unit * integration_s
    return Readout(raw, ideal, saturated, variance, per_unit, float(model.photons_per_unit),
                   shutter)


def shutter_fractions(means, sensor: dict) -> np.ndarray | None:
    """(H, W): the fraction of every frame's integration time each pixel integrates
    under the sensor's dynamic-range scheme (``sensor.shutters``, longest first): the
    longest shutter at which the pixel's brightest mean tap, over its raw frames
    ``means`` ((e_A, e_B) per frame at the full integration, ambient and dark current
    included), stays at or under ``well_fill`` of the full well; the shortest where none
    does. The camera's shutter engine chooses it from the scene's light (a static scene:
    the mean). None when the sensor has one shutter."""
    shutters = sorted(float(s) for s in sensor.get("shutters", (1.0,)))
    if len(shutters) <= 1:
        return None
    peak = np.max([np.maximum(e_a, e_b) for e_a, e_b in means], axis=0)
    limit = sensor["well_fill"] * sensor["full_well_electrons"]
    chosen = np.full(np.shape(peak), shutters[0])
    for fraction in shutters[1:]:  # ascending: the longest that fits wins
        chosen = np.where(peak * fraction <= limit, fraction, chosen)
    return chosen


def _draw_tap(mean_electrons, model: NoiseModel, rng):
    """(electrons of one tap, where it reached the full well): Poisson and read noise
    when ``rng`` is given, the mean otherwise."""
    electrons = (rng.poisson(mean_electrons).astype(np.float64) if rng is not None
                 else np.asarray(mean_electrons, np.float64))
    full = electrons >= model.full_well
    electrons = np.minimum(electrons, model.full_well)
    if rng is not None and model.read_noise > 0:
        electrons = electrons + rng.normal(0.0, model.read_noise, electrons.shape)
    return electrons, full


def to_rendered_units(raw, readout: Readout, sensor: dict) -> np.ndarray:
    """(K, H, W) raw DN back in rendered units, (DN - offset) gain / (c QE K T_k): what
    the tof/ reconstruction takes (the same with and without noise)."""
    signal = (np.asarray(raw, np.float64) - sensor["offset_dn"]) * sensor["gain_electrons_per_dn"]
    per_unit = readout.electrons_per_unit[:, None, None]
    if readout.shutter is not None:
        per_unit = per_unit * readout.shutter
    return signal / per_unit
