"""Gradients of a loss of the rendered image: one primal and one adjoint pass, whatever
the number of parameters (reverse mode; see docs/differentiable.md, "Reverse mode").

The render is the pipeline's own (integrators/pipeline.py: the same passes, sums and
film, so the image is the one :func:`dopplertof.render` gives at these settings). The
loss's derivative with respect to the image, dL/dI (H x W x C), becomes each lane's
adjoint: how much the image's pixels change per unit of the lane's value, weighted by
dL/dI. For the importance film a lane counts 1/n in its own pixel (n its pixel's
samples); for the splat film it counts w_o / (n W_{j+o}) in each pixel j + o its
filter reaches (w_o its filter weight there, W the pixel's normalizing weight, which
depends on film positions only, not on any parameter): the adjoint gathers with the
same weights the splat scattered with. The adjoint pass then traces the same lanes
(same random numbers), by one of :data:`METHODS`: with the parameters attached to
Dr.Jit's AD graph, propagating sum(adjoint x value) back through the path loop, which
Dr.Jit replays in reverse (the loop's ``max_iterations`` hint sets the stack it
records its state on: ``trajectory``); or detached, back-propagating each vertex's
local terms (``path``, integrators/path_adjoint.py). Either way memory does not grow
with the number of parameters.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from .render import (_CHANNEL, _MOTION_NAME, MODULATION_PARAMETERS, DerivativeError,
                     DifferentiableScene, _ModulationVariables, _motion_value, check_names,
                     differentiable_key, differentiable_names)


class Gradient(dict):
    """d loss / d parameter by name: a float, or an array (float64) for a vector
    parameter (a colour's channels; a texture's texels, in the data's shape).
    Also ``image`` (H, W, C float32, the render), ``loss`` (its value), ``spp``,
    ``seed`` and ``method`` (the adjoint's: ``trajectory`` or ``path``)."""

    image: np.ndarray
    loss: float
    spp: int
    seed: int
    method: str


#: how the adjoint pass runs: ``trajectory``, Dr.Jit's reverse replay of the path
#: loop (every vertex follows its ray: forward mode's tangents exactly, 18x a render's
#: memory); ``path``, path replay (integrators/path_adjoint.py: each vertex's local
#: terms, about 2x a render's memory; the same gradients where no vertex after the
#: first bounce moves, else another estimator of them, unbiased but far noisier for
#: motion in indirect light); ``auto``, path replay where it gives the same gradients
#: and can run, else the trajectory
METHODS = ("auto", "trajectory", "path")


def gradient(dscene, loss, names=None, spp: int | None = 64, seed: int = 0, params=None,
             max_lanes: int = 1 << 20, method: str = "auto") -> Gradient:
    """d loss(image) / d parameter for every name of :func:`parameter_names` (or
    ``names``), from one primal and one adjoint pass: by default every name of
    :func:`differentiable_names`.

    ``loss``: a callable taking the image (a Dr.Jit tensor, H x W x C) and returning a
    scalar (a Dr.Jit Float of width 1 or a Python float). ``params``: render parameters
    over the scene's (e.g. ``{"film_sampling": "importance"}``: with the same ``spp``
    and ``seed`` the random numbers of :func:`render_derivatives`). Adaptive sampling is
    off (the counts would depend on the parameters' render). ``max_depth`` must be
    finite (the adjoint replays at most that many bounces). ``method``: one of
    :data:`METHODS`."""
    from ..integrators.dtof_path import integrator_class
    from ..integrators.pipeline import Accumulator, PassPlanner, _spectrum_channels
    from ..sampling import check_sample_count

    dscene, names, spp, seed, p = _request(dscene, loss, names, spp, seed, params)
    mi = dscene.mi
    check_sample_count(p.time_correlate_number, spp, p.path_group_size, p.samples_per_pass)
    if method not in METHODS:
        raise DerivativeError(f"gradient: unknown method {method!r}: expected one of "
                              f"{', '.join(METHODS)}")
    width, height = (int(v) for v in dscene.scene.sensor.film().crop_size())
    variables, scene, restore = attach(dscene, names)
    try:
        setup = integrator_class(mi)().prepared(scene, p, spp, int(seed))
        variables.update(_ModulationVariables(
            mi, setup.modulation_weight, setup.modulation, names).variables)
        plan = PassPlanner(spp, setup.group_size, width * height, p, max_lanes, None)
        sums = Accumulator(mi, setup, width * height, _spectrum_channels(mi), False)
        sums.start()
        passes = plan.uniform(0)

        motion = any(_MOTION_NAME.match(name) for name in names)  # (a body's, the camera's)
        method = _method(mi, setup, motion, method)

        # ---- Primal: the render, as the pipeline sums it ----
        kept = _primal(mi, setup, plan, sums, passes, method == "path")
        image = sums.image(np.full(width * height, spp), (height, width))

        # ---- The loss and its derivative with respect to the image ----
        loss_value, image_adjoint = _loss_adjoint(mi, loss, image)
        lane_adjoint = LaneAdjoint(mi, setup, sums, image_adjoint, spp, (height, width))

        # ---- Adjoint: the same lanes, backwards ----
        if variables and np.any(image_adjoint) and method == "path":
            _path_adjoint(mi, setup, plan, passes, kept, lane_adjoint, motion)
        elif variables and np.any(image_adjoint):
            _trajectory_adjoint(mi, setup, plan, passes, kept, lane_adjoint)
        out = Gradient({name: _read_gradient(variables, name) for name in names})
    finally:
        restore()
    out.image, out.loss, out.spp, out.seed, out.method = image, loss_value, spp, seed, method
    return out


def _request(dscene, loss, names, spp, seed, params):
    """:func:`gradient`'s arguments checked (each wrong one named):
    (DifferentiableScene, names, spp, seed, render parameters)."""
    from ..arguments import check_callable, check_params, check_seed, check_spp

    dscene = as_differentiable(dscene)
    check_callable(loss, "loss", optional=False)
    spp, seed = check_spp(spp), check_seed(seed)
    names = differentiable_names(dscene) if names is None else _name_list(names)
    check_names(dscene, names)
    p = gradient_params(dscene, check_params(params))
    return dscene, names, dscene.scene.spp if spp is None else spp, seed, p


def as_differentiable(dscene):
    """``dscene`` as a DifferentiableScene: one as is, a DopplerScene (or a plain
    ``mi.Scene``) made one at its own velocities; anything else a TypeError saying what
    to pass (a DopplerScene raised AttributeError 'no attribute mi')."""
    from ..arguments import check_scene

    if isinstance(dscene, DifferentiableScene):
        return dscene
    return DifferentiableScene(check_scene(dscene, "dscene"))


def _name_list(names) -> list:
    """``names`` as a list of parameter names (a str is one name's letters: refused)."""
    if isinstance(names, str) or not all(isinstance(n, str) for n in names):
        raise TypeError(f"names must be a list of parameter names (one name: "
                        f"[{names!r}]), got {type(names).__name__} {names!r}")
    return list(names)


def _primal(mi, setup, plan, sums, passes, path: bool):
    """Trace ``passes`` into ``sums`` (the pipeline's Accumulator); one pass is kept for
    the adjoint, in the list returned, which the adjoint empties as it takes it (else
    the list is empty: the adjoint traces each pass again): for the
    trajectory method traced with the parameters attached, (layout, value, film
    offset); for path replay detached, with the values' path-length derivatives too."""
    import drjit as dr

    kept = []
    for first_chunk, end_chunk in passes:
        layout, chunk_size, threads = plan.lanes(mi, first_chunk, end_chunk, None)
        with dr.suspend_grad(when=len(passes) > 1 or path):
            traced = setup.trace(layout, length_derivative=path)
            # (path replay: the film offsets are recomputed where they are read, a
            # cheap expression of the lanes' random numbers, instead of stored)
            dr.eval(*(traced[:1] + traced[2:] if path else traced))
        sums.add(dr.detach(traced[0]), dr.detach(traced[1]), chunk_size, threads, pilot=False)
        kept = [(layout, *traced)] if len(passes) == 1 else []
    return kept


def _trajectory_adjoint(mi, setup, plan, passes, kept, lane_adjoint) -> None:
    """Each pass's lanes traced with the parameters attached, and Dr.Jit's reverse-mode
    replay of the path loop from their adjoint-weighted sum."""
    import drjit as dr

    for first_chunk, end_chunk in passes:
        if not kept:
            layout, _, _ = plan.lanes(mi, first_chunk, end_chunk, None)
            value, film_offset = setup.trace(layout)
        else:
            layout, value, film_offset = kept.pop()
        dr.backward(lane_adjoint.weighted_sum(layout, value, film_offset))
        del value, film_offset


def _path_adjoint(mi, setup, plan, passes, kept, lane_adjoint, motion: bool) -> None:
    """Each pass's paths traced again by the path-replay adjoint
    (integrators/path_adjoint.py), with each lane's adjoint and primal sums (``motion``:
    a body's or the camera's motion is differentiated)."""
    import drjit as dr

    for first_chunk, end_chunk in passes:
        if not kept:
            layout, _, _ = plan.lanes(mi, first_chunk, end_chunk, None)
            with dr.suspend_grad():
                value, film_offset, value_dl, lit = setup.trace(layout, length_derivative=True)
        else:
            layout, value, film_offset, value_dl, lit = kept.pop()
        delta = mi.Spectrum(*lane_adjoint.lane_adjoints(layout, value, film_offset))
        setup.adjoint(layout, delta, value, value_dl, motion, lit)
        dr.eval()  # (runs the loop: the gradients are what it scatters)


def _method(mi, setup, motion: bool, method: str) -> str:
    """The method ``method`` stands for: ``auto`` is path replay wherever it can run
    (check_path_replay: its memory does not grow with the path's length, and it gives
    the trajectory's gradients, per sample where the moving bodies are flat-faced and
    the lights are points, spots or directional: no MIS weight moves), else the
    trajectory. ``motion`` (whether a body's or the camera's motion is
    differentiated) does not change the choice."""
    if method == "path":
        check_path_replay(mi, setup)
    if method != "auto":
        return method
    try:
        check_path_replay(mi, setup)
    except DerivativeError:
        return "trajectory"
    return "path"


def check_path_replay(mi, setup) -> None:
    """What path replay needs, or a DerivativeError naming what is missing: an RGB
    variant, sampled time, no delta BSDF lobes (a vertex after one is not free on its
    surface)."""
    problems = []
    if mi.is_spectral or mi.is_polarized:
        problems.append(f"an RGB variant (not {mi.variant()})")
    if setup.analytic or setup.control_variate:
        problems.append(f"sampled time (not time_sampling_method="
                        f"'{setup.params.time_sampling_method}')")
    shapes = list(setup.scene.static.shapes()) + [
        shape for body in setup.scene.bodies for shape in body.scene.shapes()]
    if any(mi.has_flag(shape.bsdf().flags(), mi.BSDFFlags.Delta) for shape in shapes
           if shape.bsdf() is not None):
        problems.append("no BSDF with a delta lobe (mirror, glass)")
    if problems:
        raise DerivativeError("gradient(method='path') needs " + " and ".join(problems)
                              + "; method='trajectory' has no such limits")


def gradient_params(dscene, params=None):
    """The render parameters of :func:`gradient`: the DifferentiableScene's, with the
    scene's own film (``params`` over them), no adaptive sampling, a finite depth."""
    from ..params import RenderParams

    base = dscene.scene.params.resolved(dscene.scene.shutter_interval, sampled=True)
    p = replace(dscene.params, film_sampling=base.film_sampling)
    if params:
        p = RenderParams.from_mapping(dict(params), where="gradient params", base=p)
        p = p.resolved(dscene.scene.shutter_interval, sampled=True)
        if p.antithetic_mapping == "motion":
            p = replace(p, antithetic_mapping="replay")
    if p.max_depth < 1:
        raise DerivativeError(
            "gradient: max_depth must be finite (the adjoint pass replays at most max_depth "
            "bounces); set max_depth in the scene or params")
    return replace(p, adaptive_sampling=False)


def attach(dscene, names):
    """The AD variables of ``names`` that live outside the integrator (motion: opaque
    Floats the traced scene's VelocityMotions hold; Mitsuba parameters: a zero of the
    parameter's type added to it, in every scene that holds the key), the traced scene
    and a function that puts the scene parameters back. (The modulation's variables are
    made with the integrator: _ModulationVariables.)"""
    import drjit as dr

    mi = dscene.mi
    variables = {}
    for name in names:
        if _MOTION_NAME.match(name):
            x = dr.opaque(mi.Float, _motion_value(dscene, name))
            dr.enable_grad(x)
            variables[name] = x
    scene = dscene._traced(variables)
    touched = []
    keys = {(_CHANNEL.match(n).group(1) if _CHANNEL.match(n) else n) for n in names
            if not _MOTION_NAME.match(n) and n not in MODULATION_PARAMETERS}
    for key in sorted(keys):
        holders = dscene.scene_parameters()[key]
        if not differentiable_key(holders[0], key):
            raise DerivativeError(
                f"{key}: not a differentiable parameter (its mi.traverse flags or type: "
                f"{type(holders[0][key]).__name__}); differentiable_names(ds) lists those that are")
        x = dr.zeros(type(holders[0][key]), dr.shape(holders[0][key]))
        dr.enable_grad(x)
        for tp in holders:
            base = tp[key]
            tp[key] = base + x
            tp.update()
            touched.append((tp, key))
        variables[key] = x

    def restore():  # (x = 0: the detached value is the original, exactly)
        for tp, key in touched:
            tp[key] = dr.detach(tp[key])
            tp.update()

    return variables, scene, restore


def _loss_adjoint(mi, loss, image):
    """The loss's value and its derivative with respect to ``image`` (float64 host
    array of the image's shape; zero where the loss does not depend on it)."""
    import drjit as dr

    tensor = mi.TensorXf(image)
    dr.enable_grad(tensor)
    value = loss(tensor)
    if not (dr.is_array_v(value) or isinstance(value, (int, float, np.number, np.ndarray))):
        raise TypeError(f"gradient: the loss must return a scalar (a Dr.Jit Float of the "
                        f"image), got {type(value).__name__} {value!r}")
    if not dr.grad_enabled(value):  # every derivative would be 0: say why instead
        raise DerivativeError(
            f"gradient: the loss ({type(value).__name__}) does not depend on the image "
            "through Dr.Jit: it is detached from automatic differentiation (computed "
            "with NumPy, float() or dr.detach, or a constant); compute it with Dr.Jit "
            "operations on the image tensor, e.g. dr.mean(dr.square(image - target))")
    if dr.width(value) != 1:
        raise DerivativeError(
            f"gradient: the loss must be a scalar, got {dr.width(value)} values "
            "(reduce it, e.g. with dr.sum or dr.mean)")
    number = float(np.asarray(dr.detach(value)).ravel()[0])
    if not math.isfinite(number):
        raise DerivativeError(
            f"gradient: the loss is {number} (not finite), so no derivative of it is; "
            "check the loss for a division by zero, a log of zero or a NaN target")
    dr.backward(value)
    return number, np.asarray(dr.grad(tensor), dtype=np.float64).reshape(image.shape)


class LaneAdjoint:
    """Each lane's adjoint: sum over the pixels its sample reaches of
    (d pixel / d lane value) x dL/d pixel, per channel."""

    def __init__(self, mi, setup, sums, image_adjoint, spp: int, shape):
        self.mi, self.splat, self.spp = mi, setup.splat, spp
        self.channels = image_adjoint.shape[-1]
        h, w = shape
        if sums.weighted:  # dL/dI over each pixel's normalizing weight
            weight = sums.splat_weight(np.full(h * w, spp), shape)
            scaled = image_adjoint / weight[..., None]
            targets = [_shifted(scaled, ox, oy) for ox, oy in self.splat.offsets]
        else:  # one pixel, weight 1 (a box splat or the importance film)
            targets = [image_adjoint.reshape(h * w, -1)]
        #: per offset, per channel: dL/dI of the pixel a source pixel's samples reach there
        self.targets = [[mi.Float(t[:, c]) for c in range(self.channels)] for t in targets]

    def lane_adjoints(self, layout, value, film_offset) -> list:
        """Per channel, each lane's d loss / d its value (a Float; zero where the lane's
        value is not finite, as the film leaves such samples out), detached."""
        import drjit as dr

        mi = self.mi
        finite = dr.isfinite(dr.detach(value[0]))
        for c in range(1, self.channels):
            finite &= dr.isfinite(dr.detach(value[c]))
        weights = ([mi.Float(1.0)] if len(self.targets) == 1
                   else self.splat.lane_weights(mi, dr.detach(film_offset)))
        out = []
        for c in range(self.channels):
            adjoint = mi.Float(0.0)
            for w, target in zip(weights, self.targets):
                adjoint += w * dr.gather(mi.Float, target[c], layout.pixel)
            out.append(dr.select(finite, adjoint * (1.0 / self.spp), 0.0))
        return out

    def weighted_sum(self, layout, value, film_offset):
        """sum over lanes and channels of adjoint x value (the lanes' finite values),
        a Float whose backward pass gives the parameters' gradients."""
        import drjit as dr

        adjoints = self.lane_adjoints(layout, value, film_offset)
        total = self.mi.Float(0.0)
        for c, adjoint in enumerate(adjoints):
            total += dr.select(adjoint != 0.0, adjoint * value[c], 0.0)
        return dr.sum(total)


def _shifted(values, ox: int, oy: int):
    """(H * W, C): at source pixel (y, x), ``values`` at target (y + oy, x + ox), zero
    where the target is outside the window."""
    h, w = values.shape[:2]
    out = np.zeros_like(values)
    out[max(0, -oy):min(h, h - oy), max(0, -ox):min(w, w - ox)] = \
        values[max(0, oy):min(h, h + oy), max(0, ox):min(w, w + ox)]
    return out.reshape(h * w, -1)


def _read_gradient(variables, name):
    """d loss / d ``name`` from its variable's gradient: a float for a scalar (or one
    channel, ``KEY[c]``), else a float64 array (a tensor's in its shape, e.g. a
    texture's (H, W, C))."""
    import drjit as dr

    m = _CHANNEL.match(name)
    key = name if name in variables else m.group(1)
    variable = variables[key]
    grad = np.asarray(dr.grad(variable), dtype=np.float64)
    if name not in variables:
        return float(grad.ravel()[int(m.group(2))])
    if grad.size == 1:
        return float(grad.ravel()[0])
    return grad if dr.is_tensor_v(variable) else grad.ravel()  # (a texture: its shape)
