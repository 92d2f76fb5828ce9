"""The loaded scene: static Mitsuba scene, moving bodies, sensor and parameters."""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

from ..params import CAPTURE_HETERO_FREQUENCY, ParameterError, RenderParams
from .parameters import default_settings, parsed


#: the integrator types of a D-ToF scene (the second is the published name)
DTOF_INTEGRATORS = ("dopplertof", "dopplertofpath")
#: the plugin names dopplertof adds to Mitsuba's (for the did-you-mean of a misspelt one)
DTOF_PLUGINS = DTOF_INTEGRATORS + ("correlated",)
#: the id of a camera preset's illuminator (cameras.radiometry.illuminator_xml): its
#: offset from the camera is in metres whatever the scene's unit
CAMERA_ILLUMINATOR_ID = "camera_illuminator"
#: the lights that can move (keyframed, or riding on the camera)
MOVABLE_EMITTERS = ("point", "spot")
#: the published <sampler type="correlated">'s D-ToF parameters (render parameters)
CORRELATED_SAMPLER_PARAMS = ("time_correlate_number", "path_correlate_number",
                             "use_stratified_sampling_for_each_interval")
#: every parameter name of the correlated sampler
SAMPLER_NAMES = ("sample_count", "seed") + CORRELATED_SAMPLER_PARAMS
#: the sensor properties that give its shutter (the exposure when ``time`` is not given)
SHUTTER_NAMES = ("shutter_open", "shutter_close")


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


@dataclass(frozen=True)
class MotionClaim:
    """An <animation> (an Animation in a dict) as found: what the rule book
    (:func:`check_motion`) judges when the description is validated."""

    where: str  #: the file and line, or the dict key, for the message
    what: str  #: "sensor", "emitter" or "shape"
    plugin_type: str | None = None  #: the emitter's type
    follow: str | None = None  #: the animation's follow attribute (None: keyframes)
    has_position: bool = False  #: an emitter that also sets its 'position'
    has_area_emitter: bool = False  #: a shape that carries an area emitter


def check_motion(claim: MotionClaim) -> None:
    """What may move, one rule book for every scene (:func:`build` applies it)."""
    where, what, follow = claim.where, claim.what, claim.follow
    if what == "sensor":
        if follow:
            raise SceneError(f"{where}: 'follow' is for lights, not the sensor")
        return
    if what == "emitter":
        if claim.plugin_type not in MOVABLE_EMITTERS:
            raise SceneError(f"{where}: only point and spot lights can move, "
                             f"not type {claim.plugin_type!r}")
        if claim.has_position:
            raise SceneError(f"{where}: a moving light takes its position from the "
                             "<animation> keyframes (an Animation in a dict): remove its "
                             "'position'")
        if follow is not None and follow != "sensor":
            raise SceneError(f"{where}: follow={follow!r}: only follow=\"sensor\" is "
                             "supported")
        return
    if claim.has_area_emitter:
        raise SceneError(f"{where}: moving area emitters are not supported yet")


class SceneError(ValueError):
    """A scene that cannot be loaded; the message names the problem and where."""


