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
sums over blocks of interior pixels (a per-pixel Jacobian's Monte Carlo noise would
inflate J^T J and shorten every step; block sums keep the velocity field's variation and
average the noise). Every iteration renders with the same two seeds
(correlated sampling): the loss is a smooth function of theta, not a new noisy sample
each time.

The start is each body's linear velocity from the closed-form per-pixel radial
velocities (velocity.npy): at pixel i of a translating body, radial velocity
r_i = (u . n_i) / (d_i . n_i), linear in u, solved by least squares over the body's
pixels (normals and rays from the scene's geometry at mid-exposure); or a start the
user gives.

The Jacobian is rendered at the start and held while steps lower the loss (the captures
are nearly linear in the velocities, so a step needs only the residuals' renders), again
when no step does, and at the end where the fit ended elsewhere; with a quarter of the
residuals' samples (:data:`JACOBIAN_SHARE`), each body's columns over its own pixels.
The iterations stop on a plateau (a step lowering the loss by less than :data:`PLATEAU`
of itself) or a step below ``tolerance``.

The uncertainties are those of a least-squares fit: cov = s^2 (J^T J)^-1 with s^2 the
squared residual of the two final renders' mean over its degrees of freedom (the capture's
noise and the part of the renders' noise that reaches the fitted velocities); a radial velocity's follows from it through its
derivative. A parameter the captures do not see keeps its start; its uncertainty is
infinite (null in fit.json).
"""

from __future__ import annotations

import json
import math
import os
import re
import time as _time
from dataclasses import dataclass, field, replace

import numpy as np

from ..arguments import check_seed
from .loss import cross_loss
from .motion import VelocityMotion
from .progress import IterationProgress
from .settings import FIT_SPP, JACOBIAN_SHARE

#: captures fitted (their Doppler content is what the velocities change)
FIT_CAPTURES = ("heterodyne_0", "heterodyne_0.25")

#: captures fitted beside them with ``reflectances`` (the heterodyne captures scale
#: with albedo x velocity: the homodyne ones separate the two)
REFLECTANCE_CAPTURES = ("homodyne_0", "homodyne_0.25")

#: directions of the (column-scaled) Jacobian below this fraction of its largest
#: singular value are not constrained by the captures: no step along them
RCOND = 0.05

#: the fit stops on a plateau: a step that lowers the loss by less than this fraction
PLATEAU = 0.01

#: a truth below this (m/s, rad/s) is near zero: its error is printed in m/s, not in %
NEAR_ZERO = 0.01


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
    reflectances: dict = field(default_factory=dict)  #: key -> value, uncertainty (fitted)

    def as_json(self) -> dict:
        out = {"bodies": self.bodies, "iterations": self.iterations, "loss": self.loss,
               "history": self.history, "settings": self.settings}
        if self.reflectances:
            out["reflectances"] = self.reflectances
        return out


# ---- Reading a capture folder ------------------------------------------------------

def _declared_defaults(path: str) -> set:
    with open(path, encoding="utf-8") as f:
        return set(re.findall(r"<default\s+name=\"([^\"]+)\"", f.read()))


def load_capture(folder, defines=None, fitted=FIT_CAPTURES) -> CaptureData:
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
    for name in fitted:
        path = os.path.join(folder, f"{name}.npy")
        if name not in records or not os.path.isfile(path):
            raise FitError(f"{folder} has no {name}.npy: the fit needs the "
                           f"{name.split('_')[0]} captures")
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


#: neighbouring normals further apart than this (cosine) mark a crease between faces
#: (a box's edge: 90 degrees); curvature between neighbouring pixels stays below it
CREASE_COS = math.cos(math.radians(45.0))


def interior(truth, k: int, reach: int = 1) -> np.ndarray:
    """Pixels of body k whose footprint sees body k only, in one piece: every pixel
    within ``reach`` (the film filter's radius, at least 1) hits body k (not its
    silhouette against another body, a static surface or the background, whose motion
    the derivatives do not model), and no two neighbouring normals there meet at a
    crease (:data:`CREASE_COS`: a box's edge, whose integrand jumps). Curved faces,
    and meshes with smooth normals, are kept: their integrand is continuous."""
    on = truth.body == k
    n = np.nan_to_num(truth.normal)
    inner = on.copy()
    for dy in range(-reach, reach + 1):
        for dx in range(-reach, reach + 1):
            inner &= np.roll(np.roll(on, dy, 0), dx, 1)
            if max(abs(dy), abs(dx)) == 1:  # a crease: between the pixel and a neighbour
                shifted = np.roll(np.roll(n, dy, 0), dx, 1)
                inner &= np.sum(n * shifted, -1) > CREASE_COS
    inner[:reach, :] = inner[-reach:, :] = False  # the image's border: footprint unknown
    inner[:, :reach] = inner[:, -reach:] = False
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
        tolerance: float = 1e-3, block: int = 8, plateau: float = PLATEAU,
        reflectances: bool = False, jacobian_spp: int | None = None) -> FitResult:
    """Fit every body's velocity to the captures in ``folder`` (see the module
    docstring). ``start``: {body index: linear velocity (3,) or (v (3,), omega (3,))}
    to start from instead of the closed form; ``seed``: of the fit's renders (default:
    the capture's + 1, independent of its noise); ``block``: the residuals are sums over
    blocks of block x block interior pixels of one body (the module docstring says
    why); the iterations stop at a step
    below ``tolerance`` of the velocities, or on a plateau: a step that lowers the loss
    by less than ``plateau`` of itself; ``jacobian_spp``: samples per pixel of the
    Jacobian's renders (default :data:`JACOBIAN_SHARE` of ``spp``). ``progress``: a bar
    (True; None: when stderr is a terminal), else (None) one line per iteration on
    stderr, or nothing (False). ``reflectances``: fit :func:`reflectance_keys` too, on
    :data:`REFLECTANCE_CAPTURES`."""
    data = load_capture(folder, defines, FIT_CAPTURES + REFLECTANCE_CAPTURES * reflectances)
    if not isinstance(spp, (int, np.integer)) or spp < 1:
        raise FitError(f"spp must be a positive integer, got {spp!r}")
    jacobian_spp = _jacobian_samples(spp, jacobian_spp, data.base)
    seed = int(data.summary.get("seed", 0)) + 1 if seed is None else seed
    seed = check_seed(seed, "seed", FitError)  # (renders of seed and seed + 1: < 2^64)
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
    problem = _FitProblem(data, motions, masks, (seed, seed + 1), angular, block,
                          reflectances, jacobian_spp)
    started = _time.perf_counter()
    theta, state, history, done, stop = _gauss_newton(
        problem, spp, iterations, tolerance, plateau, _fit_progress(progress, iterations), started)
    loss = history[-1]["loss"]

    # ---- Uncertainties from the final Jacobian ----
    cov, sigma = _covariance(state, problem.seen)
    bodies = problem.body_entries(theta, cov, sigma, history[0], closed_form)
    settings = {
        "capture": os.path.abspath(os.fspath(folder)), "captures_fitted": list(problem.fitted),
        "spp": int(spp), "jacobian_spp": int(jacobian_spp), "seed": seed,
        "jacobian_seed": seed + 1,
        "pixels": int(problem.pixels.size), "block": int(block),
        "residuals": "per capture, sums over blocks of interior pixels of one body",
        "parameters": problem.names, "angular": bool(angular),
        "start": "user" if start else "closed form (velocity.npy)",
        **_method_notes(t_mid, tolerance, plateau),
        "stopped": stop,
        "unconstrained": [n for n, ok in zip(problem.names, problem.seen) if not ok],
        "seconds": round(_time.perf_counter() - started, 3),
    }
    return FitResult(bodies, done, loss, history, settings,
                     problem.reflectance_entries(theta, sigma))


def _jacobian_samples(spp: int, jacobian_spp, base) -> int:
    """The Jacobian's samples per pixel: ``jacobian_spp`` (checked against the
    capture's sample groups), else the largest divisor of ``spp`` at most
    :data:`JACOBIAN_SHARE` of it that the sample groups allow, else ``spp``."""
    from ..sampling import check_sample_count

    def usable(n) -> bool:
        try:
            check_sample_count(base.time_correlate_number, n, base.path_group_size,
                               base.samples_per_pass)
        except ValueError:
            return False
        return True

    if jacobian_spp is not None:
        if not isinstance(jacobian_spp, (int, np.integer)) or jacobian_spp < 1:
            raise FitError(f"jacobian_spp must be a positive integer, got {jacobian_spp!r}")
        if not usable(jacobian_spp):
            raise FitError(f"jacobian_spp {jacobian_spp} is not a multiple of the "
                           "capture's sample groups (time_correlate_number "
                           f"{base.time_correlate_number})")
        return int(jacobian_spp)
    wanted = max(1, int(spp * JACOBIAN_SHARE))
    return next((n for n in range(wanted, 0, -1) if spp % n == 0 and usable(n)), int(spp))


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
    """Per body, its :func:`interior` pixels (the footprint's reach from the film's
    filter); a FitError for a body with fewer than 4, saying what it lacks."""
    from ..integrators.film import _filter_of

    reach = max(1, math.ceil(_filter_of(scene.sensor.film())[1]))
    masks = [interior(geometry, k, reach) for k in range(len(scene.bodies))]
    for k, mask in enumerate(masks):
        if mask.sum() < 4:
            on = int(np.sum(geometry.body == k))
            raise FitError(
                f"body {k} ({', '.join(scene.bodies[k].names)}) covers {on} pixels, of "
                f"which {int(mask.sum())} see only the body within the filter's reach "
                f"({reach} px) away from its silhouette and its creases: too few (4) to "
                "fit; render the capture at a higher resolution")
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

    def __init__(self, data: CaptureData, motions, masks, seeds, angular: bool, block: int,
                 reflectances: bool, jacobian_spp: int):
        from .render import DifferentiableScene

        self.data, self.motions, self.masks, self.angular = data, motions, masks, angular
        self.seeds = seeds  #: (A, B): the two renders of independent random numbers
        self.per_body = 6 if angular else 3  #: parameters per body
        # ---- One differentiable scene per capture, sharing the motions ----
        self.fitted = FIT_CAPTURES + (REFLECTANCE_CAPTURES if reflectances else ())
        self.scenes = {}
        for name in self.fitted:
            ds = DifferentiableScene(data.scene, _capture_params(data, name))
            ds.motions = motions
            self.scenes[name] = ds
        self.pixels = np.flatnonzero(np.logical_or.reduce(masks))
        self.body_pixels = [np.flatnonzero(mask) for mask in masks]
        self.jacobian_spp = jacobian_spp  #: spp of the Jacobian's renders
        self.groups = _blocks(masks, block)  # per rendered pixel, its block
        self.n_groups = int(self.groups.max()) + 1
        self.names = [f"body{k}.{kind}{a}" for k in range(len(motions))
                      for kind in ("vw" if angular else "v") for a in "xyz"]
        self.reflectances = _Reflectances(self.scenes[FIT_CAPTURES[0]], reflectances)
        self.names += self.reflectances.keys
        self.target = np.concatenate([self.pool(data.captures[c].ravel()[self.pixels])
                                      for c in self.fitted])
        #: the parameters the captures see (set from the start's Jacobian); the others
        #: keep their start
        self.seen = np.ones(len(self.names), bool)

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
        return np.array(out + self.reflectances.values(), dtype=np.float64)

    def set_values(self, theta) -> None:
        per = self.per_body
        for k, m in enumerate(self.motions):
            m.velocity = theta[k * per:k * per + 3].tolist()
            if self.angular:
                m.angular_velocity = theta[k * per + 3:k * per + 6].tolist()
        self.reflectances.set(theta[len(self.motions) * per:])

    def evaluate(self, samples: int, jacobian: bool = True):
        """Residuals at the current motions from two renders of ``samples`` spp of
        independent random numbers (A, B), and (``jacobian``) their Jacobians
        (:meth:`jacobians`): ((r_A, r_B), (J_A, J_B)), the Jacobians None without."""
        from .render import render_derivatives

        residuals = []
        for seed in self.seeds:
            residual = [self.pool(render_derivatives(self.scenes[c], [], spp=samples,
                                                     seed=seed, pixels=self.pixels)
                                  .image.mean(-1).ravel()[self.pixels])
                        for c in self.fitted]
            residuals.append(np.concatenate(residual) - self.target)
        return tuple(residuals), (self.jacobians() if jacobian else (None, None))

    def jacobians(self):
        """(J_A, J_B): the residuals' derivatives from renders of seeds A and B at
        ``jacobian_spp``, each body's columns rendered over its own pixels only (its
        motion moves them; on the other bodies' blocks its derivative is left zero: the
        interreflected light it changes there is a small part of a Jacobian that
        Gauss-Newton needs only approximately), half the derivative passes of all the
        parameters over all the pixels."""
        from .render import render_derivatives

        jacobians = []
        # column groups: each body's motion over its own pixels, the reflectances over all
        groups = [(self.names[k * self.per_body:(k + 1) * self.per_body], pixels,
                   k * self.per_body) for k, pixels in enumerate(self.body_pixels)]
        if self.reflectances.keys:
            groups.append((self.reflectances.keys, self.pixels,
                           len(self.motions) * self.per_body))
        for seed in self.seeds:
            columns = []
            for c in self.fitted:
                block = np.zeros((self.n_groups, len(self.names)))
                for names, pixels, first in groups:
                    d = render_derivatives(self.scenes[c], names, spp=self.jacobian_spp,
                                           seed=seed, pixels=pixels)
                    for j, n in enumerate(names):
                        block[:, first + j] = self.pool(
                            d.tangents[n].mean(-1).ravel()[self.pixels])
                columns.append(block)
            jacobians.append(np.concatenate(columns))
        return tuple(jacobians)

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
        for j in range(len(self.motions) * self.per_body):  # (not the reflectances)
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


    def reflectance_entries(self, theta, sigma) -> dict:
        """fit.json's reflectances: per key its fitted value (the channels' mean), the
        start's and the uncertainty (None: not seen)."""
        at = len(self.motions) * self.per_body
        return {key: {"value": float(theta[at + i]), "start": start,
                      "uncertainty": _or_none(sigma[at + i:at + i + 1])[0],
                      "channels": self.reflectances.channels(key).tolist()}
                for i, (key, start) in enumerate(self.reflectances.start.items())}


