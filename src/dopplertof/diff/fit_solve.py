"""The fit's least squares: the problem (residuals and Jacobians of the renders),
Gauss-Newton with Levenberg-Marquardt damping on the cross loss, the uncertainties.
See :mod:`dopplertof.diff.fit`."""

from __future__ import annotations

import time as _time

import numpy as np

from .fit_capture import (FIT_CAPTURES, REFLECTANCE_CAPTURES, CaptureData, _capture_params,
                          _truth, radial_velocity)
from .fit_covariance import (RCOND, UNDETERMINED, metric, radial_uncertainty, residual_variance,
                             truncated_inverse)
from .fit_noise import BIRGE_SIGMAS
from .loss import cross_loss
from .progress import IterationProgress

#: the fit stops on a plateau: a step that lowers the loss by less than this fraction
PLATEAU = 0.01


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
        (:meth:`jacobians`): ((r_A, r_B), (J_A, J_B)), the Jacobians None without. The
        renders' per-pixel values stay in ``pixel_renders`` (per seed (kinds, pixels)):
        the renders' noise per block (:func:`.fit_noise.block_covariances`)."""
        from .render import render_derivatives

        residuals, self.pixel_renders = [], []
        for seed in self.seeds:
            rendered = np.array([render_derivatives(self.scenes[c], [], spp=samples, seed=seed,
                                                    pixels=self.pixels)
                                 .image.mean(-1).ravel()[self.pixels] for c in self.fitted])
            self.pixel_renders.append(rendered)  # the noise's estimate (fit_noise)
            residuals.append(np.concatenate([self.pool(x) for x in rendered]) - self.target)
        return tuple(residuals), (self.jacobians() if jacobian else (None, None))

    def jacobians(self):
        """(J_A, J_B): the residuals' derivatives from renders of seeds A and B at
        ``jacobian_spp``, each body's columns rendered over its own pixels only (its
        motion moves them; on the other bodies' blocks its derivative is left zero: the
        interreflected light it changes there is a small part of a Jacobian that
        Gauss-Newton needs only approximately), half the derivative passes of all the
        parameters over all the pixels."""
        # column groups: each body's motion over its own pixels, the reflectances over all
        groups = [(self.names[k * self.per_body:(k + 1) * self.per_body], pixels,
                   k * self.per_body) for k, pixels in enumerate(self.body_pixels)]
        if self.reflectances.keys:
            groups.append((self.reflectances.keys, self.pixels,
                           len(self.motions) * self.per_body))
        return self._columns(groups, len(self.names))

    def _columns(self, groups, width: int):
        """Per seed (A, B), the residuals' derivatives (rows, ``width``) for column
        ``groups`` of (names, the pixels they are rendered over, their first column),
        from renders at ``jacobian_spp``."""
        from .render import render_derivatives

        out = []
        for seed in self.seeds:
            columns = []
            for c in self.fitted:
                block = np.zeros((self.n_groups, width))
                for names, pixels, first in groups:
                    d = render_derivatives(self.scenes[c], names, spp=self.jacobian_spp,
                                           seed=seed, pixels=pixels)
                    for j, n in enumerate(names):
                        block[:, first + j] = self.pool(
                            d.tangents[n].mean(-1).ravel()[self.pixels])
                columns.append(block)
            out.append(np.concatenate(columns))
        return tuple(out)

    def rotation_warnings(self, state, bodies) -> list:
        """Without angular velocities fitted: per body, whether its residuals show an
        unfitted rotation (:func:`_rotation_evidence`, from the derivatives of its
        angular velocity over its pixels at the end), recorded in its entry
        (``unfitted_rotation``); the warnings of the bodies that do, each naming the body
        and the evidence."""
        warnings = []
        for k, pixels in enumerate(self.body_pixels):
            names = [f"body{k}.w{a}" for a in "xyz"]
            extra = self._columns([(names, pixels, 0)], 3)
            evidence = _rotation_evidence(state, extra, self.seen)
            bodies[k]["unfitted_rotation"] = evidence
            if evidence["chi_square"] > ROTATION_CHI_SQUARE:
                omega = ", ".join(f"{w:+.3g}" for w in evidence["angular_velocity_rad_s"])
                warnings.append(
                    f"body {k} ({bodies[k]['name']}): its residuals show an unfitted rotation: "
                    f"an angular velocity of about ({omega}) rad/s would lower the loss by "
                    f"{evidence['chi_square']:.3g} times the residuals' variance (chi-square "
                    f"of 3 degrees of freedom, above {ROTATION_CHI_SQUARE:g} once in 10^5 "
                    f"without a rotation), leaving {evidence['squared_residual_left']:.1%} of "
                    "the squared residual; its linear velocity absorbs the rotation: fit "
                    "again with --angular")
        return warnings

    def radial(self) -> list:
        """Each body's median radial velocity at the current motions (the truth's)."""
        truth = _truth(self.data.scene, self.motions, self.data.base)
        return [radial_velocity(truth, k) for k in range(len(self.motions))]

    def radial_of(self, motions) -> list:
        """Each body's median radial velocity (:meth:`radial`) with the motions set to
        ``motions`` (per body (v, omega), about the same pivots), the current motions
        kept: the truth's by the fit's own measure."""
        kept = [(m.velocity, m.angular_velocity) for m in self.motions]
        for m, (v, w) in zip(self.motions, motions):
            m.velocity, m.angular_velocity = [float(x) for x in v], [float(x) for x in w]
        try:
            return self.radial()
        finally:
            for m, (v, w) in zip(self.motions, kept):
                m.velocity, m.angular_velocity = v, w

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

    def body_entries(self, theta, cov, sigma, first: dict, closed_form, truths=None,
                     fixed=None) -> list:
        """fit.json's per-body entries at the fitted ``theta`` (the current motions),
        with the uncertainties from ``cov`` and ``sigma``, what happened to each
        component (:func:`_statuses`), the start (``first``: the history's first entry),
        the capture's own record of the body and, with ``truths`` (per body (v, omega)
        of the capture's scene), the 3-D truth and the per-component errors. ``fixed``:
        :func:`fixed_combinations`' (directions, affected), None: none."""
        partly = fixed[1] if fixed is not None else np.zeros(len(theta), bool)
        geometry = _truth(self.data.scene, self.motions, self.data.base)
        radial = [radial_velocity(geometry, k) for k in range(len(self.motions))]
        true_radial = None if truths is None else self.radial_of(truths)
        # the radial velocities' derivatives (central differences of the truth; linear in u)
        grad_radial = self.radial_gradient(theta)
        per, bodies = self.per_body, []
        start = np.asarray(first["parameters"], np.float64)
        for k, m in enumerate(self.motions):
            g = grad_radial[k]
            linear, angular = slice(k * per, k * per + 3), slice(k * per + 3, k * per + 6)
            entry = {
                "name": ", ".join(self.data.scene.bodies[k].names),
                "radial_velocity_m_s": radial[k],
                "radial_velocity_uncertainty_m_s": radial_uncertainty(
                    g, cov, sigma, partly, slice(k * per, (k + 1) * per)),
                "linear_velocity_m_s": theta[linear].tolist(),
                "linear_velocity_uncertainty_m_s": _or_none(sigma[linear]),
                "linear_velocity_status": _statuses(theta[linear], start[linear], sigma[linear],
                                                    partly[linear]),
                "angular_velocity_rad_s": [float(x) for x in m.angular_velocity],
                "angular_velocity_uncertainty_rad_s": (
                    _or_none(sigma[angular]) if self.angular else None),
                "angular_velocity_status": (
                    _statuses(theta[angular], start[angular], sigma[angular], partly[angular])
                    if self.angular
                    else [NOT_FITTED] * 3),
                "pivot_m": m.pivot,
                "start_linear_velocity_m_s": first["parameters"][linear],
                "start_radial_velocity_m_s": first["radial_velocity_m_s"][k],
                "closed_form_linear_velocity_m_s": (None if closed_form[k] is None
                                                    else closed_form[k].tolist()),
                "interior_pixels": int(self.masks[k].sum()),
            }
            entry.update(_centre_entries(geometry, self.masks[k], m.pivot,
                                         entry["linear_velocity_m_s"],
                                         entry["angular_velocity_rad_s"]))
            if truths is not None:
                entry.update(_truth_entries(entry, *truths[k]))
                entry["truth_radial_velocity_m_s"] = true_radial[k]
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


