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

The uncertainties are the sandwich covariance of the fit's estimate
(:mod:`.fit_noise`): cov = G^+ (sum over blocks of J_i^T S_i J_i) G^+, S_i each
block's noise across the capture kinds, the renders' from the two seeds' per-pixel
difference, the capture's from its std maps, its samples or the residuals, scaled by the
Birge ratio only where the residuals exceed what that noise predicts significantly
(before: s^2 (J^T J)^-1, one variance for every residual, whose errors in reported
standard deviations scattered 1.3-2x too wide); a radial velocity's follows from it through its
derivative. A parameter the captures do not see keeps its start; its uncertainty is
infinite (null in fit.json), as is one whose uncertainty passes
:data:`~.fit_covariance.UNDETERMINED` times the parameters' norm: the captures do not
determine it.
"""

from __future__ import annotations

import math
import os
import time as _time

import numpy as np

from ..arguments import check_seed
from .fit_capture import (FIT_CAPTURES, REFLECTANCE_CAPTURES, CaptureData, FitError,
                          _truth, check_start_velocity, closed_form_velocity, interior,
                          load_capture)
from .fit_noise import capture_noise
from .fit_output import FitResult, format_fit, write_fit
from .fit_covariance import COVARIANCES, FinalState, covariance, fixed_combinations
from .fit_solve import PLATEAU, _fit_progress, _FitProblem, _gauss_newton, _method_notes
from .motion import VelocityMotion
from .symmetry import symmetry_notes
from .settings import FIT_SPP, JACOBIAN_SHARE

__all__ = ["FIT_CAPTURES", "REFLECTANCE_CAPTURES", "FIT_SPP", "FitError", "FitResult",
           "closed_form_velocity", "fit", "format_fit", "interior", "load_capture",
           "write_fit"]


# ---- The fit -----------------------------------------------------------------------

def fit(folder, start=None, spp: int = FIT_SPP, seed: int | None = None,
        iterations: int = 12, angular: bool = False, defines=None, progress=None,
        tolerance: float = 1e-3, block: int = 8, plateau: float = PLATEAU,
        reflectances: bool = False, jacobian_spp: int | None = None,
        covariance_kind: str = "sandwich") -> FitResult:
    """Fit every body's velocity to the captures in ``folder`` (see the module
    docstring). ``start``: {body index: linear velocity (3,) or (v (3,), omega (3,))}
    to start from instead of the closed form; ``seed``: of the fit's renders (default:
    the capture's + 1, independent of its noise); ``block``: the residuals are sums over
    blocks of block x block interior pixels of one body (the module docstring says why);
    the iterations stop at a step below ``tolerance`` of the velocities, or on a
    plateau: a step that lowers the loss by less than ``plateau`` of itself;
    ``jacobian_spp``: samples per pixel of the Jacobian's renders (default
    :data:`JACOBIAN_SHARE` of ``spp``). ``progress``: a bar
    (True; None: when stderr is a terminal), else (None) one line per iteration on
    stderr, or nothing (False). ``reflectances``: fit :func:`reflectance_keys` too, on
    :data:`REFLECTANCE_CAPTURES`. ``covariance_kind``: the uncertainties' model,
    "sandwich" (each residual's estimated noise) or "plain" (one variance for every
    residual, s^2 G^+: for comparison; :func:`.fit_covariance.covariance`)."""
    _check_kind(covariance_kind)
    data = load_capture(folder, defines, FIT_CAPTURES + REFLECTANCE_CAPTURES * reflectances)
    jacobian_spp = _jacobian_samples(spp, jacobian_spp, data.base)
    seed = int(data.summary.get("seed", 0)) + 1 if seed is None else seed
    seed = check_seed(seed, "seed", FitError)  # (renders of seed and seed + 1: < 2^64)
    check_seed(seed + 1, "seed + 1 (the Jacobian's renders)", FitError)
    # bodies at their poses at mid-exposure (from the scene), velocities to be fitted
    motions, truths, t_mid = _motions_at_mid_exposure(data)
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
    _check_seen(problem, history[0])

    # ---- Uncertainties from the final Jacobian; an unfitted rotation's evidence ----
    cov, sigma, noise, fixed, final = _uncertainties(data, problem, spp, state, theta,
                                                     covariance_kind)
    bodies = problem.body_entries(theta, cov, sigma, history[0], closed_form, truths, fixed)
    warnings = (no_step_warnings(done, stop)
                + symmetry_notes(data.scene, motions, t_mid, bodies, angular)
                + ([] if angular else problem.rotation_warnings(state, bodies)))
    settings = {"capture": os.path.abspath(os.fspath(folder)),
                **_settings(problem, spp, jacobian_spp, seed, block, angular, start),
                **_method_notes(t_mid, tolerance, plateau), "noise": noise, "stopped": stop,
                **_unconstrained(problem.names, theta, history[0], sigma, fixed[0]),
                "seconds": round(_time.perf_counter() - started, 3)}
    return FitResult(bodies, done, loss, history, settings,
                     problem.reflectance_entries(theta, sigma), warnings, final)


def no_step_warnings(done: int, stop: str) -> list:
    """fit.json's warning of a fit that took no step ([] after one or more): every value
    it reports is its start's, with the uncertainty there, not an optimum found."""
    if done:
        return []
    return [f"no optimisation step was taken ({stop}): every velocity reported is its "
            "start, with the uncertainty at the start, not a fitted value; give another "
            "start (--start, or none: the closed form) or more samples (--spp)"]