def reflectance_keys(ds) -> list:
    """The scene's uniform reflectances: the differentiable mi.traverse keys
    ``<bsdf>.reflectance.value`` of the static scene and the bodies."""
    from .render import differentiable_names

    return [n for n in differentiable_names(ds) if n.endswith(".reflectance.value")]


class _Reflectances:
    """The fitted reflectances of a fit (none unless ``fitted``): per key one value,
    the mean of its channels; a new value shifts every channel by the same amount
    (the captures are the channels' mean), clipped to [0, 1]."""

    def __init__(self, ds, fitted: bool):
        from .inverse import get_value

        self.ds = ds
        self.keys = reflectance_keys(ds) if fitted else []
        self.base = {k: get_value(ds, k) for k in self.keys}
        self.start = {k: float(v.mean()) for k, v in self.base.items()}
        self.current = dict(self.start)

    def values(self) -> list:
        return [self.current[k] for k in self.keys]

    def channels(self, key: str) -> np.ndarray:
        return np.clip(self.base[key] + (self.current[key] - self.start[key]), 0.0, 1.0)

    def set(self, values) -> None:
        from .inverse import set_value

        for key, value in zip(self.keys, values):
            if float(value) != self.current[key]:
                self.current[key] = float(value)
                set_value(self.ds, key, self.channels(key))