#: what happened to a component of a body's motion (fit.json's ``*_status``, the printout)
FITTED = "fitted"
KEPT = "not seen: kept at its start"
MOVED_UNCONSTRAINED = "moved from its start, unconstrained at the end: no uncertainty"
NOT_FITTED = "not fitted (held at 0; --angular fits it)"
PARTLY_FIXED = "in a combination the captures do not see, kept at its start: no uncertainty"


def _statuses(values, start, sigma, partly_fixed=(False, False, False)) -> list:
    """Per component: :data:`FITTED` (a finite uncertainty), else :data:`PARTLY_FIXED`
    where it weighs on a combination the captures do not constrain, else :data:`KEPT`
    where the value is its start's, else :data:`MOVED_UNCONSTRAINED` (a
    component the start's Jacobian saw and the fit moved, 0 to 20.4 rad/s, but the final
    Jacobian did not constrain, was labelled as kept at its start)."""
    return [FITTED if np.isfinite(s) else PARTLY_FIXED if fixed else KEPT if v == s0
            else MOVED_UNCONSTRAINED
            for v, s0, s, fixed in zip(values, start, sigma, partly_fixed)]


def _truth_entries(entry: dict, v_true, w_true) -> dict:
    """fit.json's 3-D truth of a body (the capture scene's motion about the same pivot)
    and the per-component errors, in m/s (rad/s) and in reported standard deviations
    (None without one)."""
    out = {"truth_linear_velocity_m_s": [float(x) for x in v_true],
           "truth_angular_velocity_rad_s": [float(x) for x in w_true],
           "truth_centre_linear_velocity_m_s": point_velocity(
               v_true, w_true, entry["pivot_m"], entry["centre_m"]).tolist()}
    for kind, unit, truth in (("linear", "m_s", v_true), ("angular", "rad_s", w_true)):
        fitted = np.asarray(entry[f"{kind}_velocity_{unit}"], np.float64)
        error = fitted - np.asarray(truth, np.float64)
        sigma = entry[f"{kind}_velocity_uncertainty_{unit}"] or [None] * 3
        out[f"{kind}_velocity_error_{unit}"] = error.tolist()
        out[f"{kind}_velocity_error_sigmas"] = [
            None if s is None or s == 0 else float(e / s) for e, s in zip(error, sigma)]
    return out


