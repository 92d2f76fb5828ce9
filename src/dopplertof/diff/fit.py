"""Velocities fitted through the renderer: captures in, each body's motion out.

A capture folder (``dopplertof capture``) holds the captures and, in summary.json, the
scene they came from and its parameters. :func:`fit` renders the heterodyne captures
(they carry the Doppler content) with every body moving at constant linear velocity
(and, with ``angular=True``, angular velocity) about its pose at mid-exposure, and
minimizes the squared difference to the given captures over the bodies' interior
pixels:

    loss(theta) = sum over captures c and pixels i of (render_c,i(theta) - capture_c,i)^2

by Gauss-Newton steps with Levenberg-Marquardt damping, with the Jacobian J from
forward-mode derivatives (:mod:`.render`). Two details make it unbiased for renders of
few samples: the loss is estimated by the cross product (R_A - C) . (R_B - C) of two
renders of independent seeds A and B (its expectation has no variance term, which
depends on the velocities), with the metric (J_A^T J_B + J_B^T J_A) / 2 (J_A^T J_A
would add the Jacobian's noise energy and shorten every step); and the residuals are
sums over blocks of interior pixels. Every iteration renders with the same two seeds
(correlated sampling): the loss is a smooth function of theta, not a new noisy sample
each time.

The start is each body's linear velocity from the closed-form per-pixel radial
velocities (velocity.npy): at pixel i of a translating body, radial velocity
r_i = (u . n_i) / (d_i . n_i), linear in u, solved by least squares over the body's
pixels (normals and rays from the scene's geometry at mid-exposure); or a start the
user gives.

The uncertainties are those of a least-squares fit: cov = s^2 (J^T J)^-1 with s^2 the
final loss over its degrees of freedom (the render and capture noise that the residual
shows); a radial velocity's follows from it through its derivative.
"""

from __future__ import annotations

import json
import os
import re
import time as _time
from dataclasses import dataclass, field, replace

import numpy as np

from ..arguments import check_seed
from .motion import VelocityMotion

#: captures fitted (their Doppler content is what the velocities change)
FIT_CAPTURES = ("heterodyne_0", "heterodyne_0.25")

#: directions of the (column-scaled) Jacobian below this fraction of its largest
#: singular value are not constrained by the captures: no step along them
RCOND = 0.05

#: default samples per pixel of the fit's renders
FIT_SPP = 256


class FitError(ValueError):
    """A capture folder, start or setting that cannot be fitted; the message names it."""


@dataclass
class CaptureData:
    scene: object  #: DopplerScene, loaded as the capture saw it
    base: object  #: RenderParams of the capture
    summary: dict
    captures: dict  #: name -> (H, W) float64
    records: dict  #: name -> summary.json's capture record
    velocity: np.ndarray | None  #: closed-form radial velocity (H, W) or None


@dataclass
class FitResult:
    bodies: list
    iterations: int
    loss: float
    history: list = field(default_factory=list)
    settings: dict = field(default_factory=dict)

    def as_json(self) -> dict:
        return {"bodies": self.bodies, "iterations": self.iterations, "loss": self.loss,
                "history": self.history, "settings": self.settings}


# ---- Reading a capture folder ------------------------------------------------------

def _declared_defaults(path: str) -> set:
    with open(path, encoding="utf-8") as f:
        return set(re.findall(r"<default\s+name=\"([^\"]+)\"", f.read()))


