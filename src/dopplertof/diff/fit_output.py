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
    from .. import io

    with io.output_folder(folder, "fit") as staged:
        io.write_json(staged.path("fit.json"), result.as_json())
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
    if not result.iterations:
        lines[0] += ("\n  no optimisation step was taken: the values below are the start's, "
                     "not fitted ones")
    for b in result.bodies:
        lines.append(f"  {b['name']}: linear velocity "
                     + _vector(b["linear_velocity_m_s"], b["linear_velocity_uncertainty_m_s"],
                               "m/s", b.get("linear_velocity_status")))
        lines += _truth_line(b, "linear", "m/s", "")
        if b.get("angular_velocity_uncertainty_rad_s") is not None:
            lines.append("    angular velocity " + _vector(
                b["angular_velocity_rad_s"], b["angular_velocity_uncertainty_rad_s"], "rad/s",
                b.get("angular_velocity_status")))
            lines += _truth_line(b, "angular", "rad/s", "")
        elif any(abs(w) > 1e-6 for w in b.get("truth_angular_velocity_rad_s") or []):
            lines += _truth_line(b, "angular", "rad/s", "angular velocity not fitted; ")
        sd = b["radial_velocity_uncertainty_m_s"]
        lines.append(f"    radial velocity {b['radial_velocity_m_s']:+.3f} "
                     + ("(no uncertainty: it depends on what the captures do not see)"
                        if sd is None else f"+- {sd:.3f} m/s")
                     + " (median over the body)"
                     + _error(b["radial_velocity_m_s"], b.get("capture_velocity_gt_median_m_s")))
    for combination in result.settings.get("fixed_combinations") or []:
        lines.append("  kept at its start, the captures do not see it: " + " ".join(
            f"{c:+.3f} {name}" for name, c in combination["direction"].items()))
    for key, r in result.reflectances.items():
        spread = "not seen: kept at its start" if r["uncertainty"] is None else \
            f"+- {r['uncertainty']:.4f}"
        lines.append(f"  {key}: {r['value']:.4f} {spread} (start {r['start']:.4f})")
    return "\n".join(lines)
