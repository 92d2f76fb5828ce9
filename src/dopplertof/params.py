"""Parameters of a D-ToF render: names, types, defaults and the derived quantities.

Names and defaults follow the published implementation (design.md section 1). The same
parser serves the XML ``<integrator>`` and ``<sampler>`` elements, Mitsuba's
``Properties`` (when the plugin is built by Mitsuba itself), Python dicts and ``-D``
style overrides, so that a name means the same everywhere and an unknown name is an
error everywhere.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields, replace

from .hints import unknown_name
from .modulation import FULL_WAVEFORMS, SPEED_OF_LIGHT, WAVEFORMS
from .pixel_sets import PIXEL_SETS
from .sampling import (ANALYTIC, ANTITHETIC_MAPPINGS, CLOSED_FORM,  # noqa: F401
                       FULL_CORRELATION, METHOD_NAMES, auto_sampling)

#: how samples become pixels (integrators/film.py)
FILM_SAMPLINGS = ("splat", "importance")
FILM_NORMALIZATIONS = ("expected", "weights")

#: default exposure in seconds when neither ``time`` nor the sensor's shutter gives one
DEFAULT_EXPOSURE = 0.0015

#: beat periods per exposure of a capture's heterodyne captures when the scene sets no
#: (non-zero) hetero_frequency and the capture is given none (tof.capture)
CAPTURE_HETERO_FREQUENCY = 1.0

#: the modulation frequencies accepted, in MHz (w_g, w_s, capture's unwrap frequency,
#: precision's --w-g): 1 Hz (the radiance capture's constant weight) to 100 GHz, every
#: ToF camera's and far beyond; a value above is a unit mistake (Hz for MHz: w_g=30e6)
#: or not a camera (docs/parameters.md)
FREQUENCY_RANGE_MHZ = (1e-6, 1e5)


def frequency_problem(name: str, mhz: float) -> str | None:
    """Why a modulation frequency in MHz is refused (with a did-you-mean in MHz when it
    reads as Hz), or None."""
    lo, hi = FREQUENCY_RANGE_MHZ
    if lo <= mhz <= hi:
        return None
    if mhz <= 0:
        return f"{name} must be > 0 MHz, got {mhz:g}"
    as_hz = mhz * 1e-6
    hint = (f"{name} is in MHz: did you mean {name}={as_hz:g}? " if lo <= as_hz <= hi
            else "")
    return (f"{hint}{name} must be a modulation frequency in [{lo:g}, {hi:g}] MHz "
            f"(1 Hz to 100 GHz), got {mhz:g}")



class ParameterError(ValueError):
    """A parameter with an unknown name, a wrong type or a value out of range."""


@dataclass(frozen=True)
class RenderParams:
    """Everything that defines a D-ToF measurement and its sampling.

    Frequencies are in MHz and times in seconds, as in the published scenes.
    """

    # ---- Exposure and modulation ----
    time: float | None = None  #: exposure T (s); None: the sensor shutter, else 0.0015
    w_g: float = 30.0  #: illumination modulation frequency f_g (MHz)
    w_s: float | None = None  #: sensor modulation frequency f_s (MHz); default f_g + h / T
    g_0: float = 0.5  #: illumination offset g0
    g_1: float = 0.5  #: illumination amplitude g1
    sensor_phase_offset: float = 0.0  #: psi (radians), used when hetero_offset is not given
    hetero_frequency: float | None = None  #: h: f_s = f_g + h / T (beat periods per exposure)
    hetero_offset: float | None = None  #: o: psi = 2 pi o
    wave_function_type: str = "sinusoidal"
    low_frequency_component_only: bool = True
    # ---- Path tracing ----
    max_depth: int = -1  #: longest path in segments (-1: unbounded)
    rr_depth: int = 5  #: depth at which Russian roulette starts
    hide_emitters: bool = False
    # ---- Time-path sampling ----
    time_sampling_method: str = "auto"
    antithetic_shift: float | None = None  #: default 0.5 (shifted) or 0 (mirrored)
    path_correlation_depth: int = FULL_CORRELATION  #: stages sharing random numbers
    time_correlate_number: int = 2  #: K, samples per correlated group
    #: Kp, consecutive samples sharing one path random stream (None: K), as the
    #: published sampler's ``path_correlate_number``
    path_correlate_number: int | None = None
    use_stratified_sampling_for_each_interval: bool = True
    #: how an antithetic pair's partner is built: "replay" (the primal's random numbers
    #: at the paired time; None means this) or "motion" (the primal's first hit point
    #: followed on its body: integrators/antithetic_map.py)
    antithetic_mapping: str | None = None
    #: samples per pixel set from a pilot pass (the first 1/4), more where the
    #: neighbours vary most, spp on average, unbiased (allocation.py)
    adaptive_sampling: bool = False
    # ---- Film ----
    #: "splat" (each sample weighted into every pixel its filter reaches, as Mitsuba's
    #: film) or "importance" (film positions drawn from the filter, one pixel each)
    film_sampling: str = "splat"
    #: splat film: divide by the sampled "weights" (Mitsuba's ratio estimator; far less
    #: noise on smooth surfaces, bias below measurement) or by the exact "expected"
    #: filter weight (unbiased)
    film_normalization: str = "weights"
    #: "joint": a pixel's film, time and first-hit sets are strata of one scrambled
    #: sequence with its neighbours' (pixel_sets.JointSets); "independent": each pixel's
    #: own
    pixel_sets: str = "independent"
    # ---- Execution (the published integrators' own; none changes the image) ----
    is_doppler_integrator: bool = True  #: no effect: this integrator is a D-ToF one
    block_size: int = 0  #: no effect: the published scalar variants' tile size
    samples_per_pass: int = -1  #: samples per pixel per pass (-1: set by memory)
    timeout: float = -1.0  #: seconds; stop after the pass it expires in (< 0: none)

    # ---- Parsing ----

    @classmethod
    def names(cls) -> tuple[str, ...]:
        return tuple(f.name for f in fields(cls))

    @classmethod
    def from_mapping(cls, values: dict, where: str = "parameters", base=None):
        """Parse ``{name: value}`` (values typed or strings) on top of ``base``."""
        return replace(base or cls(), **cls.coerced(values, where)).validated(where)

    @classmethod
    def coerced(cls, values: dict, where: str = "parameters") -> dict:
        """``{name: value}`` with every name known and every value of its type (strings
        parsed), else a ParameterError; no scene needed (the command line checks its -P
        values with it before Mitsuba loads)."""
        known = cls.names()
        for name in values:
            if name not in known:
                raise ParameterError(f"{where}: {unknown_name('parameter', name, known)}")
        return {name: coerce_parameter(name, value, _TYPES[name], where)
                for name, value in values.items()}

    def validated(self, where: str = "parameters"):
        """These parameters when every value is in range and they agree with each other,
        else a ParameterError prefixed with ``where``. The checks run in a fixed order (by
        topic), so that an input with several problems always reports the same one."""
        for check in (self._modulation_problem, self._time_sampling_problem,
                      self._path_problem, self._execution_problem, self._pairing_problem,
                      self._film_problem, self._motion_mapping_problem):
            problem = check()
            if problem:
                raise ParameterError(f"{where}: {problem}")
        return self

    # ---- Validation, by topic: each returns its first problem, or None ----

    def _modulation_problem(self) -> str | None:
        """Exposure, frequencies, offsets and the waveform."""
        for name in ("w_g", "w_s", "g_0", "g_1", "sensor_phase_offset", "hetero_frequency",
                     "hetero_offset", "antithetic_shift", "time"):
            v = getattr(self, name)
            if v is not None and not math.isfinite(v):
                return f"{name} must be finite, got {v}"
        if self.time is not None and self.time <= 0:
            return f"time (the exposure) must be > 0 seconds, got {self.time}"
        for name in ("w_g", "w_s"):
            problem = getattr(self, name) is not None and frequency_problem(
                name, getattr(self, name))
            if problem:
                return problem
        if self.w_s is not None and self.hetero_frequency is not None:
            return ("give w_s or hetero_frequency, not both (hetero_frequency sets "
                    "w_s = w_g + h / T)")
        if self.wave_function_type not in WAVEFORMS:
            return (f"unknown wave_function_type {self.wave_function_type!r}: expected one of "
                    f"{', '.join(WAVEFORMS)}")
        if not self.low_frequency_component_only and self.wave_function_type not in FULL_WAVEFORMS:
            return (f"wave_function_type {self.wave_function_type!r} pairs a trapezoid sensor "
                    "with a delta illumination and has no full-waveform form; set "
                    "low_frequency_component_only=true")
        return None

    def _time_sampling_problem(self) -> str | None:
        """The time sampling method, and the limits of the published closed form."""
        if self.time_sampling_method not in METHOD_NAMES:
            return (f"unknown time_sampling_method {self.time_sampling_method!r}: expected "
                    f"one of {', '.join(METHOD_NAMES)}")
        method = self.time_sampling_method
        if method in CLOSED_FORM:  # the published closed form's limits
            if self.wave_function_type != "sinusoidal":
                return (f"time_sampling_method {method!r} integrates a sinusoid in closed "
                        "form: it needs wave_function_type 'sinusoidal', got "
                        f"{self.wave_function_type!r}")
            if not self.low_frequency_component_only:
                return (f"time_sampling_method {method!r} integrates the low-pass "
                        "correlation: it needs low_frequency_component_only=true")
        return None

    def _path_problem(self) -> str | None:
        """Path depths and the sizes of the correlated groups."""
        if self.max_depth < -1 or self.max_depth == 0:
            return f"max_depth must be >= 1 or -1 (unbounded), got {self.max_depth}"
        if self.rr_depth < 1:
            return f"rr_depth must be >= 1, got {self.rr_depth}"
        if self.path_correlation_depth < 0:
            return f"path_correlation_depth must be >= 0, got {self.path_correlation_depth}"
        if self.time_correlate_number < 1:
            return f"time_correlate_number must be >= 1, got {self.time_correlate_number}"
        if self.path_correlate_number is not None and self.path_correlate_number < 1:
            return f"path_correlate_number must be >= 1, got {self.path_correlate_number}"
        return None

    def _execution_problem(self) -> str | None:
        """The execution parameters (EXECUTION_PARAMS): tile, pass size and timeout."""
        if self.block_size < 0:
            return f"block_size must be >= 0, got {self.block_size}"
        if self.samples_per_pass == 0 or self.samples_per_pass < -1:
            return ("samples_per_pass must be >= 1 or -1 (automatic), got "
                    f"{self.samples_per_pass}")
        if not math.isfinite(self.timeout):
            return f"timeout must be finite (seconds, -1: none), got {self.timeout}"
        return None

    def _pairing_problem(self) -> str | None:
        """The mirrored pairs' group size and the name of the pair mapping."""
        if (self.time_sampling_method == "antithetic_mirror"
                and self.time_correlate_number != 2):
            return ("time_sampling_method 'antithetic_mirror' pairs samples: it needs "
                    f"time_correlate_number=2, got {self.time_correlate_number}")
        if self.antithetic_mapping not in (None,) + ANTITHETIC_MAPPINGS:
            return (f"unknown antithetic_mapping {self.antithetic_mapping!r}: expected one "
                    f"of {', '.join(ANTITHETIC_MAPPINGS)}")
        return None

    def _film_problem(self) -> str | None:
        """How samples become pixels."""
        if self.film_sampling not in FILM_SAMPLINGS:
            return (f"unknown film_sampling {self.film_sampling!r}: expected one of "
                    f"{', '.join(FILM_SAMPLINGS)}")
        if self.film_normalization not in FILM_NORMALIZATIONS:
            return (f"unknown film_normalization {self.film_normalization!r}: expected one "
                    f"of {', '.join(FILM_NORMALIZATIONS)}")
        if self.pixel_sets not in PIXEL_SETS:
            return (f"unknown pixel_sets {self.pixel_sets!r}: expected one of "
                    f"{', '.join(PIXEL_SETS)}")
        return None

    def _motion_mapping_problem(self) -> str | None:
        """What ``antithetic_mapping="motion"`` needs: pairs that share one path."""
        if self.antithetic_mapping != "motion":
            return None
        method = self.time_sampling_method
        if method not in ("antithetic", "antithetic_mirror"):
            return ("antithetic_mapping 'motion' maps antithetic pairs: it needs "
                    f"time_sampling_method antithetic or antithetic_mirror, got {method!r}")
        if self.time_correlate_number != 2:
            return ("antithetic_mapping 'motion' needs time_correlate_number=2, got "
                    f"{self.time_correlate_number}")
        if method == "antithetic" and self.antithetic_shift not in (None, 0.5):
            return ("antithetic_mapping 'motion' needs pairs that map onto each other: "
                    f"antithetic_shift 0.5, got {self.antithetic_shift}")
        if self.path_correlation_depth < 1:
            return ("antithetic_mapping 'motion' needs the pair to share its film position: "
                    "path_correlation_depth >= 1, got 0")
        if self.path_group_size != 2:
            return ("antithetic_mapping 'motion' maps a pair's shared path: it needs "
                    f"path_correlate_number=2 (the pair), got {self.path_correlate_number}")
        return None

    # ---- Derived quantities ----

    @property
    def path_group_size(self) -> int:
        """Kp: consecutive samples sharing one path random stream."""
        return self.path_correlate_number or self.time_correlate_number

    def image_defining(self) -> "RenderParams":
        """The parameters with the execution ones (which never change an image: pass
        size, timeout, and those without effect) at their defaults."""
        return replace(self, **{f.name: f.default for f in fields(self)
                                if f.name in EXECUTION_PARAMS})

    def resolved(self, shutter: float, sampled: bool = False) -> "RenderParams":
        """The parameters with ``time_sampling_method="auto"`` replaced by its choice
        (which never maps pairs by motion: measured, see docs/benchmarks.md);
        ``sampled``: time sampled in every path (what derivatives need), so never the
        control variate."""
        if self.time_sampling_method != "auto":
            return replace(self, antithetic_mapping=self.antithetic_mapping or "replay")
        h = self.modulation(shutter).hetero_frequency
        closed_form = (not sampled and self.wave_function_type == "sinusoidal"
                       and self.low_frequency_component_only)
        return replace(self, **auto_sampling(h, closed_form))

    def exposure(self, shutter: float) -> float:
        """Exposure T: ``time`` when given, else the sensor's shutter interval, else 0.0015."""
        if self.time is not None:
            return self.time
        return shutter if shutter > 0 else DEFAULT_EXPOSURE

    def modulation(self, shutter: float) -> "Modulation":
        T = self.exposure(shutter)
        f_g = self.w_g * 1e6
        if self.hetero_frequency is not None:
            f_s = f_g + self.hetero_frequency / T
        elif self.w_s is not None:
            f_s = self.w_s * 1e6
        else:
            f_s = f_g
        psi = (2 * math.pi * self.hetero_offset if self.hetero_offset is not None
               else self.sensor_phase_offset)
        shift = self.antithetic_shift
        if shift is None:
            shift = 0.0 if self.time_sampling_method == "antithetic_mirror" else 0.5
        return Modulation(
            exposure=T, omega_g=2 * math.pi * f_g, omega_d=2 * math.pi * (f_s - f_g), psi=psi,
            g0=self.g_0, g1=self.g_1, waveform=self.wave_function_type,
            low_pass=self.low_frequency_component_only, antithetic_shift=shift,
        )


