"""Calibrate a camera preset to measured wall noise: ``dopplertof cameras BASE
--calibrate TABLE.csv -o MINE.toml``.

TABLE.csv has one row per measurement of a flat diffuse wall: ``distance_m``,
``albedo``, ``random_error_mm`` (the per-pixel temporal standard deviation of depth,
median over a patch about the image centre: the makers' random error), optionally
``angle_deg`` (the wall turned by that angle about the vertical axis) and
``ambient_uw_cm2_nm`` (default the base preset's condition). Each distinct wall is
rendered once through the base preset (:func:`.accuracy.render_wall`, a small crop of
its pixels); the fit then reads the renders again with other constants, using the
sensor's predicted variance (:func:`.accuracy.predicted_random`: first order, no noise
drawn), and minimises the squared log ratio of simulated to measured error over the
rows. Fitted, the base preset's unpublished constants:

* ``illuminator.power_w`` always (the renders are linear in it; it stands for every
  constant in the product power x transmission x fill factor x QE / N^2);
* ``sensor.read_noise_electrons`` where the table constrains it: some row's variance owes
  at least :data:`MIN_SHARE` to read noise and the rows' signal levels tell it from the
  power (the fit's two sensitivities not parallel, :data:`MAX_CONDITION`); else kept.

An auto-exposed base has no illuminator: it gets one (at the lens, lighting its field
of view, 850 nm) and the lens constants of absolute radiometry, each marked inferred;
the fitted power absorbs them. A table of one wall cannot tell the power from the read
noise and is refused.
"""

from __future__ import annotations

import csv
import math
import os
from dataclasses import dataclass, replace

import numpy as np

from ..hints import did_you_mean

#: the table's columns: required, then optional
REQUIRED = ("distance_m", "albedo", "random_error_mm")
OPTIONAL = ("angle_deg", "ambient_uw_cm2_nm")
#: read noise is fitted when it makes at least this share of some row's depth variance
MIN_SHARE = 0.05
#: ... and the fit's sensitivities to power and read noise are this far from parallel
#: (condition number of the two log-sensitivity columns, each scaled to unit length)
MAX_CONDITION = 30.0
#: an rms log residual above this (about 20%) is a table the base's noise model does
#: not follow: the command says so
POOR_FIT = 0.2
#: the illuminator and lens an auto-exposed base gets, (section, key, value, comment)
ABSOLUTE_DEFAULTS = (
    ("optics", "f_number", 1.2, "a fast NIR ToF lens"),
    ("optics", "transmission", 0.8, "lens and band-pass filter"),
    ("optics", "filter_width_nm", 40.0, "an 850 nm band-pass for a laser diode's spread"),
    ("optics", "fill_factor", 0.9, "a pixel with microlenses"),
    ("illuminator", "wavelength_nm", 850.0, "the common NIR ToF wavelength"),
    ("illuminator", "offset_m", [0.0, 0.0, 0.0], "the illuminator taken at the lens"),
)


class CalibrationError(ValueError):
    """A table that cannot calibrate the preset; the message names the file and column."""


@dataclass(frozen=True)
class Row:
    distance_m: float
    albedo: float
    random_m: float  #: measured random error (m)
    angle_deg: float = 0.0
    ambient: float | None = None  #: uW/cm^2/nm (None: the preset's condition)

    @property
    def wall(self) -> tuple:
        return (self.distance_m, self.albedo, self.angle_deg, self.ambient)