def load_capture(folder, defines=None) -> CaptureData:
    """The scene, parameters and captures of a capture folder. The scene is loaded with
    its resolution set to the captures' (through the <default> values it declares:
    res, resx/resy, width/height) and ``defines`` (the capture's -D values)."""
    import dopplertof
    from ..params import RenderParams

    folder = os.fspath(folder)
    summary_path = os.path.join(folder, "summary.json")
    if not os.path.isdir(folder):
        raise FitError(f"capture folder not found: {folder}")
    if not os.path.isfile(summary_path):
        raise FitError(f"{folder} has no summary.json: not a folder written by "
                       "`dopplertof capture`")
    try:
        with open(summary_path, encoding="utf-8") as f:
            summary = json.load(f)
        scene_path = summary["scene"]
        width, height = summary["resolution"]
        records = {r["name"]: r for r in summary["captures"]}
        params = summary["render_params"]
    except (ValueError, KeyError, TypeError) as e:
        raise FitError(f"{summary_path} cannot be read as a capture summary: {e}") from None
    if not os.path.isfile(scene_path):
        raise FitError(f"the capture's scene file is not found: {scene_path}")
    declared = _declared_defaults(scene_path)
    overrides = {}
    for name, value in (("res", width), ("resx", width), ("width", width),
                        ("resy", height), ("height", height)):
        if name in declared and (name != "res" or width == height):
            overrides[name] = str(value)
    overrides.update(defines or {})
    scene = dopplertof.load_file(scene_path, overrides)
    got = tuple(int(v) for v in scene.sensor.film().crop_size())
    if got != (width, height):
        raise FitError(f"the scene loads at {got[0]}x{got[1]} but the captures are "
                       f"{width}x{height}: pass the capture's -D values")
    if not scene.bodies:
        raise FitError(f"{scene_path} has no moving body: nothing to fit")
    base = RenderParams.from_mapping({k: v for k, v in params.items() if v is not None},
                                     where=f"{summary_path} render_params")
    captures = {}
    for name in FIT_CAPTURES:
        path = os.path.join(folder, f"{name}.npy")
        if name not in records or not os.path.isfile(path):
            raise FitError(f"{folder} has no {name}.npy: the fit needs the heterodyne "
                           "captures")
        image = np.load(path).astype(np.float64)
        if image.shape != (height, width):
            raise FitError(f"{path} is {image.shape}, not the summary's {height}x{width}")
        captures[name] = image
    vpath = os.path.join(folder, "velocity.npy")
    velocity = np.load(vpath).astype(np.float64) if os.path.isfile(vpath) else None
    return CaptureData(scene, base, summary, captures, records, velocity)


def _capture_params(data: CaptureData, name: str):
    from ..tof.capture import CaptureSpec

    r = data.records[name]
    return CaptureSpec(name, r["kind"], r["w_g_MHz"], r["hetero_frequency"],
                       r["hetero_offset"]).params(data.base)


# ---- Geometry and the closed-form start --------------------------------------------

def _scene_with(scene, motions):
    return replace(scene, bodies=tuple(replace(b, motion=m, _swept={})
                                       for b, m in zip(scene.bodies, motions)))


def _truth(scene, motions, params):
    from ..tof.ground_truth import ground_truth

    return ground_truth(_scene_with(scene, [_plain(m) for m in motions]), params)


def _plain(m: VelocityMotion) -> VelocityMotion:
    return VelocityMotion(m.pivot, [float(x) for x in m.velocity],
                          [float(x) for x in m.angular_velocity], m.t_ref, m.reference,
                          m.interval, m.base)


def interior(truth, k: int) -> np.ndarray:
    """Pixels whose 3x3 neighbourhood sees one face of body k: away from its silhouette
    and its edges, whose motion (visibility) the derivatives do not model."""
    on = truth.body == k
    n = np.nan_to_num(truth.normal)
    inner = on.copy()
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            shifted = np.roll(np.roll(n, dy, 0), dx, 1)
            inner &= np.roll(np.roll(on, dy, 0), dx, 1) & (np.sum(n * shifted, -1) > 0.999)
    inner[[0, -1], :] = False
    inner[:, [0, -1]] = False
    return inner


def closed_form_velocity(truth, radial, mask) -> np.ndarray:
    """The linear velocity u whose radial velocities (u . n) / (d . n) best match
    ``radial`` on ``mask`` (least squares; minimum norm where faces leave it open)."""
    ok = mask & np.isfinite(radial)
    if ok.sum() < 3:
        return np.zeros(3)
    n, d = truth.normal[ok], truth.direction[ok]
    rhs = radial[ok] * np.sum(d * n, -1)
    u, *_ = np.linalg.lstsq(n, rhs, rcond=1e-3)
    return u


def radial_velocity(truth, k: int):
    """summary.json's velocity_gt_median_m_s: the median radial velocity of body k's
    pixels at mid-exposure."""
    on = truth.body == k
    return float(np.median(truth.velocity[on])) if on.any() else None


# ---- The fit -----------------------------------------------------------------------

