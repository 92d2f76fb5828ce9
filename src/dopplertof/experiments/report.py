"""Figures and a Markdown summary from a sweep's results folder.

Error of a run against its reference (same measurement parameters, high spp):

    MSE          = mean over pixels and channels of (image - reference)^2
    relative MSE = MSE / mean(reference^2)

D-ToF images are signed and heterodyne images are near zero wherever nothing moves, so
the per-pixel ratio (x - r)^2 / r^2 would be dominated by pixels where r crosses zero;
normalising by the reference's mean square keeps the measure unitless and finite.

Figures (each only when the grid has the axes it needs):

- ``relative_mse_by_method.png``: bars per time sampling method and correlation depth
  (or stratification), mean over the other axes;
- ``relative_mse_heatmap.png``: relative MSE over (heterodyne frequency, offset), one
  panel per sampling configuration;
- ``mse_vs_spp.png``: log-log MSE against samples per pixel, with a 1/spp guide;
- ``relative_mse_vs_<axis>.png``: relative MSE against a numeric axis
  (e.g. the antithetic shift), one line per other configuration;
- ``images.png``: the images over two axes beside the reference, one colour scale;
- ``summary.md`` and ``metrics.csv``.
"""

from __future__ import annotations

import csv
import io as _pyio
import itertools
import json
import math
import os
from dataclasses import dataclass, field

import numpy as np

from .config import FULL_CORRELATION, SAMPLING_ONLY, format_value
from .sweep import SUMMARY_JSON, SWEEP_JSON
from .tasks import COMPLETE_MARKER, IMAGE_NPY, PARAMS_JSON

AXIS_LABELS = {
    "hetero_frequency": "heterodyne frequency h (beat periods per exposure)",
    "hetero_offset": "sensor offset o (periods)",
    "antithetic_shift": "antithetic shift a (fraction of the exposure)",
    "spp": "samples per pixel",
    "path_correlation_depth": "path correlation depth d (stages shared)",
    "time_sampling_method": "time sampling method",
    "use_stratified_sampling_for_each_interval": "stratification across groups",
    "time_correlate_number": "samples per correlated group K",
    "w_g": "illumination frequency f_g (MHz)",
    "w_s": "sensor frequency f_s (MHz)",
    "time": "exposure T (s)",
    "max_depth": "max path depth (segments)",
    "seed": "seed",
}
RELATIVE_MSE_LABEL = "relative MSE = MSE / mean(reference²)"
MSE_LABEL = "MSE (squared time-averaged correlation)"
IMAGE_LABEL = "time-averaged correlation (mean of channels)"

#: axes a heat map or a line plot puts on its x axis (numeric)
LINE_AXES = ("antithetic_shift", "hetero_frequency", "hetero_offset", "time_correlate_number",
             "w_g", "time", "max_depth", "rr_depth")
#: axes that name a sampling configuration (the bars and the heat-map panels)
CONFIG_AXES = ("time_sampling_method", "path_correlation_depth",
               "use_stratified_sampling_for_each_interval", "time_correlate_number",
               "wave_function_type", "antithetic_shift")

MAX_PANELS = 16
MAX_LINES = 12
MAX_TABLE_ROWS = 300


class ReportError(ValueError):
    """A folder that holds no sweep results."""


@dataclass
class RunRecord:
    name: str
    point: dict
    spp: int
    seed: int
    seconds: float
    folder: str
    reference: str | None
    mse: float | None = None
    relative_mse: float | None = None

    @property
    def image(self) -> np.ndarray:
        """The rendered array, read when needed (a sweep may hold thousands)."""
        return np.load(os.path.join(self.folder, IMAGE_NPY))


@dataclass
class Report:
    output: str
    files: list = field(default_factory=list)
    runs: int = 0
    missing: list = field(default_factory=list)
    with_errors: int = 0
    #: (task folder, reason) of every complete task of another spec than the sweep's
    #: current one (excluded from every metric and figure)
    stale: list = field(default_factory=list)


# ---- Reading ------------------------------------------------------------------------------