def _add_capture_record(entry: dict, summary: dict) -> None:
    """The capture's own record of the body ``entry`` names (summary.json's velocity
    medians), for comparison, when it has one."""
    truth_summary = [b for b in summary.get("bodies", []) if b.get("name") == entry["name"]]
    if truth_summary:
        entry["capture_velocity_gt_median_m_s"] = truth_summary[0].get(
            "velocity_gt_median_m_s")
        entry["capture_velocity_median_m_s"] = truth_summary[0].get("velocity_median_m_s")


def _gauss_newton(problem: _FitProblem, spp: int, iterations: int, tolerance: float,
                  plateau: float, progress, started):
    """Gauss-Newton iterations with Levenberg-Marquardt damping from the current
    motions: (theta, the final (residuals, Jacobians), the history, the iterations
    done, why they stopped). The Jacobian is rendered at the start, held while steps
    lower the loss (the captures are nearly linear in the velocities: a step needs
    only the residuals' renders) and rendered again when none does, and at the end
    for the uncertainties (unless it was rendered there). Parameters the start's
    Jacobian does not see (a column far below its noise: a velocity along no visible
    face's normal) keep their start."""
    theta = problem.values()
    residuals, jacobians = problem.evaluate(spp)
    problem.seen = _metric(jacobians)[1]
    loss, fresh = cross_loss(*residuals), True
    history = [problem.record(0, loss, spp, theta, started)]
    progress.update(history[-1])
    damping, done, stop = 1e-3, 0, f"{iterations} iterations"
    try:
        while done < iterations:
            step, new_residuals, new_loss = _damped_trials(problem, residuals, jacobians,
                                                           loss, theta, damping, spp)
            if new_loss >= loss:
                problem.set_values(theta)
                if fresh:
                    stop = "no damped step lowers the loss"
                    break
                jacobians = problem.jacobians()  # a held Jacobian gone stale
                fresh = True
                continue
            theta, residuals, previous, loss, fresh = (theta + step, new_residuals, loss,
                                                      new_loss, False)
            done += 1
            history.append(problem.record(done, loss, spp, theta, started))
            progress.update(history[-1])
            if np.linalg.norm(step) <= tolerance * max(np.linalg.norm(theta), 1e-12):
                stop = f"a step below {tolerance:g} of the velocities"
                break
            if previous - loss < plateau * abs(previous):
                stop = f"plateau: the loss fell by less than {plateau:g} of itself"
                break
    finally:
        progress.close()
    # the uncertainties' state: the residuals at theta (its step's renders), the
    # Jacobian at theta (rendered again unless it was rendered there)
    final = (residuals, jacobians if fresh else problem.jacobians())
    return theta, final, history, done, stop


