"""The sweep report's figures (experiments/report.py names them and their file names):
relative MSE by method, over the heterodyne frequency and offset, against spp and
against a numeric axis, and the images beside their references."""

from __future__ import annotations

import itertools
import math
import os
from dataclasses import dataclass

import numpy as np

from .report_grid import (AXIS_LABELS, CONFIG_AXES, IMAGE_LABEL, LINE_AXES, MAX_LINES, MAX_PANELS,
                          MSE_LABEL, RELATIVE_MSE_LABEL, axis_value, axis_values, combo_label,
                          mean_by, short_label, value_label)

def _figure(width, height):
    from matplotlib.figure import Figure

    return Figure(figsize=(width, height), dpi=110, layout="constrained")


def _save(fig, path: str, files: list) -> None:
    from .. import io

    with io.atomic_path(path) as tmp:
        fig.savefig(tmp, format="png", metadata={"Software": "dopplertof report"})
    files.append(path)


def bars_by_method(runs, grid, out, files, title_suffix):
    config_axes = [a for a in ("time_sampling_method", "use_stratified_sampling_for_each_interval",
                               "path_correlation_depth") if len(grid.get(a, [])) > 1]
    if not config_axes:
        return
    x_axis = "path_correlation_depth" if "path_correlation_depth" in config_axes else config_axes[-1]
    series_axes = [a for a in config_axes if a != x_axis]
    means = mean_by(runs, [x_axis] + series_axes, "relative_mse")
    if not means:
        return
    xs = axis_values(grid, x_axis)
    series = list(itertools.product(*(axis_values(grid, a) for a in series_axes)))
    fig = _figure(max(6.0, 1.1 * len(xs) * max(1, len(series)) ** 0.5 + 3), 4.4)
    ax = fig.add_subplot()
    width = 0.8 / max(1, len(series))
    for j, combo in enumerate(series):
        heights = [means.get((x,) + combo, math.nan) for x in xs]
        positions = np.arange(len(xs)) + (j - (len(series) - 1) / 2) * width
        ax.bar(positions, heights, width=width * 0.95, label=combo_label(series_axes, combo))
    ax.set_xticks(np.arange(len(xs)), [value_label(x_axis, x) for x in xs])
    ax.set_xlabel(AXIS_LABELS.get(x_axis, x_axis))
    ax.set_yscale("log")
    ax.set_ylabel(RELATIVE_MSE_LABEL)
    averaged = [a for a in grid if a not in config_axes]
    ax.set_title("Relative MSE per time sampling configuration" + title_suffix
                 + (f"\n(mean over {', '.join(averaged)})" if averaged else ""), fontsize=10)
    if series_axes:
        ax.legend(title=", ".join(short_label(a) for a in series_axes), fontsize=8,
                  loc="upper left", bbox_to_anchor=(1.01, 1.0))
    ax.grid(axis="y", which="both", alpha=0.3)
    _save(fig, os.path.join(out, "relative_mse_by_method.png"), files)