def _complete(folder: str) -> bool:
    return all(os.path.isfile(os.path.join(folder, f))
               for f in (COMPLETE_MARKER, PARAMS_JSON, IMAGE_NPY))


def read_results(results: str):
    """(sweep.json contents, run records, reference images, missing task names, stale
    tasks as (folder, reason)). A stale task (complete, but for another spec than
    sweep.json's: another spp, seed, grid point or scene) is left out of the records
    and the references."""
    results = os.path.abspath(results)
    path = os.path.join(results, SWEEP_JSON)
    if not os.path.isfile(path):
        raise ReportError(f"not a sweep results folder (no {SWEEP_JSON}): {results}")
    try:
        with open(path, encoding="utf-8") as f:
            sweep = json.load(f)
        tasks = sweep["tasks"]
    except (OSError, ValueError, KeyError, TypeError) as e:
        raise ReportError(f"{path}: unreadable sweep description: {e}") from None
    references, runs, missing, stale = {}, [], [], []
    for task in tasks:
        folder = os.path.join(results, task["folder"])
        if not _complete(folder):
            missing.append(task["folder"])
            continue
        record, reason = _checked_record(task, folder)
        if reason:
            stale.append((task["folder"], reason))
            continue
        if task["kind"] == "reference":
            references[task["folder"]] = np.load(os.path.join(folder, IMAGE_NPY))
            continue
        runs.append(RunRecord(
            name=task["name"], point=dict(task["grid_point"]), spp=int(task["spp"]),
            seed=int(task["seed"]), seconds=float(record.get("render_seconds") or math.nan),
            folder=folder, reference=task.get("reference")))
    _measure_errors(runs, references)
    return sweep, runs, references, missing, stale


def _checked_record(task: dict, folder: str):
    """(params.json of a complete task, None), or (None, why the task is stale): its
    marker's or params.json's spec hash is not the sweep's, or params.json records
    another spp, seed or grid point than sweep.json's task (sweep.json written before
    spec hashes were listed holds only these)."""
    try:
        with open(os.path.join(folder, PARAMS_JSON), encoding="utf-8") as f:
            record = json.load(f)
        with open(os.path.join(folder, COMPLETE_MARKER), encoding="utf-8") as f:
            marker = json.load(f)
    except (OSError, ValueError) as e:
        return None, f"unreadable {PARAMS_JSON} or {COMPLETE_MARKER}: {e}"
    if not isinstance(record, dict) or not isinstance(marker, dict):
        return None, f"{PARAMS_JSON} or {COMPLETE_MARKER} is not a JSON object"
    for key in ("spp", "seed", "grid_point"):
        if key in task and record.get(key) != task[key]:
            return None, (f"{PARAMS_JSON} says {key} {_shown(record.get(key))}, the sweep's "
                          f"spec {_shown(task[key])}")
    expected = task.get("spec_hash")
    if expected and expected not in (marker.get("spec_hash"), record.get("spec_hash")):
        return None, ("rendered for another spec (scene, a file it references, defines, "
                      "variant or parameters)")
    if expected and marker.get("spec_hash") != record.get("spec_hash"):
        return None, f"{PARAMS_JSON} and {COMPLETE_MARKER} describe different tasks"
    return record, None


def _shown(value) -> str:
    return json.dumps(value, sort_keys=True) if isinstance(value, dict) else str(value)


def _measure_errors(runs, references) -> None:
    """Each run's MSE and relative MSE against its reference (when there is one)."""
    for run in runs:
        ref = references.get(run.reference) if run.reference else None
        if ref is None:
            continue
        image = run.image
        if ref.shape == image.shape:
            diff = image.astype(np.float64) - ref
            run.mse = float(np.mean(diff * diff))
            scale = float(np.mean(ref.astype(np.float64) ** 2))
            run.relative_mse = run.mse / scale if scale > 0 else math.nan


# ---- Grouping -----------------------------------------------------------------------------

def _value(run: RunRecord, axis: str):
    if axis == "spp":
        return run.spp
    if axis == "seed":
        return run.seed
    return run.point.get(axis)


