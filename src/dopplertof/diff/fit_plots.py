"""The fit's convergence plot (convergence.png). See :mod:`dopplertof.diff.fit`."""

from __future__ import annotations

import numpy as np


def write_convergence_plot(result, path) -> None:
    from .. import image_files

    plt = image_files.pyplot()
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
    image_files.save_figure(fig, path)
    plt.close(fig)


def _plot_angular_velocity(ax, result, its) -> None:
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
