"""PNG previews of capture products: one map per array, and the side-by-side figure,
drawn by :mod:`dopplertof.previews` (no Matplotlib).

Every file is written atomically (:func:`dopplertof.image_files.save_png`). NaN pixels (nothing
seen, a signal too weak, a mixed footprint: each captioned by its reason) are hatched on
a magenta outside every colour map (:data:`dopplertof.previews.NO_SIGNAL_COLOUR`).
Radiance is shown with one display gamma everywhere (:data:`RADIANCE_GAMMA`).
"""

from __future__ import annotations

import numpy as np

from .. import image_files
from ..previews import NO_SIGNAL_NOTE, ColourScale, Panel, draw

#: display gamma of every radiance preview: shown value = (radiance / top) ** (1 / gamma)
RADIANCE_GAMMA = 2.2
RADIANCE_GAMMA_LABEL = f"gamma {RADIANCE_GAMMA:g}"


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


#: the box (pixels) a one-panel preview's image is fitted into, and each of the
#: comparison figure's four
PREVIEW_FIT, COMPARISON_FIT = (576, 576), (432, 432)


def radiance_top(*images) -> float:
    """The radiance shown white: the 99.5th percentile over ``images`` (1 if none)."""
    values = np.concatenate([np.asarray(a, np.float64).ravel() for a in images])
    values = values[np.isfinite(values)]
    top = float(np.percentile(values, 99.5)) if values.size else 1.0
    return top if top > 0 else 1.0


def radiance_norm(top: float):
    """The radiance colour scale of Matplotlib figures (the animation): 0 to ``top`` with
    the display gamma, as :func:`radiance_scale` for the previews."""
    import matplotlib.colors as colors

    return colors.PowerNorm(gamma=1.0 / RADIANCE_GAMMA, vmin=0.0, vmax=top)


def radiance_scale(top: float) -> ColourScale:
    """The radiance colour scale of the previews: 0 to ``top`` with the display gamma."""
    return ColourScale(0.0, top, "power", 1.0 / RADIANCE_GAMMA)


def write_map(path, data, title: str, label: str, cmap: str = "viridis", vmin=None,
              vmax=None, symmetric: bool = False, note: str | None = None,
              metadata: dict | None = None, marked=None) -> None:
    """One scalar map with a colour bar; ``symmetric`` centres the range on zero (limits
    None: the 99th percentile of |data|); otherwise limits None are the 0.5th and
    99.5th percentiles; ``marked`` (H, W bool): pixels cross-hatched in white."""
    data = np.asarray(data, np.float64)
    if symmetric:
        limit = symmetric_limit(data) if vmax is None else vmax
        vmin, vmax = -limit, limit
    elif vmin is None or vmax is None:
        finite = data[np.isfinite(data)]
        vmin = float(np.percentile(finite, 0.5)) if vmin is None and finite.size else vmin
        vmax = float(np.percentile(finite, 99.5)) if vmax is None and finite.size else vmax
    panel = Panel(data, title, label, cmap, ColourScale.fitted(data, vmin, vmax), marked)
    image_files.save_png(path, draw([panel], PREVIEW_FIT, caption=note or ""), metadata)


def write_log_map(path, data, title: str, label: str, cmap: str = "magma",
                  note: str | None = None, metadata: dict | None = None) -> None:
    """A positive map (standard deviations) on a log colour scale from its 0.5th to
    99.5th percentile over the finite positive values; +inf shows as the top colour,
    NaN and zero as no signal."""
    data = np.asarray(data, np.float64)
    shown = np.where(np.isfinite(data) & (data > 0), data, np.nan)
    finite = shown[np.isfinite(shown)]
    lo = float(np.percentile(finite, 0.5)) if finite.size else 1e-3
    hi = float(np.percentile(finite, 99.5)) if finite.size else 1.0
    hi = hi if hi > lo else lo * 10
    shown = np.where(np.isposinf(data), hi, shown)
    panel = Panel(shown, title, label, cmap, ColourScale(lo, hi, "log"))
    image_files.save_png(path, draw([panel], PREVIEW_FIT, caption=note or ""), metadata)


def write_radiance(path, radiance, title: str, metadata: dict | None = None) -> None:
    data = radiance_scalar(radiance)
    panel = Panel(data, title, f"radiance (scene units, mean of RGB; {RADIANCE_GAMMA_LABEL})",
                  "gray", radiance_scale(radiance_top(data)))
    image_files.save_png(path, draw([panel], PREVIEW_FIT), metadata)


#: the comparison figure's panels, left to right: (title, colour bar label, colour map)
COMPARISON_PANELS = (
    ("radiance", f"scene units, mean of RGB ({RADIANCE_GAMMA_LABEL})", "gray"),
    ("reconstructed radial velocity", "m/s (+ receding)", "RdBu_r"),
    ("ground truth (mid-exposure)", "m/s (+ receding)", "RdBu_r"),
    ("error (reconstructed - truth)", "m/s", "PuOr_r"),
)


def write_comparison(path, radiance, velocity, velocity_gt, title: str,
                     metadata: dict | None = None, note: str = NO_SIGNAL_NOTE) -> None:
    """Side by side: radiance | reconstructed velocity | ground truth | error; ``note``
    captions the NaN pixels (by their reasons, tof.output.masked_caption)."""
    rad = radiance_scalar(radiance)
    velocity = np.asarray(velocity, np.float64)
    truth = np.asarray(velocity_gt, np.float64)
    error = velocity - truth
    limit, err_limit = truth_limit(truth, velocity), symmetric_limit(error)
    shown = [(rad, radiance_scale(radiance_top(rad))),
             (velocity, ColourScale(-limit, limit)), (truth, ColourScale(-limit, limit)),
             (error, ColourScale(-err_limit, err_limit))]
    panels = [Panel(data, panel_title, label, cmap, scale) for (data, scale),
              (panel_title, label, cmap) in zip(shown, COMPARISON_PANELS)]
    image_files.save_png(path, draw(panels, COMPARISON_FIT, title=f"{title}   ({note})"), metadata)