def _mean_by(runs, keys, metric: str) -> dict:
    """{tuple of key values: mean of the metric} over runs with a finite metric."""
    groups: dict = {}
    for run in runs:
        value = getattr(run, metric)
        if value is None or not math.isfinite(value):
            continue
        groups.setdefault(tuple(_value(run, k) for k in keys), []).append(value)
    return {k: float(np.mean(v)) for k, v in groups.items()}


def _label(axis: str, value) -> str:
    if axis == "path_correlation_depth" and value == FULL_CORRELATION:
        return "full"
    if axis == "use_stratified_sampling_for_each_interval":
        return "stratified" if value else "not stratified"
    if isinstance(value, float):
        return f"{value:g}"
    return str(value)


def _combo_label(axes, values) -> str:
    if not axes:
        return "all"
    return ", ".join(f"{_short(a)}={_label(a, v)}" if a not in ("time_sampling_method",)
                     else _label(a, v) for a, v in zip(axes, values))


def _short(axis: str) -> str:
    return {"path_correlation_depth": "d", "hetero_frequency": "h", "hetero_offset": "o",
            "antithetic_shift": "a", "use_stratified_sampling_for_each_interval": "strat",
            "time_correlate_number": "K", "time_sampling_method": "method"}.get(axis, axis)


def _axis_values(grid: dict, axis: str) -> list:
    return list(grid.get(axis, []))


# ---- Figures ------------------------------------------------------------------------------

def _figure(width, height):
    from matplotlib.figure import Figure

    return Figure(figsize=(width, height), dpi=110, layout="constrained")


def _save(fig, path: str, files: list) -> None:
    from .. import io

    with io.atomic_path(path) as tmp:
        fig.savefig(tmp, format="png", metadata={"Software": "dopplertof report"})
    files.append(path)


def _bars_by_method(runs, grid, out, files, title_suffix):
    config_axes = [a for a in ("time_sampling_method", "use_stratified_sampling_for_each_interval",
                               "path_correlation_depth") if len(grid.get(a, [])) > 1]
    if not config_axes:
        return
    x_axis = "path_correlation_depth" if "path_correlation_depth" in config_axes else config_axes[-1]
    series_axes = [a for a in config_axes if a != x_axis]
    means = _mean_by(runs, [x_axis] + series_axes, "relative_mse")
    if not means:
        return
    xs = _axis_values(grid, x_axis)
    series = list(itertools.product(*(_axis_values(grid, a) for a in series_axes)))
    fig = _figure(max(6.0, 1.1 * len(xs) * max(1, len(series)) ** 0.5 + 3), 4.4)
    ax = fig.add_subplot()
    width = 0.8 / max(1, len(series))
    for j, combo in enumerate(series):
        heights = [means.get((x,) + combo, math.nan) for x in xs]
        positions = np.arange(len(xs)) + (j - (len(series) - 1) / 2) * width
        ax.bar(positions, heights, width=width * 0.95, label=_combo_label(series_axes, combo))
    ax.set_xticks(np.arange(len(xs)), [_label(x_axis, x) for x in xs])
    ax.set_xlabel(AXIS_LABELS.get(x_axis, x_axis))
    ax.set_yscale("log")
    ax.set_ylabel(RELATIVE_MSE_LABEL)
    averaged = [a for a in grid if a not in config_axes]
    ax.set_title("Relative MSE per time sampling configuration" + title_suffix
                 + (f"\n(mean over {', '.join(averaged)})" if averaged else ""), fontsize=10)
    if series_axes:
        ax.legend(title=", ".join(_short(a) for a in series_axes), fontsize=8,
                  loc="upper left", bbox_to_anchor=(1.01, 1.0))
    ax.grid(axis="y", which="both", alpha=0.3)
    _save(fig, os.path.join(out, "relative_mse_by_method.png"), files)


def _heatmaps(runs, grid, out, files, title_suffix):
    from matplotlib.colors import LogNorm

    if len(grid.get("hetero_frequency", [])) < 2 or len(grid.get("hetero_offset", [])) < 2:
        return
    panel_axes = [a for a in grid if a not in ("hetero_frequency", "hetero_offset", "seed")
                  and len(grid[a]) > 1]
    panels = list(itertools.product(*(_axis_values(grid, a) for a in panel_axes)))
    shown = panels[:MAX_PANELS]
    freqs = sorted(_axis_values(grid, "hetero_frequency"))
    offsets = sorted(_axis_values(grid, "hetero_offset"))
    means = _mean_by(runs, panel_axes + ["hetero_frequency", "hetero_offset"], "relative_mse")
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
        ax.set_title(_combo_label(panel_axes, combo), fontsize=9)
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


