"""Mitsuba 3 XML scenes with D-ToF extensions.

What this loader adds to Mitsuba's own:

* ``<default>`` values and ``-D`` overrides are resolved here, so that animation
  keyframes may use them too; an override of an undeclared, unused name is an error.
* the files it ``<include>``s are read into the description (:mod:`.includes`), so that
  its unit, room-light and motion handling reach them as the rest.
* ``<integrator type="dopplertof">`` (alias ``dopplertofpath``) parameters are parsed
  into :class:`RenderParams`.
* ``<sampler type="correlated">`` (the published sampler) becomes Mitsuba's
  ``independent`` sampler; its ``time_correlate_number``, ``path_correlate_number``
  and ``use_stratified_sampling_for_each_interval`` become render parameters.
* ``<animation name="to_world">`` on a shape, holding ``<transform time="...">``
  keyframes, moves the shape. Shapes with equal keyframes move as one body. The
  optional attribute ``interpolation`` is ``rigid`` (default) or ``matrix``.
"""

from __future__ import annotations

import copy
import math
import os
import re
import xml.etree.ElementTree as ET
import xml.parsers.expat

import numpy as np

from ..hints import did_you_mean, with_plugin_hint
from .includes import PARAMETER, inline
from .inputs import InputFile, Resolver, file_sha256, xml_inputs
from .meshes import mesh_file_message
from .motion import Keyframes, MotionError
from .room_lights import leave_out
from .scene import (CORRELATED_SAMPLER_PARAMS, DTOF_INTEGRATORS, DTOF_PLUGINS, SHUTTER_NAMES,
                    MotionClaim, SceneDescription, SceneError, build, correlated_sampler_params,
                    mitsuba_load)
from .transforms import TransformError, compose
from .units import in_metres, unit_metres

PROPERTY_TAGS = ("float", "integer", "string", "boolean")
TRANSFORM_OPS = ("matrix", "translate", "rotate", "scale", "lookat")


class _Doc:
    """An element tree that remembers the source line of every element."""

    def __init__(self, text: str, source: str):
        self.source = source
        self.lines: dict[int, int] = {}
        self.overridden: dict[int, list] = {}  #: element id -> [(name, value)] from overrides
        self.sources: dict[int, str] = {}  #: element id -> the included file it comes from
        stack: list[ET.Element] = []
        self.root = None
        parser = xml.parsers.expat.ParserCreate()

        def start(tag, attrs):
            elem = ET.Element(tag, attrs)
            self.lines[id(elem)] = parser.CurrentLineNumber
            if stack:
                stack[-1].append(elem)
            else:
                self.root = elem
            stack.append(elem)

        parser.StartElementHandler = start
        parser.EndElementHandler = lambda tag: stack.pop()
        try:
            parser.Parse(text, True)
        except xml.parsers.expat.ExpatError as e:
            raise SceneError(f"{source}:{e.lineno}: malformed XML: "
                             f"{xml.parsers.expat.ErrorString(e.code)}") from None

    def where(self, elem) -> str:
        line = self.lines.get(id(elem))
        source = self.sources.get(id(elem), self.source)
        return f"{source}:{line}" if line else source

    def adopt(self, part: "_Doc") -> None:
        """Take in the places of an included file's document ``part``."""
        for table, theirs in ((self.lines, part.lines), (self.overridden, part.overridden),
                              (self.sources, part.sources)):
            table.update(theirs)
        for elem in part.root.iter():
            self.sources.setdefault(id(elem), part.source)

    def copy(self, elem):
        """A deep copy of ``elem`` whose elements keep the source lines of the original."""
        twin = copy.deepcopy(elem)
        for a, b in zip(elem.iter(), twin.iter()):
            for table in (self.lines, self.overridden, self.sources):
                if id(a) in table:
                    table[id(b)] = table[id(a)]
        return twin


def _take_defaults(doc: _Doc, values: dict, declared: set, included: bool = False) -> None:
    """Move the ``<default>`` values of ``doc``'s root into ``values`` and their names into
    ``declared``; an ``included`` file's keeps a value already there (an override's, the
    including file's), as Mitsuba does."""
    for el in doc.root.findall("default"):
        if "name" not in el.attrib or "value" not in el.attrib:
            raise SceneError(f"{doc.where(el)}: <default> needs 'name' and 'value'")
        if not (included and el.attrib["name"] in values):
            values[el.attrib["name"]] = el.attrib["value"]
        declared.add(el.attrib["name"])
        doc.root.remove(el)


