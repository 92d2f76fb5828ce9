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
from .scene import SceneError, build
from .xml import CORRELATED_SAMPLER_PARAMS, DTOF_INTEGRATORS


@dataclass(frozen=True)
class Animation:
    """Keyframed ``to_world`` of a shape: ``[(time_s, transform), ...]``."""

    keyframes: tuple
    interpolation: str = "rigid"

    def __init__(self, keyframes, interpolation: str = "rigid"):
        object.__setattr__(self, "keyframes", tuple(keyframes))
        object.__setattr__(self, "interpolation", interpolation)

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
        if isinstance(value.get("to_world"), Animation):
            where = f"<dict>[{key!r}]"
            if any(isinstance(v, dict) and v.get("type") == "area" for v in value.values()):
                raise SceneError(f"{where}: moving area emitters are not supported yet")
            kf = value["to_world"].to_keyframes(where)
            body_shape = dict(value, to_world=mi.ScalarTransform4f(kf.matrix_array()[0]))
            groups.setdefault(kf, []).append((key, body_shape))
            continue
        sampler = value.get("sampler")
        if isinstance(sampler, dict) and sampler.get("type") == "correlated":
            unknown = set(sampler) - set(CORRELATED_SAMPLER_PARAMS) - {"type", "sample_count",
                                                                        "seed"}
            if unknown:
                raise SceneError(f"<dict>[{key!r}]: unknown parameter {sorted(unknown)[0]!r} of "
                                 "the correlated sampler")
            sampler_values = {k: v for k, v in sampler.items() if k in CORRELATED_SAMPLER_PARAMS}
            plain = {k: v for k, v in sampler.items() if k not in CORRELATED_SAMPLER_PARAMS}
            value = dict(value, sampler=dict(plain, type="independent"))
        if any(isinstance(v, Animation) for v in value.values()):
            raise SceneError(f"<dict>[{key!r}]: only 'to_world' may be an Animation")
        static[key] = value

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
                 repr(static) + repr(list(groups.items())))