def _mse_vs_spp(runs, grid, out, files, title_suffix):
    spps = sorted(_axis_values(grid, "spp"))
    if len(spps) < 2:
        return
    series_axes = [a for a in grid if a in CONFIG_AXES and len(grid[a]) > 1]
    means = _mean_by(runs, series_axes + ["spp"], "mse")
    if not means:
        return
    fig = _figure(6.4, 4.6)
    ax = fig.add_subplot()
    combos = list(itertools.product(*(_axis_values(grid, a) for a in series_axes)))[:MAX_LINES]
    first = []
    for combo in combos:
        ys = [means.get(combo + (s,), math.nan) for s in spps]
        if all(math.isnan(y) for y in ys):
            continue
        ax.loglog(spps, ys, marker="o", label=_combo_label(series_axes, combo))
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


def _lines(runs, grid, out, files, title_suffix):
    heat = len(grid.get("hetero_frequency", [])) > 1 and len(grid.get("hetero_offset", [])) > 1
    for x_axis in LINE_AXES:
        xs = sorted(_axis_values(grid, x_axis))
        if len(xs) < 2 or (heat and x_axis in ("hetero_frequency", "hetero_offset")):
            continue
        series_axes = [a for a in grid if a not in (x_axis, "seed", "spp") and len(grid[a]) > 1
                       and not (heat and a in ("hetero_frequency", "hetero_offset"))]
        means = _mean_by(runs, series_axes + [x_axis], "relative_mse")
        if not means:
            continue
        fig = _figure(6.4, 4.6)
        ax = fig.add_subplot()
        combos = list(itertools.product(*(_axis_values(grid, a) for a in series_axes)))
        for combo in combos[:MAX_LINES]:
            ys = [means.get(combo + (x,), math.nan) for x in xs]
            ax.semilogy(xs, ys, marker="o", label=_combo_label(series_axes, combo))
        ax.set_xlabel(AXIS_LABELS.get(x_axis, x_axis))
        ax.set_ylabel(RELATIVE_MSE_LABEL)
        averaged = [a for a in grid if a not in series_axes and a != x_axis]
        ax.set_title(f"Relative MSE against {AXIS_LABELS.get(x_axis, x_axis).split(' (')[0]}"
                     + title_suffix
                     + (f"\n(mean over {', '.join(averaged)})" if averaged else ""), fontsize=10)
        if series_axes:
            ax.legend(fontsize=8, title=", ".join(_short(a) for a in series_axes))
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


def _image_grid(runs, references, grid, out, files, title_suffix):
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
    pins = ", ".join(f"{_short(a)}={_label(a, v)}" for a, v in layout.pinned.items())
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
        pinned = {a: _value(runs[0], a) for a in fixed_axes}
        chosen = _runs_at(runs, pinned)
    return _ImageLayout(row_axis=row_axis, col_axis=col_axis,
                        rows=_axis_values(grid, row_axis)[:8] if row_axis else [None],
                        cols=_axis_values(grid, col_axis)[:8] if col_axis else [None],
                        pinned=pinned, runs=chosen)


def _runs_at(runs, pinned: dict) -> list:
    """The runs whose values are the pinned ones."""
    return [r for r in runs if all(_value(r, a) == v for a, v in pinned.items())]


def _image_cells(layout: _ImageLayout) -> dict:
    """{(row value, column value): run} of the layout's runs in a shown row and column."""
    row_axis, col_axis = layout.row_axis, layout.col_axis
    cells = {(_value(r, row_axis) if row_axis else None,
              _value(r, col_axis) if col_axis else None): r for r in layout.runs}
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
                label.append(_combo_label([layout.col_axis], [cv]))
            if run.relative_mse is not None:
                label.append(f"relMSE {run.relative_mse:.2g}")
            ax.set_title("\n".join(label), fontsize=8)
            if j == 0 and layout.row_axis:
                ax.set_ylabel(_combo_label([layout.row_axis], [rv]), fontsize=8)
    return shown