def _substitute(doc: _Doc, values: dict, overrides: dict, used: set) -> None:
    """Resolve ``$name`` in ``doc`` from ``values``; the names used go to ``used``."""
    for el in doc.root.iter():
        for key, v in el.attrib.items():
            if "$" not in v:
                continue
            used.update(PARAMETER.findall(v))

            def repl(m, el=el):
                if m.group(1) not in values:
                    raise SceneError(f"{doc.where(el)}: undefined parameter ${m.group(1)} "
                                     "(declare it with <default> or pass -D)")
                if m.group(1) in overrides:
                    doc.overridden.setdefault(id(el), []).append(
                        (m.group(1), values[m.group(1)]))
                return values[m.group(1)]

            el.set(key, PARAMETER.sub(repl, v))


def _check_overrides(doc: _Doc, overrides: dict, declared: set, used: set) -> None:
    """An override of a name no ``<default>`` declares and no value uses (a scene
    option, SCENE_OPTIONS, may be given without one) is an error."""
    for name in overrides:
        if name not in declared and name not in used and name not in SCENE_OPTIONS:
            known = ", ".join(sorted(declared)) or "none"
            raise SceneError(f"{doc.source}: unknown scene parameter {name!r}"
                             f"{did_you_mean(name, declared | used)} "
                             f"(declared defaults: {known})")


def _read_in(doc: _Doc, overrides: dict, base_dir: str, resolver: Resolver) -> tuple:
    """``doc`` with its ``<default>`` values and overrides substituted and the files it
    ``<include>``s read in (:func:`.includes.inline`, each substituted as it is read):
    (values, the scene's folders, [(name, path)] of the files included)."""
    values, declared, used = {}, set(), set()
    _take_defaults(doc, values, declared)
    values.update({name: str(value) for name, value in overrides.items()})
    _substitute(doc, values, overrides, used)
    folders = _search_folders(doc, base_dir)

    def read(path):
        try:
            with open(path, encoding="utf-8") as f:
                part = _Doc(f.read(), path)
        except (OSError, UnicodeDecodeError) as e:
            raise SceneError(f"{path}: cannot read the included file: {e}") from None
        if part.root.tag == "scene":
            _take_defaults(part, values, declared, included=True)
        _substitute(part, values, overrides, used)
        doc.adopt(part)
        return part.root

    included = inline(doc.root, values, Resolver(folders + resolver.folders), read,
                      doc.where)
    _check_overrides(doc, overrides, declared, used)
    return values, folders, included


#: the names a scene may be given with -D without declaring them (loader options)
SCENE_OPTIONS = ("unit",)


NUMERIC_TAGS = ("float", "integer", "rgb", "point", "vector", "matrix", "translate", "scale",
                "rotate", "lookat", "spectrum")
NUMERIC_ATTRIBUTES = ("value", "x", "y", "z", "angle", "origin", "target", "up")


def _check_finite(doc: _Doc) -> None:
    """A NaN or infinite number in the scene is an error naming its line."""
    for el in doc.root.iter():
        if el.tag not in NUMERIC_TAGS:
            continue
        for key in NUMERIC_ATTRIBUTES:
            text = el.get(key)
            if text is None:
                continue
            for token in re.split(r"[,\s]+", text.strip()):
                try:
                    number = float(token)
                except ValueError:
                    continue  # not a number: Mitsuba names the problem
                if not math.isfinite(number):
                    name = el.get("name", el.tag)
                    raise SceneError(f"{doc.where(el)}: non-finite value {token!r} in "
                                     f"<{el.tag}> {name!r}")


def _properties(doc: _Doc, elem, allowed_children=()) -> dict:
    """``{name: value-string}`` of an element's property children."""
    out = {}
    for child in elem:
        if child.tag in allowed_children:
            continue
        if child.tag not in PROPERTY_TAGS:
            raise SceneError(f"{doc.where(child)}: unexpected <{child.tag}> inside "
                             f"<{elem.tag} type=\"{elem.get('type')}\">")
        if "name" not in child.attrib or "value" not in child.attrib:
            raise SceneError(f"{doc.where(child)}: <{child.tag}> needs 'name' and 'value'")
        if child.attrib["name"] in out:
            raise SceneError(f"{doc.where(child)}: {child.attrib['name']!r} given twice in "
                             f"<{elem.tag}> (first {out[child.attrib['name']]!r}, then "
                             f"{child.attrib['value']!r}): keep one")
        out[child.attrib["name"]] = child.attrib["value"]
    return out