def _damped_trials(problem: _FitProblem, residuals, jacobians, loss: float, theta,
                   damping: float, samples: int):
    """Levenberg-Marquardt's steps from ``theta`` (its residuals and the Jacobians
    held), the damping ten times larger after each that does not lower the loss (a
    shorter, more gradient-like step), until one does or the damping passes 1e3: (that
    step, its residuals, its cross loss); the motions are left at theta + step."""
    while True:
        step = _trust(_damped_step(residuals, jacobians, damping, problem.seen), theta)
        problem.set_values(theta + step)
        new_residuals, _ = problem.evaluate(samples, jacobian=False)
        new_loss = cross_loss(*new_residuals)
        if new_loss < loss or damping > 1e3:
            return step, new_residuals, new_loss
        damping *= 10.0


def _covariance(state, seen):
    """cov = s^2 (J^T J)^+ of the parameters (the module docstring), s^2 = the squared
    residual of the two final renders' mean over its degrees of freedom (the capture's
    noise and half of one render's, as in the fitted velocities, whose steps average the
    two seeds' residuals; positive, as the cross loss need not be), over the parameters
    ``seen`` (that the final Jacobian sees too); and the standard deviations (inf for a
    parameter not seen: unconstrained)."""
    (r_a, r_b), jacobians = state
    G, seen_now = _metric(jacobians)
    seen = seen & seen_now
    n = G.shape[0]
    dof = max(len(r_a) - int(seen.sum()), 1)
    mean_residual = 0.5 * (r_a + r_b)
    energy = float(mean_residual @ mean_residual)
    cov = np.zeros((n, n))
    if seen.any():
        scale = np.sqrt(np.diag(G)[seen])
        Gs = G[np.ix_(seen, seen)] / np.outer(scale, scale)
        cov[np.ix_(seen, seen)] = ((energy / dof) * _truncated_inverse(Gs, RCOND ** 2)
                                   / np.outer(scale, scale))
    sigma = np.where(seen, np.sqrt(np.maximum(np.diag(cov), 0.0)), np.inf)
    return cov, sigma