@dataclass
class Calibration:
    """What :func:`fit_table` found."""

    preset: object  #: the calibrated CameraPreset
    rows: list  #: Row, as read
    simulated_m: list  #: the calibrated preset's random error per row (m)
    fitted: dict  #: "section.key" -> value
    kept: dict  #: "section.key" -> why it was not fitted
    table: str  #: the table's name

    def lines(self) -> list:
        """The per-row comparison and the fitted constants, as printed."""
        out = [f"{'d (m)':>6s} {'albedo':>6s} {'angle':>5s} {'ambient':>7s} "
               f"{'measured mm':>11s} {'simulated mm':>12s} {'residual':>8s}"]
        for row, sim in zip(self.rows, self.simulated_m):
            ambient = "-" if row.ambient is None else f"{row.ambient:g}"
            out.append(f"{row.distance_m:6.3g} {row.albedo:6.3g} {row.angle_deg:5.3g} "
                       f"{ambient:>7s} {row.random_m * 1e3:11.4g} {sim * 1e3:12.4g} "
                       f"{sim / row.random_m - 1:+8.1%}")
        out.append(f"rms log residual {rms_log_residual(self):.3g}")
        out += [f"fitted {k} = {v:.5g}" for k, v in self.fitted.items()]
        out += [f"kept {k}: {why}" for k, why in self.kept.items()]
        return out


def rms_log_residual(calibration: Calibration) -> float:
    r = [math.log(s / row.random_m) for row, s in zip(calibration.rows,
                                                      calibration.simulated_m)]
    return math.sqrt(sum(x * x for x in r) / len(r))


# ---- The table -------------------------------------------------------------------------

def read_table(path) -> list:
    """The rows of a calibration table (CSV with a header row), checked: one line naming
    the file, the row and the column for anything wrong."""
    path = os.fspath(path)
    try:
        with open(path, newline="", encoding="utf-8-sig") as f:
            records = list(csv.reader(f))
    except FileNotFoundError:
        raise CalibrationError(f"calibration table not found: {path}") from None
    except (OSError, UnicodeDecodeError) as e:
        raise CalibrationError(f"{path}: cannot read the calibration table: {e}") from None
    records = [r for r in records if any(c.strip() for c in r)]
    if not records:
        raise CalibrationError(f"{path}: empty: a header row ({', '.join(REQUIRED)}) and "
                               "one row per measured wall are needed")
    header = [c.strip() for c in records[0]]
    for name in header:
        if name not in REQUIRED + OPTIONAL:
            raise CalibrationError(f"{path}: unknown column {name!r}"
                                   f"{did_you_mean(name, REQUIRED + OPTIONAL)} (columns: "
                                   f"{', '.join(REQUIRED)}; optional "
                                   f"{', '.join(OPTIONAL)})")
    for name in REQUIRED:
        if name not in header:
            raise CalibrationError(f"{path}: missing column {name!r} (columns: "
                                   f"{', '.join(REQUIRED)}; optional {', '.join(OPTIONAL)})")
    if len(set(header)) != len(header):
        raise CalibrationError(f"{path}: a column named twice in the header {header}")
    rows = []
    for number, record in enumerate(records[1:], start=2):
        if len(record) != len(header):
            raise CalibrationError(f"{path}: line {number} has {len(record)} values, the "
                                   f"header {len(header)}")
        values = {name: _number(text, path, number, name) for name, text in
                  zip(header, record)}
        rows.append(Row(values["distance_m"], values["albedo"],
                        values["random_error_mm"] * 1e-3, values.get("angle_deg", 0.0),
                        values.get("ambient_uw_cm2_nm")))
    if not rows:
        raise CalibrationError(f"{path}: no measurements below the header")
    return rows


#: column -> (check, what it must be)
_CHECKS = {"distance_m": (lambda x: 0.05 <= x <= 1e3, "a distance in metres, 0.05 to 1000"),
           "albedo": (lambda x: 0 < x <= 1, "a reflectivity in (0, 1]"),
           "random_error_mm": (lambda x: 0 < x <= 1e4, "a standard deviation in mm, above 0"),
           "angle_deg": (lambda x: 0 <= x <= 80, "degrees between the axis and the wall's "
                         "normal, 0 to 80"),
           "ambient_uw_cm2_nm": (lambda x: 0 <= x <= 1000, "uW/cm^2/nm, 0 to 1000")}


def _number(text: str, path: str, line: int, column: str) -> float:
    check, meaning = _CHECKS[column]
    try:
        value = float(text)
    except ValueError:
        raise CalibrationError(f"{path}: line {line}, column {column}: {text.strip()!r} is "
                               f"not a number ({meaning})") from None
    if not (math.isfinite(value) and check(value)):
        raise CalibrationError(f"{path}: line {line}, column {column}: {value:g} out of "
                               f"range ({meaning})")
    return value


