"""Edits of a scene file's text before it loads: its one top-level sensor's properties
and film (a camera preset's view and resolution), or its placement replaced by keyframes
(a stream's trajectory)."""

from __future__ import annotations

import re
import xml.etree.ElementTree as ET

from .scene import SceneError


def parse_scene_text(text: str, source: str, error=SceneError):
    """The root element of the scene XML ``text``, its comments kept, so that
    :func:`scene_text` writes every element back on its line of ``text``: an edited
    scene's messages name the lines of the user's file. ``error`` for text that is no
    XML."""
    try:
        return ET.fromstring(text, ET.XMLParser(target=ET.TreeBuilder(insert_comments=True)))
    except ET.ParseError as e:
        raise error(f"{source}: malformed XML: {e}") from None


def scene_text(root, text: str) -> str:
    """``root`` (:func:`parse_scene_text`'s, edited) as XML text whose root element
    starts on the line where it stands in the original ``text`` (the XML declaration
    and the comments before it become blank lines)."""
    start = next(m for m in re.finditer(r"<!--.*?-->|<\?.*?\?>|<!.*?>|<", text, re.S)
                 if m.group(0) == "<")
    return "\n" * text.count("\n", 0, start.start()) + ET.tostring(root, encoding="unicode")


def remove_keeping_lines(parent, child) -> None:
    """Remove ``child`` from ``parent``, leaving as many line breaks as it (and its
    tail) held, so that the elements after it keep their lines."""
    breaks = "\n" * ET.tostring(child, encoding="unicode").count("\n")
    index = list(parent).index(child)
    if index:
        before = parent[index - 1]
        before.tail = (before.tail or "") + breaks
    else:
        parent.text = (parent.text or "") + breaks
    parent.remove(child)


def _one_sensor(text: str, source: str, needed_by: str, error):
    """(root, the one top-level <sensor>) of the scene XML ``text``; ``error`` saying that
    ``needed_by`` needs one otherwise."""
    root = parse_scene_text(text, source, error)
    sensors = [el for el in root if el.tag == "sensor"]
    if len(sensors) != 1:
        raise error(f"{source}: {needed_by} needs exactly one <sensor> at the top level of "
                    f"the scene, found {len(sensors)}")
    return root, sensors[0]


def set_sensor_keyframes(text: str, keyframes, source: str, needed_by: str,
                         error=SceneError) -> str:
    """The scene XML ``text`` with its one top-level sensor moved by ``keyframes``
    (:class:`.motion.Keyframes` of its to_world) instead of its own placement: an
    ``<animation name="to_world">`` of one matrix per keyframe. A sensor that has an
    animation of its own raises ``error`` (two motions of one camera)."""
    root, sensor = _one_sensor(text, source, needed_by, error)
    if sensor.find("animation") is not None:
        raise error(f"{source}: the scene's sensor has an <animation> of its own; "
                    f"{needed_by} moves the camera: remove one of them")
    for placed in [t for t in sensor.findall("transform") if t.get("name") == "to_world"]:
        remove_keeping_lines(sensor, placed)
    animation = ET.Element("animation", {"name": "to_world",
                                         "interpolation": keyframes.interpolation})
    for time, matrix in zip(keyframes.times, keyframes.matrices):
        step = ET.SubElement(animation, "transform", {"time": repr(float(time))})
        ET.SubElement(step, "matrix", {"value": " ".join(repr(float(v)) for row in matrix
                                                         for v in row)})
    sensor.insert(0, animation)
    return scene_text(root, text)


def set_sensor_properties(text: str, values, source: str, needed_by: str,
                          error=SceneError) -> str:
    """The scene XML ``text`` with properties of its one top-level ``<sensor>`` set.

    ``values``: (element, tag, name, value) with element ``"sensor"`` or ``"film"`` (the
    sensor's ``<film>``, an hdrfilm added if it has none): the property ``name`` becomes
    ``<tag name=... value=...>``. A text that is no XML, or without exactly one top-level
    sensor, raises ``error`` saying that ``needed_by`` needs one."""
    root, sensor = _one_sensor(text, source, needed_by, error)
    film = next((c for c in sensor if c.tag == "film"), None)
    for where, tag, name, value in values:
        if where == "film" and film is None:
            film = ET.SubElement(sensor, "film", type="hdrfilm")
        parent = film if where == "film" else sensor
        element = next((c for c in parent if c.get("name") == name), None)
        if element is None:
            element = ET.SubElement(parent, tag, name=name)
        element.tag = tag
        element.set("value", str(value))
    return scene_text(root, text)
