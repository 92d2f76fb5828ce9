"""Room light in a scene description: the lights a ToF camera's demodulation rejects.

A ToF camera sees only its own modulated light. A stock scene's area lights (an
``<emitter type="area">`` nested in a ``<shape>``), its environment (``envmap``,
``constant``) and its directional lights light the room, unmodulated: the sensor's
demodulation cancels them except for their shot noise, which the camera's ambient
irradiance models. Through an absolute camera preset they are left out of the modulated
render (:func:`leave_out`, before Mitsuba loads the description); a shape that carried an
area light stays as a surface (its BSDF, or Mitsuba's default). Point and spot lights
(and projectors) are not room light: they stand for the camera's illuminator.
"""

from __future__ import annotations

import re

#: the emitter types that are room light
ROOM_LIGHT_TYPES = ("area", "envmap", "constant", "directional")


def room_lights(root, values: dict | None = None) -> list:
    """(parent, emitter) of every room light of an XML scene's root element: the
    top-level emitters of ROOM_LIGHT_TYPES, those nested in a top-level shape and a
    shape's ``<ref>`` to a top-level one. ``values``: the scene's parameters ({name:
    value}, its ``<default>`` values and the -D ones) where its ``$name`` values are not
    substituted yet (an emitter ``type="$light"``)."""
    found = [(parent, emitter) for parent in [root, *root.findall("shape")]
             for emitter in parent.findall("emitter")
             if _type(emitter, values or {}) in ROOM_LIGHT_TYPES]
    ids = {emitter.get("id") for parent, emitter in found if parent is root} - {None}
    return found + [(shape, ref) for shape in root.findall("shape")
                    for ref in shape.findall("ref") if ref.get("id") in ids]


def _type(emitter, values: dict) -> str | None:
    return _substituted(emitter.get("type"), values)


def _substituted(text, values: dict):
    """``text`` with its ``$name`` parts replaced by ``values``' (those missing left as
    they are: the loader names them)."""
    return text and re.sub(r"\$(\w+)", lambda m: str(values.get(m.group(1), m.group(0))),
                           text)


def has_other_light(root, values: dict | None = None, folder: str = ".") -> bool:
    """Whether an XML scene's root element, or a file it ``<include>``s (directly or
    through another; a relative name read from the including file's ``folder``), holds
    an emitter that is not room light (:func:`room_lights`; ``values`` as there). A file
    that cannot be read counts for nothing here: the loader names it."""
    import os
    import xml.etree.ElementTree as ET

    todo, read = [(root, folder)], 0
    while todo and read <= 64:  # (a file that includes itself: read a bounded number)
        element, where = todo.pop()
        room = {id(emitter) for _, emitter in room_lights(element, values)}
        if any(id(emitter) not in room for emitter in element.iter("emitter")):
            return True
        for include in element.iter("include"):
            path = os.path.join(where, os.path.expanduser(
                _substituted(include.get("filename") or "", values or {})))
            read += 1
            try:
                todo.append((ET.parse(path).getroot(), os.path.dirname(path)))
            except (OSError, ET.ParseError):
                continue
    return False


def _named(emitter, parent, root) -> str:
    """``the area light of shape 'light'``, ``the area light of an obj shape``, ``the
    envmap 'sky'``, ``a constant emitter``."""
    kind = emitter.get("type") + (" light" if emitter.get("type") == "area" else "")
    if parent is not root:
        article = "an" if str(parent.get("type"))[:1] in "aeiou" else "a"
        shape = (f"shape {parent.get('id')!r}" if parent.get("id")
                 else f"{article} {parent.get('type')} shape")
        return f"the {kind} of {shape}"
    return f"the {kind} {emitter.get('id')!r}" if emitter.get("id") else f"a {kind} emitter"


def leave_out(root) -> tuple:
    """Remove every room light (:func:`room_lights`) from the XML scene's ``root`` in
    place; what was left out, one string each."""
    left = []
    for parent, emitter in room_lights(root):
        if emitter.tag == "emitter":  # (a <ref> to one goes with it, unnamed)
            left.append(_named(emitter, parent, root))
        parent.remove(emitter)
    return tuple(left)