def _rows(table) -> tuple:
    """(rows, the table's name) of a path or of a list of Row / mappings."""
    if isinstance(table, (str, os.PathLike)):
        return read_table(table), os.fspath(table)
    rows = []
    for i, item in enumerate(table):
        if isinstance(item, Row):
            rows.append(item)
            continue
        if not isinstance(item, dict):
            raise CalibrationError(f"calibration table row {i}: a mapping of "
                                   f"{', '.join(REQUIRED)}, got {item!r}")
        missing = [c for c in REQUIRED if c not in item]
        unknown = [c for c in item if c not in REQUIRED + OPTIONAL]
        if missing or unknown:
            raise CalibrationError(f"calibration table row {i}: "
                                   + (f"missing column {missing[0]!r}" if missing else
                                      f"unknown column {unknown[0]!r}"))
        values = {c: _number(str(v), "calibration table", i, c) for c, v in item.items()}
        rows.append(Row(values["distance_m"], values["albedo"],
                        values["random_error_mm"] * 1e-3, values.get("angle_deg", 0.0),
                        values.get("ambient_uw_cm2_nm")))
    if not rows:
        raise CalibrationError("calibration table: no rows")
    return rows, f"a table of {len(rows)} rows"


# ---- The fit ---------------------------------------------------------------------------

def absolute_base(base):
    """``base`` as an absolute preset: itself when absolute; an auto-exposed one with an
    illuminator at its lens lighting its field (power 1 W, to be fitted) and
    :data:`ABSOLUTE_DEFAULTS`, through the preset loader's checks."""
    from .preset import _preset_from
    from .preset_file import preset_document

    if base.absolute:
        return base
    doc = preset_document(base)
    width, height = base.resolution
    vertical = 2 * math.degrees(math.atan(math.tan(math.radians(base.fov_deg) / 2)
                                          * height / width))
    doc["illuminator"] = {"power_w": 1.0, "fov_deg": [base.fov_deg, round(vertical, 6)]}
    comments = [("illuminator", "fov_deg", "inferred: the illuminator lights the field of "
                 "view")]
    for section, key, value, why in ABSOLUTE_DEFAULTS:
        doc[section][key] = value
        comments.append((section, key, f"inferred: {why} (a default of the calibration of "
                         "an auto-exposed base; the fitted power absorbs it)"))
    doc["sensor"]["auto_exposure"] = False
    comments.append(("sensor", "auto_exposure", "calibrated: absolute radiometry, the "
                     "illuminator's power fitted to measured noise"))
    doc["conditions"] = {"ambient_irradiance_uw_cm2_nm": 0.0}
    return replace(_preset_from(doc, base.source_file), comments=tuple(comments))


def _with(preset, power: float, read_noise: float):
    return replace(preset, illuminator=dict(preset.illuminator, power_w=float(power)),
                   sensor=dict(preset.sensor, read_noise_electrons=float(read_noise)))