def fit(folder, start=None, spp: int = FIT_SPP, seed: int | None = None,
        iterations: int = 12, angular: bool = False, defines=None, progress=None,
        tolerance: float = 1e-3, block: int = 8) -> FitResult:
    """Fit every body's velocity to the captures in ``folder`` (see the module
    docstring). ``start``: {body index: linear velocity (3,) or (v (3,), omega (3,))}
    to start from instead of the closed form; ``seed``: of the fit's renders (default:
    the capture's + 1, independent of its noise); ``block``: the residuals are sums over
    blocks of block x block interior pixels of one body (a per-pixel Jacobian's Monte
    Carlo noise would inflate J^T J and shorten every step; block sums keep the
    velocity field's variation and average the noise)."""
    data = load_capture(folder, defines)
    if not isinstance(spp, (int, np.integer)) or spp < 1:
        raise FitError(f"spp must be a positive integer, got {spp!r}")
    seed = int(data.summary.get("seed", 0)) + 1 if seed is None else seed
    # (its renders use seed and seed + 1: both below 2^64)
    seed = check_seed(seed, "seed", FitError)
    check_seed(seed + 1, "seed + 1 (the Jacobian's renders)", FitError)
    # bodies at their poses at mid-exposure (from the scene), velocities to be fitted
    motions, t_mid = _motions_at_mid_exposure(data)
    geometry = _truth(data.scene, motions, data.base)
    masks = _interior_masks(data.scene, geometry)

    # ---- Start ----
    closed_form = [None if data.velocity is None
                   else closed_form_velocity(geometry, data.velocity, mask) for mask in masks]
    start = dict(start or {})
    _start_motions(motions, start, closed_form, folder)

    # ---- Gauss-Newton with Levenberg-Marquardt damping ----
    problem = _FitProblem(data, motions, masks, (seed, seed + 1), angular, block)
    started = _time.perf_counter()
    theta, state, loss_ab, history, done = _gauss_newton(problem, spp, iterations,
                                                         tolerance, progress, started)
    (r, _), (r_b, _) = state
    loss = 0.5 * float(r @ r + r_b @ r_b)

    # ---- Uncertainties from the final Jacobian ----
    cov, sigma, seen = _covariance(state, loss)
    bodies = problem.body_entries(theta, cov, sigma, history[0], closed_form)
    settings = {
        "capture": os.path.abspath(os.fspath(folder)), "captures_fitted": list(FIT_CAPTURES),
        "spp": int(spp), "seed": seed, "jacobian_seed": seed + 1,
        "pixels": int(problem.pixels.size), "block": int(block),
        "residuals": "per capture, sums over blocks of interior pixels of one body",
        "parameters": problem.names, "angular": bool(angular),
        "start": "user" if start else "closed form (velocity.npy)",
        **_method_notes(t_mid),
        "unconstrained": [n for n, ok in zip(problem.names, seen) if not ok],
        "seconds": round(_time.perf_counter() - started, 3),
    }
    settings["cross_loss"] = loss_ab
    return FitResult(bodies, done, loss, history, settings)


def _motions_at_mid_exposure(data: CaptureData):
    """Each body's VelocityMotion about its pose at mid-exposure t_mid (velocities 0),
    and t_mid."""
    from ..tof.ground_truth import mid_exposure

    scene = data.scene
    t0, _, t1 = mid_exposure(scene, data.base)
    t_mid = 0.5 * (t0 + t1)
    motions = [VelocityMotion.from_motion(b.motion, t0, t1, t_ref=t_mid)
               for b in scene.bodies]
    for m in motions:
        m.velocity, m.angular_velocity = [0.0] * 3, [0.0] * 3
    return motions, t_mid


def _interior_masks(scene, geometry) -> list:
    """Per body, its :func:`interior` pixels; a FitError for a body with fewer than 4."""
    masks = [interior(geometry, k) for k in range(len(scene.bodies))]
    for k, mask in enumerate(masks):
        if mask.sum() < 4:
            raise FitError(f"body {k} ({', '.join(scene.bodies[k].names)}) covers fewer than "
                           "4 interior pixels: too small to fit at this resolution")
    return masks


def _start_motions(motions, start: dict, closed_form, folder) -> None:
    """Set each body's velocities to the user's ``start`` where it names the body, else
    to its closed form; a FitError for a body named that the scene lacks, or for a body
    with neither."""
    n_bodies = len(motions)
    for k, value in start.items():
        if not isinstance(k, (int, np.integer)) or not 0 <= k < n_bodies:
            raise FitError(f"start names body {k!r}; the scene has bodies 0 .. {n_bodies - 1}")
    for k, m in enumerate(motions):
        if k in start:
            value = start[k]
            v, w = (value if len(value) == 2 and np.ndim(value[0]) == 1 else (value, None))
            m.velocity = [float(x) for x in np.asarray(v, float).reshape(3)]
            if w is not None:
                m.angular_velocity = [float(x) for x in np.asarray(w, float).reshape(3)]
        elif closed_form[k] is not None:
            m.velocity = closed_form[k].tolist()
        else:
            raise FitError(f"{folder} has no velocity.npy for the closed-form start: give a "
                           f"start for body {k}")


