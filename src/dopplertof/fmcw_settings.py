"""The FMCW lidar's settings as a scene carries them: its integrator's ``fmcw_*``
parameters (docs/parameters.md, "FMCW lidar"), in the units of the ``fmcw`` command's
options, parsed and checked as the D-ToF render parameters are (the same types, the
same one-line messages) but held apart from them: a D-ToF render never reads them, so
a D-ToF scene that carries them renders and checkpoints as one without.

The FMCW lidar's (dopplertof.fmcw) own, kept below the scene loaders that parse them
(scene/parameters.py: rooms import down, and fmcw/ is a top room). No Mitsuba and no
NumPy here: the scene loaders and the command line read these before anything heavy
loads.
"""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass, fields, replace

from .modulation import SPEED_OF_LIGHT
from .params import ParameterError, coerce_parameter

#: the wavelengths an FMCW lidar may have (nm): ultraviolet to far infrared
WAVELENGTH_RANGE_NM = (200.0, 20000.0)
#: the FMCW lidar's beams (dopplertof.fmcw.beam)
BEAMS = ("flood", "collimated")
#: the narrowest chirp sweep B (Hz): 1 MHz, a range bin c/(2B) of 150 m
MIN_BANDWIDTH_HZ = 1e6
#: the widest chirp sweep, as a fraction of the optical carrier c/lambda it sweeps
MAX_SWEEP_OF_CARRIER = 1e-2
#: a chirp's duration T (s): from 1 ns (the round trip of 15 cm) to 1 s (the scene is
#: traced at one instant, as a chirp of microseconds allows)
CHIRP_TIME_RANGE_S = (1e-9, 1.0)
#: the largest beam intensity (W/sr): float32's largest number, that of the spectra
MAX_BEAM_INTENSITY = 3.4028234663852886e38


@dataclass(frozen=True)
class FMCWSettings:
    """The chirp pair and the beam a scene gives the FMCW lidar. A field ``x`` is the
    scene's parameter ``fmcw_x`` (:attr:`PREFIX`)."""

    PREFIX = "fmcw_"  #: (class constants, not fields)
    WHOSE = "the FMCW lidar's (the fmcw command, dopplertof.fmcw)"  #: for messages

    wavelength: float = 1550.0  #: lambda (nm)
    bandwidth: float = 1.0  #: B, one chirp's sweep (GHz)
    chirp_time: float = 10.0  #: T, one chirp (us)
    bins: int = 256  #: M, spectrum bins of width 1/T
    beam: str = "flood"  #: "flood" or "collimated"
    #: a collimated beam's radiant intensity in each pixel's cone (W/sr)
    beam_intensity: float = 1.0
    #: an I/Q (complex) receiver: signed beats, 2 M bins from -M / T; else a real one
    iq: bool = False

    @classmethod
    def names(cls) -> tuple[str, ...]:
        """The scene parameters' names, ``fmcw_wavelength`` ... ``fmcw_iq``."""
        return tuple(cls.PREFIX + f.name for f in fields(cls))

    @classmethod
    def coerced(cls, values: dict, where: str = "parameters") -> dict:
        """``{field: value}`` of ``values`` (``{fmcw_name: value}``, every name one of
        :meth:`names`), each value of its field's type (strings parsed)."""
        # a field's type is its name, or the class itself once Dr.Jit has traversed the
        # dataclass (mitsuba.render's custom op does: it resolves the names in place)
        types = {cls.PREFIX + f.name: _TYPES[getattr(f.type, "__name__", f.type)]
                 for f in fields(cls)}
        return {name[len(cls.PREFIX):]: coerce_parameter(name, value, types[name], where)
                for name, value in values.items()}

    @classmethod
    def from_mapping(cls, values: dict, where: str = "parameters", base=None):
        """``values`` (``{fmcw_name: value}``) parsed on top of ``base``, checked."""
        return replace(base or cls(), **cls.coerced(values, where)).validated(where)

    def validated(self, where: str = "parameters"):
        """These settings when every value is in range, else a ParameterError prefixed
        with ``where``."""
        problem = self.problem()
        if problem:
            raise ParameterError(f"{where}: {problem}")
        return self

    def problem(self) -> str | None:
        """The first problem of the chirp pair and the beam, in the units of the ``fmcw``
        command's options (the same ranges as dopplertof.fmcw.Chirp's), else None."""
        for f in fields(self):
            v = getattr(self, f.name)
            if f.name not in ("beam", "iq") and not math.isfinite(v):
                return f"{self.PREFIX}{f.name} must be finite, got {v}"
        lo, hi = WAVELENGTH_RANGE_NM
        if not lo <= self.wavelength <= hi:
            return (f"fmcw_wavelength must be within {lo:g} - {hi:g} nm (200 nm - 20 um), "
                    f"got {self.wavelength:g}")
        for name, unit in (("bandwidth", "GHz"), ("chirp_time", "us"),
                           ("beam_intensity", "W/sr")):
            if getattr(self, name) <= 0:
                return f"fmcw_{name} must be > 0 {unit}, got {getattr(self, name):g}"
        problem = (chirp_problem(
            self.wavelength / 1e9, self.bandwidth * 1e9, self.chirp_time / 1e6,
            {"bandwidth": ("fmcw_bandwidth", "GHz", 1e9),
             "chirp_time": ("fmcw_chirp_time", "us", 1e-6)})
            or beam_intensity_problem(float(self.beam_intensity)))
        if problem:
            return problem
        if self.bins < 2:
            return f"fmcw_bins must be >= 2, got {self.bins}"
        if self.beam not in BEAMS:
            return f"unknown fmcw_beam {self.beam!r}: expected one of {', '.join(BEAMS)}"
        return None

    @property
    def lights_the_scene(self) -> bool:
        """Whether the lidar brings its own light (a collimated beam), so that a scene
        without emitters is still lit."""
        return self.beam == "collimated"