@dataclass(frozen=True)
class DopplerScene:
    """A loaded D-ToF scene (``dopplertof.load_file``/``load_string``/``load_dict``): a
    Mitsuba scene of what stays still plus the moving bodies, which Mitsuba alone cannot
    render. Render it with ``dopplertof.render``/``capture`` (or ``mi.render(scene)``,
    which calls ``dopplertof.render``). Its parts, for Mitsuba's own calls:

    - ``static``: the ``mi.Scene`` with the static shapes, the sensor and the emitters
      (``mi.traverse(scene.static)`` edits their parameters; ``mi.render(scene.static)``
      renders without the moving bodies);
    - ``bodies``: one MovingBody per animation: ``.scene`` (an ``mi.Scene`` of its
      shapes at the first keyframe's pose), ``.motion`` and ``.names`` (the shape ids);
    - ``params`` (RenderParams, the D-ToF camera's), ``modality_settings`` (the other
      modalities' settings, by modality: ``["fmcw"]`` the FMCW lidar's), ``spp``,
      ``variant``, ``source``, ``sensor_motion``, ``light_motions``, ``notes``,
      ``fingerprint``; ``sensor``, ``shutter_open`` and ``shutter_interval`` are the
      sensor's.
    """

    static: object  #: mi.Scene with the static shapes, the sensor and the emitters
    bodies: tuple  #: MovingBody, one per animation
    params: RenderParams  #: from the scene's <integrator> and <sampler>
    spp: int  #: the sensor sampler's sample count
    variant: str  #: the Mitsuba variant it was loaded with
    source: str = "<dict>"
    #: content hash of the resolved description and every file it references
    #: (inputs.content_digest; checkpoints compare it)
    fingerprint: str = ""
    sensor_motion: object = None  #: Motion of the camera (None: static)
    light_motions: tuple = ()  #: (index in static.emitters(), Motion) of moving lights
    notes: tuple = ()  #: what the loader assumed (e.g. default integrator), for the user
    inputs: tuple = ()  #: InputFile of every file the scene references (meshes, textures...)
    #: (open, interval) in s replacing the sensor's shutter (None: the sensor's own)
    shutter_window: tuple | None = None
    #: Brown-Conrady (k1, k2, p1, p2, k3) of the lens, OpenCV's order (None: a pinhole;
    #: set by a camera preset, integrators.camera.LensDistortion)
    lens_distortion: tuple | None = None
    #: {modality: settings} of the modalities besides the D-ToF camera, from the
    #: <integrator>'s prefixed parameters (parameters.MODALITY_SETTINGS)
    modality_settings: dict = field(default_factory=default_settings)
    #: the room lights the loader left out (:mod:`.room_lights`), one string each
    left_out_lights: tuple = ()

    @property
    def sensor(self):
        return self.static.sensors()[0]

    @property
    def shutter_open(self) -> float:
        if self.shutter_window is not None:
            return float(self.shutter_window[0])
        return float(self.sensor.shutter_open())

    @property
    def shutter_interval(self) -> float:
        if self.shutter_window is not None:
            return float(self.shutter_window[1])
        return float(self.sensor.shutter_open_time())

    @property
    def keyframe_span(self):
        """(first, last) keyframe time (s) over everything that moves (bodies, camera,
        lights), or None when nothing does."""
        motions = ([b.motion for b in self.bodies] + [m for _, m in self.light_motions]
                   + ([self.sensor_motion] if self.sensor_motion is not None else []))
        if not motions:
            return None
        return (min(float(m.times[0]) for m in motions),
                max(float(m.times[-1]) for m in motions))

    def __hash__(self):  # its Mitsuba objects compare by identity: so does the scene
        return hash((id(self.static), tuple(id(body.scene) for body in self.bodies)))

    def traverse(self, callback):
        """``mi.traverse(scene)``: a DopplerScene is no Mitsuba node, say what is."""
        raise TypeError(
            "mi.traverse takes a Mitsuba object, not a DopplerScene: traverse scene.static "
            "(static shapes, sensor, emitters) or a moving body's scene.bodies[i].scene; "
            "for derivatives of a moving scene use dopplertof.diff.render_derivatives")

    def with_shutter(self, open_s: float, interval_s: float) -> "DopplerScene":
        """A copy whose exposure window is [open_s, open_s + interval_s] (scene clock, s)
        whatever its sensor says: a camera that reads its raw frames one after the other
        renders each in its own window from one loaded scene."""
        if not (math.isfinite(open_s) and math.isfinite(interval_s) and interval_s > 0):
            raise SceneError(f"a shutter window needs a finite start and a positive length, "
                             f"got {open_s!r}, {interval_s!r}")
        return replace(self, shutter_window=(float(open_s), float(interval_s)))

    def with_params(self, **changes) -> "DopplerScene":
        """A copy with integrator parameters changed (validated), the D-ToF camera's or
        another modality's (``fmcw_bins=64``)."""
        params, settings = parsed(changes, "parameters", self.params, self.modality_settings)
        return replace(self, params=params, modality_settings=settings)


