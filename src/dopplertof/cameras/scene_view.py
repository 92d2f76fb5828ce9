"""A scene file seen through a camera: its sensor's film and field of view set to a
preset's (or the preset's field of view taken from the scene's framing), the preset's
illuminator added where the scene has no light, and a note when the framing changes."""

from __future__ import annotations

import os

import numpy as np

from ..tof.capture import CaptureError
from . import radiometry
from .preset import CameraPreset


def scene_text_for_camera(text: str, width: int, height: int, fov_deg: float,
                          source: str) -> str:
    """The scene XML with its (single, top-level) sensor's film size and horizontal
    field of view set to the camera's."""
    from ..scene.sensor_text import set_sensor_properties

    return set_sensor_properties(
        text, [("sensor", "float", "fov", repr(float(fov_deg))),
               ("sensor", "string", "fov_axis", "x"), ("film", "integer", "width", int(width)),
               ("film", "integer", "height", int(height))],
        source, "a camera preset", CaptureError)


def with_illuminator(text: str, preset: CameraPreset, view=None, defines=None,
                     folder: str = ".") -> str:
    """The scene XML with the camera's illuminator (:func:`radiometry.illuminator_xml`,
    confined to its field where ``view``, the (tan_x, tan_y) of the view's half extents,
    reaches past it; default the preset's view) added when it has no light but room
    light (:mod:`dopplertof.scene.room_lights`, which the loader leaves out through an
    absolute preset; a scene's own point and spot lights stand for it otherwise): at the
    preset's offset from the lens, riding with the camera (a keyframed camera's: placed
    at its first keyframe, whose pose the loader takes for the rest pose). The offset is
    in OpenCV's camera axes (x right, y down, z forward); Mitsuba's camera has x left and
    y up, so the light is translated by (-x, -y, z) in the camera's frame. ``defines``:
    the -D values, with the scene's ``<default>`` ones, that an emitter's ``$name`` type
    takes (as the loader substitutes them); ``folder``: the scene file's, where the files
    it ``<include>`` are read (their lights count too)."""
    import xml.etree.ElementTree as ET

    from ..scene.room_lights import has_other_light
    from ..scene.sensor_text import parse_scene_text, scene_text

    root = parse_scene_text(text, "the scene", CaptureError)
    values = {el.get("name"): el.get("value") for el in root.findall("default")}
    if has_other_light(root, {**values, **(defines or {})}, folder):
        return text
    light = ET.fromstring(radiometry.illuminator_xml(preset, view))
    sensor = root.find("sensor")
    placed = next((t for t in sensor.findall("transform") if t.get("name") == "to_world"),
                  None) if sensor is not None else None
    moving = sensor.find("animation") if sensor is not None else None
    if placed is None and moving is not None:  # the first keyframe: the camera's rest pose
        placed = moving.find("transform")  # (the light rides on: follow="sensor")
    transform = light.find("transform")
    if placed is not None:
        for step in placed:  # after the offset: the camera's own placement
            transform.append(step)
    root.append(light)
    return scene_text(root, text)


def parse_resolution(text: str) -> tuple:
    """``WIDTHxHEIGHT`` as (width, height), or a CaptureError naming --res."""
    try:
        width, height = (int(v) for v in str(text).lower().split("x"))
    except ValueError:
        raise CaptureError(f"--res must be WIDTHxHEIGHT (e.g. 64x53), got {text!r}") from None
    if width < 1 or height < 1:
        raise CaptureError(f"--res must be positive, got {text!r}")
    return width, height


def scene_view_note(text: str, preset: CameraPreset, source: str) -> str | None:
    """A note when the preset's field of view replaces the one the scene's sensor gives
    (its framing is lost), None when they agree or the text has no single sensor."""
    import xml.etree.ElementTree as ET

    try:
        sensors = [el for el in ET.fromstring(text) if el.tag == "sensor"]
    except ET.ParseError:
        return None  # the loader names the problem
    if len(sensors) != 1:
        return None
    given = {el.get("name"): el.get("value") for el in sensors[0]
             if el.get("name") in ("fov", "fov_axis", "focal_length")}
    axis = given.get("fov_axis") or "x"
    if "fov" in given:
        try:
            if axis == "x" and float(given["fov"]) == preset.fov_deg:
                return None
        except ValueError:
            pass  # a $name: say what is written
        said = f"fov {given['fov']}" + (f", fov_axis {axis}" if axis != "x" else "")
    else:
        said = f"focal_length {given.get('focal_length', '50mm')}"
    return (f"{source}: the camera preset {preset.name}'s {preset.fov_deg:g} degree "
            f"horizontal field of view replaces the scene's sensor's ({said}): the framing "
            "differs from the scene's; --keep-view keeps the scene's view with the preset's "
            "sensor")