# ---- Tables -------------------------------------------------------------------------------

def _fmt(x, digits=3) -> str:
    if x is None or (isinstance(x, float) and not math.isfinite(x)):
        return "–"
    return f"{x:.{digits}g}"


def _config_table(runs, grid) -> list[str]:
    config_axes = [a for a in grid if a in SAMPLING_ONLY and a not in ("seed", "spp")
                   and len(grid[a]) > 1]
    if not config_axes:
        return []
    rel = _mean_by(runs, config_axes, "relative_mse")
    secs = _mean_by(runs, config_axes, "seconds")
    if not rel:
        return []
    worst = max(rel.values())
    lines = ["## Sampling configurations", "",
             "Mean over every other axis; *gain* is the worst configuration's relative MSE "
             "divided by this one's (higher is better); *efficiency* is 1 / (relative MSE x "
             "render seconds).", "",
             "| " + " | ".join(_short(a) for a in config_axes)
             + " | relative MSE | gain | render s | efficiency |",
             "|" + "---|" * (len(config_axes) + 4)]
    for combo, value in sorted(rel.items(), key=lambda kv: kv[1]):
        s = secs.get(combo)
        eff = 1.0 / (value * s) if value and s else None
        lines.append("| " + " | ".join(_label(a, v) for a, v in zip(config_axes, combo))
                     + f" | {_fmt(value)} | {_fmt(worst / value if value else None)} | "
                       f"{_fmt(s)} | {_fmt(eff)} |")
    return lines + [""]


def _points_table(runs, grid) -> list[str]:
    axes = [a for a in grid if a != "seed"]
    rel = _mean_by(runs, axes, "relative_mse")
    mse = _mean_by(runs, axes, "mse")
    secs = _mean_by(runs, axes, "seconds")
    keys = sorted(secs, key=lambda k: [str(x) for x in k])
    seeds = len(grid.get("seed", [])) or 1
    names = [_short(a) for a in axes] or ["point"]
    head = ["## Every grid point", "",
            f"Mean over {seeds} seed(s).", "",
            "| " + " | ".join(names) + " | relative MSE | MSE | render s |",
            "|" + "---|" * (len(names) + 3)]
    rows = [("| " + (" | ".join(_label(a, v) for a, v in zip(axes, k)) or "all")
             + f" | {_fmt(rel.get(k))} | {_fmt(mse.get(k))} | {_fmt(secs.get(k))} |")
            for k in keys[:MAX_TABLE_ROWS]]
    tail = (["", f"({len(keys) - MAX_TABLE_ROWS} more rows in metrics.csv)"]
            if len(keys) > MAX_TABLE_ROWS else [])
    return head + rows + tail + [""]


def _metrics_csv(runs, grid, path, files):
    from .. import io

    axes = [a for a in grid if a not in ("spp", "seed")]
    buffer = _pyio.StringIO()
    writer = csv.writer(buffer)
    writer.writerow(["name", *axes, "spp", "seed", "mse", "relative_mse", "render_seconds"])
    for r in runs:
        writer.writerow([r.name, *(format_value(a, r.point.get(a)) for a in axes), r.spp,
                         r.seed, r.mse, r.relative_mse, r.seconds])
    with io.atomic_path(path) as tmp:
        with open(tmp, "w", encoding="utf-8", newline="") as f:
            f.write(buffer.getvalue())
    files.append(path)


# ---- Entry point --------------------------------------------------------------------------