def _integrator_params(doc: _Doc) -> dict:
    integrators = doc.root.findall("integrator")
    if len(integrators) > 1:
        raise SceneError(f"{doc.where(integrators[1])}: more than one <integrator>")
    if not integrators:
        return {}
    integ = integrators[0]
    if integ.get("type") not in DTOF_INTEGRATORS:  # a stock scene's: the defaults, a note
        doc.root.remove(integ)
        return {}
    values = _properties(doc, integ)
    doc.root.remove(integ)
    return {"__where__": doc.where(integ), **values}


def _sensor(doc: _Doc) -> tuple[dict, ET.Element | None]:
    """Checks the sensor; turns a correlated sampler into an independent one."""
    sensors = doc.root.findall("sensor")
    if len(sensors) > 1:
        raise SceneError(f"{doc.where(sensors[1])}: more than one <sensor>")
    if not sensors:
        raise SceneError(f"{doc.source}: the scene has no <sensor>")
    sensor = sensors[0]
    sampler = sensor.find("sampler")
    if sampler is None or sampler.get("type") != "correlated":
        return {}, sensor
    params = correlated_sampler_params(_properties(doc, sampler), doc.where(sampler))
    for child in list(sampler):
        if child.get("name") in CORRELATED_SAMPLER_PARAMS:
            sampler.remove(child)
    sampler.set("type", "independent")
    return {"__where__": doc.where(sampler), **params}, sensor


def _keyframes(doc: _Doc, shape, anim) -> Keyframes:
    where = doc.where(anim)
    if anim.get("name") != "to_world":
        raise SceneError(f"{where}: only <animation name=\"to_world\"> is supported, "
                         f"got name={anim.get('name')!r}")
    times, mats = [], []
    for kf in anim:
        if kf.tag != "transform":
            raise SceneError(f"{doc.where(kf)}: unexpected <{kf.tag}> in <animation>: "
                             "expected <transform time=\"...\">")
        if "time" not in kf.attrib:
            raise SceneError(f"{doc.where(kf)}: keyframe <transform> needs a 'time'")
        try:
            t = float(kf.attrib["time"])
        except ValueError:
            raise SceneError(f"{doc.where(kf)}: keyframe time {kf.attrib['time']!r} "
                             "is not a number") from None
        ops = []
        for op in kf:
            if op.tag not in TRANSFORM_OPS:
                raise SceneError(f"{doc.where(op)}: unknown transform operation <{op.tag}>")
            ops.append((op.tag, dict(op.attrib), doc.where(op)))
        try:
            mats.append(compose(ops))
        except TransformError as e:
            raise SceneError(str(e)) from None
        times.append(t)
    try:
        return Keyframes.create(times, mats, anim.get("interpolation", "rigid"), where)
    except MotionError as e:
        raise SceneError(str(e)) from None


def _matrix_element(M: np.ndarray) -> ET.Element:
    tr = ET.Element("transform", {"name": "to_world"})
    ET.SubElement(tr, "matrix", {"value": " ".join(repr(float(x)) for x in M.reshape(-1))})
    return tr


def _referenced_ids(elements) -> set:
    return {el.get("id") for e in elements for el in e.iter("ref") if el.get("id")}


def _rest_pose(doc: _Doc, elem, anim, what: str) -> Keyframes:
    """Replace ``anim`` by a to_world transform at the first keyframe; the keyframes."""
    if any(t.get("name") == "to_world" for t in elem.findall("transform")):
        raise SceneError(f"{doc.where(anim)}: a {what} with an <animation> must not also have "
                         "a <transform name=\"to_world\">")
    kf = _keyframes(doc, elem, anim)
    elem.remove(anim)
    elem.insert(0, _matrix_element(kf.matrix_array()[0]))
    return kf