def fit_table(base, table, crop: int = 8, spp: int = 8, seed: int = 0) -> Calibration:
    """Calibrate ``base`` (a preset, its name or file) to ``table`` (a CSV path, or rows:
    :class:`Row` or mappings of the columns): the fitted preset, the rows measured
    against simulated, what was fitted and what kept (module docstring)."""
    from .accuracy import predicted_random, render_wall
    from .preset import CameraPreset, load_preset

    preset = base if isinstance(base, CameraPreset) else load_preset(base)
    rows, where = _rows(table)
    name = os.path.basename(where) if isinstance(table, (str, os.PathLike)) else where
    walls = _check_rows(rows, preset, where)
    start = absolute_base(preset)
    renders = {wall: render_wall(start, wall[0], wall[1], wall[3], crop, spp, seed, wall[2])
               for wall in walls}
    measured = np.log([row.random_m for row in rows])
    power0 = start.illuminator["power_w"]
    read0 = max(start.sensor["read_noise_electrons"], 1.0)
    s = start.sensor
    margin = min(s["offset_dn"] - 1, (1 << s["adc_bits"]) - 2 - s["offset_dn"])
    read_max = min(1e4, margin * s["gain_electrons_per_dn"] / 5.0)  # the loader's margin

    def simulated(x, fit_read: bool) -> np.ndarray:
        power = power0 * math.exp(x[0])
        read = read0 * math.exp(x[1]) if fit_read else s["read_noise_electrons"]
        trial = _with(start, power, read)
        sims = {wall: predicted_random(renders[wall], trial) for wall in walls}
        return np.log([sims[row.wall] for row in rows])

    def residuals(x, fit_read: bool) -> np.ndarray:
        r = simulated(x, fit_read) - measured
        return np.where(np.isfinite(r), r, 10.0)  # nothing reported: far off

    low_p, high_p = math.log(1e-6 / power0), math.log(100.0 / power0)
    bounds_read = (math.log(0.01 / read0), math.log(read_max / read0))
    power_only = _minimise(lambda x: residuals(x, False), [0.0], [(low_p, high_p)])
    both = _minimise(lambda x: residuals(x, True), [power_only[0], 0.0],
                     [(low_p, high_p), bounds_read])
    why = _read_noise_unconstrained(both, lambda x: simulated(x, True))
    fitted, kept = {}, {}
    if why is None:
        power, read = power0 * math.exp(both[0]), read0 * math.exp(both[1])
        fitted["sensor.read_noise_electrons"] = read
    else:
        power, read = power0 * math.exp(power_only[0]), s["read_noise_electrons"]
        kept["sensor.read_noise_electrons"] = (f"{read:g} e- as in {preset.name}: {why}")
    fitted = {"illuminator.power_w": power, **fitted}
    result = _calibrated(preset, _with(start, power, read), start.comments, fitted, name,
                         len(rows))
    sims = {wall: predicted_random(renders[wall], result) for wall in walls}
    return Calibration(result, rows, [sims[row.wall] for row in rows], fitted, kept, name)


def _check_rows(rows, preset, where: str) -> list:
    """The distinct walls of ``rows`` (at least two: one cannot tell the power from the
    read noise), each within the preset's range; a CalibrationError naming ``where``."""
    walls = list(dict.fromkeys(row.wall for row in rows))
    if len(walls) < 2:
        d, albedo, angle, _ = walls[0]
        raise CalibrationError(f"{where}: every row measures one wall ({d:g} m, albedo "
                               f"{albedo:g}{f', {angle:g} deg' if angle else ''}): at one "
                               "signal level the illuminator power and the read noise trade "
                               "off; measure at least two distances or albedos")
    for row in rows:
        r = preset.reconstruction
        if not r["min_range_m"] <= row.distance_m <= r["max_range_m"]:
            raise CalibrationError(f"{where}: column distance_m: {row.distance_m:g} is "
                                   f"outside {preset.name}'s range {r['min_range_m']:g} to "
                                   f"{r['max_range_m']:g} m")
    return walls


def _calibrated(base, fitted_preset, comments, fitted: dict, name: str, n: int):
    """``fitted_preset`` named, described and commented as ``base`` calibrated to the
    table ``name`` of ``n`` rows (the fitted keys' comments say so)."""
    note = f"calibrated: fitted to {name} ({n} rows)"
    comments = tuple(c for c in comments if f"{c[0]}.{c[1]}" not in fitted) + tuple(
        (key.split(".")[0], key.split(".")[1], note) for key in fitted)
    return replace(fitted_preset, comments=comments, name=f"{base.name}-calibrated",
                   description=f"{base.description}; noise calibrated to {name}",
                   sources=tuple(base.sources) + (f"measured wall noise: {name}",),
                   noise_calibration=(f"measured wall noise, {name} ({n} rows): "
                                      + ", ".join(fitted) + f" fitted to it (from "
                                      f"{base.name})"))