def write_report(results, output) -> Report:
    """Read a sweep results folder and write figures, ``metrics.csv`` and ``summary.md``
    into ``output``, replacing the previous report there all or nothing (the output set
    "report" of :func:`dopplertof.io.output_folder`)."""
    from .. import io

    results = os.path.abspath(os.fspath(results))
    output = os.path.abspath(os.fspath(output))
    sweep, runs, references, missing, stale = read_results(results)
    config = sweep.get("config", {})
    raw_grid = config.get("grid", {})
    grid = {k: list(raw_grid[k]) for k in config.get("grid_axes", sorted(raw_grid))}
    if not runs:
        raise ReportError(f"{results}: no completed grid point of the sweep's spec yet "
                          f"({len(missing)} task(s) incomplete, {len(stale)} stale); run the "
                          "sweep first")
    report = Report(output=output, runs=len(runs), missing=missing,
                    with_errors=sum(r.relative_mse is not None for r in runs), stale=stale)
    summary_path = os.path.join(results, SUMMARY_JSON)
    last_run = None
    if os.path.isfile(summary_path):
        with open(summary_path, encoding="utf-8") as f:
            last_run = json.load(f)
    suffix = f" — {config.get('name', 'sweep')}"
    files = report.files
    # ---- every file of the report, replacing the last report's all or nothing
    with io.output_folder(output, "report") as staged:
        staging = staged.staging
        if report.with_errors:
            _bars_by_method(runs, grid, staging, files, suffix)
            _heatmaps(runs, grid, staging, files, suffix)
            _mse_vs_spp(runs, grid, staging, files, suffix)
            _lines(runs, grid, staging, files, suffix)
        _image_grid(runs, references, grid, staging, files, suffix)
        _metrics_csv(runs, grid, staged.path("metrics.csv"), files)
        md = _markdown(config, runs, grid, report, last_run, results)
        with io.atomic_path(staged.path("summary.md")) as tmp:
            with open(tmp, "w", encoding="utf-8") as f:
                f.write(md)
        files.append(staged.path("summary.md"))
    report.files = [os.path.join(output, os.path.basename(f)) for f in files]
    return report


def _markdown(config, runs, grid, report, last_run, results) -> str:
    ref = config.get("reference")
    lines = [f"# Sweep report: {config.get('name', 'sweep')}", "",
             f"- results: `{results}`",
             f"- scene: `{config.get('scene')}`",
             "- grid: " + ", ".join(f"{k} ({len(v)} values)" for k, v in grid.items()),
             "- fixed: " + (", ".join(f"{k}={v}" for k, v in config.get("fixed", {}).items())
                             or "none"),
             f"- runs complete: {report.runs}; incomplete tasks: {len(report.missing)}; "
             f"stale tasks (excluded): {len(report.stale)}"]
    if last_run and last_run.get("failed"):
        lines.append(f"- failed in the last run: {len(last_run['failed'])} "
                     f"(see summary.json)")
    if ref:
        lines.append(f"- reference: {ref['spp']} spp, seed {ref['seed']}"
                     + (f", {ref['params']}" if ref.get("params") else ""))
        lines += ["", "Errors: MSE = mean over pixels and channels of (image - reference)²; "
                      "relative MSE = MSE / mean(reference²) (unitless). Images are the "
                      "time-averaged correlation (1/T times the integral over the exposure). "
                      "The reference's own noise adds to every MSE: give it many more samples "
                      "than the runs. Render seconds include a worker's kernel compilation the "
                      "first time it renders an image of a given size and sample count."]
    else:
        lines += ["", "No reference in this sweep: errors are not computed "
                      "(add a [reference] table to the configuration)."]
    lines.append("")
    figures = [f for f in report.files if f.endswith(".png")]
    if figures:
        lines += ["## Figures", ""]
        lines += [f"![{os.path.basename(f)}]({os.path.basename(f)})" for f in figures]
        lines.append("")
    if report.with_errors:
        lines += _config_table(runs, grid)
    lines += _points_table(runs, grid)
    if report.missing:
        lines += ["## Incomplete tasks", ""] + [f"- `{m}`" for m in report.missing[:50]]
        if len(report.missing) > 50:
            lines.append(f"- ... and {len(report.missing) - 50} more")
        lines.append("")
    if report.stale:  # every one: each is a result that the metrics leave out
        lines += ["## Stale tasks (excluded: complete for another spec; the next sweep "
                  "run redoes them)", ""]
        lines += [f"- `{folder}`: {reason}" for folder, reason in report.stale] + [""]
    return "\n".join(lines)
