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

from ..params import ParameterError, RenderParams
from .motion import Keyframes, Motion, MotionError
from .scene import (CORRELATED_SAMPLER_PARAMS, DTOF_INTEGRATORS, MOVABLE_EMITTERS, SceneError,
                    build, check_motion, correlated_sampler_params)

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
    if not isinstance(scene, dict) or scene.get("type") != "scene":
        raise SceneError("<dict>: the scene dict must have \"type\": \"scene\"")
    static = {}
    params = RenderParams()
    integrator_values, sampler_values = {}, {}
    groups: dict[Keyframes, list] = {}
    sensor_kf, light_kfs = None, []
    for key, value in scene.items():
        if not isinstance(value, dict):
            static[key] = value
            continue
        kind = value.get("type")
        if key == "integrator" and kind not in DTOF_INTEGRATORS:
            raise SceneError(f"<dict>[{key!r}]: integrator type {kind!r} is not a D-ToF "
                             "integrator: use \"dopplertof\"")
        if kind in DTOF_INTEGRATORS:
            integrator_values = {k: v for k, v in value.items() if k != "type"}
            continue
        anim = value.get("to_world")
        if isinstance(anim, Animation) and kind in SENSOR_TYPES + MOVABLE_EMITTERS:
            where = f"<dict>[{key!r}]"
            if kind in SENSOR_TYPES:
                check_motion(where, "sensor", follow=anim.follow)
                sensor_kf = anim.to_keyframes(where)
                value = dict(value, to_world=_rest_transform(mi, sensor_kf))
            else:
                check_motion(where, "emitter", kind, anim.follow,
                             has_position="position" in value)
                value = dict(value)
                if anim.follow == "sensor":
                    light_kfs.append((key, "sensor"))
                    value.pop("to_world")  # placed at the camera below
                else:
                    kf = anim.to_keyframes(where)
                    light_kfs.append((key, kf))
                    value["to_world"] = _rest_transform(mi, kf)
            static[key] = _correlated_sampler_replaced(key, value, sampler_values)
            continue
        if isinstance(anim, Animation):
            where = f"<dict>[{key!r}]"
            if kind in ("directional", "area", "envmap", "constant"):  # a light, not a shape
                check_motion(where, "emitter", kind)
            check_motion(where, "shape", has_area_emitter=any(
                isinstance(v, dict) and v.get("type") == "area" for v in value.values()))
            kf = value["to_world"].to_keyframes(where)
            body_shape = dict(value, to_world=_rest_transform(mi, kf))
            groups.setdefault(kf, []).append((key, body_shape))
            continue
        value = _correlated_sampler_replaced(key, value, sampler_values)
        if any(isinstance(v, Animation) for v in value.values()):
            raise SceneError(f"<dict>[{key!r}]: only 'to_world' may be an Animation")
        static[key] = value

    # A light that follows the camera sits at the camera's rest pose.
    sensor_key = next((k for k, v in static.items() if isinstance(v, dict)
                       and v.get("type") in SENSOR_TYPES), None)
    for key, kind in light_kfs:
        if kind == "sensor" and sensor_key is not None and "to_world" in static[sensor_key]:
            static[key] = dict(static[key], to_world=static[sensor_key]["to_world"])

    for values, where in ((sampler_values, "correlated sampler"),
                          (integrator_values, "integrator")):
        if values:
            try:
                params = RenderParams.from_mapping(values, where=f"<dict> {where}", base=params)
            except ParameterError as e:
                raise SceneError(str(e)) from None

    def load(d, what):
        try:
            return mi.load_dict(d)
        except Exception as e:
            lines = [x for x in str(e).strip().splitlines() if x.strip()]
            raise SceneError(f"<dict> {what}: {lines[-1] if lines else 'load failed'}") from None

    static_scene = load(static, "scene")
    from .bodies import MovingBody

    bodies = []
    for kf, shapes in groups.items():
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
        bodies.append(MovingBody(load(body, f"body {[k for k, _ in shapes]}"), Motion(kf),
                                 tuple(k for k, _ in shapes)))
    return build(mi, static_scene, bodies, params, "<dict>",
                 repr(static) + repr(list(groups.items())) + repr((sensor_kf, light_kfs)),
                 sensor_keyframes=sensor_kf, light_keyframes=light_kfs,
                 has_integrator=any(isinstance(v, dict) and v.get("type") in DTOF_INTEGRATORS
                                    for v in scene.values()))


def _correlated_sampler_replaced(key, value: dict, sampler_values: dict) -> dict:
    """The published correlated sampler becomes Mitsuba's independent one; its
    parameters go to ``sampler_values``."""
    sampler = value.get("sampler")
    if not (isinstance(sampler, dict) and sampler.get("type") == "correlated"):
        return value
    sampler_values.update(correlated_sampler_params(
        {k: v for k, v in sampler.items() if k != "type"}, f"<dict>[{key!r}]"))
    plain = {k: v for k, v in sampler.items() if k not in CORRELATED_SAMPLER_PARAMS}
    return dict(value, sampler=dict(plain, type="independent"))
