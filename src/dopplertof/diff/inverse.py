"""Inverse problems by gradient descent: many parameters (a texture's texels, the
bodies' velocities) fitted to captures through reverse-mode gradients.

:func:`fit_captures` minimizes the captures' squared error

    loss(theta) = sum over captures c and pixels i of (render_c,i(theta) - capture_c,i)^2

(a render is the mean of its channels, as a capture is) by Adam steps, with one
:func:`dopplertof.diff.gradient` call per capture per iteration, whatever the number
of parameters. Each iteration renders with a new seed. The gradient uses the
residual of the previous iteration's render (another seed) as the loss's weights:
d/dtheta of sum_i 2 r_i(previous) render_i(theta), i.e. (R_A - C) . dR_B with A and B
independent. The plain 2 (R - C) . dR of one render would add the covariance of a
render and its own derivative, which pulls the fit off the truth by the renders'
relative variance (the same reason fit.py uses a cross loss). The first iteration
only renders (its adjoint is skipped: no weights yet).

Parameters are any names of :func:`dopplertof.diff.render.differentiable_names`
among the bodies' velocities (``body<k>.v<x|y|z>``, ``body<k>.w<x|y|z>``) and the
scene's mi.traverse keys (a uniform reflectance ``<bsdf>.reflectance.value``, a
texture ``<bsdf>.reflectance.data``). Each group has its own step size (Adam's steps
are about that size whatever the gradient's scale): velocities in m/s, angular
velocities in rad/s, reflectances (albedos, clipped to [0, 1]). The step sizes
decay geometrically to ``decay`` of themselves over the iterations (the late
iterations average the renders' noise).
"""

from __future__ import annotations

import time as _time
from dataclasses import dataclass, field

import numpy as np

from .loss import residual, residual_weighted_loss
from .progress import IterationProgress
from .render import _MOTION_NAME, DerivativeError, check_names

#: default Adam step sizes per group: m/s, rad/s, albedo
STEP_SIZES = {"velocity": 0.3, "angular": 0.1, "reflectance": 0.05}

#: bounds per group (None: unbounded)
BOUNDS = {"velocity": None, "angular": None, "reflectance": (0.0, 1.0)}


@dataclass
class InverseResult:
    values: dict  #: name -> fitted value (float, or a float64 array in the key's layout)
    history: list = field(default_factory=list)  #: per iteration: loss, seconds, scalars
    settings: dict = field(default_factory=dict)

    def __repr__(self) -> str:
        """One line: the values (an array by its shape and mean), the iterations and the
        last loss; not the history (print() showed all of it)."""
        values = ", ".join(f"{n}: {_short(v)}" for n, v in self.values.items())
        last = self.history[-1] if self.history else {}
        loss = f", loss {last['loss']:.4g}" if "loss" in last else ""
        return (f"InverseResult({values}; {max(len(self.history) - 1, 0)} iterations{loss}; "
                "history and settings: .history, .settings)")


def _short(value) -> str:
    """A fitted value in a few characters: a float to 6 digits, an array by its shape
    and mean."""
    array = np.asarray(value)
    if array.ndim == 0:
        return f"{float(array):.6g}"
    return f"array{array.shape} mean {float(array.mean()):.4g}"


def group_of(name: str) -> str:
    """The step-size group of a parameter name: velocity, angular or reflectance."""
    m = _MOTION_NAME.match(name)
    if m is None:
        return "reflectance"
    if m.group(1) == "camera":
        raise DerivativeError(f"{name}: fit_captures fits the bodies' motion and the "
                              "scene's keys, not the camera's velocity")
    return "angular" if m.group(3) == "w" else "velocity"


# ---- Reading and setting parameter values ----------------------------------------

