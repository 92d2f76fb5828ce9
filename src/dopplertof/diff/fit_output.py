"""The fit's result: fit.json and the printed summary. See :mod:`dopplertof.diff.fit`."""

from __future__ import annotations

from dataclasses import dataclass, field

from .fit_plots import write_convergence_plot

#: a truth below this (m/s, rad/s) is near zero: its error is printed in m/s, not in %
NEAR_ZERO = 0.01


@dataclass
class FitResult:
    bodies: list
    iterations: int
    loss: float
    history: list = field(default_factory=list)
    settings: dict = field(default_factory=dict)
    reflectances: dict = field(default_factory=dict)  #: key -> value, uncertainty (fitted)
    warnings: list = field(default_factory=list)  #: e.g. a body's unfitted rotation
    #: what the uncertainties were computed from (.fit_covariance.FinalState), to compute
    #: another covariance model on the same fit; not written to fit.json
    final: object = None

    def as_json(self) -> dict:
        out = {"bodies": self.bodies, "iterations": self.iterations, "loss": self.loss,
               "history": self.history, "settings": self.settings}
        if self.reflectances:
            out["reflectances"] = self.reflectances
        if self.warnings:
            out["warnings"] = self.warnings
        return out


def write_fit(result: FitResult, folder) -> list:
    """fit.json and convergence.png into ``folder`` (created if missing), both or
    neither (the output set "fit" of :func:`dopplertof.io.output_folder`)."""
    from .. import file_formats, io

    with io.output_folder(folder, "fit") as staged:
        file_formats.write_json(staged.path("fit.json"), result.as_json())
        write_convergence_plot(result, staged.path("convergence.png"))
    return staged.written


def _vector(values, uncertainties, unit: str, statuses=None) -> str:
    """(x +- sx, y +- sy, z +- sz) unit; a component without an uncertainty says what
    happened to it (its status in fit.json: kept at its start, or moved and unconstrained
    at the end), not "kept at its start" for every one."""
    parts = []
    for value, sigma, status in zip(values, uncertainties or [None] * 3,
                                    statuses or ["no uncertainty"] * 3):
        parts.append(f"{value:+.3f} ({status})" if sigma is None
                     else f"{value:+.3f} +- {sigma:.3f}")
    return f"({', '.join(parts)}) {unit}"


def _truth_line(body: dict, kind: str, unit: str, shown: str) -> list:
    """The line under a fitted vector: the capture's 3-D truth and the per-component
    errors (in m/s or rad/s, and in reported standard deviations where there is one);
    none where fit.json has no truth."""
    key = "m_s" if unit == "m/s" else "rad_s"
    truth = body.get(f"truth_{kind}_velocity_{key}")
    if truth is None:
        return []
    errors = [f"{e:+.3f}" + ("" if z is None else f" ({z:+.1f} sd)") for e, z in zip(
        body[f"{kind}_velocity_error_{key}"], body[f"{kind}_velocity_error_sigmas"])]
    left_out = body.get(f"{kind}_velocity_error_sigmas_leave_out")
    return [f"    {shown}truth ({', '.join(f'{t:+.3f}' for t in truth)}) {unit}, "
            f"error ({', '.join(errors)}) {unit}"
            + (f" (sd of the error without {left_out})" if left_out else "")]


def _difference(value: float, truth: float) -> str:
    """``value``'s error against ``truth``: relative where the truth is not near zero
    (:data:`NEAR_ZERO`), else in m/s."""
    if abs(truth) < NEAR_ZERO:
        return f"{value - truth:+.3f} m/s"
    return f"{100 * (value / truth - 1):+.2f}%"


def _sds(error: float, sd) -> str:
    """``error`` in reported standard deviations ("" without one)."""
    return "" if not sd else f", {error / sd:+.1f} sd"


def _error(body: dict) -> str:
    """The radial velocity's error against the truth, in reported standard deviations
    too, and its start's: the truth by the fit's own measure (median over the body's
    pixels at its pose at mid-exposure) where fit.json has it, else the capture's
    record; nothing without either."""
    value, truth = body["radial_velocity_m_s"], body.get("truth_radial_velocity_m_s")
    label = "truth"
    if truth is None:
        truth, label = body.get("capture_velocity_gt_median_m_s"), "capture's truth"
    if truth is None:
        return ""
    start = body.get("start_radial_velocity_m_s")
    return (f" ({label} {truth:+.3f}, error {_difference(value, truth)}"
            f"{_sds(value - truth, body.get('radial_velocity_uncertainty_m_s'))}"
            + ("" if start is None else f"; start {start:+.3f}, error "
               f"{_difference(start, truth)}") + ")")


