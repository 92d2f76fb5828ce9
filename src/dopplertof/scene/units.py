"""Scene units: a scene written in another length unit than metres (``-D unit=mm`` or
``<default name="unit" value="mm"/>``), placed in metres as its XML is read. The
document (``doc``) is the XML loader's: its ``root`` element, and ``where(element)``
naming a place in the file for a message."""

from __future__ import annotations

import math
import re
import xml.etree.ElementTree as ET

from ..hints import did_you_mean
from .scene import CAMERA_ILLUMINATOR_ID, SceneError


#: the scene's length unit (``-D unit=mm`` or ``<default name="unit" value="mm"/>``): its
#: name, or a number, to metres per scene unit
UNITS = {"m": 1.0, "dm": 0.1, "cm": 0.01, "mm": 0.001, "um": 1e-6, "km": 1000.0,
         "in": 0.0254, "ft": 0.3048}
#: the sensor's lengths (scene units), scaled to metres with its position
SENSOR_LENGTHS = ("near_clip", "far_clip", "focus_distance")


def unit_metres(text: str, where: str) -> float:
    """Metres per scene unit of a ``unit`` value: a name of UNITS or a positive number."""
    if text in UNITS:
        return UNITS[text]
    try:
        value = float(text)
    except ValueError:
        value = float("nan")
    if not (math.isfinite(value) and value > 0):
        raise SceneError(f"{where}: unknown unit {text!r}{did_you_mean(text, UNITS)} (known: "
                         f"{', '.join(UNITS)}; or metres per scene unit, a positive number)")
    return value


def _placements(el):
    """An element's ``<transform name="to_world">`` and its animation's keyframes."""
    found = [t for t in el.findall("transform") if t.get("name") == "to_world"]
    for anim in el.findall("animation"):
        found += anim.findall("transform")
    return found


def in_metres(doc, metres: float) -> None:
    """The scene, written in units of ``metres`` m, placed in metres: every top-level
    shape's to_world (and keyframes) scaled (S M), the sensor's and lights' placements
    moved, not scaled (S M S^-1: their positions, and the sensor's near and far clip, in
    metres; orientations kept), a point light's position scaled. Velocities follow
    from the keyframes. The lights give the radiance stock Mitsuba renders of the scene
    as written: an area light's, an environment's or a directional light's does not
    depend on the unit, a point, spot or projector light's irradiance falls as
    I / r^2 with r in scene units, so its intensity is scaled by metres^2
    (:func:`_scale_intensity`). A preset's illuminator (CAMERA_ILLUMINATOR_ID) keeps its
    offset from the camera and its intensity, which are in metres."""
    if metres == 1.0:
        return
    scale = {"value": repr(metres)}
    inverse = {"value": repr(1.0 / metres)}
    for el in doc.root:
        if el.tag == "shape" and el.get("type") != "shapegroup":
            placements = _placements(el)
            if not placements:
                placements = [ET.Element("transform", {"name": "to_world"})]
                el.insert(0, placements[0])
            for t in placements:
                t.append(ET.Element("scale", scale))
        elif el.tag in ("sensor", "emitter"):
            after = 1 if el.get("id") == CAMERA_ILLUMINATOR_ID else 0  # (its offset first)
            for t in _placements(el):
                t.insert(min(after, len(t)), ET.Element("scale", inverse))
                t.append(ET.Element("scale", scale))
            if el.tag == "emitter" and el.get("id") != CAMERA_ILLUMINATOR_ID:
                _scale_intensity(doc, el, metres ** 2)
            for child in el:
                if child.tag == "point" and child.get("name") == "position":
                    _scale_numbers(child, ("x", "y", "z", "value"), metres)
                elif child.tag == "float" and child.get("name") in SENSOR_LENGTHS \
                        and el.tag == "sensor":
                    _scale_numbers(child, ("value",), metres)


#: emitters whose irradiance falls as 1 / r^2 from a point: the property scaled by a
#: scene's unit squared (a projector's ``scale`` multiplies its irradiance at unit distance)
INVERSE_SQUARE_EMITTERS = {"point": "intensity", "spot": "intensity", "projector": "scale"}


def _scale_intensity(doc, el, factor: float) -> None:
    """A point, spot or projector light's intensity times ``factor`` (metres^2 per scene
    unit^2: the same irradiance I / r^2 at the same scene distance); a value it cannot
    scale (a spectrum file) is one line naming it."""
    name = INVERSE_SQUARE_EMITTERS.get(el.get("type"))
    if name is None:
        return
    found = [c for c in el if c.get("name") == name]
    if not found:  # (Mitsuba's default: 1, white)
        el.append(ET.Element("float", {"name": name, "value": repr(factor)}))
        return
    child = found[0]
    if child.tag not in ("float", "rgb", "spectrum") or "value" not in child.attrib:
        raise SceneError(f"{doc.where(child)}: the {el.get('type')} light's '{name}' "
                         f"(<{child.tag}>) cannot be scaled to metres (-D unit): its "
                         f"irradiance falls as 1 / r^2; write it as values and multiply them "
                         f"by {factor:g} yourself, without -D unit")
    # a spectrum's "wavelength:value" pairs keep their wavelengths
    child.set("value", ", ".join(
        (f"{token.split(':')[0]}:{float(token.split(':')[1]) * factor!r}" if ":" in token
         else repr(float(token) * factor))
        for token in re.split(r"[,\s]+", child.get("value").strip()) if token))


def _scale_numbers(el, keys, factor: float) -> None:
    """The numbers of ``el``'s attributes ``keys`` times ``factor``."""
    for key in keys:
        if key in el.attrib:
            el.set(key, ", ".join(repr(float(v) * factor)
                                  for v in re.split(r"[,\s]+", el.get(key).strip()) if v))