_TYPES = {"float": float, "int": int, "str": str, "bool": bool}


def chirp_problem(wavelength: float, bandwidth: float, chirp_time: float,
                  names: dict) -> str | None:
    """What is physically wrong with a chirp's sweep ``bandwidth`` (Hz) and duration
    ``chirp_time`` (s) at ``wavelength`` (m), all finite and > 0, else None: a sweep
    over a hundredth of the optical carrier or under 1 MHz, a chirp shorter than 1 ns or
    longer than 1 s (most likely a unit mistake). ``names``: {"bandwidth" and
    "chirp_time": (name, unit, SI per unit)}, how the message names the value given."""
    def given(field, si, si_unit):
        name, unit, per_unit = names[field]
        value = f"{si / per_unit:g} {unit}" + ("" if per_unit == 1 else f" = {si:g} {si_unit}")
        return f"{name} is in {unit}: got {value}"

    carrier = SPEED_OF_LIGHT / wavelength
    if bandwidth > MAX_SWEEP_OF_CARRIER * carrier:
        return (f"{given('bandwidth', bandwidth, 'Hz')}, "
                f"{'above' if bandwidth > carrier else 'over 1% of'} the optical carrier "
                f"c/lambda = {carrier / 1e12:.4g} THz: a sweep must stay far below its "
                f"carrier (under {MAX_SWEEP_OF_CARRIER * carrier / 1e9:.4g} GHz)")
    if bandwidth < MIN_BANDWIDTH_HZ:
        return (f"{given('bandwidth', bandwidth, 'Hz')}, under the 1 MHz minimum (a range "
                f"bin c/(2B) of {SPEED_OF_LIGHT / (2 * bandwidth):.3g} m resolves nothing)")
    lo, hi = CHIRP_TIME_RANGE_S
    if chirp_time < lo:
        return (f"{given('chirp_time', chirp_time, 's')}, under the 1 ns minimum (a chirp "
                "shorter than the round trip of 15 cm)")
    if chirp_time > hi:
        return (f"{given('chirp_time', chirp_time, 's')}, over the 1 s maximum (the scene "
                "is traced at one instant: a chirp lasts microseconds)")
    return None


def beam_intensity_problem(intensity, name: str = "fmcw_beam_intensity") -> str | None:
    """What is wrong with a collimated beam's radiant intensity (W/sr), else None: not
    a finite number > 0, or too large for the float32 spectra."""
    if isinstance(intensity, bool) or not isinstance(intensity, numbers.Real) \
            or not math.isfinite(intensity) or intensity <= 0:
        return f"{name} must be > 0 W/sr, got {intensity!r}"
    if intensity > MAX_BEAM_INTENSITY:
        return (f"{name} must be at most {MAX_BEAM_INTENSITY:.4g} W/sr (float32's "
                f"largest number: the spectra would overflow), got {intensity:g}")
    return None
