"""Sensor noise of a two-tap ToF pixel: shot noise, read noise, full well, ADC, ambient.

Off by default. The model (``docs/camera.md`` has the derivation):

* A rendered capture V is the time-averaged correlation of the sensor code s(t) in
  [-1, 1] with the light (the renderer's value, in scene radiance units). A ToF pixel
  measures it differentially with two taps that collect the light while
  (1 + s) / 2 and (1 - s) / 2 respectively: their sum sees the unmodulated light
  g0 R (R the time-averaged radiance, from the radiance capture) and their
  difference the correlation V.
* ``photons_per_unit``: photons reaching the pixel per second per unit of rendered
  value. Mean photo-electrons of the taps over the exposure T:

      e_A = QE K T (g0 R + V) / 2 + QE a T / 2,   e_B = QE K T (g0 R - V) / 2 + QE a T / 2

  with K = photons_per_unit and a the ambient (unmodulated) photon rate, which both
  taps share equally.
* Each tap: Poisson(e) electrons, clipped at the full well, plus Gaussian read noise,
  then the ADC: DN = round(electrons / gain) clipped to [0, 2^bits - 1].
* The camera reports gain (DN_A - DN_B) / (QE K T), the capture in rendered units
  again, so that reconstruction is the same with and without noise. Ambient light
  cancels in the mean and adds shot noise.

Mean and variance of the reported value, away from clipping:
mean = V, variance = (e_A + e_B + 2 read_noise^2 + 2 gain^2 / 12) / (QE K T)^2.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, replace

import numpy as np

from ..arguments import check_seed


class NoiseError(ValueError):
    """A noise parameter out of range."""


@dataclass(frozen=True)
class NoiseModel:
    """A two-tap ToF sensor in physical units (electrons, photons, seconds)."""

    photons_per_unit: float | None = None  #: photons/s at a pixel per rendered unit; None: auto
    well_fill: float = 0.5  #: auto scale: brightest unmodulated signal = this x usable range
    quantum_efficiency: float = 0.4  #: electrons per photon
    read_noise: float = 5.0  #: electrons rms per tap and read
    full_well: float = 20000.0  #: electrons per tap
    gain: float = 5.0  #: electrons per digital number (DN)
    bits: int = 12  #: ADC resolution
    ambient: float = 0.0  #: unmodulated photons/s per pixel (background light)
    seed: int = 0  #: seed of the noise generator (numpy PCG64)

    def __post_init__(self):
        def fail(msg):
            raise NoiseError(f"noise: {msg}")

        if self.photons_per_unit is not None and not (
                math.isfinite(self.photons_per_unit) and self.photons_per_unit > 0):
            fail(f"photons_per_unit must be > 0, got {self.photons_per_unit}")
        if not 0 < self.well_fill <= 1:
            fail(f"well_fill must be in (0, 1], got {self.well_fill}")
        if not 0 < self.quantum_efficiency <= 1:
            fail(f"quantum_efficiency must be in (0, 1], got {self.quantum_efficiency}")
        if not (math.isfinite(self.read_noise) and self.read_noise >= 0):
            fail(f"read_noise must be >= 0 electrons, got {self.read_noise}")
        if not (math.isfinite(self.full_well) and self.full_well > 0):
            fail(f"full_well must be > 0 electrons, got {self.full_well}")
        if not (math.isfinite(self.gain) and self.gain > 0):
            fail(f"gain must be > 0 electrons/DN, got {self.gain}")
        if not (isinstance(self.bits, (int, np.integer)) and 1 <= self.bits <= 32):
            fail(f"bits must be an integer in 1..32, got {self.bits!r}")
        if not (math.isfinite(self.ambient) and self.ambient >= 0):
            fail(f"ambient must be >= 0 photons/s, got {self.ambient}")
        check_seed(self.seed, "noise: seed", NoiseError)

    @property
    def adc_max(self) -> int:
        return (1 << int(self.bits)) - 1

    @property
    def usable_range(self) -> float:
        """Electrons a tap can record: min(full well, gain x (2^bits - 1))."""
        return min(self.full_well, self.gain * self.adc_max)

    def scaled_for(self, unmodulated: np.ndarray, exposure: float) -> "NoiseModel":
        """This model with ``photons_per_unit`` chosen when it is None: the 99.5th
        percentile of the unmodulated signal g0 R, in electrons, is ``well_fill`` of
        the usable range (full well or ADC, the smaller)."""
        if self.photons_per_unit is not None:
            return self
        values = np.asarray(unmodulated, np.float64)
        values = values[np.isfinite(values)]
        reference = float(np.percentile(values, 99.5)) if values.size else 0.0
        if reference <= 0:
            raise NoiseError("noise: nothing in the image is lit, so no photon scale can be "
                             "chosen; give photons_per_unit")
        budget = self.well_fill * self.usable_range - self.quantum_efficiency * self.ambient \
            * exposure / 2
        if budget <= 0:
            raise NoiseError("noise: the ambient light alone fills the well fraction "
                             f"{self.well_fill:g}; lower ambient or raise well_fill")
        return replace(self, photons_per_unit=budget / (self.quantum_efficiency * exposure
                                                        * reference))

    def electrons_per_unit(self, exposure: float) -> float:
        """Signal electrons (A - B) per unit of rendered value: QE K T."""
        if self.photons_per_unit is None:
            raise NoiseError("noise: photons_per_unit is not set (call scaled_for first)")
        return self.quantum_efficiency * self.photons_per_unit * exposure

    def tap_means(self, value, unmodulated, exposure: float):
        """Mean photo-electrons (e_A, e_B) of the two taps; negative means (a g0 too small
        for the correlation, or Monte Carlo noise) are clipped to zero."""
        k = self.electrons_per_unit(exposure)
        ambient = 0.5 * self.quantum_efficiency * self.ambient * exposure
        value = np.asarray(value, np.float64)
        unmodulated = np.asarray(unmodulated, np.float64)
        e_a = 0.5 * k * (unmodulated + value) + ambient
        e_b = 0.5 * k * (unmodulated - value) + ambient
        return np.maximum(e_a, 0.0), np.maximum(e_b, 0.0)

    def read_tap(self, mean_electrons, rng: np.random.Generator):
        """Digital numbers of one tap and where it saturated (full well or ADC)."""
        electrons = rng.poisson(np.asarray(mean_electrons, np.float64)).astype(np.float64)
        full = electrons >= self.full_well
        electrons = np.minimum(electrons, self.full_well)
        if self.read_noise > 0:
            electrons = electrons + rng.normal(0.0, self.read_noise, electrons.shape)
        dn = np.rint(electrons / self.gain)
        top = dn >= self.adc_max
        return np.clip(dn, 0, self.adc_max), full | top

    def measure(self, value, unmodulated, exposure: float, rng: np.random.Generator):
        """The noisy capture in rendered units, and its saturation mask."""
        e_a, e_b = self.tap_means(value, unmodulated, exposure)
        dn_a, sat_a = self.read_tap(e_a, rng)
        dn_b, sat_b = self.read_tap(e_b, rng)
        noisy = self.gain * (dn_a - dn_b) / self.electrons_per_unit(exposure)
        return noisy.astype(np.float32), sat_a | sat_b

    def variance(self, value, unmodulated, exposure: float):
        """Predicted variance of :meth:`measure` away from clipping (rendered units^2)."""
        e_a, e_b = self.tap_means(value, unmodulated, exposure)
        k = self.electrons_per_unit(exposure)
        return (e_a + e_b + 2 * self.read_noise**2 + 2 * self.gain**2 / 12) / k**2

    def describe(self) -> dict:
        """Parameters with their units, for summaries."""
        d = asdict(self)
        return {
            "photons_per_unit": d["photons_per_unit"],
            "photons_per_unit_units": "photons per second at a pixel per unit of rendered value",
            "well_fill": d["well_fill"],
            "quantum_efficiency": d["quantum_efficiency"],
            "read_noise_electrons": d["read_noise"],
            "full_well_electrons": d["full_well"],
            "gain_electrons_per_DN": d["gain"],
            "bits": d["bits"],
            "ambient_photons_per_second": d["ambient"],
            "seed": d["seed"],
            "model": "two taps (1 +- s)/2; Poisson shot noise per tap, full-well clip, "
                     "Gaussian read noise, ADC rounding and clipping; reported "
                     "gain (DN_A - DN_B) / (QE K T) in rendered units",
        }


def apply_noise(captures: dict, unmodulated: np.ndarray, exposure: float, model: NoiseModel):
    """Noisy copies of ``captures`` (name -> (H, W) image, noise drawn in this order)
    and the saturation mask of any tap of any capture. Returns (noisy, saturated, model)
    with the model's photon scale resolved."""
    model = model.scaled_for(unmodulated, exposure)
    rng = np.random.Generator(np.random.PCG64(int(model.seed)))
    noisy, saturated = {}, np.zeros(np.shape(unmodulated), bool)
    for name, value in captures.items():
        noisy[name], sat = model.measure(value, unmodulated, exposure, rng)
        saturated |= sat
    return noisy, saturated, model
