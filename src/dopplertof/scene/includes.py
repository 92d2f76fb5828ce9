"""Mitsuba's ``<include filename="..."/>`` read into the scene description.

The loader reads what a scene includes into its own description (:func:`inline`) before
it converts the scene's unit, leaves out room light or adds a camera's illuminator, so
that an included shape, light or sensor is placed in metres, left out or counted as an
inline one is. It follows Mitsuba's parser: a relative name is looked up in the including
file's folder first (the scene file's folders for the scene file's own includes), then
where Mitsuba looks up files; an included ``<scene>``'s children take the ``<include>``'s
place, another root element (a ``<bsdf>``, say) takes it whole, with the ``<include>``'s
``name``; includes nest up to Mitsuba's depth; ``$name`` values reach included files.
"""

from __future__ import annotations

import os
import re

from .inputs import Resolver
from .scene import SceneError

#: nested ``<include>`` files followed at most this deep (Mitsuba refuses deeper ones)
MAX_INCLUDE_DEPTH = 15
#: a ``$name`` reference to a scene parameter (a ``<default>`` or -D value)
PARAMETER = re.compile(r"\$(\w+)")


def substituted(text, values: dict):
    """``text`` with its ``$name`` parts replaced by ``values``' (those missing left as
    they are: the loader names them)."""
    return text and PARAMETER.sub(lambda m: str(values.get(m.group(1), m.group(0))), text)


def parsed(path: str):
    """The root element of the XML file ``path``; a SceneError naming it when it cannot be
    read."""
    import xml.etree.ElementTree as ET

    try:
        return ET.parse(path).getroot()
    except (OSError, UnicodeDecodeError, ET.ParseError) as e:
        raise SceneError(f"{path}: cannot read the included file: {e}") from None


def inline(element, values: dict, resolver: Resolver, read=parsed,
           where=lambda el: "the scene", folder: str | None = None, depth: int = 0) -> list:
    """Replace every ``<include>`` in ``element``'s tree, in place, by what the file holds
    (nested ones too): ``values`` fill a ``$name`` file name, ``resolver`` finds a
    relative one (after the including file's ``folder``; None for the scene file itself),
    ``read(path)`` gives a file's root element, ``where(el)`` names an element's place
    for a message. The (name as written, path) of each file included, in document
    order; a file that is missing, unreadable, without a version or nested too deep is
    a SceneError naming it and the ``<include>``."""
    found, k = [], 0
    while k < len(element):
        child = element[k]
        if child.tag != "include":
            found += inline(child, values, resolver, read, where, folder, depth)
            k += 1
            continue
        name, path = _resolved(child, values, resolver, where, folder, depth)
        included = read(path)
        if included.get("version") is None:
            raise SceneError(f"{path}: the root element <{included.tag}> of a file "
                             f"{where(child)} includes has no 'version' (Mitsuba needs one, "
                             "e.g. <scene version=\"3.0.0\">)")
        found.append((name, path))
        found += inline(included, values, resolver, read, where, os.path.dirname(path),
                        depth + 1)
        if included.tag == "scene":
            parts = list(included)
        else:
            parts = [included]
            included.attrib.pop("version")
            if child.get("name"):
                included.set("name", child.get("name"))
        element[k:k + 1] = parts
        k += len(parts)
    return found


def _resolved(include, values: dict, resolver: Resolver, where, folder, depth: int) -> tuple:
    """(name as written, path) of the file an ``<include>`` names."""
    name = substituted(include.get("filename"), values)
    if not name:
        raise SceneError(f"{where(include)}: <include> needs a 'filename'")
    if depth >= MAX_INCLUDE_DEPTH:
        raise SceneError(f"{where(include)}: <include> of {name!r} nested more than "
                         f"{MAX_INCLUDE_DEPTH} files deep (Mitsuba's limit): does a file "
                         "include itself?")
    path = (resolver.inside(folder) if folder else resolver).resolve(
        os.path.expanduser(name))
    if not os.path.isfile(path):
        looked = ", ".join(dict.fromkeys(([folder] if folder else []) + list(resolver.folders)))
        raise SceneError(f"{where(include)}: included file {name!r} not found (looked in "
                         f"{looked}: a relative name is read from the including file's "
                         "folder, then the scene's)")
    return name, path
