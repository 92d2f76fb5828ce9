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

    def as_json(self) -> dict:
        out = {"bodies": self.bodies, "iterations": self.iterations, "loss": self.loss,
               "history": self.history, "settings": self.settings}
        if self.reflectances:
            out["reflectances"] = self.reflectances
        return out


def write_fit(result: FitResult, folder) -> list:
    """fit.json and convergence.png into ``folder`` (created if missing), both or
    neither (the output set "fit" of :func:`dopplertof.io.output_folder`)."""
    from .. import io

    with io.output_folder(folder, "fit") as staged:
        io.write_json(staged.path("fit.json"), result.as_json())
        write_convergence_plot(result, staged.path("convergence.png"))
    return staged.written


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
