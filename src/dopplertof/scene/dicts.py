"""Python dict scenes (Mitsuba's ``load_dict`` format) with D-ToF extensions.

The same extensions as the XML loader, said in Python:

    {
      "type": "scene",
      "integrator": {"type": "dopplertof", "hetero_frequency": 1.0},
      "sensor": {"type": "perspective", ..., "sampler": {"type": "correlated", "sample_count": 64}},
      "box": {"type": "cube", "bsdf": {"type": "ref", "id": "white"},
              "to_world": dopplertof.Animation([(0.0, T0), (0.0015, T1)])},
    }

Keyframe transforms may be ``mi.ScalarTransform4f`` or 4x4 arrays.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..hints import with_plugin_hint
from .meshes import mesh_file_message
from .inputs import Resolver, dict_inputs
from .motion import Keyframes, MotionError
from .scene import (CORRELATED_SAMPLER_PARAMS, DTOF_INTEGRATORS, DTOF_PLUGINS, MOVABLE_EMITTERS,
                    SHUTTER_NAMES, MotionClaim, SceneDescription, SceneError, build,
                    correlated_sampler_params, mitsuba_load)

SENSOR_TYPES = ("perspective", "thinlens", "orthographic")


@dataclass(frozen=True)
class Animation:
    """Keyframed ``to_world`` of a shape: ``[(time_s, transform), ...]``."""

    keyframes: tuple
    interpolation: str = "rigid"
    follow: str | None = None

    def __init__(self, keyframes, interpolation: str = "rigid", follow: str | None = None):
        object.__setattr__(self, "keyframes", tuple(keyframes))
        object.__setattr__(self, "interpolation", interpolation)
        object.__setattr__(self, "follow", follow)

    @classmethod
    def follow_sensor(cls) -> "Animation":
        """For a point or spot light: move rigidly with the camera (a light on the camera)."""
        return cls((), follow="sensor")

    def to_keyframes(self, where: str) -> Keyframes:
        times, mats = [], []
        for item in self.keyframes:
            try:
                t, T = item
            except (TypeError, ValueError):
                raise SceneError(f"{where}: keyframes must be (time, transform) pairs") from None
            times.append(t)
            mats.append(_matrix(T, where))
        try:
            return Keyframes.create(times, mats, self.interpolation, where)
        except MotionError as e:
            raise SceneError(str(e)) from None


def _matrix(T, where) -> np.ndarray:
    M = getattr(T, "matrix", T)
    try:
        M = np.array(M, dtype=np.float64)
    except (TypeError, ValueError):
        raise SceneError(f"{where}: a keyframe transform must be a 4x4 matrix or "
                         f"mi.ScalarTransform4f, got {type(T).__name__}") from None
    if M.shape != (4, 4):
        raise SceneError(f"{where}: a keyframe matrix must be 4x4, got shape {M.shape}")
    return M


def _rest_transform(mi, kf: Keyframes):
    """The transform of the first keyframe: where the object is loaded."""
    return mi.ScalarTransform4f(kf.matrix_array()[0])


def _refs(value) -> set:
    out = set()
    if isinstance(value, dict):
        if value.get("type") == "ref" and "id" in value:
            out.add(value["id"])
        for v in value.values():
            out |= _refs(v)
    return out


def load_dict(scene: dict):
    """Load a dict scene with D-ToF extensions (see the module docstring)."""
    from ..backend import require_variant

    mi = require_variant()
    return build(mi, describe(mi, scene), lambda part, what: (_load(mi, part, what), repr(part)))


def describe(mi, scene: dict) -> SceneDescription:
    """The SceneDescription of a dict scene (parts: dicts for ``mi.load_dict``)."""
    if not isinstance(scene, dict) or scene.get("type") != "scene":
        raise SceneError("<dict>: the scene dict must have \"type\": \"scene\"")
    parts = _DictParts(mi)
    for key, value in scene.items():
        parts.add(key, value)
    parts.place_lights_on_sensor()
    bodies = [(kf, [key for key, _ in shapes], _body_dict(scene, shapes))
              for kf, shapes in parts.groups.items()]
    parameters = [(f"<dict> {where}", values) for values, where in (
        (parts.sampler_values, "correlated sampler"), (parts.integrator_values, "integrator"))
        if values]
    return SceneDescription("<dict>", parts.static, bodies, parameters,
                            sensor_keyframes=parts.sensor_kf, light_keyframes=parts.light_kfs,
                            motions=parts.motions, has_integrator=parts.has_integrator,
                            shutter_given=parts.shutter_given,
                            other_integrator=parts.other_integrator,
                            inputs=dict_inputs(scene, Resolver.of(mi)))


class _DictParts:
    """A dict scene's entries sorted into the description's parts: the static scene,
    the moving bodies' shapes by keyframes, the camera's and lights' keyframes, the
    integrator's and the correlated sampler's parameters."""

    def __init__(self, mi):
        self.mi = mi
        self.static = {}  #: what mi.load_dict loads as the static scene
        self.groups: dict[Keyframes, list] = {}  #: keyframes -> [(key, shape dict)]
        self.sensor_kf, self.light_kfs = None, []
        self.integrator_values, self.sampler_values = {}, {}
        self.has_integrator = False
        self.other_integrator = None  #: where and what a stock integrator is
        self.motions = []  #: MotionClaim of every Animation
        self.shutter_given = None  #: the sensor's key when it gives its shutter

    def add(self, key, value) -> None:
        """Sort one entry of the scene dict."""
        if not isinstance(value, dict):
            self.static[key] = value
            return
        kind = value.get("type")
        if kind in SENSOR_TYPES and any(name in value for name in SHUTTER_NAMES):
            self.shutter_given = f"<dict>[{key!r}]"
        if key == "integrator" and kind not in DTOF_INTEGRATORS:  # the defaults, a note
            self.other_integrator = f"<dict>[{key!r}]: integrator type {kind!r}"
            return
        if kind in DTOF_INTEGRATORS:
            self.integrator_values = {k: v for k, v in value.items() if k != "type"}
            self.has_integrator = True
            return
        anim = value.get("to_world")
        if isinstance(anim, Animation) and kind in SENSOR_TYPES + MOVABLE_EMITTERS:
            self.static[key] = self._sampler_replaced(key, self._observer(key, kind, value, anim))
            return
        if isinstance(anim, Animation):
            self._body(key, kind, value, anim)
            return
        value = self._sampler_replaced(key, value)
        if any(isinstance(v, Animation) for v in value.values()):
            raise SceneError(f"<dict>[{key!r}]: only 'to_world' may be an Animation")
        self.static[key] = value

    def _observer(self, key, kind, value: dict, anim: Animation) -> dict:
        """A moving sensor or light: its keyframes noted, loaded at its rest pose (a
        light that follows the sensor: placed by place_lights_on_sensor)."""
        where = f"<dict>[{key!r}]"
        if kind in SENSOR_TYPES:
            self.motions.append(MotionClaim(where, "sensor", follow=anim.follow))
            if anim.follow:  # (refused when the description is validated)
                return value
            self.sensor_kf = anim.to_keyframes(where)
            return dict(value, to_world=_rest_transform(self.mi, self.sensor_kf))
        self.motions.append(MotionClaim(where, "emitter", kind, anim.follow,
                                        has_position="position" in value))
        value = dict(value)
        if anim.follow is not None:
            self.light_kfs.append((key, "sensor"))
            value.pop("to_world")  # placed at the camera
        else:
            kf = anim.to_keyframes(where)
            self.light_kfs.append((key, kf))
            value["to_world"] = _rest_transform(self.mi, kf)
        return value

    def _body(self, key, kind, value: dict, anim: Animation) -> None:
        """A moving shape: to the body of its keyframes, at its rest pose."""
        where = f"<dict>[{key!r}]"
        if kind in ("directional", "area", "envmap", "constant"):  # a light, not a shape
            self.motions.append(MotionClaim(where, "emitter", kind))
        self.motions.append(MotionClaim(where, "shape", has_area_emitter=any(
            isinstance(v, dict) and v.get("type") == "area" for v in value.values())))
        kf = anim.to_keyframes(where)
        self.groups.setdefault(kf, []).append((key, dict(value, to_world=_rest_transform(
            self.mi, kf))))

    def place_lights_on_sensor(self) -> None:
        """A light that follows the camera sits at the camera's rest pose."""
        sensor_key = next((k for k, v in self.static.items() if isinstance(v, dict)
                           and v.get("type") in SENSOR_TYPES), None)
        for key, kind in self.light_kfs:
            if (kind == "sensor" and sensor_key is not None
                    and "to_world" in self.static[sensor_key]):
                self.static[key] = dict(self.static[key],
                                        to_world=self.static[sensor_key]["to_world"])

    def _sampler_replaced(self, key, value: dict) -> dict:
        """The published correlated sampler becomes Mitsuba's independent one; its
        parameters go to the render parameters."""
        sampler = value.get("sampler")
        if not (isinstance(sampler, dict) and sampler.get("type") == "correlated"):
            return value
        self.sampler_values.update(correlated_sampler_params(
            {k: v for k, v in sampler.items() if k != "type"}, f"<dict>[{key!r}]"))
        plain = {k: v for k, v in sampler.items() if k not in CORRELATED_SAMPLER_PARAMS}
        return dict(value, sampler=dict(plain, type="independent"))


def _body_dict(scene: dict, shapes) -> dict:
    """A scene dict holding a body's shapes and the entries they reference."""
    body = {"type": "scene"}
    todo = set().union(*(_refs(s) for _, s in shapes))
    done = set()
    while todo:
        ident = todo.pop()
        done.add(ident)
        if ident in scene:
            body[ident] = scene[ident]
            todo |= _refs(scene[ident]) - done
    body.update({k: s for k, s in shapes})
    return body


def _load(mi, d: dict, what: str):
    """``mi.load_dict``; its error as a one-line SceneError naming ``what``."""
    for key, shape in d.items():  # ---- mesh files, before Mitsuba reads them
        problem = isinstance(shape, dict) and mesh_file_message(
            shape.get("type"), shape.get("filename"), Resolver.of(mi))
        if problem:
            raise SceneError(f"<dict> {what}: {key!r}: {problem}")
    try:
        return mitsuba_load(mi.load_dict, d)
    except Exception as e:
        lines = [x for x in str(e).strip().splitlines() if x.strip()]
        detail = with_plugin_hint(lines[-1], DTOF_PLUGINS) if lines else "load failed"
        raise SceneError(f"<dict> {what}: {detail}") from None