def get_value(ds, name: str):
    """The current value of ``name``: a float for a velocity component, a float64
    array for a mi.traverse key (its values in Dr.Jit's ravel order)."""
    import drjit as dr

    m = _MOTION_NAME.match(name)
    if m is not None:
        v, w = ds.body_velocity(int(m.group(2)))
        return float((w if m.group(3) == "w" else v)["xyz".index(m.group(4))])
    current = ds.scene_parameters()[name][0][name]
    return np.asarray(dr.ravel(current), dtype=np.float64).ravel().copy()


def set_value(ds, name: str, value) -> None:
    """Set ``name`` to ``value`` (as :func:`get_value` returns it) in every scene
    holding it."""
    import drjit as dr

    m = _MOTION_NAME.match(name)
    if m is not None:
        k, axis = int(m.group(2)), "xyz".index(m.group(4))
        v, w = ds.body_velocity(k)
        (w if m.group(3) == "w" else v)[axis] = float(value)
        ds.set_body_velocity(k, v, w)
        return
    mi = ds.mi
    for tp in ds.scene_parameters()[name]:
        current = tp[name]
        flat = np.asarray(value, dtype=np.float32).ravel()
        if isinstance(current, mi.TensorXf):
            tp[name] = mi.TensorXf(flat.reshape(dr.shape(current)))
        else:
            tp[name] = dr.unravel(type(current), mi.Float(flat))
        tp.update()


# ---- Adam with per-group step sizes and bounds ------------------------------------

class Adam:
    """Adam (Kingma and Ba) over a flat vector of parameters, each with its own step
    size and bounds."""

    def __init__(self, step_sizes, lower, upper, beta1=0.6, beta2=0.9, eps=1e-12):
        self.step_sizes, self.lower, self.upper = step_sizes, lower, upper
        self.beta1, self.beta2, self.eps = beta1, beta2, eps
        self.m = np.zeros_like(step_sizes)
        self.v = np.zeros_like(step_sizes)
        self.t = 0

    def step(self, theta, grad, scale: float = 1.0):
        """theta after one step along -grad (step sizes times ``scale``), clipped."""
        self.t += 1
        self.m = self.beta1 * self.m + (1 - self.beta1) * grad
        self.v = self.beta2 * self.v + (1 - self.beta2) * grad * grad
        m_hat = self.m / (1 - self.beta1 ** self.t)
        v_hat = self.v / (1 - self.beta2 ** self.t)
        theta = theta - scale * self.step_sizes * m_hat / (np.sqrt(v_hat) + self.eps)
        return np.clip(theta, self.lower, self.upper)


class Parameters:
    """The fitted names as one flat vector: their layout, step sizes and bounds."""

    def __init__(self, ds, names, step_sizes=None, bounds=None):
        steps = {**STEP_SIZES, **(step_sizes or {})}
        limits = {**BOUNDS, **(bounds or {})}
        self.ds, self.names, self.slices = ds, list(names), {}
        sizes, lower, upper, at = [], [], [], 0
        for name in self.names:
            group = group_of(name)
            n = np.size(get_value(ds, name))
            self.slices[name] = slice(at, at + n)
            at += n
            lo, hi = limits[group] or (-np.inf, np.inf)
            sizes.append(np.full(n, float(steps[group])))
            lower.append(np.full(n, lo))
            upper.append(np.full(n, hi))
        self.step_sizes, self.lower, self.upper = (np.concatenate(a) for a in (sizes, lower, upper))

    def values(self) -> np.ndarray:
        return np.concatenate([np.atleast_1d(get_value(self.ds, n)) for n in self.names])

    def set(self, theta) -> None:
        for name in self.names:
            part = theta[self.slices[name]]
            set_value(self.ds, name, part[0] if _MOTION_NAME.match(name) else part)

    def flat(self, grad: dict) -> np.ndarray:
        return np.concatenate([np.atleast_1d(np.asarray(grad[n], np.float64)).ravel()
                               for n in self.names])

    def as_dict(self, theta) -> dict:
        return {n: (float(theta[s][0]) if _MOTION_NAME.match(n) else theta[s].copy())
                for n, s in self.slices.items()}


# ---- The fit ------------------------------------------------------------------------