@dataclass(frozen=True)
class Modulation:
    """Derived, SI units: what the integrator evaluates per contribution."""

    exposure: float  #: T (s)
    omega_g: float  #: illumination angular frequency (rad/s)
    omega_d: float  #: omega_s - omega_g (rad/s)
    psi: float  #: sensor phase offset (rad)
    g0: float
    g1: float
    waveform: str
    low_pass: bool
    antithetic_shift: float
    c: float = field(default=SPEED_OF_LIGHT)

    @property
    def omega_s(self) -> float:
        return self.omega_g + self.omega_d

    @property
    def hetero_frequency(self) -> float:
        return self.omega_d * self.exposure / (2 * math.pi)


#: parameters that decide how a render runs, never what it computes
EXECUTION_PARAMS = ("is_doppler_integrator", "block_size", "samples_per_pass", "timeout")

_TYPES = {
    "time": float, "w_g": float, "w_s": float, "g_0": float, "g_1": float,
    "sensor_phase_offset": float, "hetero_frequency": float, "hetero_offset": float,
    "wave_function_type": str, "low_frequency_component_only": bool, "max_depth": int,
    "rr_depth": int, "hide_emitters": bool, "time_sampling_method": str,
    "antithetic_shift": float, "path_correlation_depth": int, "time_correlate_number": int,
    "use_stratified_sampling_for_each_interval": bool, "antithetic_mapping": str,
    "adaptive_sampling": bool, "film_sampling": str, "film_normalization": str,
    "pixel_sets": str,
    "path_correlate_number": int, "is_doppler_integrator": bool, "block_size": int,
    "samples_per_pass": int, "timeout": float,
}
assert set(_TYPES) == set(RenderParams.names())

_TYPE_NAMES = {float: "a number", int: "an integer", str: "a string", bool: "a boolean"}


def coerce_parameter(name, value, typ, where):
    """``value`` (typed, or a string to parse) as a ``typ`` (float, int, str or bool),
    else a ParameterError naming parameter ``name`` (prefixed with ``where``)."""
    def bad():
        return ParameterError(f"{where}: parameter {name!r} must be {_TYPE_NAMES[typ]}, "
                              f"got {value!r}")

    if typ is bool:
        if isinstance(value, bool):
            return value
        if isinstance(value, str) and value.strip().lower() in ("true", "false", "1", "0"):
            return value.strip().lower() in ("true", "1")
        raise bad()
    if typ is str:
        if isinstance(value, str):
            return value.strip()
        raise bad()
    if isinstance(value, bool):
        raise bad()
    if typ is int:
        try:
            f = float(value)
        except (TypeError, ValueError):
            raise bad() from None
        if not math.isfinite(f) or f != int(f):
            raise bad()
        return int(f)
    try:
        f = float(value)
    except (TypeError, ValueError):
        raise bad() from None
    if not math.isfinite(f):
        raise ParameterError(f"{where}: parameter {name!r} must be finite, got {value!r}")
    return f
