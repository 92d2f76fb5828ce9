"""Camera presets as data: one TOML file per camera, validated strictly.

A preset says what a real AMCW ToF camera is: its optics (resolution, field of view,
pixel pitch), its raw frame sequence (for each raw frame: modulation frequency, sensor
phase step, integration time, start time within the depth frame), its modulation
(waveform, demodulation contrast), its sensor (quantum efficiency, full well, read noise,
dark current, ADC bits, gain, offset, ambient light) and its own depth reconstruction
(unwrapping over its frequencies, its range, its wiggling calibration, its confidence
threshold). ``docs/cameras.md`` describes the format; the packaged presets live in
``presets/*.toml``, each number with its source in a comment.

Every key is required unless :data:`OPTIONAL` gives it a default; an unknown or
misspelt key, a missing key or a value of the wrong type or range is one line naming
the key and the file (:class:`PresetError`).
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass

from ..hints import did_you_mean, unknown_key
from ..io import read_toml
from ..modulation import WAVEFORMS

#: the folder of the packaged presets
PRESET_FOLDER = os.path.join(os.path.dirname(os.path.abspath(__file__)), "presets")

#: unwrapping schemes a preset may name
UNWRAPPING = ("none", "wrap-search")


class PresetError(ValueError):
    """A preset that cannot be used; the message names the file and the key."""


# ---- The schema: section -> key -> (type, check, what it means) --------------------------

def _positive(x):
    return x > 0


def _non_negative(x):
    return x >= 0


def _fraction(x):
    return 0 < x <= 1


SCHEMA = {
    "": {"name": (str, None, "the preset's name"),
         "description": (str, None, "one line"),
         "sources": (list, None, "the documents its numbers come from")},
    "optics": {"resolution": (list, None, "[width, height] pixels"),
               "fov_deg": (float, lambda x: 0 < x < 180, "horizontal field of view, degrees"),
               "pixel_pitch_um": (float, _positive, "micrometres")},
    "modulation": {"waveform": (str, lambda x: x in WAVEFORMS, "one of " + ", ".join(WAVEFORMS)),
                   "contrast": (float, _fraction, "demodulation contrast in (0, 1]")},
    "sensor": {"quantum_efficiency": (float, _fraction, "electrons per photon"),
               "full_well_electrons": (float, _positive, "electrons per tap"),
               "read_noise_electrons": (float, _non_negative, "electrons rms per tap"),
               "dark_current_electrons_per_s": (float, _non_negative, "per tap"),
               "adc_bits": (int, lambda x: 1 <= x <= 24, "ADC resolution"),
               "gain_electrons_per_dn": (float, _positive, "electrons per DN"),
               "offset_dn": (float, _non_negative, "DN of a zero differential signal"),
               "well_fill": (float, _fraction, "auto photon scale: the brightest unmodulated "
                             "signal fills this fraction of the full well"),
               "ambient_photons_per_s": (float, _non_negative, "per pixel")},
    "reconstruction": {"unwrapping": (str, lambda x: x in UNWRAPPING,
                                      "one of " + ", ".join(UNWRAPPING)),
                       "max_range_m": (float, _positive, "the range the camera reports"),
                       "wiggling_calibration": (bool, None, "whether the camera removes the "
                                                "wiggling error with a calibration table"),
                       "min_amplitude_dn": (float, _non_negative, "confidence threshold")},
    "frames": {"frequency_mhz": (float, _positive, "modulation frequency"),
               "phase_deg": (float, lambda x: math.isfinite(x), "sensor phase step"),
               "integration_s": (float, _positive, "integration time"),
               "start_s": (float, _non_negative, "start within the depth frame"),
               "hetero_frequency": (float, lambda x: math.isfinite(x),
                                    "beat periods per integration (0: homodyne)")},
}

#: keys with a default
OPTIONAL = {("frames", "hetero_frequency"): 0.0}


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

    @property
    def frequencies_mhz(self) -> tuple:
        """The homodyne frames' distinct frequencies, in order of first appearance."""
        return tuple(dict.fromkeys(f.frequency_mhz for f in self.frames if f.homodyne))

    @property
    def heterodyne(self) -> bool:
        return any(not f.homodyne for f in self.frames)

    def describe(self) -> dict:
        """Every value, for summaries and ``dopplertof cameras NAME``."""
        return {"name": self.name, "description": self.description,
                "sources": list(self.sources), "file": self.source_file,
                "optics": {"resolution": list(self.resolution), "fov_deg": self.fov_deg,
                           "pixel_pitch_um": self.pixel_pitch_um},
                "modulation": {"waveform": self.waveform, "contrast": self.contrast},
                "sensor": dict(self.sensor), "reconstruction": dict(self.reconstruction),
                "frames": [vars(f).copy() for f in self.frames]}


# ---- Loading -------------------------------------------------------------------------