def _split_observers(doc: _Doc, motions: list):
    """Sensor and light motion: (sensor Keyframes or None, [(emitter id, Keyframes | "sensor")]);
    each <animation> found goes to ``motions`` (MotionClaim).

    A moving point or spot light gives its keyframes, or ``follow="sensor"`` on its
    <animation> to move rigidly with the camera (a light on the camera)."""
    root = doc.root
    sensor = root.find("sensor")
    sensor_kf = None
    anims = sensor.findall("animation") if sensor is not None else []
    if len(anims) > 1:
        raise SceneError(f"{doc.where(anims[1])}: the sensor has more than one <animation>")
    if anims:
        motions.append(MotionClaim(doc.where(anims[0]), "sensor", follow=anims[0].get("follow")))
        if not anims[0].get("follow"):  # (a follow is refused by the validation)
            sensor_kf = _rest_pose(doc, sensor, anims[0], "sensor")
    lights = []
    for k, el in enumerate(root.findall("emitter")):
        anims = el.findall("animation")
        if not anims:
            continue
        anim = anims[0]
        if len(anims) > 1:
            raise SceneError(f"{doc.where(anims[1])}: an emitter has more than one <animation>")
        follow = anim.get("follow")
        motions.append(MotionClaim(doc.where(anim), "emitter", el.get("type"), follow,
                                   has_position=any(c.get("name") == "position" for c in el)))
        ident = el.get("id") or f"__dopplertof_light_{k}"
        el.set("id", ident)
        if follow is not None:
            if len(anim) and follow == "sensor":
                raise SceneError(f"{doc.where(anim)}: an <animation follow=\"sensor\"> takes "
                                 "no keyframes")
            el.remove(anim)
            if sensor is not None and el.find("transform") is None:
                # no placement of its own: at the camera's rest pose
                placed = [t for t in sensor.findall("transform") if t.get("name") == "to_world"]
                if placed:
                    el.insert(0, doc.copy(placed[0]))
            if sensor_kf is not None:
                lights.append((ident, "sensor"))
            continue
        lights.append((ident, _rest_pose(doc, el, anim, "light")))
    return sensor_kf, lights


def _split_bodies(doc: _Doc, motions: list):
    """Remove animated shapes from the tree; return [(Keyframes, [(shape element,
    name)])]; each <animation> found goes to ``motions`` (MotionClaim)."""
    root = doc.root
    for el in root.iter("emitter"):
        if el.find("animation") is not None:
            raise SceneError(f"{doc.where(el.find('animation'))}: only top-level point and spot "
                             "lights can move")
    groups: dict[Keyframes, list] = {}
    for shape in list(root.findall("shape")):
        anims = shape.findall("animation")
        if not anims:
            continue
        if len(anims) > 1:
            raise SceneError(f"{doc.where(anims[1])}: a shape has more than one <animation>")
        anim = anims[0]
        motions.append(MotionClaim(doc.where(anim), "shape",
                                   has_area_emitter=shape.find("emitter") is not None))
        body_shape = doc.copy(shape)  # (the copy keeps the lines, for the messages)
        kf = _rest_pose(doc, body_shape, body_shape.find("animation"), "shape")
        groups.setdefault(kf, []).append((body_shape, shape.get("id", "shape")))
        root.remove(shape)
    return list(groups.items())


def _body_document(doc: _Doc, shapes) -> ET.Element:
    """A scene holding the shapes and the top-level objects they reference."""
    root = doc.root
    top = {el.get("id"): el for el in root if el.get("id")}
    body = ET.Element("scene", {"version": root.get("version", "3.0.0")})
    needed, todo = [], list(_referenced_ids(shapes))
    while todo:
        ident = todo.pop()
        if ident in top and top[ident] not in needed:
            needed.append(top[ident])
            todo.extend(_referenced_ids([top[ident]]))
    for el in root:  # keep document order: references must precede use
        if el in needed:
            body.append(doc.copy(el))
    for s in shapes:
        body.append(s)
    return body


def _element_at(doc: _Doc, root: ET.Element, text: str, column: int):
    """The element of ``root`` (serialized as the one line ``text``) that Mitsuba's
    parser names by ``column``, mapped back to the user's file: the last element that
    starts at or before it, else the nearest one before it with a source line."""
    starts = []
    parser = xml.parsers.expat.ParserCreate()
    parser.StartElementHandler = lambda tag, attrs: starts.append(parser.CurrentByteIndex)
    parser.Parse(text.encode("utf-8"), True)
    elements = list(root.iter())
    k = max((i for i, start in enumerate(starts) if start < column), default=0)
    for el in reversed(elements[:k + 1]):
        if id(el) in doc.lines:
            return el
    return None