#: the least share of an exposure its keyframes should cover: below it, a render or
#: capture warns (bodies hold their first or last pose outside the keyframes)
MIN_KEYFRAME_COVERAGE = 0.5


def keyframe_coverage(span, start: float, exposure: float) -> float:
    """The share of the exposure [start, start + exposure] (s) inside the keyframe
    ``span`` (first, last), 1 when nothing moves (``span`` None)."""
    if span is None:
        return 1.0
    inside = min(span[1], start + exposure) - max(span[0], start)
    return max(0.0, inside) / exposure


#: a keyframe span at least this many times the exposure reads as keyframe times written
#: in ms (``time="1.5"`` for 1.5 ms): a render or capture warns
MAX_SPAN_PER_EXPOSURE = 100


def keyframe_coverage_warning(span, start: float, exposure: float,
                              what: str = "the exposure") -> str | None:
    """A warning when the keyframes cover less than MIN_KEYFRAME_COVERAGE of the
    exposure (a unit mistake: ``time=1.5`` meant as ms), or span MAX_SPAN_PER_EXPOSURE
    exposures or more (keyframe times in ms), else None. ``what``: the interval's name
    in the message (a camera's: "the raw frames")."""
    share = keyframe_coverage(span, start, exposure)
    if share >= MIN_KEYFRAME_COVERAGE:
        if span is None or span[1] - span[0] < MAX_SPAN_PER_EXPOSURE * exposure:
            return None
        length = span[1] - span[0]
        return (f"the keyframes span {length:g} s, {length / exposure:.0f} times the "
                f"exposure ({exposure:g} s): the bodies travel that small a part "
                "of their keyframed path during it; keyframe times are in seconds (were "
                "they written in ms?)")
    return (f"the keyframes ({span[0]:g} to {span[1]:g} s) cover {share:.1%} of {what} "
            f"({start:g} to {start + exposure:g} s): outside them everything holds its first "
            "or last pose, and the measured motion stops; time and keyframe times are in "
            "seconds")


def default_integrator_note(source: str, other: str | None = None) -> str:
    """What a scene without a D-ToF integrator renders with; ``other``: where and what
    its stock integrator is (None: it has none)."""
    p = RenderParams()
    depth = "unbounded" if p.max_depth == -1 else p.max_depth
    said = (f"{other} is not a D-ToF integrator" if other
            else f"{source} has no <integrator>")
    return (f"{said}: using the D-ToF defaults: w_g {p.w_g:g} MHz, "
            f"{p.wave_function_type} waveform, max_depth {depth}, time sampling "
            f"{p.time_sampling_method}, no hetero_frequency; `render` "
            "renders one homodyne image (sensor offset 0), `capture` its homodyne captures "
            f"and heterodyne ones at {CAPTURE_HETERO_FREQUENCY:g} beat period(s) per "
            "exposure (its default where the scene sets no hetero_frequency; a --camera "
            "preset: the preset's frames)")


