"""The loaded scene: static Mitsuba scene, moving bodies, sensor and parameters."""

from __future__ import annotations

from dataclasses import dataclass, replace

from ..params import RenderParams


#: the integrator types of a D-ToF scene (the second is the published name)
DTOF_INTEGRATORS = ("dopplertof", "dopplertofpath")
#: the lights that can move (keyframed, or riding on the camera)
MOVABLE_EMITTERS = ("point", "spot")
#: the published <sampler type="correlated">'s D-ToF parameters (render parameters)
CORRELATED_SAMPLER_PARAMS = ("time_correlate_number", "path_correlate_number",
                             "use_stratified_sampling_for_each_interval")
#: every parameter name of the correlated sampler
SAMPLER_NAMES = ("sample_count", "seed") + CORRELATED_SAMPLER_PARAMS


def correlated_sampler_params(values: dict, where: str) -> dict:
    """The render parameters of a published correlated sampler whose properties are
    ``values`` (its type left out): one rule for the XML and the dict loaders, any other
    name than sample_count, seed and these is an error."""
    from ..hints import did_you_mean

    unknown = set(values) - set(SAMPLER_NAMES)
    if unknown:
        name = sorted(unknown)[0]
        raise SceneError(f"{where}: unknown parameter {name!r} of the correlated "
                         f"sampler{did_you_mean(name, SAMPLER_NAMES)} (known: "
                         f"{', '.join(SAMPLER_NAMES)})")
    return {k: v for k, v in values.items() if k in CORRELATED_SAMPLER_PARAMS}


def check_motion(where: str, what: str, plugin_type=None, follow=None,
                 has_position: bool = False, has_area_emitter: bool = False) -> None:
    """What may move, one rule book for both loaders: ``what`` is "sensor", "emitter"
    or "shape", ``follow`` its animation's follow attribute (None: keyframes)."""
    if what == "sensor":
        if follow:
            raise SceneError(f"{where}: 'follow' is for lights, not the sensor")
        return
    if what == "emitter":
        if plugin_type not in MOVABLE_EMITTERS:
            raise SceneError(f"{where}: only point and spot lights can move, "
                             f"not type {plugin_type!r}")
        if has_position:
            raise SceneError(f"{where}: a moving light takes its position from the "
                             "<animation> keyframes (an Animation in a dict): remove its "
                             "'position'")
        if follow is not None and follow != "sensor":
            raise SceneError(f"{where}: follow={follow!r}: only follow=\"sensor\" is "
                             "supported")
        return
    if has_area_emitter:
        raise SceneError(f"{where}: moving area emitters are not supported yet")


class SceneError(ValueError):
    """A scene that cannot be loaded; the message names the problem and where."""


@dataclass(frozen=True)
class DopplerScene:
    static: object  #: mi.Scene with the static shapes, the sensor and the emitters
    bodies: tuple  #: MovingBody, one per animation
    params: RenderParams  #: from the scene's <integrator> and <sampler>
    spp: int  #: the sensor sampler's sample count
    variant: str  #: the Mitsuba variant it was loaded with
    source: str = "<dict>"
    fingerprint: str = ""  #: hash of the resolved scene description (checkpoints compare it)
    sensor_motion: object = None  #: Motion of the camera (None: static)
    light_motions: tuple = ()  #: (index in static.emitters(), Motion) of moving lights
    notes: tuple = ()  #: what the loader assumed (e.g. default integrator), for the user

    @property
    def sensor(self):
        return self.static.sensors()[0]

    @property
    def shutter_open(self) -> float:
        return float(self.sensor.shutter_open())

    @property
    def shutter_interval(self) -> float:
        return float(self.sensor.shutter_open_time())

    def with_params(self, **changes) -> "DopplerScene":
        """A copy with integrator parameters changed (validated)."""
        params = RenderParams.from_mapping(changes, where="parameters", base=self.params)
        return replace(self, params=params)


def default_integrator_note(source: str) -> str:
    """What a scene without a D-ToF integrator renders with."""
    p = RenderParams()
    depth = "unbounded" if p.max_depth == -1 else p.max_depth
    return (f"{source} has no <integrator>: using the D-ToF defaults, a homodyne capture "
            f"(hetero_frequency 0, sensor offset 0) at w_g {p.w_g:g} MHz, "
            f"{p.wave_function_type} waveform, max_depth {depth}, time sampling "
            f"{p.time_sampling_method}")


def build(mi, static, bodies, params: RenderParams, source: str,
          description: str = "", sensor_keyframes=None, light_keyframes=(),
          has_integrator: bool = True) -> DopplerScene:
    """Checks shared by the XML and dict loaders; camera and light motions.

    ``light_keyframes`` is ``[(emitter id, Keyframes or "sensor"), ...]``; "sensor"
    moves the light rigidly with the camera.
    """
    from .motion import Motion

    sensors = static.sensors()
    if len(sensors) != 1:
        raise SceneError(f"{source}: a D-ToF scene needs exactly one sensor, found {len(sensors)}")
    for emitter in static.emitters():
        if emitter.is_environment():
            raise SceneError(
                f"{source}: environment emitters are not modulated sources of a ToF camera; "
                "remove it (ambient light belongs to the sensor noise model)"
            )
    if not static.emitters():
        raise SceneError(f"{source}: the scene has no emitter: a ToF camera needs its light")
    spp = int(sensors[0].sampler().sample_count())
    sensor_motion = Motion(sensor_keyframes) if sensor_keyframes is not None else None
    ids = [e.id() for e in static.emitters()]
    light_motions = []
    for ident, kf in light_keyframes:
        if ident not in ids:
            raise SceneError(f"{source}: moving light {ident!r} not found in the loaded scene")
        motion = sensor_motion if kf == "sensor" else Motion(kf)
        light_motions.append((ids.index(ident), motion))

    import hashlib

    fingerprint = hashlib.sha256(description.encode()).hexdigest() if description else ""
    notes = () if has_integrator else (default_integrator_note(source),)
    return DopplerScene(static, tuple(bodies), params, spp, mi.variant(), source, fingerprint,
                        sensor_motion, tuple(light_motions), notes)
