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

from .includes import substituted

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
    return substituted(emitter.get("type"), values)


def has_other_light(root, values: dict | None = None, folder: str = ".") -> bool:
    """Whether an XML scene's root element, with the files it ``<include>``s read in
    (:func:`.includes.inline`; a relative name read from the scene's ``folder``), holds
    an emitter that is not room light (:func:`room_lights`; ``values`` as there). A file
    that cannot be read counts for nothing here: the loader names it."""
    import copy

    from .includes import inline
    from .inputs import Resolver
    from .scene import SceneError

    root = copy.deepcopy(root)
    try:
        inline(root, values or {}, Resolver((folder,)))
    except SceneError:
        pass  # (the loader names it)
    room = {id(emitter) for _, emitter in room_lights(root, values)}
    return any(id(emitter) not in room for emitter in root.iter("emitter"))


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
