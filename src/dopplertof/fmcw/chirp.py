"""An FMCW lidar's chirp pair and its beat frequencies (docs/fmcw.md).

A laser at wavelength ``wavelength`` sweeps its optical frequency linearly by
``bandwidth`` over ``chirp_time`` (the up chirp), then back (the down chirp). A path of
length L (m, source to sensor through every bounce) changing at dL/dt (m/s) beats with
the local oscillator at

    f_up   = (B / T) L / c + (dL/dt) / lambda
    f_down = (B / T) L / c - (dL/dt) / lambda

(the convention of Kim et al. 2025, ACM TOG 44(4): a receding path, dL/dt > 0, is
red-shifted, which raises the up chirp's beat). A real receiver sees |f| (a real beat
has no sign): its spectrum has ``bins`` bins of width 1 / T (the Fourier resolution of
one chirp), bin m centred on m / T: the one-sided spectrum of the beat sampled at
2 bins / T over the chirp. An I/Q (complex, ``iq``) receiver sees the beat's sign: its
spectrum has 2 ``bins`` bins, bin m centred on m / T for m = -bins .. bins - 1, and a
beat below zero (a Doppler beat larger than the range beat) no longer folds. Range from the pair: L = c T (f_up + f_down) / (2 B), the
range L / 2 (light at the camera); radial velocity (dL/dt) / 2 = lambda (f_up - f_down) / 4,
positive receding as in the rest of the project.

No Mitsuba here: the command line checks its options with this module before the
scene loads. A scene carries its chirp as the integrator's fmcw_* parameters
(:class:`..fmcw_settings.FMCWSettings`, :meth:`Chirp.of_settings`; docs/fmcw.md
section 4).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..arguments import is_integer, is_number
from ..modulation import SPEED_OF_LIGHT
from ..fmcw_settings import WAVELENGTH_RANGE_NM, FMCWSettings, chirp_problem

#: the wavelengths an FMCW lidar may have here (m): ultraviolet to far infrared (the
#: scene's fmcw_wavelength's range, fmcw_settings.WAVELENGTH_RANGE_NM)
WAVELENGTH_RANGE = tuple(nm / 1e9 for nm in WAVELENGTH_RANGE_NM)


class FMCWError(ValueError):
    """A chirp parameter out of its range (one line, for the command line's exit 2)."""


@dataclass(frozen=True)
class Chirp:
    """The chirp pair of an FMCW lidar (SI units)."""

    wavelength: float = 1550e-9  #: lambda, m
    bandwidth: float = 1e9  #: B, the optical frequency sweep of one chirp, Hz
    chirp_time: float = 10e-6  #: T, the duration of one chirp, s
    bins: int = 256  #: M, spectrum bins of width 1 / T (per sign with ``iq``)
    iq: bool = False  #: an I/Q (complex) receiver: signed beats, bins -M .. M - 1

    def __post_init__(self):
        problem = self.problem()
        if problem:
            raise FMCWError(problem)
        for name in ("wavelength", "bandwidth", "chirp_time"):  # (NumPy scalars: Python's)
            object.__setattr__(self, name, float(getattr(self, name)))
        object.__setattr__(self, "bins", int(self.bins))
        object.__setattr__(self, "iq", bool(self.iq))

    def problem(self, names: dict | None = None) -> str | None:
        """What is wrong with these parameters, else None; ``names`` (as
        :func:`..fmcw_settings.chirp_problem`'s) name the bandwidth and the chirp time as
        they were given (default: these fields, SI)."""
        lo, hi = WAVELENGTH_RANGE
        for name, value in (("wavelength", self.wavelength), ("bandwidth", self.bandwidth),
                            ("chirp_time", self.chirp_time)):
            if not is_number(value) or not math.isfinite(value):
                return f"{name} must be a finite number, got {value!r}"
        if not lo <= self.wavelength <= hi:
            return (f"wavelength must be within {lo * 1e9:g} nm - {hi * 1e6:g} um, got "
                    f"{self.wavelength * 1e9:g} nm")
        if self.bandwidth <= 0:
            return f"bandwidth B must be > 0 Hz, got {self.bandwidth:g}"
        if self.chirp_time <= 0:
            return f"chirp_time T must be > 0 s, got {self.chirp_time:g}"
        problem = chirp_problem(
            float(self.wavelength), float(self.bandwidth), float(self.chirp_time),
            names or {"bandwidth": ("bandwidth B", "Hz", 1.0),
                      "chirp_time": ("chirp_time T", "s", 1.0)})
        if problem:
            return problem
        if not is_integer(self.bins) or self.bins < 2:
            return f"bins M must be an integer >= 2, got {self.bins!r}"
        if not isinstance(self.iq, (bool, np.bool_)):
            return f"iq must be True or False, got {self.iq!r}"
        return None

    @classmethod
    def of_settings(cls, settings: FMCWSettings | None = None, names: dict | None = None,
                    **given) -> "Chirp":
        """The chirp of ``settings`` (a scene's ``modality_settings["fmcw"]``: its
        fmcw_wavelength (nm), fmcw_bandwidth (GHz), fmcw_chirp_time (us), fmcw_bins and
        fmcw_iq, XML or defaults; None: the defaults) with the values of ``given`` (SI, as the
        fields; None: the settings') over them; ``names`` (:meth:`problem`'s) name a
        sweep or a duration out of its range as it was given."""
        settings = settings or FMCWSettings()
        values = {"wavelength": settings.wavelength / 1e9,
                  "bandwidth": settings.bandwidth * 1e9,
                  "chirp_time": settings.chirp_time / 1e6, "bins": settings.bins,
                  "iq": settings.iq}
        values.update({k: v for k, v in given.items() if v is not None})
        if names is not None:
            unchecked = object.__new__(cls)  # (its fields set, not yet validated)
            for name, value in values.items():
                object.__setattr__(unchecked, name, value)
            problem = unchecked.problem(names)
            if problem:
                raise FMCWError(problem)
        return cls(**values)

    @property
    def slope(self) -> float:
        """B / T, Hz per second of delay."""
        return self.bandwidth / self.chirp_time

    @property
    def bin_width(self) -> float:
        """Hz per bin: 1 / T."""
        return 1.0 / self.chirp_time

    @property
    def max_path_length(self) -> float:
        """The longest path length (m) whose static beat falls inside the last bin."""
        return (self.bins - 1) * self.bin_width * SPEED_OF_LIGHT / self.slope

    def unambiguous_speed(self, distance):
        """The radial speed (m/s) at which a direct return from ``distance`` (m, the
        light at the camera) has a Doppler beat 2 v / lambda as large as its range beat
        (B / T) 2 d / c: B lambda d / (c T). Faster, its lower beat crosses zero and folds,
        and the pair reads range and velocity swapped (docs/fmcw.md section 3)."""
        return self.slope * self.wavelength * distance / SPEED_OF_LIGHT

    @property
    def first_bin(self) -> int:
        """The index m of the spectrum's first bin (centred on m / T): 0, or -M with
        ``iq``."""
        return -self.bins if self.iq else 0

    @property
    def spectrum_bins(self) -> int:
        """The bins of one chirp's spectrum: M, or 2 M with ``iq``."""
        return 2 * self.bins if self.iq else self.bins

    def frequencies(self):
        """The bins' centre frequencies (Hz), a NumPy array of :attr:`spectrum_bins`."""
        return (np.arange(self.spectrum_bins, dtype=np.float64) + self.first_bin) \
            * self.bin_width

    def beats(self, path_length, length_rate):
        """(f_up, f_down), Hz, signed, of paths of length ``path_length`` (m) changing
        at ``length_rate`` (m/s); scalars or arrays."""
        range_beat = self.slope * path_length / SPEED_OF_LIGHT
        doppler = length_rate / self.wavelength
        return range_beat + doppler, range_beat - doppler

    def range_and_velocity(self, f_up, f_down):
        """(range, radial velocity): L / 2 (m) and (dL/dt) / 2 (m/s, > 0 receding) from
        the up and down beats (Hz)."""
        path_length = SPEED_OF_LIGHT * self.chirp_time * 0.5 * (f_up + f_down) / self.bandwidth
        return 0.5 * path_length, 0.25 * self.wavelength * (f_up - f_down)

    def record(self) -> dict:
        """The parameters and what follows from them, for summary.json."""
        return {"wavelength_nm": self.wavelength * 1e9, "bandwidth_GHz": self.bandwidth * 1e-9,
                "chirp_time_us": self.chirp_time * 1e6, "bins": self.bins,
                "receiver": ("I/Q: signed beats, 2 M bins from -M / T" if self.iq
                             else "real: |beat|, M bins from 0"),
                "bin_width_Hz": self.bin_width,
                "range_per_bin_m": 0.5 * self.bin_width * SPEED_OF_LIGHT / self.slope,
                "velocity_per_bin_m_s": 0.25 * self.wavelength * self.bin_width,
                "max_range_m": 0.5 * self.max_path_length}