@dataclass
class SceneDescription:
    """What a scene file or dict says, in one form for both loaders, before Mitsuba
    loads it. The XML loader's parts are XML elements, the dict loader's dicts; a
    loader's ``load_part(part, what)`` turns one into a Mitsuba scene and the text
    that identifies it. :func:`build` validates the description and loads it."""

    source: str  #: the file, "<string>" or "<dict>", for messages
    static: object  #: the static scene (sensor, emitters, static shapes), loader's form
    #: each moving body: (Keyframes, its shapes' names, its scene in the loader's form)
    bodies: list = field(default_factory=list)
    #: (where, {name: value}) of the correlated sampler and the integrator, in that order
    parameters: list = field(default_factory=list)
    params: RenderParams = field(default_factory=RenderParams)  #: what they override
    #: {modality: settings} they override (parameters.default_settings())
    settings: dict = field(default_factory=default_settings)
    sensor_keyframes: object = None  #: Keyframes of the camera (None: static)
    #: (emitter id, Keyframes or "sensor") of each moving light; "sensor": on the camera
    light_keyframes: list = field(default_factory=list)
    motions: list = field(default_factory=list)  #: MotionClaim of every animation
    has_integrator: bool = True  #: whether the scene names its integrator
    #: where the sensor gives its shutter (shutter_open or shutter_close), for messages;
    #: None: not given, the exposure is ``time`` or the default 1.5 ms
    shutter_given: str | None = None
    #: InputFile of every file the description references (inputs.xml_inputs, dict_inputs)
    inputs: list = field(default_factory=list)
    #: the folders its relative file names are looked up in before Mitsuba's own, first
    #: first (an XML scene's <path> entries and its folder)
    folders: tuple = ()
    #: where and what its integrator is when it is not a D-ToF one (the defaults render)
    other_integrator: str | None = None
    #: the room lights left out of it (:func:`.room_lights.leave_out`), one string each
    left_out_lights: tuple = ()


def _parameters(d: SceneDescription) -> tuple:
    """(RenderParams, {modality: settings}) of the description: the sampler's, then the
    integrator's, over its ``params`` and ``settings``; a SceneError naming the first
    problem."""
    params, settings = d.params, d.settings
    for where, values in d.parameters:
        try:
            params, settings = parsed(values, where, params, settings)
        except ParameterError as e:
            raise SceneError(str(e)) from None
    return params, settings


def build(mi, description: SceneDescription, load_part) -> DopplerScene:
    """Validate ``description`` (what may move, the parameters, the sensor and the
    lights), load its parts with ``load_part(part, what)`` -> (mi.Scene, text) and
    assemble the DopplerScene: the one path of the XML and dict loaders and of the
    Mitsuba plugin."""
    from .bodies import MovingBody
    from .motion import Motion

    d, source = description, description.source
    # ---- What may move ----
    for claim in d.motions:
        check_motion(claim)
    params, settings = _parameters(d)

    # ---- Load the static scene and each body ----
    static, text = _load_checked(mi, load_part, d.static, "scene", source)
    texts, bodies = [text], []
    for kf, names, part in d.bodies:
        body_scene, text = _load_checked(mi, load_part, part, f"body {list(names)}", source)
        texts += [text, repr(kf)]
        bodies.append(MovingBody(body_scene, Motion(kf), tuple(names)))
    texts += [repr(d.sensor_keyframes), repr(d.light_keyframes)]

    # ---- The sensor and the lights ----
    sensors = static.sensors()
    if len(sensors) != 1:
        raise SceneError(f"{source}: a D-ToF scene needs exactly one sensor, found {len(sensors)}")
    for emitter in static.emitters():
        if emitter.is_environment():
            raise SceneError(
                f"{source}: environment emitters are not modulated sources of a ToF camera; "
                "remove it (ambient light belongs to the sensor noise model)"
            )
    require_light(static, source, any(s.lights_the_scene for s in settings.values()))
    _check_sensor(sensors[0], source, d.shutter_given, params)
    spp = int(sensors[0].sampler().sample_count())
    sensor_motion = Motion(d.sensor_keyframes) if d.sensor_keyframes is not None else None
    ids = [e.id() for e in static.emitters()]
    light_motions = []
    for ident, kf in d.light_keyframes:
        if ident not in ids:
            raise SceneError(f"{source}: moving light {ident!r} not found in the loaded scene")
        motion = sensor_motion if kf == "sensor" else Motion(kf)
        light_motions.append((ids.index(ident), motion))

    from .inputs import content_digest

    # ---- The fingerprint: the description and the files it references ----
    description_text = "\n".join(t for t in texts if t)
    fingerprint = content_digest(description_text, d.inputs) if texts[0] else ""
    notes = () if d.has_integrator else (default_integrator_note(source,
                                                                 d.other_integrator),)
    return DopplerScene(static, tuple(bodies), params, spp, mi.variant(), source, fingerprint,
                        sensor_motion, tuple(light_motions), notes, tuple(d.inputs),
                        modality_settings=settings,
                        left_out_lights=tuple(d.left_out_lights))