def _centre_entries(geometry, mask, pivot, v, w) -> dict:
    """fit.json's ``centre_m`` (the mean of the body's interior points at mid-exposure:
    the part of it the captures see) and ``centre_linear_velocity_m_s`` (the velocity
    of that point, v + omega x (centre - pivot)): a turning body's linear velocity is
    its pivot's, which may lie far from the body (a mesh's own origin); at the centre it
    compares with what the body does where it is seen."""
    on = mask & np.isfinite(geometry.depth)
    points = geometry.camera_origin + geometry.depth[on][:, None] * geometry.direction[on]
    centre = points.mean(axis=0)
    return {"centre_m": centre.tolist(),
            "centre_linear_velocity_m_s": point_velocity(v, w, pivot, centre).tolist()}


def point_velocity(v, w, pivot, point) -> np.ndarray:
    """The velocity of ``point`` of a rigid body moving at ``v`` (its pivot's) and
    turning at ``w`` about ``pivot``: v + w x (point - pivot)."""
    return np.asarray(v, np.float64) + np.cross(np.asarray(w, np.float64),
                                                np.asarray(point, np.float64)
                                                - np.asarray(pivot, np.float64))


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
    problem.seen = metric(jacobians)[1]
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


#: the chi-square (3 degrees of freedom) of an unfitted rotation's loss reduction above
#: which ``fit`` warns: exceeded by chance once in about 10^5 fits of a body without one
ROTATION_CHI_SQUARE = 25.9


