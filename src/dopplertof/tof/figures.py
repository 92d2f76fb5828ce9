"""PNG previews of capture products: one map per array, and the side-by-side figure.

Every file is written atomically (:func:`dopplertof.io.atomic_path`). NaN pixels
(nothing seen, a signal too weak, a mixed footprint: each captioned by its reason) are hatched on a magenta outside every
colour map (:data:`dopplertof.io.NO_SIGNAL_COLOUR`). Radiance is shown with one display
gamma everywhere (:data:`RADIANCE_GAMMA`).
"""

from __future__ import annotations

import numpy as np

from ..io import (NO_SIGNAL_NOTE, ImagePanel, add_caption, agg_figure, colorbar_extend,
                  layout_as_made, restore_layout, save_figure, show_preview, take_figure)

#: display gamma of every radiance preview: shown value = (radiance / top) ** (1 / gamma)
RADIANCE_GAMMA = 2.2
RADIANCE_GAMMA_LABEL = f"gamma {RADIANCE_GAMMA:g}"


def _pyplot():
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    return plt


def symmetric_limit(*arrays, percentile: float = 99.0) -> float:
    """A symmetric colour range covering ``percentile`` of |values| of all arrays."""
    values = np.concatenate([np.abs(np.asarray(a, np.float64)).ravel() for a in arrays])
    values = values[np.isfinite(values)]
    limit = float(np.percentile(values, percentile)) if values.size else 0.0
    if limit <= 0:
        limit = float(values.max()) if values.size and values.max() > 0 else 1.0
    return limit


def truth_limit(truth, fallback) -> float:
    """Colour range of a velocity map: 1.25 x the truth's largest speed (99.5th
    percentile), so that reconstruction outliers saturate instead of washing out the
    truth; the reconstruction's range where everything is static."""
    limit = symmetric_limit(truth, percentile=99.5)
    finite = np.asarray(truth, np.float64)
    if not np.any(np.abs(finite[np.isfinite(finite)]) > 0):
        return symmetric_limit(fallback)
    return 1.25 * limit


def radiance_scalar(radiance: np.ndarray) -> np.ndarray:
    r = np.asarray(radiance, np.float64)
    return r.mean(axis=-1) if r.ndim == 3 else r


#: the colour bar's label and tick label sizes (points) of every capture preview
BAR_TEXT = (9, 8)


def _preview(data, title, label, cmap, norm, extra_height: float = 0.9):
    """(figure, axes) of a capture's one-panel preview of ``data`` (H, W): 6 inches
    wide at 120 dpi (:func:`dopplertof.io.show_preview`)."""
    h, w = data.shape
    return show_preview((6.0, 4.8 * h / w + extra_height), 120, data, title, label, cmap,
                        norm, BAR_TEXT)


def radiance_top(*images) -> float:
    """The radiance shown white: the 99.5th percentile over ``images`` (1 if none)."""
    values = np.concatenate([np.asarray(a, np.float64).ravel() for a in images])
    values = values[np.isfinite(values)]
    top = float(np.percentile(values, 99.5)) if values.size else 1.0
    return top if top > 0 else 1.0


def radiance_norm(top: float):
    """The radiance colour scale: 0 to ``top`` with the display gamma."""
    import matplotlib.colors as colors

    return colors.PowerNorm(gamma=1.0 / RADIANCE_GAMMA, vmin=0.0, vmax=top)


def _radiance_norm(data):
    return radiance_norm(radiance_top(data))


def write_map(path, data, title: str, label: str, cmap: str = "viridis", vmin=None,
              vmax=None, symmetric: bool = False, note: str | None = None,
              metadata: dict | None = None, marked=None) -> None:
    """One scalar map with a colour bar; ``symmetric`` centres the range on zero;
    ``marked`` (H, W bool): pixels cross-hatched in white (:func:`mark_pixels`)."""
    import matplotlib.colors as colors

    data = np.asarray(data, np.float64)
    if symmetric:
        limit = symmetric_limit(data) if vmax is None else vmax
        vmin, vmax = -limit, limit
    elif vmin is None or vmax is None:
        finite = data[np.isfinite(data)]
        vmin = float(np.percentile(finite, 0.5)) if vmin is None and finite.size else vmin
        vmax = float(np.percentile(finite, 99.5)) if vmax is None and finite.size else vmax
    fig, ax = _preview(data, title, label, cmap, colors.Normalize(vmin, vmax))
    if marked is not None:
        mark_pixels(ax, marked)
    if note:
        add_caption(fig, note)
    save_figure(fig, path, metadata)


#: how :func:`mark_pixels` marks a pixel (the depth preview: beyond the wrap distance)
MARK_HATCH, MARK_COLOUR = "xx", "white"