def _method_notes(t_mid: float, tolerance: float, plateau: float) -> dict:
    """fit.json's settings that describe the method, the motion, the stopping rule and
    the uncertainty."""
    return {
        "method": "Gauss-Newton with Levenberg-Marquardt damping on the cross loss "
                  "(R_A - C).(R_B - C) of two renders of independent seeds, forward-mode "
                  "Jacobians (rendered at the start, held while steps lower the loss, "
                  "rendered again when none does and at the end; jacobian_spp samples, "
                  "each body's columns over its own pixels), the same seeds every "
                  "iteration (correlated sampling)",
        "motion": "constant linear (and angular) velocity about the pose at mid-exposure, "
                  "t_ref = %.9g s" % t_mid,
        "stopping": "after a step below %g of the velocities' norm, or on a plateau: a "
                    "step that lowers the loss by less than %g of itself, or when no "
                    "damped step lowers it" % (tolerance, plateau),
        "uncertainty": "sqrt(diag(s^2 (J^T J)^+)), s^2 = the squared residual of the "
                       "two final renders' mean / (residuals - parameters), "
                       "^+: the pseudo-inverse over the directions the captures constrain "
                       "(singular values >= %g of the largest, columns scaled); null: a "
                       "parameter the captures do not see (kept at its start, "
                       "unconstrained: its uncertainty is infinite)" % RCOND,
    }