def drift_warnings(bodies) -> list:
    """Per body whose fit ended further from its radial velocity's truth (by the fit's
    own measure) than its start: a warning with both errors and what the end's means
    against the fit's uncertainty: within 3 reported standard deviations the start's
    nearness is chance (the captures do not determine the velocity more closely),
    beyond them the renders and the captures differ by more than their noise. The loss
    decides the fit, not the truth (unknown to a real camera): the end is kept."""
    out = []
    for k, b in enumerate(bodies):
        end, truth = b["radial_velocity_m_s"], b.get("truth_radial_velocity_m_s")
        start, sd = b.get("start_radial_velocity_m_s"), b["radial_velocity_uncertainty_m_s"]
        if None in (end, truth, start) or abs(end - truth) <= abs(start - truth):
            continue
        z = abs(end - truth) / sd if sd else None
        meaning = (
            "it has no uncertainty: the captures do not determine it" if z is None else
            f"{z:.2g} of its reported standard deviations (+- {sd:.3g} m/s): within its "
            "uncertainty, the start's nearness is chance (more samples per pixel in the "
            "capture and the fit, or more pixels on the body, narrow it)" if z <= 3 else
            f"{z:.2g} of its reported standard deviations (+- {sd:.3g} m/s): beyond its "
            "uncertainty, the fit's renders and the captures differ by more than their "
            "noise (another scene, -D value or max_depth than the capture's?)")
        out.append(f"body {k} ({b['name']}): the fit ended further from the truth's radial "
                   f"velocity ({truth:+.3f} m/s) than its start: error "
                   f"{_difference(end, truth)} against the start's "
                   f"{_difference(start, truth)}; {meaning}")
    return out


def _centre_line(body: dict) -> list:
    """For a body that turns (in the fit or in the truth): the velocity at the centre of
    its seen points, fitted and true, which does not depend on where its pivot lies;
    none for a body that only translates (the same at every point)."""
    turns = [w for key in ("angular_velocity_rad_s", "truth_angular_velocity_rad_s")
             for w in body.get(key) or []]
    centre = body.get("centre_m")
    if centre is None or not any(abs(w) > 1e-6 for w in turns):
        return []
    truth = body.get("truth_centre_linear_velocity_m_s")
    return ["    at its seen centre (" + ", ".join(f"{c:+.3f}" for c in centre) + ") m: ("
            + ", ".join(f"{v:+.3f}" for v in body["centre_linear_velocity_m_s"]) + ") m/s"
            + ("" if truth is None else
               ", truth (" + ", ".join(f"{v:+.3f}" for v in truth) + ") m/s")]


def format_fit(result: FitResult) -> str:
    """The fit's readable summary: per body the fitted linear (and angular) velocity
    with uncertainties and its median radial velocity against the capture's truth."""
    lines = [f"fit: {result.iterations} iterations ({result.settings.get('stopped', '')}), "
             f"final loss {result.loss:.4g}, {result.settings.get('seconds', 0):.1f} s"]
    if not result.iterations:
        lines[0] += ("\n  no optimisation step was taken: the values below are the start's, "
                     "not fitted ones")
    for b in result.bodies:
        pivot = b.get("pivot_m")
        lines.append(f"  {b['name']}: linear velocity "
                     + _vector(b["linear_velocity_m_s"], b["linear_velocity_uncertainty_m_s"],
                               "m/s", b.get("linear_velocity_status"))
                     + ("" if pivot is None else " at its pivot ("
                        + ", ".join(f"{p:+.4g}" for p in pivot) + ") m"))
        lines += _truth_line(b, "linear", "m/s", "")
        if b.get("angular_velocity_uncertainty_rad_s") is not None:
            lines.append("    angular velocity " + _vector(
                b["angular_velocity_rad_s"], b["angular_velocity_uncertainty_rad_s"], "rad/s",
                b.get("angular_velocity_status")))
            lines += _truth_line(b, "angular", "rad/s", "")
        elif any(abs(w) > 1e-6 for w in b.get("truth_angular_velocity_rad_s") or []):
            lines += _truth_line(b, "angular", "rad/s", "angular velocity not fitted; ")
        lines += _centre_line(b)
        sd = b["radial_velocity_uncertainty_m_s"]
        lines.append(f"    radial velocity {b['radial_velocity_m_s']:+.3f} "
                     + ("(no uncertainty: it depends on what the captures do not see)"
                        if sd is None else f"+- {sd:.3f} m/s")
                     + " (median over the body)" + _error(b))
    for combination in result.settings.get("fixed_combinations") or []:
        lines.append("  kept at its start, the captures do not see it: " + " ".join(
            f"{c:+.3f} {name}" for name, c in combination["direction"].items()))
    for key, r in result.reflectances.items():
        spread = "not seen: kept at its start" if r["uncertainty"] is None else \
            f"+- {r['uncertainty']:.4f}"
        lines.append(f"  {key}: {r['value']:.4f} {spread} (start {r['start']:.4f})")
    return "\n".join(lines)