def _rotation_evidence(state, extra, seen) -> dict:
    """How much an angular velocity would lower the cross loss at the end of a fit
    without one (Gauss-Newton's predicted reduction g^T G^+ g with its columns ``extra``
    beside the fitted ones, less that without them: a score test), in units of the
    residuals' variance s^2 (:func:`residual_variance`): about chi-square of 3 degrees
    of freedom for a body that does not turn; and the angular velocity of that step."""
    (r_a, r_b), (J_a, J_b) = state
    n = J_a.shape[1]
    jacobians = (np.hstack([J_a, extra[0]]), np.hstack([J_b, extra[1]]))
    G, seen_all = metric(jacobians)
    g = 0.5 * (jacobians[0].T @ r_b + jacobians[1].T @ r_a)
    fitted = np.concatenate([seen & seen_all[:n], np.zeros(3, bool)])
    both = np.concatenate([fitted[:n], seen_all[n:]])
    (without, _), (with_rotation, step) = (_predicted_reduction(G, g, mask)
                                           for mask in (fitted, both))
    gain = max(with_rotation - without, 0.0)
    # s^2 of the residuals the fit with the rotation would leave (an F test: the
    # rotation's misfit left in them would hide it in its own noise)
    s2 = residual_variance((r_a, r_b), int(both.sum()), with_rotation)
    chi_square = gain / s2 if s2 > 0 else 0.0
    energy = float(np.sum(np.square(0.5 * (r_a + r_b))))
    return {"chi_square": float(chi_square),
            "squared_residual_left": float(max(energy - with_rotation, 0.0) / energy
                                           if energy > 0 else 1.0),
            "angular_velocity_rad_s": [float(x) for x in step[n:]],
            "seen": [bool(x) for x in seen_all[n:]],
            "threshold": ROTATION_CHI_SQUARE}


def _predicted_reduction(G, g, mask):
    """Gauss-Newton's (predicted reduction of the cross loss, step) over the parameters
    ``mask``: the step -G^+ g (columns scaled, directions below RCOND^2 dropped) and
    g^T G^+ g."""
    step = _scaled_step(G, g, mask)
    return float(-g @ step), step


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
        "uncertainty": "sqrt(diag(G^+ M G^+)): the sandwich covariance of the fit's "
                       "estimate, G the metric (the two seeds' Jacobians crossed), M = "
                       "sum over blocks of J_i^T S_i J_i with S_i each block's estimated "
                       "noise covariance across the capture kinds: the renders' from the "
                       "difference of the two seeds' renders, the capture's as "
                       "settings.noise.capture_noise says; scaled by the Birge ratio B "
                       "(the residuals' energy over what that noise predicts after the "
                       "fit) only where B > 1 + %g sd(B); "
                       "^+: the pseudo-inverse over the directions the captures constrain "
                       "(singular values >= %g of the largest, columns scaled); null: a "
                       "parameter the captures do not see (kept at its start, "
                       "unconstrained: its uncertainty is infinite), or whose uncertainty "
                       "passes %g times the parameters' norm (not determined)"
                       % (BIRGE_SIGMAS, RCOND, UNDETERMINED),
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


def _damped_step(residuals, jacobians, damping, seen, rcond=RCOND):
    """The Levenberg-Marquardt step of the cross loss, -(G + damping diag(G))^+ g with
    g = (J_A^T r_B + J_B^T r_A) / 2 and G from :func:`metric`, over the parameters
    ``seen`` (:func:`_scaled_step`)."""
    (r_a, r_b), (J_a, J_b) = residuals, jacobians
    G = metric(jacobians)[0]
    return _scaled_step(G, 0.5 * (J_a.T @ r_b + J_b.T @ r_a), seen, damping, rcond)


def _scaled_step(G, g, mask, damping: float = 0.0, rcond: float = RCOND):
    """-(G + damping diag(G))^+ g over the parameters ``mask`` (zero elsewhere), with
    the columns scaled by G's diagonal and only the directions whose eigenvalue reaches
    ``rcond``^2 of the largest."""
    step = np.zeros(len(g))
    if not mask.any():
        return step
    scale = np.sqrt(np.diag(G)[mask])
    A = G[np.ix_(mask, mask)] / np.outer(scale, scale)
    A += damping * np.diag(np.diag(A))
    step[mask] = -truncated_inverse(A, rcond ** 2) @ (g[mask] / scale) / scale
    return step


def _trust(step, theta, fraction=0.5):
    """The step with each component clipped to ``fraction`` of |theta| (at least
    1 m/s): noise in a weakly constrained parameter can neither throw the motion far
    in one iteration nor, through a common scale, stop the others."""
    limit = fraction * max(np.linalg.norm(theta), 1.0)
    return np.clip(step, -limit, limit)


def _or_none(values):
    return [None if not np.isfinite(x) else float(x) for x in values]
