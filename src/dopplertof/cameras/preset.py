"""Camera presets as data: one TOML file per camera, validated strictly.

A preset says what a real AMCW ToF camera is: its optics (resolution, field of view,
pixel pitch), its raw frame sequence (for each raw frame: modulation frequency, sensor
phase step, integration time, start time within the depth frame), its modulation
(waveform, demodulation contrast), its sensor (quantum efficiency, full well, read noise,
dark current, ADC bits, gain, offset, ambient light) and its own depth reconstruction
(unwrapping over its frequencies, its range, its wiggling calibration, its confidence
threshold). ``docs/cameras.md`` describes the format; the packaged presets live in
``presets/*.toml``, each number with its source in a comment.

Every key is required unless :data:`SCHEMA` gives it a default; an unknown or
misspelt key, a missing key or a value of the wrong type or range is one line naming
the key and the file (:class:`PresetError`, through the package's one TOML validator,
toml_schema.py).
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field

from ..hints import did_you_mean
from ..file_formats import read_toml
from ..modulation import WAVEFORMS
from ..toml_schema import Key, section, table

#: the folder of the packaged presets
PRESET_FOLDER = os.path.join(os.path.dirname(os.path.abspath(__file__)), "presets")

#: an illuminator's narrowest field (deg): below it a field is a beam, or radians
MIN_ILLUMINATOR_FOV_DEG = 5.0
#: a dark pixel's reading must stay this many read-noise deviations (plus one DN of
#: rounding) inside the ADC's range: a reading at either end counts as saturated
DARK_MARGIN_SIGMAS = 5.0

#: unwrapping schemes a preset may name
UNWRAPPING = ("none", "wrap-search")


class PresetError(ValueError):
    """A preset that cannot be used; the message names the file and the key."""


# ---- The schema -----------------------------------------------------------------------

def _positive(x):
    return x > 0


def _non_negative(x):
    return x >= 0


def _fraction(x):
    return 0 < x <= 1


def _finite_list(n, check=None):
    """A list of ``n`` finite numbers (each passing ``check``)."""
    def ok(x):
        return (len(x) == n and all(isinstance(v, (int, float)) and not isinstance(v, bool)
                                    and math.isfinite(v) and (check is None or check(v))
                                    for v in x))
    return ok


def _shutter_list(x):
    """1, then strictly shorter fractions in (0, 1), at most 16."""
    return (1 <= len(x) <= 16 and _finite_list(len(x), _fraction)(x) and x[0] == 1
            and all(a > b for a, b in zip(x, x[1:])))


#: section -> key -> Key (toml_schema.py: kind, meaning, range check, default)
SCHEMA = {
    "": {
        "name": Key("string", "the preset's name"),
        "description": Key("string", "one line"),
        "sources": Key("list", "the documents its numbers come from"),
        "noise_calibration": Key("string", "what its noise is fitted to (a published figure "
                                 "or a measured table); absent: not calibrated", default=""),
        "frame_rate_hz": Key("float", "depth frames per second, the rate of a stream "
                             "(dopplertof animate --camera)", lambda x: 0 < x <= 1e5,
                             default=None),
    },
    "optics": {
        "resolution": Key("list", "[width, height] pixels"),
        "fov_deg": Key("float", "a pinhole's horizontal field of view, 0.1 to 160 degrees "
                       "(a wider lens is no pinhole)", lambda x: 0.1 <= x <= 160),
        "pixel_pitch_um": Key("float", "micrometres, 0.1 to 1000 (sensor pixels are about 1 "
                              "to 100)", lambda x: 0.1 <= x <= 1000),
        "f_number": Key("float", "the lens's f-number N", lambda x: 0.3 <= x <= 64,
                        default=None),
        "transmission": Key("float", "lens and band-pass filter transmission at the "
                            "illuminator's wavelength", _fraction, default=None),
        "filter_width_nm": Key("float", "the band-pass filter's width (nm): the ambient light "
                               "it lets through", lambda x: 0.1 <= x <= 1000, default=None),
        "fill_factor": Key("float", "light-sensitive fraction of a pixel (microlenses "
                           "included)", _fraction, default=None),
        "binning": Key("integer", "pixels summed per side (NFOV binned: 2)",
                       lambda x: 1 <= x <= 8, default=1),
        "distortion": Key("list", "Brown-Conrady [k1, k2, p1, p2, k3] (OpenCV's order)",
                          _finite_list(5, lambda v: abs(v) < 10), default=[0.0] * 5),
    },
    "illuminator": {
        "power_w": Key("float", "mean optical power (W)", lambda x: 0 < x <= 100),
        "wavelength_nm": Key("float", "nm", lambda x: 300 <= x <= 2000),
        "fov_deg": Key("list", f"[horizontal, vertical] full angles lit, degrees, "
                       f"{MIN_ILLUMINATOR_FOV_DEG:g} to 180 (radians are no degrees: 1.31 "
                       "rad = 75 deg)",
                       _finite_list(2, lambda v: MIN_ILLUMINATOR_FOV_DEG <= v < 180)),
        "offset_m": Key("list", "[x, y, z] of the emitter from the lens centre, camera axes "
                        "(m)", _finite_list(3, lambda v: abs(v) < 1)),
    },
    "conditions": {
        "ambient_irradiance_uw_cm2_nm": Key("float", "the maker's ambient light condition "
                                            "(uW/cm^2/nm at the wavelength)",
                                            lambda x: 0 <= x <= 1000, default=0.0),
    },
    "modulation": {
        "waveform": Key("string", "one of " + ", ".join(WAVEFORMS), lambda x: x in WAVEFORMS),
        "contrast": Key("float", "demodulation contrast in [0.01, 1]",
                        lambda x: 0.01 <= x <= 1),
    },
    "sensor": {
        "quantum_efficiency": Key("float", "electrons per photon", _fraction),
        "full_well_electrons": Key("float", "electrons per tap", _positive),
        "read_noise_electrons": Key("float", "electrons rms per tap, 0 to 10000",
                                    lambda x: 0 <= x <= 1e4),
        "dark_current_electrons_per_s": Key("float", "per tap, 0 to 1e9",
                                            lambda x: 0 <= x <= 1e9),
        "adc_bits": Key("integer", "ADC resolution", lambda x: 1 <= x <= 24),
        "gain_electrons_per_dn": Key("float", "electrons per DN, 0.001 to 10000",
                                     lambda x: 1e-3 <= x <= 1e4),
        "offset_dn": Key("float", "DN of a zero differential signal", _non_negative),
        "well_fill": Key("float", "auto photon scale: the brightest unmodulated signal "
                         "fills this fraction of the full well; with several shutters, the "
                         "fill a pixel's shutter keeps it under", _fraction),
        "shutters": Key("list", "the dynamic-range scheme: fractions of each frame's "
                        "integration, longest first, from 1 (each pixel integrates for the "
                        "longest that keeps its taps under well_fill of the well); [1.0]: "
                        "one shutter", _shutter_list, default=[1.0]),
        "ambient_photons_per_s": Key("float", "per pixel (auto exposure only: an absolute "
                                     "preset takes the ambient irradiance)", _non_negative),
        "auto_exposure": Key("bool", "true: the photon scale is chosen per capture "
                             "(well_fill); false: absolute radiometry from the [illuminator] "
                             "and the optics", default=True),
    },
    "reconstruction": {
        "unwrapping": Key("string", "one of " + ", ".join(UNWRAPPING),
                          lambda x: x in UNWRAPPING),
        "max_range_m": Key("float", "the range the camera reports (m)",
                           lambda x: 0.05 <= x <= 1e4),
        "min_range_m": Key("float", "the nearest depth the camera reports (m)",
                           lambda x: 0 <= x < 1e4, default=0.0),
        "min_snr": Key("float", "invalid below this amplitude-to-noise ratio",
                       lambda x: 0 <= x <= 1e3, default=0.0),
        "edge_range_m": Key("float", "edge filter: invalid where the 3 x 3 neighbourhood's "
                            "depths span more (0: off)", lambda x: 0 <= x <= 1e3, default=0.0),
        "wiggling_calibration": Key("bool", "whether the camera removes the wiggling error "
                                    "with a calibration table"),
        "min_amplitude_dn": Key("float", "confidence threshold", _non_negative),
    },
    "frames": {
        "frequency_mhz": Key("float", "modulation frequency, 0.1 to 2000 MHz",
                             lambda x: 0.1 <= x <= 2000),
        "phase_deg": Key("float", "sensor phase step"),
        "integration_s": Key("float", "integration time, 0.1 us to 1 s",
                             lambda x: 1e-7 <= x <= 1),
        "start_s": Key("float", "start within the depth frame", lambda x: 0 <= x <= 10),
        "hetero_frequency": Key("float", "beat periods per integration (0: homodyne)",
                                default=0.0),
    },
}
#: the optics keys absolute radiometry needs
RADIOMETRIC_OPTICS = ("f_number", "transmission", "filter_width_nm", "fill_factor")


@dataclass(frozen=True)
class RawFrame:
    """One raw frame of the sequence."""

    frequency_mhz: float
    phase_deg: float
    integration_s: float
    start_s: float
    hetero_frequency: float = 0.0

    @property
    def homodyne(self) -> bool:
        return self.hetero_frequency == 0.0

    @property
    def offset(self) -> float:
        """The sensor offset in periods (the renderer's hetero_offset)."""
        return self.phase_deg / 360.0


@dataclass(frozen=True)
class CameraPreset:
    """A camera: the sections of its TOML file, checked."""

    name: str
    description: str
    sources: tuple
    source_file: str
    resolution: tuple  #: (width, height)
    fov_deg: float
    pixel_pitch_um: float
    waveform: str
    contrast: float
    sensor: dict  #: the [sensor] section
    reconstruction: dict  #: the [reconstruction] section
    frames: tuple  #: RawFrame, in read-out order
    optics: dict = None  #: the [optics] section (radiometry, binning, distortion)
    illuminator: dict | None = None  #: the [illuminator] section (None: auto exposure)
    conditions: dict = None  #: the [conditions] section (the maker's ambient light)
    noise_calibration: str = ""  #: what its noise is fitted to ("": not calibrated)
    #: ((section, key, comment), ...): the comments :func:`write_preset` gives these keys
    #: beyond those of ``source_file`` (a calibration's fitted lines)
    comments: tuple = field(default=(), compare=False)
    frame_rate_hz: float | None = None  #: depth frames per second (None: not given)

    @property
    def absolute(self) -> bool:
        """Whether photons follow from the illuminator and optics (no auto exposure)."""
        return not self.sensor["auto_exposure"]

    @property
    def distortion(self) -> tuple:
        """(k1, k2, p1, p2, k3), OpenCV's order."""
        return tuple((self.optics or {}).get("distortion", (0.0,) * 5))

    @property
    def default_ambient(self) -> float:
        """The maker's ambient irradiance condition, uW/cm^2/nm (0 when not given)."""
        return float((self.conditions or {}).get("ambient_irradiance_uw_cm2_nm", 0.0))

    @property
    def frequencies_mhz(self) -> tuple:
        """The homodyne frames' distinct frequencies, in order of first appearance."""
        return tuple(dict.fromkeys(f.frequency_mhz for f in self.frames if f.homodyne))

    @property
    def heterodyne(self) -> bool:
        return any(not f.homodyne for f in self.frames)

    @property
    def exposure(self) -> str:
        """How a capture's photons are scaled, for summary.json's noise.exposure."""
        if self.absolute:
            return ("absolute: photons from the illuminator's power, the lens and the pixel"
                    + (" (a shutter per pixel: sensor.shutters)"
                       if len(self.sensor["shutters"]) > 1 else ""))
        return ("auto: every capture scaled so that its brightest pixel fills "
                "sensor.well_fill of the well, whatever the distance, albedo and ambient "
                "light: the noise is relative, not the camera's")

    @property
    def noise_calibrated(self) -> bool:
        """Whether its noise is fitted to a published figure or a measured table: an
        absolute preset with ``noise_calibration`` (an auto-exposed one's noise is
        relative whatever its file says: the loader refuses the key there)."""
        return self.absolute and bool(self.noise_calibration)

    @property
    def noise_source(self) -> str:
        """What its noise is fitted to, or why it is not the camera's."""
        if self.noise_calibrated:
            return self.noise_calibration
        if not self.absolute:
            return ("not calibrated: auto exposure scales every capture so that its "
                    "brightest pixel fills the well (sensor.well_fill): the noise is "
                    "relative, not the camera's (dopplertof cameras NAME --calibrate "
                    "TABLE.csv fits it to measurements)")
        return ("not calibrated: absolute radiometry from the preset's inferred constants, "
                "not fitted to a measured noise figure")

    def uncalibrated_note(self) -> str | None:
        """The line a capture prints when its noise is not the camera's, else None."""
        if self.noise_calibrated:
            return None
        if not self.absolute:
            return (f"{self.name} is auto-exposed: its noise is relative, not the camera's "
                    "(each capture fills the well at its brightest pixel); dopplertof "
                    f"cameras {self.name} --calibrate TABLE.csv -o MINE.toml fits it to "
                    "measurements")
        return (f"{self.name}'s noise comes from inferred constants, not calibrated to a "
                "measured figure (no noise_calibration in its file)")

    def describe(self) -> dict:
        """Every value, for summaries and ``dopplertof cameras NAME``."""
        return {"name": self.name, "description": self.description,
                "sources": list(self.sources), "file": self.source_file,
                "noise_calibrated": self.noise_calibrated, "noise_source": self.noise_source,
                **({"frame_rate_hz": self.frame_rate_hz} if self.frame_rate_hz else {}),
                "optics": {"resolution": list(self.resolution), "fov_deg": self.fov_deg,
                           "pixel_pitch_um": self.pixel_pitch_um},
                "modulation": {"waveform": self.waveform, "contrast": self.contrast},
                "sensor": dict(self.sensor), "reconstruction": dict(self.reconstruction),
                "frames": [vars(f).copy() for f in self.frames],
                **({"illuminator": dict(self.illuminator)} if self.illuminator else {}),
                **({"optics_radiometry": {k: v for k, v in self.optics.items()
                                          if k not in ("resolution", "fov_deg",
                                                       "pixel_pitch_um")}}
                   if self.optics else {}),
                **({"conditions": dict(self.conditions)} if self.conditions else {})}


# ---- Loading -------------------------------------------------------------------------

def preset_names() -> list:
    """The packaged presets' names, sorted."""
    return sorted(n[:-5] for n in os.listdir(PRESET_FOLDER) if n.endswith(".toml"))


def preset_path(name_or_path) -> str:
    """The file of a packaged preset's name, or ``name_or_path`` when it is a TOML file."""
    if not isinstance(name_or_path, (str, os.PathLike)):
        raise TypeError(f"camera preset: a packaged preset's name or a path to a .toml "
                        f"file, got {name_or_path!r}")
    text = os.fspath(name_or_path)
    if not isinstance(text, str):
        raise TypeError(f"camera preset: a path must be text, got {name_or_path!r}")
    if text.endswith(".toml") or os.sep in text:
        if not os.path.isfile(text):
            raise PresetError(f"camera preset file not found: {text}")
        return text
    if text not in preset_names():
        raise PresetError(f"unknown camera {text!r}{did_you_mean(text, preset_names())} "
                          f"(known: {', '.join(preset_names())}; or a path to a .toml file)")
    return os.path.join(PRESET_FOLDER, f"{text}.toml")


def load_preset(name_or_path) -> CameraPreset:
    """A packaged preset by name, or a user's preset file (.toml), checked."""
    path = preset_path(name_or_path)
    return _preset_from(read_toml(path, PresetError), path)


def _preset_from(data: dict, path: str) -> CameraPreset:
    """The checked preset of a parsed TOML document."""
    def checked(values, name, label=None, extra=()):
        return section(values, SCHEMA[name], path, PresetError,
                       name if label is None else label, extra)

    top = checked(data, "", extra=("optics", "modulation", "sensor", "reconstruction",
                                   "frames", "illuminator", "conditions"))
    sections = {name: checked(table(data, name, path, PresetError), name)
                for name in ("optics", "modulation", "sensor", "reconstruction")}
    illuminator = (None if "illuminator" not in data else
                   checked(table(data, "illuminator", path, PresetError), "illuminator"))
    conditions = checked(table(data, "conditions", path, PresetError, required=False),
                         "conditions")
    frames = data.get("frames")
    if not isinstance(frames, list) or not frames:
        raise PresetError(f"{path}: frames: a non-empty array of raw frames is required "
                          "([[frames]] tables)")
    for i, frame in enumerate(frames):
        if not isinstance(frame, dict):
            raise PresetError(f"{path}: frames[{i}] must be a table ([[frames]]), got "
                              f"{frame!r}")
    raw = tuple(RawFrame(**checked(f, "frames", f"frames[{i}]")) for i, f in enumerate(frames))
    optics = sections["optics"]
    resolution = _resolution(optics["resolution"], path)
    _check_sources(top["sources"], path)
    preset = CameraPreset(top["name"], top["description"], tuple(top["sources"]), path,
                          resolution, optics["fov_deg"], optics["pixel_pitch_um"],
                          sections["modulation"]["waveform"], sections["modulation"]["contrast"],
                          sections["sensor"], sections["reconstruction"], raw, optics,
                          illuminator, conditions, top["noise_calibration"],
                          frame_rate_hz=top["frame_rate_hz"])
    _check_radiometry(preset)
    ignored = [f"[{name}]" for name in ("illuminator", "conditions") if name in data]
    ignored += ["noise_calibration"] if "noise_calibration" in data else []
    if ignored and not preset.absolute:
        raise PresetError(f"{path}: {' and '.join(ignored)} would be ignored: "
                          "sensor.auto_exposure = true chooses the photon scale per capture "
                          "(set it false for absolute radiometry, or remove "
                          f"{'them' if len(ignored) > 1 else 'it'})")
    _check_ranges(preset)
    _check_sequence(preset)
    if preset.frame_rate_hz is not None:
        problem = sequence_too_long(preset, preset.frame_rate_hz)
        if problem:
            raise PresetError(f"{path}: frame_rate_hz = {preset.frame_rate_hz:g}: {problem}")
    return preset


def sequence_window(preset: CameraPreset) -> tuple:
    """(first start, last end) of the raw frames within the depth frame (s)."""
    return (min(f.start_s for f in preset.frames),
            max(f.start_s + f.integration_s for f in preset.frames))


def sequence_too_long(preset: CameraPreset, fps: float) -> str | None:
    """Why ``preset``'s raw frame sequence does not fit in a depth frame at ``fps``
    frames per second (its first start to its last end longer than 1 / fps), else
    None."""
    first, last = sequence_window(preset)
    if last - first <= 1.0 / fps:
        return None
    return (f"{preset.name}'s raw frame sequence lasts {(last - first) * 1e3:.6g} ms, longer "
            f"than a depth frame at {fps:g} fps ({1e3 / fps:.6g} ms): the frames would "
            f"overlap (at most {1.0 / (last - first):.6g} fps)")


def _resolution(value, path: str) -> tuple:
    if (len(value) != 2 or not all(isinstance(v, int) and not isinstance(v, bool) and v > 0
                                   for v in value)):
        raise PresetError(f"{path}: optics.resolution must be [width, height] in pixels, "
                          f"got {value!r}")
    return int(value[0]), int(value[1])


def _check_sources(sources, path: str) -> None:
    if not sources or not all(isinstance(s, str) and s.strip() for s in sources):
        raise PresetError(f"{path}: sources must be a non-empty list of citations")


def _check_radiometry(preset: CameraPreset) -> None:
    """An absolute preset (auto_exposure = false) needs its illuminator and optics; the
    ADC's offset must lie inside its range."""
    path, sensor = preset.source_file, preset.sensor
    top = (1 << sensor["adc_bits"]) - 1
    if sensor["offset_dn"] >= top:
        raise PresetError(f"{path}: sensor.offset_dn = {sensor['offset_dn']:g} is past the "
                          f"{sensor['adc_bits']}-bit ADC's largest value {top}")
    margin = DARK_MARGIN_SIGMAS * sensor["read_noise_electrons"] / sensor["gain_electrons_per_dn"] + 1
    if not margin <= sensor["offset_dn"] <= top - margin:
        raise PresetError(f"{path}: sensor.offset_dn = {sensor['offset_dn']:g} leaves a pixel "
                          f"without signal saturated: it must lie {margin:.3g} DN "
                          f"({DARK_MARGIN_SIGMAS:g} read-noise deviations and a DN) inside "
                          f"the {sensor['adc_bits']}-bit ADC's 0 to {top}")
    if not preset.absolute:
        return
    if preset.illuminator is None:
        raise PresetError(f"{path}: sensor.auto_exposure = false needs an [illuminator] "
                          "section (power_w, wavelength_nm, fov_deg, offset_m)")
    for key in RADIOMETRIC_OPTICS:
        if preset.optics.get(key) is None:
            meaning = SCHEMA["optics"][key].meaning
            raise PresetError(f"{path}: missing key optics.{key} ({meaning}; "
                              "sensor.auto_exposure = false needs it)")


def _check_ranges(preset: CameraPreset) -> None:
    """The reconstruction's range is an interval; the lens distortion can be inverted
    over the image (integrators/camera.py, LensDistortion.problem)."""
    path, r = preset.source_file, preset.reconstruction
    if r["min_range_m"] >= r["max_range_m"]:
        raise PresetError(f"{path}: reconstruction.min_range_m = {r['min_range_m']:g} is not "
                          f"below reconstruction.max_range_m = {r['max_range_m']:g}: no depth "
                          "could be reported")
    if any(preset.distortion):
        from ..integrators.camera import LensDistortion

        width, height = preset.resolution
        problem = LensDistortion(preset.distortion, width, height,
                                 preset.fov_deg).problem(width, height)
        if problem:
            raise PresetError(f"{path}: optics.distortion = {list(preset.distortion)}: "
                              f"{problem}")


def _check_sequence(preset: CameraPreset) -> None:
    """What the reconstruction needs of the frames: three phase steps per frequency,
    integer beat counts, unwrapping only with two frequencies or more."""
    path = preset.source_file
    # the beat counts first: a half beat makes its frame heterodyne and takes it from its
    # frequency's phase steps
    for i, fr in enumerate(preset.frames):
        if abs(fr.hetero_frequency - round(fr.hetero_frequency)) > 1e-9:
            raise PresetError(f"{path}: frames[{i}].hetero_frequency must be an integer "
                              f"number of beat periods, got {fr.hetero_frequency:g}")
    for f in preset.frequencies_mhz:
        steps = {round(fr.phase_deg % 360.0, 9) for fr in preset.frames
                 if fr.homodyne and fr.frequency_mhz == f}
        if len(steps) < 3:
            raise PresetError(f"{path}: frames: {f:g} MHz has {len(steps)} distinct phase "
                              "step(s); depth needs at least 3")
        condition = _phase_condition(sorted(steps))
        if condition > 20:
            raise PresetError(f"{path}: frames: the phase steps of {f:g} MHz "
                              f"({', '.join(f'{x:g}' for x in sorted(steps))} deg) are too close "
                              f"together to give a phase (condition number {condition:.3g}; "
                              "spread them over the period, e.g. 0, 120, 240)")
    if not preset.frequencies_mhz:
        raise PresetError(f"{path}: frames: no homodyne frame (hetero_frequency = 0)")
    _check_heterodyne(preset)
    n = len(preset.frequencies_mhz)
    scheme = preset.reconstruction["unwrapping"]
    if (scheme == "wrap-search") != (n >= 2):
        raise PresetError(f"{path}: reconstruction.unwrapping = {scheme!r} does not fit "
                          f"{n} modulation frequenc{'y' if n == 1 else 'ies'} "
                          "('wrap-search' needs two or more, 'none' one)")


def _check_heterodyne(preset: CameraPreset) -> None:
    """Heterodyne frames give velocity as dopplertof's capture does (docs/camera.md): at
    phase steps 0 and 90 deg, one frequency and beat count and integration time, beside
    homodyne frames at 0, 90, 180 and 270 deg of that frequency and integration time."""
    hetero = [f for f in preset.frames if not f.homodyne]
    if not hetero:
        return
    first = hetero[0]
    fail = (f"{preset.source_file}: frames: heterodyne frames give velocity only as "
            "dopplertof's capture takes them: phase steps 0 and 90 deg at one frequency, "
            "beat count and integration time, beside homodyne frames at 0, 90, 180 and "
            "270 deg of the same frequency and integration time")
    same = [(f.frequency_mhz, f.hetero_frequency, f.integration_s) for f in hetero]
    if len(set(same)) != 1 or sorted(f.phase_deg for f in hetero) != [0.0, 90.0]:
        raise PresetError(fail)
    steps = {f.phase_deg for f in preset.frames if f.homodyne and f.frequency_mhz ==
             first.frequency_mhz and f.integration_s == first.integration_s}
    if not {0.0, 90.0, 180.0, 270.0} <= steps:
        raise PresetError(fail)


def _phase_condition(steps_deg) -> float:
    """The condition number of the N-phase fit's design matrix [1, cos, sin] (3 equally
    spaced steps: 1.41)."""
    a = [[1.0, math.cos(math.radians(x)), math.sin(math.radians(x))] for x in steps_deg]
    import numpy as np

    values = np.linalg.svd(np.array(a), compute_uv=False)
    return float(values[0] / values[-1]) if values[-1] > 0 else math.inf


def format_preset(preset: CameraPreset) -> str:
    """What ``dopplertof cameras NAME`` prints."""
    s, r = preset.sensor, preset.reconstruction
    w, h = preset.resolution
    lines = [f"{preset.name}: {preset.description}", f"  file: {preset.source_file}",
             f"  optics: {w}x{h} pixels, {preset.fov_deg:g} deg horizontal field of view, "
             f"{preset.pixel_pitch_um:g} um pixels",
             f"  modulation: {preset.waveform}, demodulation contrast {preset.contrast:g}",
             f"  sensor: QE {s['quantum_efficiency']:g}, full well "
             f"{s['full_well_electrons']:g} e-, read noise {s['read_noise_electrons']:g} e-, "
             f"dark current {s['dark_current_electrons_per_s']:g} e-/s, {s['adc_bits']} bits at "
             f"{s['gain_electrons_per_dn']:g} e-/DN, offset {s['offset_dn']:g} DN, ambient "
             f"{s['ambient_photons_per_s']:g} photons/s"
             + (f", {len(s['shutters'])} shutters per pixel from 1 to {s['shutters'][-1]:g} "
                f"of each frame (under {s['well_fill']:g} of the well)"
                if len(s["shutters"]) > 1 else ""),
             f"  reconstruction: unwrapping {r['unwrapping']}, range {r['max_range_m']:g} m, "
             f"wiggling calibration {'on' if r['wiggling_calibration'] else 'off'}, "
             f"confidence above {r['min_amplitude_dn']:g} DN",
             f"  raw frames ({len(preset.frames)}):"]
    for i, f in enumerate(preset.frames):
        kind = "homodyne" if f.homodyne else f"heterodyne h={f.hetero_frequency:g}"
        lines.append(f"    {i}: {f.frequency_mhz:g} MHz, phase {f.phase_deg:g} deg, "
                     f"{f.integration_s * 1e6:g} us from {f.start_s * 1e6:g} us, {kind}")
    lines.append("  sources: " + "; ".join(preset.sources))
    return "\n".join(lines)


# ---- Writing -------------------------------------------------------------------------

#: the sections of a preset file, in the packaged presets' order ([[frames]] last)
SECTIONS = ("optics", "illuminator", "conditions", "modulation", "sensor", "reconstruction")