def film_define_note(text: str, defines, preset: CameraPreset, source: str) -> str | None:
    """A note when a ``-D`` value sets the scene's film size (``width="$res"``), which
    the preset's pixels replace: ``--res`` sets the camera's. None otherwise."""
    import xml.etree.ElementTree as ET

    from ..scene.includes import PARAMETER

    try:
        films = [film for sensor in ET.fromstring(text) if sensor.tag == "sensor"
                 for film in sensor if film.tag == "film"]
    except ET.ParseError:
        return None  # the loader names the problem
    names = {m for film in films for el in film if el.get("name") in ("width", "height")
             for m in PARAMETER.findall(el.get("value") or "")}
    given = sorted(n for n in names if n in (defines or {}))
    if not given:
        return None
    said = ", ".join(f"-D {n}={defines[n]}" for n in given)
    width, height = preset.resolution
    return (f"{source}: {said} sets the scene's film, which the camera preset "
            f"{preset.name}'s {width}x{height} pixels replace: --res WIDTHxHEIGHT sets the "
            "camera's pixel count (the same field of view)")


def _scene_text(path) -> str:
    with open(path, encoding="utf-8") as f:
        return f.read()


def preset_with_scene_view(path, preset: CameraPreset, resolution=None,
                           defines=None) -> CameraPreset:
    """``preset`` with the horizontal field of view that the scene file ``path``'s
    sensor has on the preset's pixels (or ``resolution``): the scene's framing, the
    preset's sensor (its pixels, pitch and radiometry; a shorter or longer focal
    length)."""
    from dataclasses import replace

    import mitsuba as mi

    from ..scene import load_string
    from ..scene.sensor_text import set_sensor_properties

    width, height = resolution or preset.resolution
    text = set_sensor_properties(_scene_text(path),
                                 [("film", "integer", "width", int(width)),
                                  ("film", "integer", "height", int(height))],
                                 os.fspath(path), "a camera preset", CaptureError)
    if preset.absolute:
        text = with_illuminator(text, preset, defines=defines,
                                folder=os.path.dirname(os.path.abspath(path)))
    scene = load_string(text, dict(defines or {}), source=os.fspath(path),
                        base_dir=os.path.dirname(os.path.abspath(path)),
                        without_room_lights=preset.absolute)
    fov = mi.traverse(scene.sensor).get("x_fov")
    if fov is None:
        raise CaptureError(f"{path}: --keep-view needs a perspective sensor (a field of "
                           "view), the scene's has none")
    fov = float(np.asarray(fov).reshape(-1)[0])
    if not 0.1 <= fov <= 160:
        raise CaptureError(f"{path}: --keep-view: the scene's horizontal field of view "
                           f"{fov:g} degrees is outside a preset's 0.1 to 160")
    return replace(preset, fov_deg=fov)


def load_scene_for_camera(path, preset: CameraPreset, resolution=None, defines=None,
                          keep_view: bool = False, camera_keyframes=None):
    """The scene file ``path`` with the camera's field of view and resolution (or
    ``resolution`` = (width, height): the same field of view, other pixels); a note
    (``scene.notes``) when that field of view replaces the scene's, unless
    ``keep_view`` (``preset`` is :func:`preset_with_scene_view`'s: the scene's view).
    ``camera_keyframes``: :class:`dopplertof.scene.motion.Keyframes` of the sensor's
    to_world that replace its placement (a trajectory's,
    :meth:`dopplertof.scene.trajectory.Trajectory.keyframes`). Through an absolute
    preset the scene's room lights are left out (:mod:`dopplertof.scene.room_lights`),
    with a note naming them, and where no light remains the preset's illuminator
    lights it (:func:`with_illuminator`)."""
    from dataclasses import replace

    from ..scene import load_string
    from ..scene.sensor_text import set_sensor_keyframes

    text = _scene_text(path)
    note = None if keep_view else scene_view_note(text, preset, os.fspath(path))
    film = None if resolution else film_define_note(text, defines, preset, os.fspath(path))
    width, height = resolution or preset.resolution
    text = scene_text_for_camera(text, width, height, preset.fov_deg, os.fspath(path))
    if camera_keyframes is not None:
        text = set_sensor_keyframes(text, camera_keyframes, os.fspath(path), "a trajectory",
                                    CaptureError)
    if preset.absolute:
        text = with_illuminator(text, preset,
                                radiometry.view_tangents(preset.fov_deg, width, height),
                                defines, os.path.dirname(os.path.abspath(path)))
    scene = load_string(text, dict(defines or {}), source=os.fspath(path),
                        base_dir=os.path.dirname(os.path.abspath(path)),
                        without_room_lights=preset.absolute)
    notes = tuple(n for n in (note, film, room_light_note(scene, preset)) if n)
    return replace(scene, notes=scene.notes + notes) if notes else scene


def room_light_note(scene, preset: CameraPreset) -> str | None:
    """The one line naming the room lights the loader left out of ``scene`` (its
    ``left_out_lights``) through ``preset`` and why; None when it left out none."""
    if not scene.left_out_lights:
        return None
    return (f"{scene.source}: room light left out of the render through {preset.name}, "
            f"which sees only its own modulated light: {', '.join(scene.left_out_lights)}; "
            "the sensor's demodulation rejects room light but for its shot noise: give its "
            f"level with --ambient-irradiance (uW/cm^2/nm; {preset.name}'s default "
            f"{preset.default_ambient:g})")
