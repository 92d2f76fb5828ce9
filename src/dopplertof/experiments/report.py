"""Figures and a Markdown summary from a sweep's results folder (the figures: report_figures.py;
the grid's axes and averages: report_grid.py).

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
import json
import math
import os
from dataclasses import dataclass, field

import numpy as np

from .config import SAMPLING_ONLY, format_value
from .report_figures import bars_by_method, heatmaps, image_grid, lines_vs_axis, mse_vs_spp
from .report_grid import MAX_TABLE_ROWS, mean_by, short_label, value_label
from .sweep import SUMMARY_JSON, SWEEP_JSON
from .tasks import COMPLETE_MARKER, IMAGE_NPY, PARAMS_JSON

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
    rel = mean_by(runs, config_axes, "relative_mse")
    secs = mean_by(runs, config_axes, "seconds")
    if not rel:
        return []
    worst = max(rel.values())
    lines = ["## Sampling configurations", "",
             "Mean over every other axis; *gain* is the worst configuration's relative MSE "
             "divided by this one's (higher is better); *efficiency* is 1 / (relative MSE x "
             "render seconds).", "",
             "| " + " | ".join(short_label(a) for a in config_axes)
             + " | relative MSE | gain | render s | efficiency |",
             "|" + "---|" * (len(config_axes) + 4)]
    for combo, value in sorted(rel.items(), key=lambda kv: kv[1]):
        s = secs.get(combo)
        eff = 1.0 / (value * s) if value and s else None
        lines.append("| " + " | ".join(value_label(a, v) for a, v in zip(config_axes, combo))
                     + f" | {_fmt(value)} | {_fmt(worst / value if value else None)} | "
                       f"{_fmt(s)} | {_fmt(eff)} |")
    return lines + [""]


def _points_table(runs, grid) -> list[str]:
    axes = [a for a in grid if a != "seed"]
    rel = mean_by(runs, axes, "relative_mse")
    mse = mean_by(runs, axes, "mse")
    secs = mean_by(runs, axes, "seconds")
    keys = sorted(secs, key=lambda k: [str(x) for x in k])
    seeds = len(grid.get("seed", [])) or 1
    names = [short_label(a) for a in axes] or ["point"]
    head = ["## Every grid point", "",
            f"Mean over {seeds} seed(s).", "",
            "| " + " | ".join(names) + " | relative MSE | MSE | render s |",
            "|" + "---|" * (len(names) + 3)]
    rows = [("| " + (" | ".join(value_label(a, v) for a, v in zip(axes, k)) or "all")
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
            bars_by_method(runs, grid, staging, files, suffix)
            heatmaps(runs, grid, staging, files, suffix)
            mse_vs_spp(runs, grid, staging, files, suffix)
            lines_vs_axis(runs, grid, staging, files, suffix)
        image_grid(runs, references, grid, staging, files, suffix)
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