class _FitProblem:
    """The least squares of a fit. theta: per body its linear velocity (and, with
    ``angular``, its angular velocity), in the order of ``names``; it sets the
    ``motions`` that one differentiable scene per fitted capture shares. The residuals:
    per capture, block sums of render - capture over the bodies' interior pixels."""

    def __init__(self, data: CaptureData, motions, masks, seeds, angular: bool, block: int):
        from .render import DifferentiableScene

        self.data, self.motions, self.masks, self.angular = data, motions, masks, angular
        self.seeds = seeds  #: (A, B): the two renders of independent random numbers
        self.per_body = 6 if angular else 3  #: parameters per body
        # ---- One differentiable scene per capture, sharing the motions ----
        self.scenes = {}
        for name in FIT_CAPTURES:
            ds = DifferentiableScene(data.scene, _capture_params(data, name))
            ds.motions = motions
            self.scenes[name] = ds
        self.pixels = np.flatnonzero(np.logical_or.reduce(masks))
        self.groups = _blocks(masks, block)  # per rendered pixel, its block
        self.n_groups = int(self.groups.max()) + 1
        self.names = [f"body{k}.{kind}{a}" for k in range(len(motions))
                      for kind in ("vw" if angular else "v") for a in "xyz"]
        self.target = np.concatenate([self.pool(data.captures[c].ravel()[self.pixels])
                                      for c in FIT_CAPTURES])

    def pool(self, values):
        """Per-pixel values (of the rendered pixels) -> block sums."""
        return np.bincount(self.groups, weights=values, minlength=self.n_groups)

    def values(self) -> np.ndarray:
        """theta of the current motions."""
        out = []
        for m in self.motions:
            out += m.velocity
            if self.angular:
                out += m.angular_velocity
        return np.array(out, dtype=np.float64)

    def set_values(self, theta) -> None:
        per = self.per_body
        for k, m in enumerate(self.motions):
            m.velocity = theta[k * per:k * per + 3].tolist()
            if self.angular:
                m.angular_velocity = theta[k * per + 3:k * per + 6].tolist()

    def evaluate(self, samples: int):
        """Residuals and Jacobians at the current motions from two renders of
        independent random numbers (A, B): [(r_A, J_A), (r_B, J_B)]."""
        from .render import render_derivatives

        out = []
        for seed in self.seeds:
            residual, jacobian = [], []
            for c in FIT_CAPTURES:
                d = render_derivatives(self.scenes[c], self.names, spp=samples, seed=seed,
                                       pixels=self.pixels)
                residual.append(self.pool(d.image.mean(-1).ravel()[self.pixels]))
                jacobian.append(np.stack([self.pool(d.tangents[n].mean(-1).ravel()
                                                    [self.pixels]) for n in self.names], -1))
            out.append((np.concatenate(residual) - self.target, np.concatenate(jacobian)))
        return out

    def radial(self) -> list:
        """Each body's median radial velocity at the current motions (the truth's)."""
        truth = _truth(self.data.scene, self.motions, self.data.base)
        return [radial_velocity(truth, k) for k in range(len(self.motions))]

    def record(self, iteration: int, loss: float, samples: int, theta, started) -> dict:
        """One entry of the fit's history."""
        return {"iteration": iteration, "loss": loss, "spp": samples,
                "radial_velocity_m_s": self.radial(), "parameters": theta.tolist(),
                "seconds": _time.perf_counter() - started}

    def radial_gradient(self, theta) -> np.ndarray:
        """d (each body's radial velocity) / d theta (n_bodies, n_params): central
        differences of the truth (linear in u); leaves the motions at ``theta``."""
        grad_radial = np.zeros((len(self.motions), len(theta)))
        for j in range(len(theta)):
            h = 1e-3 * max(1.0, abs(theta[j]))
            up, down = theta.copy(), theta.copy()
            up[j] += h
            down[j] -= h
            self.set_values(up)
            r_up = self.radial()
            self.set_values(down)
            r_down = self.radial()
            for k in range(len(self.motions)):
                if r_up[k] is not None:
                    grad_radial[k, j] = (r_up[k] - r_down[k]) / (2 * h)
        self.set_values(theta)
        return grad_radial

    def body_entries(self, theta, cov, sigma, first: dict, closed_form) -> list:
        """fit.json's per-body entries at the fitted ``theta`` (the current motions),
        with the uncertainties from ``cov`` and ``sigma``, the start (``first``: the
        history's first entry) and the capture's own record of the body."""
        radial = self.radial()
        # the radial velocities' derivatives (central differences of the truth; linear in u)
        grad_radial = self.radial_gradient(theta)
        per, bodies = self.per_body, []
        for k, m in enumerate(self.motions):
            g = grad_radial[k]
            entry = {
                "name": ", ".join(self.data.scene.bodies[k].names),
                "radial_velocity_m_s": radial[k],
                "radial_velocity_uncertainty_m_s": float(np.sqrt(max(g @ cov @ g, 0.0))),
                "linear_velocity_m_s": theta[k * per:k * per + 3].tolist(),
                "linear_velocity_uncertainty_m_s": _or_none(sigma[k * per:k * per + 3]),
                "angular_velocity_rad_s": [float(x) for x in m.angular_velocity],
                "angular_velocity_uncertainty_rad_s": (
                    _or_none(sigma[k * per + 3:k * per + 6]) if self.angular else None),
                "pivot_m": m.pivot,
                "start_linear_velocity_m_s": first["parameters"][k * per:k * per + 3],
                "start_radial_velocity_m_s": first["radial_velocity_m_s"][k],
                "closed_form_linear_velocity_m_s": (None if closed_form[k] is None
                                                    else closed_form[k].tolist()),
                "interior_pixels": int(self.masks[k].sum()),
            }
            _add_capture_record(entry, self.data.summary)
            bodies.append(entry)
        return bodies