def _check_seen(problem, first: dict) -> None:
    """A FitError where the captures see none of any body's linear velocity components
    at its start (a start far beyond its speed, or bodies too small or too noisy to see:
    the fit can move nothing, and its starts would be reported as a result). Where some
    body is seen, an unseen one is reported with the status "not seen: kept at its
    start", not as a fitted velocity."""
    per = problem.per_body
    unseen = [k for k in range(len(problem.data.scene.bodies))
              if not problem.seen[k * per:k * per + 3].any()]
    if unseen and len(unseen) == len(problem.data.scene.bodies):
        k = unseen[0]
        body = problem.data.scene.bodies[k]
        start = ", ".join(f"{v:.3g}" for v in first["parameters"][k * per:k * per + 3])
        raise FitError(f"the captures see none of body {k} ({', '.join(body.names)})'s "
                       f"velocity components at its start ({start}) m/s, nor any other "
                       "body's: the fit cannot move them; give a start nearer their "
                       "speeds, or none (the closed form); no result")


def _settings(problem, spp, jacobian_spp, seed, block, angular, start) -> dict:
    """fit.json's settings of the renders and the residuals."""
    return {"captures_fitted": list(problem.fitted), "spp": int(spp),
            "jacobian_spp": int(jacobian_spp), "seed": seed, "jacobian_seed": seed + 1,
            "pixels": int(problem.pixels.size), "block": int(block),
            "residuals": "per capture, sums over blocks of interior pixels of one body",
            "parameters": problem.names, "angular": bool(angular),
            "start": "user" if start else "closed form (velocity.npy)"}


def _check_kind(covariance_kind: str) -> None:
    if covariance_kind not in COVARIANCES:
        raise FitError(f"covariance_kind must be one of {', '.join(COVARIANCES)}, got "
                       f"{covariance_kind!r}")


def _uncertainties(data, problem, spp: int, state, theta, kind: str = "sandwich"):
    """(cov, sigma, fit.json's settings.noise, fixed, the FinalState they come from) at
    the end of the fit: the ``kind`` covariance with the capture's noise as its folder
    gives it (:mod:`.fit_noise`); ``fixed``: the combinations the captures do not
    constrain and the mask of the parameters weighing on them
    (:func:`.fit_covariance.fixed_combinations`), which have no uncertainty (``cov``
    keeps them: a radial velocity that does not depend on a fixed combination has its
    variance from them all)."""
    capture = capture_noise(data, problem, spp)
    noise = {"capture_noise": capture.describe()}
    cov, sigma = covariance(state, problem.seen, theta, capture, noise, kind)
    fixed = fixed_combinations(state, problem.seen)
    final = FinalState(state, problem.seen, theta, capture)
    return cov, np.where(fixed[1], np.inf, sigma), noise, fixed, final


def _combinations(names, directions) -> list:
    """fit.json's fixed combinations: per direction the parameters weighing on it (unit
    norm in the parameters' own units) and the prior that holds it."""
    return [{"direction": {n: round(float(c), 6) for n, c in zip(names, d)
                           if abs(c) >= 1e-3},
             "prior": "kept at its start: the captures do not constrain it (an eigenvalue "
                      "of the column-scaled metric below RCOND^2 of the largest)"}
            for d in directions]


def _unconstrained(names, theta, first: dict, sigma, directions) -> dict:
    """fit.json's settings that name the parameters without an uncertainty at the end
    (``unconstrained``), those of them the fit never moved (``kept_at_start``) and the
    combinations the captures do not constrain (``fixed_combinations``)."""
    start = np.asarray(first["parameters"], np.float64)
    loose = [i for i, s in enumerate(sigma) if not np.isfinite(s)]
    return {"unconstrained": [names[i] for i in loose],
            "kept_at_start": [names[i] for i in loose if theta[i] == start[i]],
            "fixed_combinations": _combinations(names, directions)}


def _jacobian_samples(spp: int, jacobian_spp, base) -> int:
    """The Jacobian's samples per pixel: ``jacobian_spp`` (checked against the
    capture's sample groups), else the largest divisor of ``spp`` at most
    :data:`JACOBIAN_SHARE` of it that the sample groups allow, else ``spp`` (a
    FitError where ``spp`` is no positive integer)."""
    from ..sampling import check_sample_count

    if not isinstance(spp, (int, np.integer)) or spp < 1:
        raise FitError(f"spp must be a positive integer, got {spp!r}")

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
    the truth (per body (v, omega) of the capture scene's keyframed motion: its chord
    over the exposure about the same pivot, exact for two keyframes of a rigid motion),
    and t_mid."""
    from ..tof.ground_truth import mid_exposure

    scene = data.scene
    t0, _, t1 = mid_exposure(scene, data.base)
    t_mid = 0.5 * (t0 + t1)
    motions = [VelocityMotion.from_motion(b.motion, t0, t1, t_ref=t_mid)
               for b in scene.bodies]
    truths = [([float(x) for x in m.velocity], [float(x) for x in m.angular_velocity])
              for m in motions]
    for m in motions:
        m.velocity, m.angular_velocity = [0.0] * 3, [0.0] * 3
    return motions, truths, t_mid


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
            m.velocity = check_start_velocity(v, f"start of body {k}")
            if w is not None:
                m.angular_velocity = [float(x) for x in np.asarray(w, float).reshape(3)]
                if not all(map(math.isfinite, m.angular_velocity)):
                    raise FitError(f"start of body {k}: the angular velocity must be "
                                   f"finite, got {m.angular_velocity}")
        elif closed_form[k] is not None:
            m.velocity = closed_form[k].tolist()
        else:
            raise FitError(f"{folder} has no velocity.npy for the closed-form start: give a "
                           f"start for body {k}")