def _fit_progress(progress, iterations: int) -> IterationProgress:
    """The fit's progress: a bar "fitting", or a line per iteration (_fit_line)."""
    return IterationProgress(progress, iterations, "fitting", _fit_line)


def _fit_line(entry: dict) -> str:
    """The fit's progress line of one iteration."""
    radial = ", ".join("n/a" if r is None else f"{r:+.4f}" for r in entry["radial_velocity_m_s"])
    return (f"fit iteration {entry['iteration']}: loss {entry['loss']:.6g}, radial "
            f"velocity {radial} m/s, {entry['seconds']:.1f} s")


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


def _metric(jacobians, snr=0.5):
    """The Gauss-Newton metric from two Jacobians of independent noise: G = (J_A^T J_B +
    J_B^T J_A) / 2, whose expectation is J^T J of the expected Jacobian (J_A^T J_A would
    add the noise's energy, and shorten every step by it). The mask of the parameters
    the captures see: those whose column's signal (G's diagonal) is at least ``snr`` of
    its energy (the mean of J_A^T J_A and J_B^T J_B) at the Jacobian's own samples (a
    column of noise only passes as rarely at any sample count: at 512 spp a test scaled
    to the residuals' samples let the tall box's unseen vertical velocity through, and
    its radial velocity 1.3% off)."""
    J_a, J_b = jacobians
    G = 0.5 * (J_a.T @ J_b + J_b.T @ J_a)
    energy = 0.5 * (np.sum(J_a * J_a, 0) + np.sum(J_b * J_b, 0))
    d = np.diag(G)
    seen = (d > 0) & (d >= snr * energy) & (energy > 0)
    return G, seen


def _damped_step(residuals, jacobians, damping, seen, rcond=RCOND):
    """The Levenberg-Marquardt step of the cross loss, -(G + damping diag(G))^+ g with
    g = (J_A^T r_B + J_B^T r_A) / 2 and G from :func:`_metric`, over the parameters
    ``seen``, in the directions whose eigenvalue (columns scaled by G's diagonal)
    reaches ``rcond``^2 of the largest."""
    (r_a, r_b), (J_a, J_b) = residuals, jacobians
    G = _metric(jacobians)[0]
    step = np.zeros(J_a.shape[1])
    if not seen.any():
        return step
    scale = np.sqrt(np.diag(G)[seen])
    A = G[np.ix_(seen, seen)] / np.outer(scale, scale)
    A += damping * np.diag(np.diag(A))
    g = 0.5 * (J_a.T @ r_b + J_b.T @ r_a)[seen] / scale
    step[seen] = -_truncated_inverse(A, rcond ** 2) @ g / scale
    return step


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
    from .. import io

    plt = io.pyplot()
    its = [h["iteration"] for h in result.history]
    loss = np.array([h["loss"] for h in result.history])
    angular = bool(result.settings.get("angular"))
    fig, axes = plt.subplots(1, 3 if angular else 2, figsize=(15 if angular else 10, 4))
    # ---- The loss: |loss| on a log axis, negative values (the cross loss's noise) open ----
    magnitude = np.maximum(np.abs(loss), np.finfo(float).tiny)
    axes[0].semilogy(its, magnitude, "-", color="C0")
    axes[0].semilogy(np.compress(loss >= 0, its), magnitude[loss >= 0], "o", color="C0",
                     label="loss")
    if np.any(loss < 0):
        axes[0].semilogy(np.compress(loss < 0, its), magnitude[loss < 0], "o", mfc="none",
                         color="C0", label="-loss (negative: the two renders' noise)")
    axes[0].legend(fontsize=7)
    axes[0].set_xlabel("iteration")
    axes[0].set_ylabel("|loss| (cross product of capture differences)")
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
    if angular:
        _plot_angular_velocity(axes[2], result, its)
    fig.tight_layout()
    io.save_figure(fig, path)
    plt.close(fig)