def preset_names() -> list:
    """The packaged presets' names, sorted."""
    return sorted(n[:-5] for n in os.listdir(PRESET_FOLDER) if n.endswith(".toml"))


def preset_path(name_or_path) -> str:
    """The file of a packaged preset's name, or ``name_or_path`` when it is a TOML file."""
    text = os.fspath(name_or_path)
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
    top = _section(data, "", path, extra=("optics", "modulation", "sensor",
                                          "reconstruction", "frames"))
    sections = {name: _section(_table(data, name, path), name, path)
                for name in ("optics", "modulation", "sensor", "reconstruction")}
    frames = data.get("frames")
    if not isinstance(frames, list) or not frames:
        raise PresetError(f"{path}: frames: a non-empty array of raw frames is required "
                          "([[frames]] tables)")
    for i, frame in enumerate(frames):
        if not isinstance(frame, dict):
            raise PresetError(f"{path}: frames[{i}] must be a table ([[frames]]), got "
                              f"{frame!r}")
    raw = tuple(RawFrame(**_section(f, "frames", path, where=f"frames[{i}]"))
                for i, f in enumerate(frames))
    optics = sections["optics"]
    resolution = _resolution(optics["resolution"], path)
    _check_sources(top["sources"], path)
    preset = CameraPreset(top["name"], top["description"], tuple(top["sources"]), path,
                          resolution, optics["fov_deg"], optics["pixel_pitch_um"],
                          sections["modulation"]["waveform"], sections["modulation"]["contrast"],
                          sections["sensor"], sections["reconstruction"], raw)
    _check_sequence(preset)
    return preset


def _table(data: dict, name: str, path: str, where: str | None = None) -> dict:
    value = data.get(name)
    if not isinstance(value, dict):
        what = "missing" if value is None else f"a {type(value).__name__}, not a table"
        raise PresetError(f"{path}: [{where or name}] is {what}")
    return value


def _section(values: dict, section: str, path: str, extra=(), where: str | None = None) -> dict:
    """The keys of one section checked against :data:`SCHEMA` (``extra``: sub-tables
    allowed beside them); defaults filled in."""
    schema = SCHEMA[section]
    label = where or section
    prefix = f"{label}." if label else ""
    problem = unknown_key(values, list(schema) + list(extra), prefix)
    if problem:
        raise PresetError(f"{path}: {problem}")
    out = {}
    for key, (kind, check, meaning) in schema.items():
        if key not in values:
            if (section, key) in OPTIONAL:
                out[key] = OPTIONAL[(section, key)]
                continue
            raise PresetError(f"{path}: missing key {prefix}{key} ({meaning})")
        out[key] = _typed(values[key], kind, check, f"{path}: {prefix}{key}", meaning)
    return out


def _typed(value, kind, check, where: str, meaning: str):
    """``value`` as ``kind`` (an int is a float too; a bool is no number)."""
    if kind is float and isinstance(value, int) and not isinstance(value, bool):
        value = float(value)
    if not isinstance(value, kind) or (kind is not bool and isinstance(value, bool)):
        raise PresetError(f"{where} must be a {kind.__name__} ({meaning}), got {value!r}")
    if kind is float and not math.isfinite(value):
        raise PresetError(f"{where} must be finite, got {value!r}")
    if check is not None and not check(value):
        raise PresetError(f"{where} out of range ({meaning}), got {value!r}")
    return value


def _resolution(value, path: str) -> tuple:
    if (len(value) != 2 or not all(isinstance(v, int) and not isinstance(v, bool) and v > 0
                                   for v in value)):
        raise PresetError(f"{path}: optics.resolution must be [width, height] in pixels, "
                          f"got {value!r}")
    return int(value[0]), int(value[1])


def _check_sources(sources, path: str) -> None:
    if not sources or not all(isinstance(s, str) and s.strip() for s in sources):
        raise PresetError(f"{path}: sources must be a non-empty list of citations")


def _check_sequence(preset: CameraPreset) -> None:
    """What the reconstruction needs of the frames: three phase steps per frequency,
    integer beat counts, unwrapping only with two frequencies or more."""
    path = preset.source_file
    for f in preset.frequencies_mhz:
        steps = {round(fr.phase_deg % 360.0, 9) for fr in preset.frames
                 if fr.homodyne and fr.frequency_mhz == f}
        if len(steps) < 3:
            raise PresetError(f"{path}: frames: {f:g} MHz has {len(steps)} distinct phase "
                              "step(s); depth needs at least 3")
    if not preset.frequencies_mhz:
        raise PresetError(f"{path}: frames: no homodyne frame (hetero_frequency = 0)")
    for i, fr in enumerate(preset.frames):
        if abs(fr.hetero_frequency - round(fr.hetero_frequency)) > 1e-9:
            raise PresetError(f"{path}: frames[{i}].hetero_frequency must be an integer "
                              f"number of beat periods, got {fr.hetero_frequency:g}")
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
             f"{s['ambient_photons_per_s']:g} photons/s",
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