def _minimise(residuals, x0, bounds) -> np.ndarray:
    """The x (log constants) of least squared ``residuals`` within ``bounds``:
    Nelder-Mead from steps of 0.5 (a factor 1.6), to 1e-4 in x. The simulated error is
    piecewise smooth only at small scales (the noiseless read rounds to whole DN), so
    no finite-difference gradient is taken."""
    from scipy.optimize import minimize

    x0 = np.asarray(x0, np.float64)
    simplex = np.vstack([x0] + [x0 + 0.5 * np.eye(len(x0))[k] for k in range(len(x0))])
    simplex = np.clip(simplex, [b[0] for b in bounds], [b[1] for b in bounds])
    found = minimize(lambda x: float(np.sum(residuals(x) ** 2)), x0, method="Nelder-Mead",
                     bounds=bounds, options={"initial_simplex": simplex, "xatol": 1e-4,
                                             "fatol": 1e-10, "maxiter": 400})
    return np.asarray(found.x, np.float64)


#: the step (in log of a constant) of the sensitivities that decide what the table fixes
SENSITIVITY_STEP = 0.05


def _read_noise_unconstrained(x, simulate) -> str | None:
    """Why the table cannot fix the read noise at ``x`` (log power, log read noise), or
    None: the log-sensitivity of each row's error to read noise (half its share of the
    variance) and its parallelism with the power's (central differences of
    :data:`SENSITIVITY_STEP`)."""
    x = np.asarray(x, np.float64)
    step = SENSITIVITY_STEP
    columns = []
    for k in range(2):
        dx = np.zeros(2)
        dx[k] = step
        columns.append((simulate(x + dx) - simulate(x - dx)) / (2 * step))
    jac = np.stack(columns, axis=1)
    if not np.isfinite(jac).all():
        return "some walls report no depth at the fit"
    share = 2 * np.abs(jac[:, 1]).max()
    if share < MIN_SHARE:
        return (f"the walls are shot-noise limited (read noise makes at most {share:.1%} of "
                f"a row's variance; {MIN_SHARE:.0%} needed): measure darker or farther walls")
    unit = jac / np.linalg.norm(jac, axis=0)
    values = np.linalg.svd(unit, compute_uv=False)
    condition = values[0] / values[-1] if values[-1] > 0 else math.inf
    if condition > MAX_CONDITION:
        return (f"the rows' signal levels do not tell it from the power (condition number "
                f"{condition:.3g} over {MAX_CONDITION:g}): measure a wider range of distances "
                "or albedos")
    return None


def calibrate(base, table, **options):
    """The preset ``base`` calibrated to ``table`` (:func:`fit_table`): a CameraPreset,
    written with :func:`write_preset`."""
    return fit_table(base, table, **options).preset


def write_calibration_figure(path, calibration: Calibration) -> None:
    """Measured and simulated random error against distance, one colour per albedo
    (angle, ambient)."""
    from .. import image_files

    plt = image_files.pyplot()
    fig, ax = plt.subplots(figsize=(6.4, 4.4))
    groups = {}
    for row, sim in zip(calibration.rows, calibration.simulated_m):
        key = (row.albedo, row.angle_deg, row.ambient)
        groups.setdefault(key, []).append((row.distance_m, row.random_m, sim))
    for i, ((albedo, angle, ambient), points) in enumerate(sorted(
            groups.items(), key=lambda kv: tuple(-1 if v is None else v for v in kv[0]))):
        points.sort()
        d, meas, sim = (np.array(v) * s for v, s in zip(zip(*points), (1, 1e3, 1e3)))
        label = f"albedo {albedo:g}" + (f", {angle:g} deg" if angle else "") + (
            f", ambient {ambient:g}" if ambient is not None else "")
        colour = f"C{i % 10}"
        ax.plot(d, meas, "o", color=colour, label=f"{label}: measured")
        ax.plot(d, sim, "x-", color=colour, label=f"{label}: simulated")
    ax.set_xlabel("distance (m)")
    ax.set_ylabel("random error (mm, temporal std)")
    ax.set_title(f"{calibration.preset.name}: {calibration.table}, rms log residual "
                 f"{rms_log_residual(calibration):.3g}")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7)
    image_files.save_figure(fig, path)