def _plot_angular_velocity(ax, result: FitResult, its) -> None:
    """The fitted angular velocity (omega, rad/s) of every body over the iterations (an
    --angular fit): each component the captures see, from the history's parameters."""
    names = result.settings["parameters"]
    unseen = set(result.settings.get("unconstrained", ()))
    for k, body in enumerate(result.bodies):
        for axis in "xyz":
            name = f"body{k}.w{axis}"
            if name not in names or name in unseen:
                continue
            column = names.index(name)
            ax.plot(its, [h["parameters"][column] for h in result.history], "o-",
                    label=f"{body['name']}: omega_{axis}")
    ax.set_xlabel("iteration")
    ax.set_ylabel("angular velocity omega (rad/s)")
    ax.set_title("fitted angular velocity")
    ax.legend(fontsize=7)


def _vector(values, uncertainties, unit: str) -> str:
    """(x, y, z) +- (sx, sy, sz) unit; a component without an uncertainty (not seen by
    the captures) is marked as kept at its start."""
    parts = []
    for value, sigma in zip(values, uncertainties or [None] * 3):
        parts.append(f"{value:+.3f} (not seen: kept at its start)" if sigma is None
                     else f"{value:+.3f} +- {sigma:.3f}")
    return f"({', '.join(parts)}) {unit}"


def _error(value: float, truth) -> str:
    """The error against ``truth``: relative where the truth is not near zero
    (:data:`NEAR_ZERO`), else in the value's unit."""
    if truth is None:
        return ""
    if abs(truth) < NEAR_ZERO:
        return f" (capture's truth {truth:+.3f}, error {value - truth:+.3f} m/s)"
    return f" (capture's truth {truth:+.3f}, error {100 * (value / truth - 1):+.2f}%)"


def format_fit(result: FitResult) -> str:
    """The fit's readable summary: per body the fitted linear (and angular) velocity
    with uncertainties and its median radial velocity against the capture's truth."""
    lines = [f"fit: {result.iterations} iterations ({result.settings.get('stopped', '')}), "
             f"final loss {result.loss:.4g}, {result.settings.get('seconds', 0):.1f} s"]
    for b in result.bodies:
        lines.append(f"  {b['name']}: linear velocity "
                     + _vector(b["linear_velocity_m_s"], b["linear_velocity_uncertainty_m_s"],
                               "m/s"))
        if b.get("angular_velocity_uncertainty_rad_s") is not None:
            lines.append("    angular velocity " + _vector(
                b["angular_velocity_rad_s"], b["angular_velocity_uncertainty_rad_s"], "rad/s"))
        lines.append(f"    radial velocity {b['radial_velocity_m_s']:+.3f} "
                     f"+- {b['radial_velocity_uncertainty_m_s']:.3f} m/s (median over the body)"
                     + _error(b["radial_velocity_m_s"], b.get("capture_velocity_gt_median_m_s")))
    for key, r in result.reflectances.items():
        spread = "not seen: kept at its start" if r["uncertainty"] is None else \
            f"+- {r['uncertainty']:.4f}"
        lines.append(f"  {key}: {r['value']:.4f} {spread} (start {r['start']:.4f})")
    return "\n".join(lines)