def _mitsuba_error(doc: _Doc, root: ET.Element, text: str, error: Exception) -> str:
    """Mitsuba's message about a rewritten document, in terms of the user's file."""
    detail = " ".join(str(error).split()) or "load failed"
    detail = re.sub(r"^RuntimeError:\s*", "", detail)
    detail = re.sub(r"\[[\w.]+:\d+\]\s*", "", detail)  # [parser.cpp:451]
    location = r"(?:(?:Error while loading|While loading|At) string\s*)?\(line 1, col (\d+)\):?\s*"
    at = re.search(location, detail)
    detail = with_plugin_hint(re.sub(location, "", detail).strip() or "load failed",
                              DTOF_PLUGINS)
    if not at:
        return f"{doc.source}: {detail}"
    el = _element_at(doc, root, text, int(at.group(1)))
    if el is None:
        return f"{doc.source}: {detail}"
    return f"{doc.where(el)}: {detail}{_origin(doc, el)}"


def _origin(doc: _Doc, el) -> str:
    """"; from -D name=value" when ``el``'s values came from overrides, else ""."""
    given = doc.overridden.get(id(el))
    return ("; from " + ", ".join(f"-D {name}={value}" for name, value in given)
            if given else "")


def _check_film_size(doc: _Doc, sensor) -> None:
    """A film of 0 pixels (Mitsuba accepts one) is an error naming the line."""
    film = sensor.find("film")
    for child in [] if film is None else film.findall("integer"):
        name = child.get("name")
        if name not in ("width", "height", "crop_width", "crop_height"):
            continue
        try:
            value = int(child.get("value", ""))
        except ValueError:
            continue  # not an integer: Mitsuba names the problem
        if value < 1:
            raise SceneError(f"{doc.where(child)}: the film's {name} must be >= 1 pixel, "
                             f"got {value}{_origin(doc, child)}")


def _load_string(mi, doc: _Doc, root: ET.Element, folders):
    """Load ``root`` (the document or a body's) with Mitsuba, relative file names looked
    up in ``folders`` (first first) before Mitsuba's own; errors name the user's file
    and line."""
    resolver = mi.file_resolver()
    before = [resolver[i] for i in range(len(resolver))]
    mine = Resolver(folders)
    for shape in root.iter("shape"):  # ---- mesh files, before Mitsuba reads them
        filename = next((el.get("value") for el in shape.findall("string")
                         if el.get("name") == "filename"), None)
        problem = mesh_file_message(shape.get("type"), filename, mine)
        if problem:
            raise SceneError(f"{doc.where(shape)}: {problem}")
    text = ET.tostring(root, encoding="unicode")
    for folder in reversed(folders):
        resolver.prepend(folder)
    try:
        return mitsuba_load(mi.load_string, text), text
    except Exception as e:  # Mitsuba reports XML problems as RuntimeError
        raise SceneError(_mitsuba_error(doc, root, text, e)) from None
    finally:
        # the resolver as it was: no scene's folder serves the next scene's files
        resolver.clear()
        for folder in before:
            resolver.append(folder)


def _unread_depth(integrator) -> str:
    """`` (its max_depth 3 is not read: -P max_depth=3 gives it)`` for a stock
    integrator that sets one (the D-ToF defaults replace it), else ``""``."""
    depth = next((el.get("value") for el in integrator if el.get("name") == "max_depth"), None)
    return (f" (its max_depth {depth} is not read: -P max_depth={depth} gives it)"
            if depth is not None else "")


def _search_folders(doc: _Doc, base_dir: str) -> tuple:
    """The folders a scene's relative file names are looked up in, first first, as
    stock Mitsuba does for a scene file: each top-level ``<path value=...>`` (relative to
    the scene file's folder ``base_dir``; a later one before an earlier one), then
    ``base_dir``. The ``<path>`` elements leave the document: every part of the scene (a
    moving body's too) is loaded with these folders."""
    paths = []
    for el in doc.root.findall("path"):
        if "value" not in el.attrib:
            raise SceneError(f"{doc.where(el)}: <path> needs a 'value' (a folder)")
        folder = os.path.abspath(os.path.join(base_dir, os.path.expanduser(el.get("value"))))
        if not os.path.isdir(folder):
            raise SceneError(f"{doc.where(el)}: <path> folder {el.get('value')!r} not found "
                             f"(looked for {folder}; a relative one is read from the scene "
                             f"file's folder){_origin(doc, el)}")
        paths.insert(0, folder)
        doc.root.remove(el)
    return tuple(paths) + (os.path.abspath(base_dir),)


