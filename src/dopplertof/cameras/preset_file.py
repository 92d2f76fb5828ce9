"""Writing a camera preset's file: its TOML document, each key with the comment its
source file gives it (or a calibration's), written atomically so that it loads back to
the same camera (preset.py reads and checks preset files)."""

from __future__ import annotations

import math
import os

from .preset import SCHEMA, SECTIONS, CameraPreset, PresetError, _preset_from


def preset_document(preset: CameraPreset) -> dict:
    """The TOML document of ``preset``: :func:`load_preset` reads it back to an equal
    preset (keys without a value, such as an auto-exposed preset's optics f_number,
    left out)."""
    doc = {"name": preset.name, "description": preset.description,
           "sources": list(preset.sources)}
    if preset.noise_calibration:
        doc["noise_calibration"] = preset.noise_calibration
    if preset.frame_rate_hz:
        doc["frame_rate_hz"] = preset.frame_rate_hz
    optics = {k: v for k, v in (preset.optics or {}).items() if v is not None}
    optics.update(resolution=list(preset.resolution), fov_deg=preset.fov_deg,
                  pixel_pitch_um=preset.pixel_pitch_um)
    doc["optics"] = {k: optics[k] for k in SCHEMA["optics"] if k in optics}
    if preset.illuminator is not None:
        doc["illuminator"] = dict(preset.illuminator)
    if preset.absolute:
        doc["conditions"] = dict(preset.conditions or {})
    doc["modulation"] = {"waveform": preset.waveform, "contrast": preset.contrast}
    doc["sensor"] = dict(preset.sensor)
    doc["reconstruction"] = dict(preset.reconstruction)
    doc["frames"] = [vars(f).copy() for f in preset.frames]
    return doc


def toml_value(value) -> str:
    """One TOML value: a string (JSON's escapes are TOML's), a bool, a number (floats
    as Python's shortest repr, which reads back bitwise), a list of them."""
    import json

    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, (int, float)):
        if isinstance(value, float) and not math.isfinite(value):
            raise ValueError(f"a TOML preset holds finite numbers, got {value!r}")
        return repr(value)
    if isinstance(value, str):
        return json.dumps(value)
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(toml_value(v) for v in value) + "]"
    raise TypeError(f"no TOML value for {value!r}")


def preset_comments(path) -> dict:
    """{(section, key): comment} of the ``key = value  # comment`` lines of a preset file
    (the top-level keys' under section "", [[frames]] left out); {} when ``path`` is no
    readable file."""
    import re

    try:
        with open(path, encoding="utf-8") as f:
            lines = f.read().splitlines()
    except (OSError, TypeError, UnicodeDecodeError):
        return {}
    pattern = re.compile(r'\s*([A-Za-z_][A-Za-z0-9_]*)\s*=\s*("[^"#]*"|[^"#]*?)\s+#\s?(.*)$')
    section, found = "", {}
    for line in lines:
        header = re.match(r"\s*\[+\s*([A-Za-z_]+)\s*\]+", line)
        if header:
            section = header.group(1)
            continue
        match = pattern.match(line)
        if match and section in SCHEMA and section != "frames":
            found[(section, match.group(1))] = match.group(3)
    return found


def format_preset_toml(preset: CameraPreset) -> str:
    """The text of ``preset``'s file: its document (:func:`preset_document`), each key
    with the comment its source file gives it, or ``preset.comments``."""
    doc = preset_document(preset)
    comments = preset_comments(preset.source_file)
    comments.update({(s, k): c for s, k, c in preset.comments})
    lines = [f"# {preset.name}: {preset.description}",
             f"# written by dopplertof (cameras.write_preset) from {preset.source_file};",
             "# the comments say where each value comes from (docs/cameras.md)."]
    top = ("name", "description", "sources", "noise_calibration", "frame_rate_hz")
    lines += [f"{k} = {toml_value(doc[k])}" + (f"  # {comments[('', k)]}"
                                                 if ("", k) in comments else "")
              for k in top if k in doc]
    for section in SECTIONS:
        if section not in doc:
            continue
        lines += ["", f"[{section}]"]
        for key, value in doc[section].items():
            note = comments.get((section, key))
            lines.append(f"{key} = {toml_value(value)}" + (f"  # {note}" if note else ""))
    for frame in doc["frames"]:
        lines.append("[[frames]]")
        lines += [f"{key} = {toml_value(value)}" for key, value in frame.items()]
    return "\n".join(lines) + "\n"


def write_preset(preset: CameraPreset, path) -> str:
    """Write ``preset`` as a preset file (.toml) that :func:`load_preset` reads back to
    the same camera, atomically (a failed write leaves no file and an earlier one
    whole); returns the path."""
    from .. import io

    path = os.fspath(path)
    if not path.lower().endswith(".toml"):
        raise PresetError(f"a preset file ends in .toml, got {path!r}")
    if os.path.isdir(path):
        raise PresetError(f"{path}: is a folder, not a preset file")
    text = format_preset_toml(preset)
    _preset_from(_parse_toml(text, path), path)  # what is written loads
    with io.atomic_path(path) as tmp:
        with open(tmp, "w", encoding="utf-8") as f:
            f.write(text)
    return path


def _parse_toml(text: str, path: str) -> dict:
    try:  # Python 3.11+
        import tomllib
    except ModuleNotFoundError:  # pragma: no cover - Python < 3.11
        import tomli as tomllib
    return tomllib.loads(text)
