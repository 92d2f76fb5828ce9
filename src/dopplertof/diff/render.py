"""Renders and their forward-mode derivatives (Dr.Jit AD through the path loop).

What is differentiable (see docs/differentiable.md):

* each moving body's linear and angular velocity (``body{k}.v{x,y,z}``,
  ``body{k}.w{x,y,z}``: m/s and rad/s, world axes; the body moves as a
  :class:`~dopplertof.diff.motion.VelocityMotion` about its pivot);
* the camera's linear velocity (``camera.v{x,y,z}``; lights that follow the camera
  move with it);
* the modulation: ``w_g`` (MHz), ``hetero_offset`` (periods), ``g_1``;
* any Mitsuba parameter that ``mi.traverse`` exposes in the static scene or a body's
  scene, by its key (e.g. ``ShortBoxBSDF.brdf_0.reflectance.value``); ``KEY[c]``
  differentiates channel c only, ``KEY`` all channels together.

The accumulation is the importance film (``film_sampling="importance"``): each
sample lands in one pixel with weight 1, so that a pixel is the mean of its samples,
a ``dr.block_sum`` through which AD passes. The splat film's kernel (gathers and
scatters into float64 totals) is not differentiable as written; both films have the
same expectation.

Derivatives are those of the integrand at fixed random numbers (a path's vertices
move with the surfaces they lie on): they are unbiased for the interior of surfaces,
and the discontinuities at moving silhouettes (visibility) are not differentiated,
as with Mitsuba's ``prb`` without reparameterization.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, replace

import numpy as np

from ..hints import unknown_name
from ..modulation import SPEED_OF_LIGHT
from .motion import VelocityMotion

AXES = "xyz"
MODULATION_PARAMETERS = ("w_g", "hetero_offset", "g_1")
_MOTION_NAME = re.compile(r"^(body(\d+)|camera)\.([vw])([xyz])$")
_CHANNEL = re.compile(r"^(.*)\[(\d+)\]$")
_MESH_DATA = re.compile(r"\.(vertex_\w+|faces)$")  # a mesh's vertex attributes


class DerivativeError(ValueError):
    """A parameter that cannot be differentiated; the message names it."""


@dataclass
class Derivatives:
    """A render and its derivatives."""

    image: np.ndarray  #: (H, W, C) float64, the render (importance film)
    tangents: dict  #: name -> (H, W, C) float64, d image / d parameter
    spp: int
    seed: int


class DifferentiableScene:
    """A DopplerScene whose motions are velocities (Dr.Jit arrays of width 1).

    ``velocities``: optional {body index: (v, omega)} to start from (else each body's
    chord over the exposure); ``camera_velocity``: the camera's (else its chord, or 0
    for a static camera).
    """

    def __init__(self, scene, params=None, velocities=None, camera_velocity=None):
        from ..arguments import check_mapping, check_params, check_scene
        from ..backend import require_variant

        scene = check_scene(scene)
        check_params(params)
        check_mapping(velocities, "velocities")
        self.mi = mi = require_variant()
        if not dr_is_diff(mi):
            raise DerivativeError(
                f"variant {mi.variant()} has no automatic differentiation: use an _ad_ "
                "variant (e.g. llvm_ad_rgb)")
        self.scene = scene
        p = scene.params if params is None else params
        if not hasattr(p, "film_sampling"):
            from ..params import RenderParams

            p = RenderParams.from_mapping(dict(p), where="render parameters",
                                          base=scene.params)
        # importance film (differentiable accumulation), pairs by replay
        p = replace(p.resolved(scene.shutter_interval, sampled=True), film_sampling="importance",
                    adaptive_sampling=False)
        if p.antithetic_mapping == "motion":
            p = replace(p, antithetic_mapping="replay")
        self.params = p
        t0 = scene.shutter_open
        t1 = t0 + p.exposure(scene.shutter_interval)
        self.interval = (t0, t1)
        velocities = velocities or {}
        self.motions = []
        for k, body in enumerate(scene.bodies):
            m = VelocityMotion.from_motion(body.motion, t0, t1)
            if k in velocities:
                v, w = velocities[k]
                m.velocity, m.angular_velocity = list(map(float, v)), list(map(float, w))
            self.motions.append(m)
        self.camera_motion = self._camera_motion(scene, t0, t1, camera_velocity)
        self._bsdf_params = None
        self._boxes = {}  #: body index -> its swept box, held while the sweep fits in it

    def _camera_motion(self, scene, t0, t1, camera_velocity):
        if scene.sensor_motion is not None:
            m = VelocityMotion.from_motion(scene.sensor_motion, t0, t1)
        else:
            to_world = np.array(scene.sensor.world_transform().matrix,
                                dtype=np.float64).reshape(4, 4, -1)[..., 0]
            m = VelocityMotion(to_world[:3, 3], [0.0] * 3, [0.0] * 3, t0, to_world, (t0, t1))
        if camera_velocity is not None:
            m.velocity = list(map(float, camera_velocity))
        return m

    # ---- Velocities as plain numbers ----

    def body_velocity(self, k: int):
        """(v, omega) of body k as float lists."""
        m = self.motions[k]
        return _floats(m.velocity), _floats(m.angular_velocity)

    def set_body_velocity(self, k: int, v=None, omega=None):
        m = self.motions[k]
        if v is not None:
            m.velocity = [float(x) for x in v]
        if omega is not None:
            m.angular_velocity = [float(x) for x in omega]

    # ---- The scene the renderer reads ----

    def _traced(self, variables: dict):
        """The DopplerScene with VelocityMotions whose components are Dr.Jit arrays
        (``variables`` maps motion names to the AD variables to use)."""
        mi = self.mi
        bodies = []
        for k, (body, m) in enumerate(zip(self.scene.bodies, self.motions)):
            vm = _with_variables(mi, m, f"body{k}", variables)
            bodies.append(replace(body, motion=vm, _swept={self.interval: self._box(k)}))
        cam = _with_variables(mi, self.camera_motion, "camera", variables)
        moving_camera = self.scene.sensor_motion is not None or any(
            n.startswith("camera.") for n in variables) or any(
            x != 0.0 for x in _floats(self.camera_motion.velocity))
        old = self.scene.sensor_motion
        lights = tuple((i, cam if (m is old and old is not None) else m)
                       for i, m in self.scene.light_motions)
        return replace(self.scene, bodies=tuple(bodies),
                       sensor_motion=cam if moving_camera else None, light_motions=lights)

    def _box(self, k: int):
        """Body k's swept bounding box over the exposure, kept while the sweep at the
        current velocities stays inside it: the box is a literal of the render's kernel,
        and a new box at every new velocity (each step of a fit) would compile a new
        kernel. A new box is the sweep padded by a tenth of its diagonal."""
        mi = self.mi
        bb = self.scene.bodies[k].scene.bbox()
        lo, hi = self.motions[k].swept_bbox(np.array(bb.min), np.array(bb.max), *self.interval)
        held = self._boxes.get(k)
        if held is None or np.any(lo < held[0]) or np.any(hi > held[1]):
            pad = 0.1 * np.linalg.norm(hi - lo)
            held = self._boxes[k] = (lo - pad, hi + pad)
        return mi.ScalarBoundingBox3f(mi.ScalarPoint3f(*held[0]), mi.ScalarPoint3f(*held[1]))

    def scene_parameters(self):
        """{key: [mi.SceneParameters holding it]}: the static scene's and the bodies'."""
        if self._bsdf_params is None:
            out = {}
            mi = self.mi
            for sc in [self.scene.static] + [b.scene for b in self.scene.bodies]:
                tp = mi.traverse(sc)
                for key in tp.keys():
                    out.setdefault(key, []).append(tp)
            self._bsdf_params = out
        return self._bsdf_params


def dr_is_diff(mi) -> bool:
    import drjit as dr

    return dr.is_diff_v(mi.Float)


def _floats(values):
    return [float(np.asarray(x).ravel()[0]) if not isinstance(x, float) else x for x in values]


def _with_variables(mi, motion: VelocityMotion, prefix: str, variables: dict):
    """A copy of ``motion`` whose components are Dr.Jit Floats: the AD variables in
    ``variables`` where named, else opaque values (one kernel serves every velocity,
    as a fit needs) and zero angular velocities as plain zeros (no rotation: the
    renderer's translation-only path)."""
    import drjit as dr

    out = VelocityMotion(motion.pivot, [0.0] * 3, [0.0] * 3, motion.t_ref,
                         motion.reference, motion.interval, motion.base)
    v, w = _floats(motion.velocity), _floats(motion.angular_velocity)
    out.velocity = [variables.get(f"{prefix}.v{a}", dr.opaque(mi.Float, v[i]))
                    for i, a in enumerate(AXES)]
    turning = any(f"{prefix}.w{a}" in variables for a in AXES) or any(w)
    out.angular_velocity = [variables.get(f"{prefix}.w{a}", dr.opaque(mi.Float, w[i]))
                            if turning else 0.0 for i, a in enumerate(AXES)]
    return out


def _motion_value(dscene, name):
    m = _MOTION_NAME.match(name)
    body, kind, axis = m.group(2), m.group(3), AXES.index(m.group(4))
    if body is None:
        if kind == "w":
            raise DerivativeError(f"{name}: the camera's angular velocity is not a parameter "
                                  "(camera.v{x,y,z} are)")
        motion = dscene.camera_motion
    else:
        if int(body) >= len(dscene.motions):
            raise DerivativeError(f"{name}: the scene has {len(dscene.motions)} moving bodies")
        motion = dscene.motions[int(body)]
    values = motion.velocity if kind == "v" else motion.angular_velocity
    return _floats(values)[axis]


def check_names(dscene: DifferentiableScene, names) -> None:
    """Raise DerivativeError naming the first parameter that cannot be differentiated."""
    for name in names:
        if _MOTION_NAME.match(name):
            _motion_value(dscene, name)
        elif name in MODULATION_PARAMETERS:
            continue
        else:
            m = _CHANNEL.match(name)
            key = m.group(1) if m else name
            if key not in dscene.scene_parameters():
                raise DerivativeError(
                    f"{unknown_name('parameter', name, parameter_names(dscene))}: expected "
                    "body<k>.v<x|y|z>, body<k>.w<x|y|z>, camera.v<x|y|z>, w_g, "
                    "hetero_offset, g_1 or a mi.traverse key of the scene")


def parameter_names(dscene: DifferentiableScene) -> list:
    """Every name :func:`render_derivatives` differentiates in ``dscene``: the bodies'
    and the camera's velocities, the modulation's and the scene's mi.traverse keys."""
    motions = [f"body{k}.{kind}{axis}" for k in range(len(dscene.motions))
               for kind in "vw" for axis in AXES]
    return (motions + [f"camera.v{axis}" for axis in AXES] + list(MODULATION_PARAMETERS)
            + list(dscene.scene_parameters()))


def differentiable_names(dscene: DifferentiableScene) -> list:
    """The names :func:`dopplertof.diff.gradient` differentiates by default: the bodies'
    and the camera's velocities, the modulation's, and the mi.traverse keys whose value
    is a differentiable floating-point array (flags without NonDifferentiable or
    Discontinuous: reflectances, textures, emitters' radiance; not transforms, sizes,
    the sensor's settings or meshes' vertex data, which can be named)."""
    motions = [f"body{k}.{kind}{axis}" for k in range(len(dscene.motions))
               for kind in "vw" for axis in AXES]
    keys = [key for key, holders in dscene.scene_parameters().items()
            if differentiable_key(holders[0], key) and not _MESH_DATA.search(key)]
    return motions + [f"camera.v{axis}" for axis in AXES] + list(MODULATION_PARAMETERS) + keys


def differentiable_key(parameters, key: str) -> bool:
    """Whether ``key`` of mi.SceneParameters ``parameters`` holds a differentiable
    floating-point Dr.Jit array."""
    import drjit as dr

    value, flags = parameters[key], int(parameters.properties[key][3])
    return flags == 0 and dr.is_array_v(value) and dr.is_float_v(value) and not dr.is_matrix_v(value)


class _ModulationVariables:
    """The modulation weight's scalars as AD variables (one per differentiated
    parameter), with the ones derived from them."""

    def __init__(self, mi, weight, mod, names):
        import drjit as dr

        F = weight.F
        self.variables = {}

        def var(name, value):
            x = F(value)
            if name in names:
                dr.enable_grad(x)
                self.variables[name] = x
            return x

        w_g = var("w_g", mod.omega_g / (2e6 * math.pi))
        offset = var("hetero_offset", mod.psi / (2 * math.pi))
        g1 = var("g_1", mod.g1)
        omega_g = w_g * (2e6 * math.pi)
        weight.omega_g = omega_g
        weight.omega_s = omega_g + F(mod.omega_d)  # f_s = f_g + h / T: omega_d fixed
        weight.k_length = omega_g * (1.0 / SPEED_OF_LIGHT)
        weight.psi = offset * (2 * math.pi)
        weight.g1 = g1


def render_derivatives(dscene: DifferentiableScene, names=(), spp: int | None = None,
                       seed: int = 0, max_lanes: int = 1 << 20, pixels=None) -> Derivatives:
    """The render of ``dscene`` and its derivatives w.r.t. ``names`` (forward mode, one
    derivative pass per parameter). ``pixels``: optional flat pixel indices to render
    (others are zero): fits and tests that need only some pixels pay only for them."""
    import drjit as dr

    from ..integrators.pipeline import _spectrum_channels
    from ..sampling import check_sample_count

    mi = dscene.mi
    names = list(names)
    check_names(dscene, names)
    scene0 = dscene.scene
    spp = scene0.spp if spp is None else int(spp)
    p = dscene.params
    check_sample_count(p.time_correlate_number, spp, p.path_group_size,
                               p.samples_per_pass)
    width, height = (int(v) for v in scene0.sensor.film().crop_size())
    n_pixels = width * height
    pixels = np.arange(n_pixels) if pixels is None else np.asarray(pixels, dtype=np.int64)
    channels = _spectrum_channels(mi)
    image = np.zeros((n_pixels, channels))
    tangents = {n: np.zeros((n_pixels, channels)) for n in names}
    K = p.time_correlate_number
    # passes of whole groups of samples for every rendered pixel
    per_pass = max(K, min(spp, (max_lanes // max(len(pixels), 1)) // K * K))
    for s0 in range(0, spp, per_pass):
        samples = min(per_pass, spp - s0)
        # one trace per parameter (the first also gives the render): a forward
        # traversal clears the graph it passes
        for i, name in enumerate(names or [None]):
            value, x, restore = _trace(dscene, name, pixels, samples, s0, spp, seed)
            if i == 0:  # the render: one path tracing kernel, then the pixel sums
                dr.eval(value)
                image[pixels] += _host(_pixel_sums(mi, dr.detach(value), samples))
            if name is not None:
                if dr.grad(x) == 0.0:
                    dr.forward_from(x)
                else:  # already traversed into the scene's data
                    dr.forward_to(value)
                tangent = dr.grad(value)
                dr.eval(tangent)  # one derivative kernel (its loop carries the primal)
                finite = _finite(dr.detach(value))
                tangents[name][pixels] += _host(_pixel_sums(mi, tangent, samples, finite))
            restore()
            del value, x
    shape = (height, width, channels)
    return Derivatives((image / spp).reshape(shape),
                       {n: (t / spp).reshape(shape) for n, t in tangents.items()}, spp, seed)


def _channels_of(value):
    return [value[c] for c in range(len(value))] if hasattr(value, "__len__") else [value]


def _finite(value):
    """Lanes whose every channel is finite (the renderer drops the others)."""
    import drjit as dr

    raw = _channels_of(value)
    finite = dr.isfinite(raw[0])
    for v in raw[1:]:
        finite &= dr.isfinite(v)
    return finite


def _pixel_sums(mi, value, samples, finite=None):
    """Per pixel, each channel's sum of its samples (evaluated ``value``, pixel-major
    lanes: one block sum per channel), over the lanes ``finite`` (default: those whose
    value is finite, as the renderer drops the others)."""
    import drjit as dr

    finite = _finite(value) if finite is None else finite
    sums = [dr.block_sum(dr.select(finite, v, 0.0), samples) for v in _channels_of(value)]
    dr.eval(sums)
    return sums


def _host(values):
    return np.stack([np.asarray(v, dtype=np.float64) for v in values], -1)


def _trace(dscene, name, pixels, samples, s0, spp, seed):
    """One pass's lane values, the AD variable of parameter ``name`` (None: none) and
    a function that puts the scene parameters back."""
    import drjit as dr

    from ..integrators.dtof_path import integrator_class
    from ..integrators.path_steps import PassLayout

    mi = dscene.mi
    names = [] if name is None else [name]
    motion_vars = {}
    if name is not None and _MOTION_NAME.match(name):
        x = dr.opaque(mi.Float, _motion_value(dscene, name))  # not a literal: one kernel
        dr.enable_grad(x)
        motion_vars[name] = x
    scene = dscene._traced(motion_vars)
    setup = integrator_class(mi)().prepared(scene, dscene.params, spp, int(seed))
    variables = {**motion_vars,
                 **_ModulationVariables(mi, setup.modulation_weight, setup.modulation, names).variables}
    # ---- Mitsuba scene parameters: the value plus x (channel c: x on c only), at 0 ----
    touched = []
    if name is not None and name not in variables:
        m = _CHANNEL.match(name)
        key, channel = (m.group(1), int(m.group(2))) if m else (name, None)
        x = mi.Float(0.0)
        dr.enable_grad(x)
        for tp in dscene.scene_parameters()[key]:
            base = tp[key]
            direction = dr.ones(type(base)) if channel is None else dr.zeros(type(base))
            if channel is not None:
                direction[channel] = 1.0
            tp[key] = base + x * direction
            tp.update()
            touched.append((tp, key, base))
        # the tangent into the scene's data now: the loop reads that data implicitly
        # (a traversal that reaches the loop from x across other edges is refused)
        dr.set_grad(x, 1.0)
        dr.enqueue(dr.ADMode.Forward, x)
        dr.traverse(dr.ADMode.Forward, dr.ADFlag.ClearEdges)
        variables[name] = x

    def restore():  # (x = 0: the detached value is the original, exactly)
        for tp, key, _ in touched:
            tp[key] = dr.detach(tp[key])
            tp.update()

    # ---- The pass: lanes of the chosen pixels, samples s0 .. s0 + samples ----
    n_pixels = int(np.prod(scene.sensor.film().crop_size()))
    if len(pixels) == n_pixels and np.array_equal(pixels, np.arange(n_pixels)):
        layout = PassLayout(mi, n_pixels, samples, dr.opaque(mi.UInt32, s0), setup.group_size)
    else:  # some pixels: lanes from host arrays
        lane = np.arange(len(pixels) * samples)
        layout = PassLayout.of_lanes(mi, np.repeat(pixels, samples), s0 + lane % samples,
                                     setup.group_size)
    value, _ = setup.trace(layout)
    return value, variables.get(name), restore