def heatmaps(runs, grid, out, files, title_suffix):
    from matplotlib.colors import LogNorm

    if len(grid.get("hetero_frequency", [])) < 2 or len(grid.get("hetero_offset", [])) < 2:
        return
    panel_axes = [a for a in grid if a not in ("hetero_frequency", "hetero_offset", "seed")
                  and len(grid[a]) > 1]
    panels = list(itertools.product(*(axis_values(grid, a) for a in panel_axes)))
    shown = panels[:MAX_PANELS]
    freqs = sorted(axis_values(grid, "hetero_frequency"))
    offsets = sorted(axis_values(grid, "hetero_offset"))
    means = mean_by(runs, panel_axes + ["hetero_frequency", "hetero_offset"], "relative_mse")
    if not means:
        return
    positive = [v for v in means.values() if v > 0]
    if not positive:
        return
    norm = LogNorm(vmin=min(positive), vmax=max(positive))
    cols = min(4, len(shown))
    rows = -(-len(shown) // cols)
    fig = _figure(3.3 * cols + 1.2, 3.0 * rows + 0.8)
    axes = np.atleast_1d(fig.subplots(rows, cols, squeeze=False)).ravel()
    image = None
    for ax, combo in zip(axes, shown):
        data = np.array([[means.get(combo + (f, o), math.nan) for o in offsets] for f in freqs])
        image = ax.imshow(data, origin="lower", aspect="auto", norm=norm, cmap="magma",
                          extent=_extent(offsets) + _extent(freqs), interpolation="nearest")
        ax.set_title(combo_label(panel_axes, combo), fontsize=9)
    for index, ax in enumerate(axes[:len(shown)]):
        if index % cols == 0:
            ax.set_ylabel(AXIS_LABELS["hetero_frequency"], fontsize=8)
        if index + cols >= len(shown):
            ax.set_xlabel(AXIS_LABELS["hetero_offset"], fontsize=8)
    for ax in axes[len(shown):]:
        ax.set_visible(False)
    bar = fig.colorbar(image, ax=list(axes[:len(shown)]), shrink=0.9)
    bar.set_label(RELATIVE_MSE_LABEL)
    more = f" (first {MAX_PANELS} of {len(panels)})" if len(panels) > MAX_PANELS else ""
    fig.suptitle("Relative MSE over heterodyne frequency and sensor offset" + title_suffix
                 + more, fontsize=11)
    _save(fig, os.path.join(out, "relative_mse_heatmap.png"), files)


def _extent(values) -> list:
    if len(values) < 2:
        return [values[0] - 0.5, values[0] + 0.5]
    step = (values[-1] - values[0]) / (len(values) - 1)
    return [values[0] - step / 2, values[-1] + step / 2]


def mse_vs_spp(runs, grid, out, files, title_suffix):
    spps = sorted(axis_values(grid, "spp"))
    if len(spps) < 2:
        return
    series_axes = [a for a in grid if a in CONFIG_AXES and len(grid[a]) > 1]
    means = mean_by(runs, series_axes + ["spp"], "mse")
    if not means:
        return
    fig = _figure(6.4, 4.6)
    ax = fig.add_subplot()
    combos = list(itertools.product(*(axis_values(grid, a) for a in series_axes)))[:MAX_LINES]
    first = []
    for combo in combos:
        ys = [means.get(combo + (s,), math.nan) for s in spps]
        if all(math.isnan(y) for y in ys):
            continue
        ax.loglog(spps, ys, marker="o", label=combo_label(series_axes, combo))
        first.append(next(y for y in ys if not math.isnan(y)))
    if first:
        guide = np.array(spps, dtype=float)
        ax.loglog(guide, max(first) * spps[0] / guide, "k--", lw=1, label="∝ 1/spp")
    ax.set_xlabel(AXIS_LABELS["spp"])
    ax.set_ylabel(MSE_LABEL)
    averaged = [a for a in grid if a not in series_axes and a != "spp"]
    ax.set_title("MSE against samples per pixel" + title_suffix
                 + (f"\n(mean over {', '.join(averaged)})" if averaged else ""), fontsize=10)
    ax.legend(fontsize=8)
    ax.grid(which="both", alpha=0.3)
    _save(fig, os.path.join(out, "mse_vs_spp.png"), files)


def lines_vs_axis(runs, grid, out, files, title_suffix):
    heat = len(grid.get("hetero_frequency", [])) > 1 and len(grid.get("hetero_offset", [])) > 1
    for x_axis in LINE_AXES:
        xs = sorted(axis_values(grid, x_axis))
        if len(xs) < 2 or (heat and x_axis in ("hetero_frequency", "hetero_offset")):
            continue
        series_axes = [a for a in grid if a not in (x_axis, "seed", "spp") and len(grid[a]) > 1
                       and not (heat and a in ("hetero_frequency", "hetero_offset"))]
        means = mean_by(runs, series_axes + [x_axis], "relative_mse")
        if not means:
            continue
        fig = _figure(6.4, 4.6)
        ax = fig.add_subplot()
        combos = list(itertools.product(*(axis_values(grid, a) for a in series_axes)))
        for combo in combos[:MAX_LINES]:
            ys = [means.get(combo + (x,), math.nan) for x in xs]
            ax.semilogy(xs, ys, marker="o", label=combo_label(series_axes, combo))
        ax.set_xlabel(AXIS_LABELS.get(x_axis, x_axis))
        ax.set_ylabel(RELATIVE_MSE_LABEL)
        averaged = [a for a in grid if a not in series_axes and a != x_axis]
        ax.set_title(f"Relative MSE against {AXIS_LABELS.get(x_axis, x_axis).split(' (')[0]}"
                     + title_suffix
                     + (f"\n(mean over {', '.join(averaged)})" if averaged else ""), fontsize=10)
        if series_axes:
            ax.legend(fontsize=8, title=", ".join(short_label(a) for a in series_axes))
        ax.grid(which="both", alpha=0.3)
        _save(fig, os.path.join(out, f"relative_mse_vs_{x_axis}.png"), files)


@dataclass
class _ImageLayout:
    """What ``images.png`` shows: the runs over (at most) two axes, the others pinned."""

    row_axis: str | None  #: the rows' axis (None: one row)
    col_axis: str | None  #: the columns' axis (None: one column)
    rows: list  #: the rows' values (the first 8)
    cols: list  #: the columns' values (the first 8)
    pinned: dict  #: {axis: value} of every other axis
    runs: list  #: the runs at the pinned values


def image_grid(runs, references, grid, out, files, title_suffix):
    """``images.png``: the runs over two axes beside their reference, one colour scale."""
    from ..previews import preview_scalar

    if not runs:
        return
    layout = _image_layout(runs, grid)
    # ---- the images and their shared colour scale
    first = layout.runs[0]
    reference = references.get(first.reference) if first.reference else None
    cells = _image_cells(layout)
    scalars = {key: preview_scalar(r.image) for key, r in cells.items()}
    ref_scalar = preview_scalar(reference) if reference is not None else None
    basis = (ref_scalar if ref_scalar is not None
             else np.concatenate([x.ravel() for x in scalars.values()]))
    vmax = float(np.percentile(np.abs(basis), 99)) or 1.0
    # ---- the figure: the reference's column (if any), then one column per value
    extra = 1 if ref_scalar is not None else 0
    ncols = len(layout.cols) + extra
    fig = _figure(2.3 * ncols + 1.2, 2.3 * len(layout.rows) + 1.0)
    axes = fig.subplots(len(layout.rows), ncols, squeeze=False)
    shown = _draw_reference_column(axes[:, 0], ref_scalar, vmax) if extra else None
    last_run = _draw_run_cells(axes[:, extra:], layout, cells, scalars, vmax)
    if last_run is not None:
        shown = last_run
    # ---- colour bar and title
    bar = fig.colorbar(shown, ax=axes.ravel().tolist(), shrink=0.8)
    bar.set_label(IMAGE_LABEL)
    pins = ", ".join(f"{short_label(a)}={value_label(a, v)}" for a, v in layout.pinned.items())
    fig.suptitle("Rendered images" + title_suffix + (f"\n({pins})" if pins else ""),
                 fontsize=10)
    _save(fig, os.path.join(out, "images.png"), files)


def _image_layout(runs, grid) -> _ImageLayout:
    """Rows and columns over the first two varying axes (sampling configurations first,
    never the seed); every other axis pinned to its middle value (the seed to its first),
    or to the first run's values where that point is not rendered yet."""
    varying = [a for a in grid if a != "seed" and len(grid[a]) > 1]
    preferred = [a for a in CONFIG_AXES if a in varying] + [a for a in varying
                                                            if a not in CONFIG_AXES]
    row_axis = preferred[0] if preferred else None
    col_axis = preferred[1] if len(preferred) > 1 else None
    fixed_axes = [a for a in grid if a not in (row_axis, col_axis)]
    # other axes at their middle value (h = 1 of 0..2: the heterodyne case), seed the first
    pinned = {a: grid[a][0 if a == "seed" else len(grid[a]) // 2] for a in fixed_axes}
    chosen = _runs_at(runs, pinned)
    if not chosen:  # that point is not rendered yet: pin to a run that is
        pinned = {a: axis_value(runs[0], a) for a in fixed_axes}
        chosen = _runs_at(runs, pinned)
    return _ImageLayout(row_axis=row_axis, col_axis=col_axis,
                        rows=axis_values(grid, row_axis)[:8] if row_axis else [None],
                        cols=axis_values(grid, col_axis)[:8] if col_axis else [None],
                        pinned=pinned, runs=chosen)


def _runs_at(runs, pinned: dict) -> list:
    """The runs whose values are the pinned ones."""
    return [r for r in runs if all(axis_value(r, a) == v for a, v in pinned.items())]


def _image_cells(layout: _ImageLayout) -> dict:
    """{(row value, column value): run} of the layout's runs in a shown row and column."""
    row_axis, col_axis = layout.row_axis, layout.col_axis
    cells = {(axis_value(r, row_axis) if row_axis else None,
              axis_value(r, col_axis) if col_axis else None): r for r in layout.runs}
    return {key: r for key, r in cells.items() if key[0] in layout.rows
            and key[1] in layout.cols}


def _show_signed(ax, scalar, vmax):
    """A signed image on the shared diverging colour scale [-vmax, vmax]."""
    return ax.imshow(scalar, cmap="RdBu_r", vmin=-vmax, vmax=vmax, interpolation="nearest")


def _draw_reference_column(column, ref_scalar, vmax):
    """The reference at the top of its column (the cells below stay empty); its image."""
    shown = None
    for i, ax in enumerate(column):
        if i == 0:
            shown = _show_signed(ax, ref_scalar, vmax)
            ax.set_title("reference", fontsize=9)
        ax.set_axis_off()
    return shown


def _draw_run_cells(axes, layout: _ImageLayout, cells, scalars, vmax):
    """Every run in its cell: the column's value above the top row, the relative MSE
    above each image, the row's value beside the first column; a cell without a run is
    left blank. Returns the last image drawn (None if none)."""
    shown = None
    for i, rv in enumerate(layout.rows):
        for j, cv in enumerate(layout.cols):
            ax = axes[i][j]
            ax.set_xticks([])
            ax.set_yticks([])
            run = cells.get((rv, cv))
            if run is None:
                ax.set_axis_off()
                continue
            shown = _show_signed(ax, scalars[(rv, cv)], vmax)
            label = []
            if i == 0 and layout.col_axis:
                label.append(combo_label([layout.col_axis], [cv]))
            if run.relative_mse is not None:
                label.append(f"relMSE {run.relative_mse:.2g}")
            ax.set_title("\n".join(label), fontsize=8)
            if j == 0 and layout.row_axis:
                ax.set_ylabel(combo_label([layout.row_axis], [rv]), fontsize=8)
    return shown