def mark_pixels(ax, marked):
    """Cross-hatch the pixels ``marked`` (H, W bool) of the image on ``ax`` (white
    lines over its colours, one rectangle per run of marked pixels in a row); returns
    the PatchCollection (None when no pixel is marked)."""
    from matplotlib.collections import PatchCollection
    from matplotlib.patches import Rectangle

    marked = np.asarray(marked, bool)
    runs = []
    for row in range(marked.shape[0]):
        edges = np.flatnonzero(np.diff(np.concatenate([[0], marked[row].astype(np.int8), [0]])))
        runs += [Rectangle((start - 0.5, row - 0.5), end - start, 1.0)
                 for start, end in zip(edges[::2], edges[1::2])]
    if not runs:
        return None
    patches = PatchCollection(runs, facecolor="none", edgecolor=MARK_COLOUR, hatch=MARK_HATCH,
                              linewidth=0, zorder=2)
    ax.add_collection(patches)
    return patches


def write_log_map(path, data, title: str, label: str, cmap: str = "magma",
                  note: str | None = None, metadata: dict | None = None) -> None:
    """A positive map (standard deviations) on a log colour scale from its 0.5th to
    99.5th percentile over the finite positive values; +inf shows as the top colour,
    NaN and zero as no signal."""
    import matplotlib.colors as colors
    data = np.asarray(data, np.float64)
    shown = np.where(np.isfinite(data) & (data > 0), data, np.nan)
    finite = shown[np.isfinite(shown)]
    lo = float(np.percentile(finite, 0.5)) if finite.size else 1e-3
    hi = float(np.percentile(finite, 99.5)) if finite.size else 1.0
    hi = hi if hi > lo else lo * 10
    shown = np.where(np.isposinf(data), hi, shown)
    fig, _ = _preview(shown, title, label, cmap, colors.LogNorm(vmin=lo, vmax=hi))
    if note:
        add_caption(fig, note)
    save_figure(fig, path, metadata)


def write_radiance(path, radiance, title: str, metadata: dict | None = None) -> None:
    data = radiance_scalar(radiance)
    fig, _ = _preview(data, title, f"radiance (scene units, mean of RGB; {RADIANCE_GAMMA_LABEL})",
                      "gray", _radiance_norm(data), extra_height=0.8)
    save_figure(fig, path, metadata)


#: the comparison figure's panels, left to right: (title, colour bar label, colour map)
COMPARISON_PANELS = (
    ("radiance", f"scene units, mean of RGB ({RADIANCE_GAMMA_LABEL})", "gray"),
    ("reconstructed radial velocity", "m/s (+ receding)", "RdBu_r"),
    ("ground truth (mid-exposure)", "m/s (+ receding)", "RdBu_r"),
    ("error (reconstructed - truth)", "m/s", "PuOr_r"),
)


class ComparisonFigure:
    """The side-by-side figure on its own canvas: four :class:`dopplertof.io.ImagePanel`
    in a row; ``key`` = (image shape, the four colour bars' arrows). Made once per key
    and Matplotlib settings and shown again (:func:`dopplertof.io.take_figure`), as the
    one-panel previews are; :func:`dopplertof.io.save_figure` gives it back."""

    def __init__(self, key, settings):
        (h, w), extends = key
        self.key, self.settings, self.in_use = key, settings, True
        self.fig = agg_figure((20, 3.9 * h / w + 1.0), 110)
        self.fig.dopplertof_preview = self  # (how save_figure knows it)
        self.panels = [ImagePanel(self.fig, ax, (h, w), extend, BAR_TEXT)
                       for ax, extend in zip(self.fig.subplots(1, 4), extends)]
        self.made = layout_as_made(self.fig)  # (before tight_layout and the fit)

    def reset(self) -> None:
        """Back as made: the data let go, the layout restored (the title stays, set anew
        by each use)."""
        for panel in self.panels:
            panel.clear()
        restore_layout(self.fig, self.made)


def write_comparison(path, radiance, velocity, velocity_gt, title: str,
                     metadata: dict | None = None, note: str = NO_SIGNAL_NOTE) -> None:
    """Side by side: radiance | reconstructed velocity | ground truth | error; ``note``
    captions the NaN pixels (by their reasons, tof.output.masked_caption)."""
    import matplotlib.colors as colors

    rad = radiance_scalar(radiance)
    velocity = np.asarray(velocity, np.float64)
    truth = np.asarray(velocity_gt, np.float64)
    error = velocity - truth
    limit, err_limit = truth_limit(truth, velocity), symmetric_limit(error)
    shown = [(rad, _radiance_norm(rad)), (velocity, colors.Normalize(-limit, limit)),
             (truth, colors.Normalize(-limit, limit)),
             (error, colors.Normalize(-err_limit, err_limit))]
    extends = tuple(colorbar_extend(data, norm.vmin, norm.vmax) for data, norm in shown)
    comparison = take_figure((rad.shape, extends), ComparisonFigure)
    for panel, (data, norm), (panel_title, label, cmap) in zip(comparison.panels, shown,
                                                               COMPARISON_PANELS):
        panel.show(np.ma.masked_invalid(data), panel_title, label, cmap, norm)
    fig = comparison.fig
    fig.suptitle(f"{title}   ({note})", fontsize=11)
    fig.tight_layout()
    save_figure(fig, path, metadata)