def fit_captures(ds, captures, names, iterations: int = 60, spp: int = 32, seed: int = 1,
                 step_sizes=None, bounds=None, decay: float = 0.1, mask=None,
                 progress=None, callback=None) -> InverseResult:
    """Fit ``names`` of DifferentiableScene ``ds`` to ``captures`` (see the module
    docstring), starting from the scene's current values; the scene is left at the
    fitted values. ``captures``: {name: (render params mapping, e.g. w_g,
    hetero_frequency, hetero_offset; target image (H, W))}; iteration i renders with
    seed ``seed + i`` (give the captures' own seed outside that range: independent
    random numbers). ``step_sizes``/``bounds``: per group over :data:`STEP_SIZES` and
    :data:`BOUNDS`; ``mask``: (H, W) pixels of the loss (default all); ``progress``: a
    tqdm bar (True, or None with stderr a terminal), one line per iteration on stderr
    (None otherwise), nothing (False); ``callback(iteration, values)`` after each."""
    if not isinstance(iterations, (int, np.integer)) or iterations < 1:
        raise DerivativeError(f"iterations must be a positive integer, got {iterations!r}")
    check_names(ds, names)
    params = Parameters(ds, names, step_sizes, bounds)
    targets = {c: np.asarray(image, np.float64) for c, (_, image) in captures.items()}
    weight = None if mask is None else np.asarray(mask, np.float64)
    adam, theta = Adam(params.step_sizes, params.lower, params.upper), params.values()
    residuals, history, started = {}, [], _time.perf_counter()
    report = IterationProgress(progress, iterations, "inverse", _inverse_line,
                               lambda entry: {"loss": f"{entry['loss']:.4g}"})
    try:
        for i in range(iterations + 1):
            grad, loss = _iteration(ds, captures, targets, residuals, names, spp,
                                    seed + i, weight)
            entry = {"iteration": i, "loss": loss, "seconds": _time.perf_counter() - started,
                     **{n: v for n, v in params.as_dict(theta).items() if np.ndim(v) == 0}}
            history.append(entry)
            report.update(entry)
            if callback is not None:
                callback(i, params.as_dict(theta))
            if i == iterations:
                break
            if grad is not None:  # (the first iteration only renders)
                scale = decay ** (i / max(iterations - 1, 1))
                theta = adam.step(theta, params.flat(grad), scale)
                params.set(theta)
    finally:
        report.close()
    settings = {"iterations": int(iterations), "spp": int(spp), "seeds": [seed, seed + iterations],
                "names": list(names), "captures": list(captures), "decay": decay,
                "step_sizes": {**STEP_SIZES, **(step_sizes or {})}}
    return InverseResult(params.as_dict(theta), history, settings)


def _iteration(ds, captures, targets, residuals, names, spp, seed, weight):
    """One gradient call per capture at ``seed``: the summed gradient of the cross
    loss against ``residuals`` (the previous renders' residuals; None when there are
    none yet) and the current renders' squared loss; ``residuals`` is updated."""
    from .adjoint import gradient

    total, loss = None, 0.0
    for c, (render_params, _) in captures.items():
        previous = residuals.get(c)
        g = gradient(ds, residual_weighted_loss(ds.mi, previous), names=names, spp=spp,
                     seed=seed, params=dict(render_params))
        current = residuals[c] = residual(g.image, targets[c], weight)
        loss += float(np.sum(current * current))
        if previous is not None:
            total = dict(g) if total is None else {n: total[n] + g[n] for n in names}
    return total, loss


def _inverse_line(entry: dict) -> str:
    """fit_captures' progress line of one iteration: the loss and the scalar values."""
    scalars = ", ".join(f"{k} {v:+.4f}" for k, v in entry.items()
                        if k not in ("iteration", "loss", "seconds"))
    return (f"inverse iteration {entry['iteration']}: loss {entry['loss']:.6g}"
            + (f", {scalars}" if scalars else "") + f", {entry['seconds']:.1f} s")