def load_string(text: str, overrides: dict | None = None, source: str = "<string>",
                base_dir: str = ".", params: dict | None = None,
                without_room_lights: bool = False):
    """Load a scene from XML text (see :func:`load_file`); ``without_room_lights``:
    its room lights left out (:mod:`.room_lights`; the scene's ``left_out_lights``)."""
    from ..backend import require_variant

    mi = require_variant()
    doc = _Doc(text, source)
    description = describe(doc, overrides, Resolver.of(mi), base_dir, without_room_lights)
    if params:  # (the command's, over the <integrator>'s)
        description.parameters.append(("parameters given", dict(params)))
    return build(mi, description,
                 lambda part, what: _load_string(mi, doc, part, description.folders))


def describe(doc: _Doc, overrides: dict | None = None, resolver: Resolver | None = None,
             base_dir: str = ".", without_room_lights: bool = False) -> SceneDescription:
    """The SceneDescription of an XML document: ``<default>`` values substituted, the
    files it references found (in the scene's folders, :func:`_search_folders`, then
    with ``resolver``, as Mitsuba will), the integrator's
    and the correlated sampler's parameters taken out, the moving bodies split off
    into documents of their own, the camera's and lights' keyframes replaced by their
    rest poses (parts: XML elements); ``without_room_lights``: its room lights left out
    (:func:`.room_lights.leave_out`)."""
    if doc.root.tag != "scene":
        raise SceneError(f"{doc.where(doc.root)}: the root element must be <scene>, "
                         f"got <{doc.root.tag}>")
    values, folders, included = _read_in(doc, dict(overrides or {}), base_dir,
                                         resolver or Resolver(()))
    _check_finite(doc)
    left_out = leave_out(doc.root) if without_room_lights else ()
    if "unit" in values:
        in_metres(doc, unit_metres(values["unit"], doc.source + ": unit"))
    resolver = Resolver(folders + (resolver or Resolver(())).folders)
    inputs = list(dict.fromkeys([InputFile(name, path, file_sha256(path))
                                 for name, path in included]
                                + xml_inputs(doc.root, resolver, folders[-1])))
    other_integrator = next((f"{doc.where(el)}: <integrator type=\"{el.get('type')}\">"
                             + _unread_depth(el) for el in doc.root.findall("integrator")
                             if el.get("type") not in DTOF_INTEGRATORS), None)
    has_integrator = bool(doc.root.findall("integrator")) and other_integrator is None
    integrator = _integrator_params(doc)
    sampler, sensor = _sensor(doc)
    _check_film_size(doc, sensor)
    shutter_given = (doc.where(sensor) if any(child.get("name") in SHUTTER_NAMES
                                             for child in sensor) else None)
    parameters = [(values.pop("__where__"), values) for values in (sampler, integrator)
                  if values]
    motions = []
    sensor_kf, light_kfs = _split_observers(doc, motions)
    bodies = [(kf, [name for _, name in shapes],
               _body_document(doc, [shape for shape, _ in shapes]))
              for kf, shapes in _split_bodies(doc, motions)]
    return SceneDescription(doc.source, doc.root, bodies, parameters,
                            sensor_keyframes=sensor_kf, light_keyframes=light_kfs,
                            motions=motions, has_integrator=has_integrator,
                            shutter_given=shutter_given, inputs=inputs, folders=folders,
                            other_integrator=other_integrator, left_out_lights=left_out)


def load_file(path, overrides: dict | None = None, params: dict | None = None):
    """Load a Mitsuba 3 XML scene with D-ToF extensions.

    ``overrides`` set ``<default>`` values, like ``mitsuba -D name=value``; ``params``
    integrator parameters over the file's (a command's, e.g. the FMCW beam that lights
    a scene without emitters).
    """
    path = os.fspath(path)
    if not os.path.isfile(path):
        raise SceneError(f"scene file not found: {path}")
    try:
        with open(path, encoding="utf-8") as f:
            text = f.read()
    except (OSError, UnicodeDecodeError) as e:
        raise SceneError(f"{path}: cannot read the scene file: {e}") from None
    return load_string(text, overrides, source=path,
                       base_dir=os.path.dirname(os.path.abspath(path)), params=params)