def _check_sensor(sensor, source: str, shutter_given: str | None,
                  params: RenderParams) -> None:
    """A film of at least one pixel, and a shutter that is open for a while when the
    scene gives it and it sets the exposure (no ``time``): a zero-length one is refused,
    as ``time=0`` is (Mitsuba's default shutter, 0 to 0, means none was given: the
    default exposure)."""
    width, height = (int(v) for v in sensor.film().crop_size())
    if width < 1 or height < 1:
        raise SceneError(f"{source}: the film is {width}x{height} pixels: its width and "
                         "height must be >= 1")
    if (shutter_given is None or params.time is not None
            or float(sensor.shutter_open_time()) > 0):
        return
    opens = float(sensor.shutter_open())
    raise SceneError(f"{shutter_given}: the sensor's shutter (the exposure) must be open "
                     f"for > 0 seconds, got shutter_open = shutter_close = {opens:g}: set "
                     "shutter_close > shutter_open, or the integrator's time")


def mitsuba_load(load, scene):
    """``load(scene)`` (``mi.load_string`` or ``mi.load_dict``), on Mitsuba's threads; if
    that fails, once more on this thread alone, whose error is the one raised. A child
    that fails on a loader thread can surface as another child's "has not been
    instantiated yet" (seen for a missing mesh file under a loaded test suite), which
    names neither the child nor its problem; the serial load names both."""
    try:
        return load(scene)
    except Exception:
        return load(scene, parallel=False)


def require_light(static, source: str, lit_by_beam: bool = False) -> None:
    """A SceneError unless the scene (``static``, an mi.Scene) has an emitter, or an
    FMCW lidar's collimated beam (``lit_by_beam``) is its only light."""
    if not lit_by_beam and not static.emitters():
        raise SceneError(f"{source}: the scene has no emitter: a ToF camera needs its light "
                         "(an FMCW frame lit by its collimated beam needs none: --beam "
                         "collimated, fmcw_beam=\"collimated\")")


def _load_checked(mi, load_part, part, what: str, source: str):
    """``load_part(part, what)``, its meshes checked (no faces, indices past the last
    vertex, non-finite positions: Mitsuba loads some of these)."""
    from .meshes import loaded_meshes_problem

    scene, text = load_part(part, what)
    problem = loaded_meshes_problem(mi, scene)
    if problem:
        raise SceneError(f"{source}: {problem}")
    return scene, text


def loaded(mi, scene, params: RenderParams, source: str = "<mitsuba scene>",
           has_integrator: bool = True, settings: dict | None = None) -> DopplerScene:
    """A DopplerScene of a static scene Mitsuba has loaded already (the plugin's, with
    its parameters and other modalities' ``settings``; None: the defaults)."""
    return build(mi, SceneDescription(source, scene, params=params,
                                      settings=settings or default_settings(),
                                      has_integrator=has_integrator),
                 lambda part, what: (part, ""))


def as_doppler_scene(scene):
    """``scene`` if it is a DopplerScene; a plain ``mi.Scene`` (what ``mi.load_file``
    gives) as a static DopplerScene, with the parameters of its dopplertof integrator
    (the defaults, and a note saying so, under another integrator or none); anything
    else as it is, for the caller's own check."""
    if isinstance(scene, DopplerScene):
        return scene
    import sys

    mi = sys.modules.get("mitsuba")
    if mi is None or mi.variant() is None or not isinstance(scene, mi.Scene):
        return scene
    integrator = scene.integrator()
    params = getattr(integrator, "params", None)
    own = isinstance(params, RenderParams)
    return loaded(mi, scene, params if own else RenderParams(), has_integrator=own,
                  settings=getattr(integrator, "modality_settings", None) if own else None)