def _add_capture_record(entry: dict, summary: dict) -> None:
    """The capture's own record of the body ``entry`` names (summary.json's velocity
    medians), for comparison, when it has one."""
    truth_summary = [b for b in summary.get("bodies", []) if b.get("name") == entry["name"]]
    if truth_summary:
        entry["capture_velocity_gt_median_m_s"] = truth_summary[0].get(
            "velocity_gt_median_m_s")
        entry["capture_velocity_median_m_s"] = truth_summary[0].get("velocity_median_m_s")


def _gauss_newton(problem: _FitProblem, spp: int, iterations: int, tolerance: float,
                  progress, started):
    """Gauss-Newton iterations with Levenberg-Marquardt damping from the current
    motions: (theta, the last (r, J) pair of renders, its cross loss, the history, the
    iterations done). Early iterations render a quarter of the samples (the start may be
    far off); the last ones all of them. Parameters the captures do not see (a Jacobian
    column far below the others: a velocity along no visible face's normal) keep their
    start."""
    from tqdm import tqdm

    from ..integrators.pipeline import _show_progress

    K = problem.scenes[FIT_CAPTURES[0]].params.time_correlate_number
    coarse = max(K, (spp // 4) // K * K)
    samples = coarse if coarse < spp else spp
    damping = 1e-3
    theta = problem.values()
    state = problem.evaluate(samples)
    loss = _cross_loss(state)
    history = [problem.record(0, loss, samples, theta, started)]
    bar = tqdm(total=iterations, desc="fitting", unit="it", leave=False,
               disable=not _show_progress(progress))
    done = 0
    try:
        for it in range(1, iterations + 1):
            step, state_new, loss_new, damping = _damped_trials(problem, state, loss, theta,
                                                                damping, samples)
            theta, state, loss = theta + step, state_new, loss_new
            damping = max(damping / 10.0, 1e-6)
            done = it
            bar.update(1)
            history.append(problem.record(it, loss, samples, theta, started))
            small = np.linalg.norm(step) <= 1e-2 * max(np.linalg.norm(theta), 1e-12)
            stalled = loss_new > 0.9 * history[-2]["loss"]  # the noise's floor
            if samples < spp and (small or stalled or it >= iterations // 2):
                samples = spp  # near: the precise renders (the loss is re-evaluated)
                state = problem.evaluate(samples)
                loss = _cross_loss(state)
            elif np.linalg.norm(step) <= tolerance * max(np.linalg.norm(theta), 1e-12):
                break
    finally:
        bar.close()
    return theta, state, loss, history, done


def _damped_trials(problem: _FitProblem, state, loss: float, theta, damping: float,
                   samples: int):
    """Levenberg-Marquardt's steps from ``theta`` (renders ``state``), the damping ten
    times larger after each that makes the loss worse (a shorter, more gradient-like
    step), until one does not or the damping passes 1e3: (that step, its state, its
    cross loss, the damping); the motions are left at theta + step."""
    while True:
        step = _trust(_damped_step(state, damping)[0], theta)
        problem.set_values(theta + step)
        state_new = problem.evaluate(samples)
        loss_new = _cross_loss(state_new)
        if loss_new <= loss or damping > 1e3:
            return step, state_new, loss_new, damping
        damping *= 10.0


def _covariance(state, loss: float):
    """cov = s^2 (J^T J)^+ of the parameters (the module docstring), s^2 = ``loss`` / its
    degrees of freedom, over the parameters the captures see; the standard deviations
    (NaN for a parameter not seen) and that mask."""
    G, seen = _metric(state)
    (r, _), _ = state
    n = G.shape[0]
    dof = max(len(r) - int(seen.sum()), 1)
    cov = np.zeros((n, n))
    if seen.any():
        scale = np.sqrt(np.diag(G)[seen])
        Gs = G[np.ix_(seen, seen)] / np.outer(scale, scale)
        # s^2 of one render's residual: the mean of the two
        cov[np.ix_(seen, seen)] = ((loss / dof) * _truncated_inverse(Gs, RCOND ** 2)
                                   / np.outer(scale, scale))
    sigma = np.where(seen, np.sqrt(np.maximum(np.diag(cov), 0.0)), np.nan)
    return cov, sigma, seen


def _method_notes(t_mid: float) -> dict:
    """fit.json's settings that describe the method, the motion and the uncertainty."""
    return {
        "method": "Gauss-Newton with Levenberg-Marquardt damping on the cross loss "
                  "(R_A - C).(R_B - C) of two renders of independent seeds, forward-mode "
                  "Jacobians, the same seeds every iteration (correlated sampling)",
        "motion": "constant linear (and angular) velocity about the pose at mid-exposure, "
                  "t_ref = %.9g s" % t_mid,
        "uncertainty": "sqrt(diag(s^2 (J^T J)^+)), s^2 = loss / (residuals - parameters), "
                       "^+: the pseudo-inverse over the directions the captures constrain "
                       "(singular values >= %g of the largest, columns scaled); null: a "
                       "parameter the captures do not see (kept at its start)" % RCOND,
    }


def _blocks(masks, block: int) -> np.ndarray:
    """Per pixel of the union of ``masks`` (flat order), the index of its block: its
    body and its block x block tile."""
    height, width = masks[0].shape
    y, x = np.divmod(np.arange(height * width), width)
    tile = (y // block) * (-(-width // block)) + x // block
    label = np.full(height * width, -1)
    for k, mask in enumerate(masks):
        on = mask.ravel()
        label[on] = k * (tile.max() + 1) + tile[on]
    used = label[label >= 0]
    return np.unique(used, return_inverse=True)[1]


def _cross_loss(state) -> float:
    """(R_A - C) . (R_B - C): its expectation is the squared distance of the expected
    render to the captures, without the renders' variance (which depends on the
    velocities and would bias a fit of the plain squared loss, by O(1/spp))."""
    (r_a, _), (r_b, _) = state
    return float(r_a @ r_b)


def _metric(state, snr=0.5):
    """The Gauss-Newton metric from two Jacobians of independent noise: G = (J_A^T J_B +
    J_B^T J_A) / 2, whose expectation is J^T J of the expected Jacobian (J_A^T J_A would
    add the noise's energy, and shorten every step by it). The mask of the parameters
    the captures see: those whose column's signal (G's diagonal) is at least ``snr`` of
    its energy (the mean of J_A^T J_A and J_B^T J_B); the others keep their start."""
    (_, J_a), (_, J_b) = state
    G = 0.5 * (J_a.T @ J_b + J_b.T @ J_a)
    energy = 0.5 * (np.sum(J_a * J_a, 0) + np.sum(J_b * J_b, 0))
    d = np.diag(G)
    seen = (d > 0) & (d >= snr * energy) & (energy > 0)
    return G, seen


def _damped_step(state, damping, rcond=RCOND):
    """The Levenberg-Marquardt step of the cross loss, -(G + damping diag(G))^+ g with
    g = (J_A^T r_B + J_B^T r_A) / 2 and G from :func:`_metric`, over the parameters
    the captures see, in the directions whose eigenvalue (columns scaled by G's
    diagonal) reaches ``rcond``^2 of the largest. Returns the step and that mask."""
    (r_a, J_a), (r_b, J_b) = state
    G, seen = _metric(state)
    step = np.zeros(J_a.shape[1])
    if not seen.any():
        return step, seen
    scale = np.sqrt(np.diag(G)[seen])
    A = G[np.ix_(seen, seen)] / np.outer(scale, scale)
    A += damping * np.diag(np.diag(A))
    g = 0.5 * (J_a.T @ r_b + J_b.T @ r_a)[seen] / scale
    step[seen] = -_truncated_inverse(A, rcond ** 2) @ g / scale
    return step, seen


def _trust(step, theta, fraction=0.5):
    """The step with each component clipped to ``fraction`` of |theta| (at least
    1 m/s): noise in a weakly constrained parameter can neither throw the motion far
    in one iteration nor, through a common scale, stop the others."""
    limit = fraction * max(np.linalg.norm(theta), 1.0)
    return np.clip(step, -limit, limit)


def _truncated_inverse(A, rcond):
    """Pseudo-inverse of a symmetric matrix without its eigen-directions below ``rcond``
    of the largest eigenvalue."""
    w, V = np.linalg.eigh(A)
    keep = w > rcond * max(w.max(), 1e-300)
    return (V[:, keep] / w[keep]) @ V[:, keep].T


def _or_none(values):
    return [None if not np.isfinite(x) else float(x) for x in values]


# ---- Output --------------------------------------------------------------------------

def write_fit(result: FitResult, folder) -> list:
    """fit.json and convergence.png into ``folder`` (created if missing), both or
    neither (the output set "fit" of :func:`dopplertof.io.output_folder`)."""
    from .. import io

    with io.output_folder(folder, "fit") as staged:
        io.write_json(staged.path("fit.json"), result.as_json())
        write_convergence_plot(result, staged.path("convergence.png"))
    return staged.written


def write_convergence_plot(result: FitResult, path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from .. import io

    its = [h["iteration"] for h in result.history]
    fig, axes = plt.subplots(1, 2, figsize=(10, 4))
    axes[0].semilogy(its, [max(h["loss"], 1e-300) for h in result.history], "o-")
    axes[0].set_xlabel("iteration")
    axes[0].set_ylabel("loss (sum of squared capture differences)")
    axes[0].set_title("loss")
    for k, body in enumerate(result.bodies):
        line, = axes[1].plot(its, [h["radial_velocity_m_s"][k] for h in result.history],
                             "o-", label=body["name"])
        if body.get("capture_velocity_gt_median_m_s") is not None:
            axes[1].axhline(body["capture_velocity_gt_median_m_s"], color=line.get_color(),
                            ls="--", lw=1, label=f"{body['name']}: capture's truth")
        if body.get("capture_velocity_median_m_s") is not None:
            axes[1].axhline(body["capture_velocity_median_m_s"], color=line.get_color(),
                            ls=":", lw=1, label=f"{body['name']}: closed form")
    axes[1].set_xlabel("iteration")
    axes[1].set_ylabel("radial velocity (m/s, median over the body)")
    axes[1].set_title("fitted radial velocity")
    axes[1].legend(fontsize=7)
    fig.tight_layout()
    io.save_figure(fig, path)
    plt.close(fig)


def format_fit(result: FitResult) -> str:
    lines = [f"fit: {result.iterations} iterations, loss {result.loss:.4g}, "
             f"{result.settings.get('seconds', 0):.1f} s"]
    for b in result.bodies:
        truth = b.get("capture_velocity_gt_median_m_s")
        lines.append(
            f"  {b['name']}: radial {b['radial_velocity_m_s']:+.3f} "
            f"+- {b['radial_velocity_uncertainty_m_s']:.3f} m/s"
            + (f" (capture's truth {truth:+.3f}, error "
               f"{100 * (b['radial_velocity_m_s'] / truth - 1):+.2f}%)" if truth else ""))
    return "\n".join(lines)
