"""A sweep report's grid: the axes a sweep varies, their labels, and the runs' metrics
averaged over the axes a figure or table does not show."""

from __future__ import annotations

import math

import numpy as np

from .config import FULL_CORRELATION

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


def axis_value(run, axis: str):
    if axis == "spp":
        return run.spp
    if axis == "seed":
        return run.seed
    return run.point.get(axis)


def mean_by(runs, keys, metric: str) -> dict:
    """{tuple of key values: mean of the metric} over runs with a finite metric."""
    groups: dict = {}
    for run in runs:
        value = getattr(run, metric)
        if value is None or not math.isfinite(value):
            continue
        groups.setdefault(tuple(axis_value(run, k) for k in keys), []).append(value)
    return {k: float(np.mean(v)) for k, v in groups.items()}


def value_label(axis: str, value) -> str:
    if axis == "path_correlation_depth" and value == FULL_CORRELATION:
        return "full"
    if axis == "use_stratified_sampling_for_each_interval":
        return "stratified" if value else "not stratified"
    if isinstance(value, float):
        return f"{value:g}"
    return str(value)


def combo_label(axes, values) -> str:
    if not axes:
        return "all"
    return ", ".join(f"{short_label(a)}={value_label(a, v)}" if a not in ("time_sampling_method",)
                     else value_label(a, v) for a, v in zip(axes, values))


def short_label(axis: str) -> str:
    return {"path_correlation_depth": "d", "hetero_frequency": "h", "hetero_offset": "o",
            "antithetic_shift": "a", "use_stratified_sampling_for_each_interval": "strat",
            "time_correlate_number": "K", "time_sampling_method": "method"}.get(axis, axis)


def axis_values(grid: dict, axis: str) -> list:
    return list(grid.get(axis, []))


