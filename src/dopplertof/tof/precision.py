"""How precise is a capture? Per-pixel standard deviations of velocity and depth.

Two sources, both propagated to first order (the delta method) through the
reconstruction of :mod:`.reconstruct`:

* **Monte Carlo.** With ``mc_batches=B`` every capture is rendered B times with all
  its spp samples (seeds :func:`batch_seeds`): the first render, with the capture's
  own seed, is the reported capture (bitwise the capture without error bars), the
  others are independent renders of the same estimator, whose spread is the
  reported capture's Monte Carlo error. (B batches of spp / B samples would cost
  nothing more but lose the stratification of the whole set: the mean of B
  independent 32-sample sets is much noisier than one stratified 256-sample set, 5x
  in velocity on the starter sphere; interleaved strata of one set are not
  independent. Rendering B times is what error bars cost: B x the render time.)
  The splat film correlates neighbouring pixels and the samples of a group (K time-
  correlated samples, antithetic pairs, a shared path) are not independent, so no
  per-sample formula is honest; the spread of independent renders is. Captures that
  share seeds (common random numbers) have correlated errors: the propagation takes
  the deviations of *all* captures together, so that

      var(v) = sum_b (sum_c J_c (x_cb - mean_b x_cb))^2 / (B - 1) = J Sigma J^T,

  Sigma the covariance of one render of the captures (its cross terms included), J
  the Jacobian of velocity (or depth) with respect to the captures.
* **Sensor.** The noise model's predicted variance of each reported capture
  (:meth:`.noise.NoiseModel.variance`: shot, read, ADC, ambient; full well by the
  saturation mask), independent between captures and pixels, without drawing noise:
  var(v) = sum_c J_c^2 var_c.

The Jacobians are analytic (:func:`jacobians`) and evaluated at the noise-free
captures. Where first order fails, a ratio whose denominator is near zero (the
homodyne amplitude that velocity and depth divide by is uncertain by more than
:data:`FIRST_ORDER_LIMIT` of itself), the pixel's standard deviation is +inf: marked,
not mispredicted.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..modulation import SPEED_OF_LIGHT
from . import reconstruct as rec

#: relative standard deviation of the homodyne amplitude above which first-order
#: propagation is not trusted (its second-order bias, ~ (sigma / A)^2, exceeds 4%)
FIRST_ORDER_LIMIT = 0.2

#: default number of independent renders per capture when an uncertainty is asked for
DEFAULT_MC_BATCHES = 8


class PrecisionError(ValueError):
    """Precision settings that cannot work; the message names the problem."""


def batch_seeds(seed: int, batches: int) -> list:
    """Seeds of the B independent renders of a capture rendered with ``seed``: ``seed``
    itself (the reported capture) and 2^63 + (seed (B - 1) + b mod 2^63), b < B - 1
    (distinct for distinct seeds below 2^63 / (B - 1) at the same B, and apart from every
    capture seed below 2^63; all 64 bits key the random streams)."""
    extra = int(batches) - 1
    return [int(seed)] + [(1 << 63) + (int(seed) * extra + b) % (1 << 63)
                          for b in range(extra)]


def check_batches(batches) -> int:
    """``batches`` as an int >= 2; raises otherwise."""
    if isinstance(batches, bool) or not isinstance(batches, (int, np.integer)) or batches < 2:
        raise PrecisionError(f"mc_batches must be an integer >= 2 (independent renders "
                             f"whose spread gives the Monte Carlo error), got {batches!r}")
    return int(batches)


# ---- Jacobians of the reconstruction ------------------------------------------------

def _name(prefix, offset):
    return f"{prefix}_{offset:g}"


def _depth_jacobian(captures, prefix, omega_g, waveform, scale=1.0):
    """d depth / d capture for the four homodyne captures of ``prefix``, and the
    amplitude hypot(x, y) / 2 with its Jacobian (the depth's denominator)."""
    h = {o: np.asarray(captures[_name(prefix, o)], np.float64) for o in rec.DEPTH_OFFSETS}
    x, y = h[0.0] - h[0.5], h[0.75] - h[0.25]
    rho2 = x * x + y * y
    with np.errstate(divide="ignore", invalid="ignore"):
        raw = np.mod(np.arctan2(y, x), 2 * math.pi)
        slope = 1.0
        if waveform != "sinusoidal":  # d true / d raw phase of the calibration table
            true, measured = rec.phase_calibration(waveform)
            slope = np.interp(raw, measured, np.gradient(true, measured))
        k = scale * slope * SPEED_OF_LIGHT / (2 * omega_g)
        dx, dy = -k * y / rho2, k * x / rho2
        amp = 0.5 * np.sqrt(rho2)
        ax, ay = 0.25 * x / amp, 0.25 * y / amp
    depth = {_name(prefix, 0.0): dx, _name(prefix, 0.5): -dx,
             _name(prefix, 0.75): dy, _name(prefix, 0.25): -dy}
    amplitude = {_name(prefix, 0.0): ax, _name(prefix, 0.5): -ax,
                 _name(prefix, 0.75): ay, _name(prefix, 0.25): -ay}
    return depth, amp, amplitude


def jacobians(captures: dict, model: rec.CaptureModel, unwrap_mhz=None,
              calibration: str = "none", depth=None):
    """First-order sensitivities of the reconstruction to each capture.

    Returns dicts capture name -> (H, W) arrays: d velocity / d capture, d depth /
    d capture, and the denominators (the velocity amplitude sqrt(H0^2 + H1^2) and
    the depth amplitudes) as (value, Jacobian) pairs. ``calibration``
    "inverse-square": the calibrated velocity depends on the ratio and on the pixel's
    phase and ``depth``; its partial derivatives in phase and depth are central
    differences of :func:`.reconstruct.velocity_inverse_square`, chained with the
    depth's Jacobian.
    """
    velocity, amp_v, dv_dd = _velocity_jacobian(captures, model, calibration, depth)
    depth_jac, amplitudes = _depth_jacobians(captures, model, unwrap_mhz)
    if dv_dd is not None:  # the calibration reads the first frequency's phase and depth
        if unwrap_mhz is None:
            phase_depth = depth_jac
        else:
            phase_depth = _depth_jacobian(captures, "homodyne", model.omega_g,
                                          model.waveform)[0]
        for name, jac in phase_depth.items():
            velocity[name] = velocity.get(name, 0.0) + dv_dd * jac
    return velocity, depth_jac, [amp_v] + amplitudes


def _velocity_jacobian(captures, model, calibration, depth):
    """d velocity / d capture through the ratio r = sum H_i E_i / sum H_i^2 of the
    velocity offsets' homodyne H_i and heterodyne E_i captures; the velocity amplitude
    sqrt(sum H_i^2) with its Jacobian; and d velocity / d depth of the inverse-square
    calibration (None without it)."""
    H = [np.asarray(captures[_name("homodyne", o)], np.float64) for o in rec.VELOCITY_OFFSETS]
    E = [np.asarray(captures[_name("heterodyne", o)], np.float64) for o in rec.VELOCITY_OFFSETS]
    den = sum(h * h for h in H)
    with np.errstate(divide="ignore", invalid="ignore"):
        r = sum(h * e for h, e in zip(H, E)) / den
        dv_dr, dv_dd = _velocity_slopes(r, model, calibration, depth)
        amp_v = np.sqrt(den)
    velocity, amp_v_jac = {}, {}
    for o, h, e in zip(rec.VELOCITY_OFFSETS, H, E):
        velocity[_name("heterodyne", o)] = dv_dr * h / den
        velocity[_name("homodyne", o)] = dv_dr * (e - 2 * r * h) / den
        amp_v_jac[_name("homodyne", o)] = h / amp_v
    return velocity, (amp_v, amp_v_jac), dv_dd


def _velocity_slopes(r, model, calibration, depth):
    """(d v / d r, d v / d depth) of the velocity from the ratio ``r``: the exact E/H
    inversion v = c omega_d r / (2 omega_g (1 - r)) (no depth term, None), or the
    inverse-square calibration's, whose depth term moves the phase with the depth (one
    path)."""
    if calibration != "inverse-square":
        return model.omega_d * model.velocity_per_delta_omega() / (1.0 - r) ** 2, None
    depth = np.asarray(depth, np.float64)
    phase = rec.phase_from_depth(depth, model.omega_g)
    grid, coefficients = rec.inverse_square_coefficients(model)
    c10, c01, c20, c11, c02 = (np.interp(phase, grid, c) for c in coefficients)
    inv_d = 1.0 / depth
    v = rec.velocity_inverse_square(r, phase, depth, model)
    dv_dr = 1.0 / (c10 + c01 * inv_d + 2 * (c20 + c11 * inv_d + c02 * inv_d**2) * v)
    step = 1e-4 * depth  # along depth, the phase following it (one path)

    def v_at(k):
        d = depth + k * step
        return rec.velocity_inverse_square(r, phase + 2 * model.omega_g * k * step
                                           / SPEED_OF_LIGHT, d, model)
    return dv_dr, (v_at(1) - v_at(-1)) / (2 * step)


def _depth_jacobians(captures, model, unwrap_mhz):
    """d depth / d capture and the depth amplitudes (value, Jacobian): one frequency's,
    or with ``unwrap_mhz`` the f^2-weighted mean of the two matched depths'."""
    if unwrap_mhz is None:
        depth_jac, amp_d, amp_d_jac = _depth_jacobian(captures, "homodyne", model.omega_g,
                                                      model.waveform)
        return depth_jac, [(amp_d, amp_d_jac)]
    f1, f2 = model.frequency_hz, unwrap_mhz * 1e6
    w1, w2 = f1 * f1 / (f1 * f1 + f2 * f2), f2 * f2 / (f1 * f1 + f2 * f2)
    depth_jac, amp_d, amp_d_jac = _depth_jacobian(captures, "homodyne", model.omega_g,
                                                  model.waveform, w1)
    second, amp_2, amp_2_jac = _depth_jacobian(captures, f"homodyne_{unwrap_mhz:g}MHz",
                                               2 * math.pi * f2, model.waveform, w2)
    depth_jac.update(second)
    return depth_jac, [(amp_d, amp_d_jac), (amp_2, amp_2_jac)]


# ---- Propagation ------------------------------------------------------------------

def mc_variance(jacobian: dict, batches: dict) -> np.ndarray:
    """J Sigma J^T from the independent renders (name -> (B, H, W)) of the captures in
    ``jacobian``: the variance of the linearized quantity over the renders (ddof 1),
    that of one render such as the reported capture, cross-capture covariance
    included."""
    linear = None
    for name, jac in jacobian.items():
        b = np.asarray(batches[name], np.float64)
        term = jac[None] * (b - b.mean(axis=0, keepdims=True))
        linear = term if linear is None else linear + term
    n = linear.shape[0]
    return np.sum(linear * linear, axis=0) / (n - 1)


def sensor_variance(jacobian: dict, capture_variance: dict) -> np.ndarray:
    """sum_c J_c^2 var_c: independent sensor noise per capture and pixel."""
    return sum(jac * jac * capture_variance[name] for name, jac in jacobian.items())


def capture_variances(rendered: dict, unmodulated, exposure: float, noise) -> dict:
    """The noise model's variance of every reported capture (name -> (H, W)), with
    ``noise`` resolved (photons_per_unit set)."""
    return {name: noise.variance(value, unmodulated, exposure)
            for name, value in rendered.items()}


@dataclass
class Uncertainty:
    """Predicted standard deviations (H, W): NaN where there is no value, +inf where
    first order fails (``first_order_failed``)."""

    velocity_std_mc: np.ndarray
    depth_std_mc: np.ndarray
    velocity_std_sensor: np.ndarray
    depth_std_sensor: np.ndarray
    velocity_std: np.ndarray
    depth_std: np.ndarray
    first_order_failed: np.ndarray  #: (H, W) bool
    mc_batches: int
    #: name -> (H, W) Monte Carlo standard deviation of each capture (the renders' spread)
    capture_std_mc: dict = None

    def maps(self) -> dict:
        return {k: getattr(self, k) for k in ("velocity_std_mc", "depth_std_mc",
                                              "velocity_std_sensor", "depth_std_sensor",
                                              "velocity_std", "depth_std")}


def predict(rendered: dict, batches: dict | None, model: rec.CaptureModel, unwrap_mhz=None,
            calibration: str = "none", depth=None, capture_variance: dict | None = None,
            velocity_valid=None, depth_valid=None) -> Uncertainty:
    """Per-pixel standard deviations of velocity and depth from the noise-free captures
    ``rendered``, their Monte Carlo ``batches`` (or None: no MC term) and the sensor's
    ``capture_variance`` (or None: no sensor noise). ``*_valid``: where the quantity
    has a value (else NaN)."""
    jv, jd, amplitudes = jacobians(rendered, model, unwrap_mhz, calibration, depth)
    shape = np.shape(next(iter(rendered.values())))
    zero = np.zeros(shape)
    parts = {}
    for key, jac in (("velocity", jv), ("depth", jd)):
        parts[f"{key}_mc"] = mc_variance(jac, batches) if batches else zero
        parts[f"{key}_sensor"] = (sensor_variance(jac, capture_variance)
                                  if capture_variance else zero)
    failed = np.zeros(shape, bool)
    for value, jac in amplitudes:
        var = zero.copy()
        if batches:
            var = var + mc_variance(jac, batches)
        if capture_variance:
            var = var + sensor_variance(jac, capture_variance)
        with np.errstate(invalid="ignore"):
            failed |= ~(np.sqrt(var) <= FIRST_ORDER_LIMIT * value)
    out = {}
    for key, valid in (("velocity", velocity_valid), ("depth", depth_valid)):
        valid = np.ones(shape, bool) if valid is None else np.asarray(valid, bool)
        for part in ("mc", "sensor"):
            std = np.sqrt(parts[f"{key}_{part}"])
            out[f"{key}_std_{part}"] = _mark(std, valid, failed)
        total = np.sqrt(parts[f"{key}_mc"] + parts[f"{key}_sensor"])
        out[f"{key}_std"] = _mark(total, valid, failed)
    no_value = np.isnan(out["velocity_std"]) & np.isnan(out["depth_std"])
    return Uncertainty(**out, first_order_failed=failed & ~no_value,
                       mc_batches=len(next(iter(batches.values()))) if batches else 0,
                       capture_std_mc=capture_standard_errors(batches) if batches else {})


def capture_standard_errors(batches: dict) -> dict:
    """Per-pixel Monte Carlo standard deviation of each reported capture: the std over
    its B independent renders (ddof 1)."""
    return {name: np.std(np.asarray(b, np.float64), axis=0, ddof=1).astype(np.float32)
            for name, b in batches.items()}


def _mark(std, valid, failed):
    std = np.where(failed, np.inf, std)
    return np.where(valid, std, np.nan).astype(np.float32)


# ---- Summaries ------------------------------------------------------------------

def _median(values):
    values = np.asarray(values, np.float64)
    values = values[np.isfinite(values)]
    return float(np.median(values)) if values.size else None


def robust_spread(values) -> float | None:
    """1.4826 x the median absolute deviation from the median (the standard deviation
    of a normal distribution), over the finite values."""
    values = np.asarray(values, np.float64)
    values = values[np.isfinite(values)]
    if values.size < 2:
        return None
    return float(1.4826 * np.median(np.abs(values - np.median(values))))


def _precision_entry(u: Uncertainty, velocity, velocity_gt, depth, depth_gt, on, modulo):
    v_err = np.where(on, velocity - velocity_gt, np.nan)
    d_err = np.where(on, depth - depth_gt, np.nan)
    if modulo:
        d_err = np.mod(d_err + 0.5 * modulo, modulo) - 0.5 * modulo
    return {
        "pixels": int(np.sum(on)),
        "velocity_m_s": {
            "predicted_std_median": _median(np.where(on, u.velocity_std, np.nan)),
            "predicted_std_mc_median": _median(np.where(on, u.velocity_std_mc, np.nan)),
            "predicted_std_sensor_median": _median(np.where(on, u.velocity_std_sensor,
                                                            np.nan)),
            "measured_error_spread": robust_spread(v_err),
        },
        "depth_m": {
            "predicted_std_median": _median(np.where(on, u.depth_std, np.nan)),
            "predicted_std_mc_median": _median(np.where(on, u.depth_std_mc, np.nan)),
            "predicted_std_sensor_median": _median(np.where(on, u.depth_std_sensor, np.nan)),
            "measured_error_spread": robust_spread(d_err),
        },
        "first_order_failed_pixels": int(np.sum(u.first_order_failed & on)),
    }


def precision_summary(u: Uncertainty, recon, truth, bodies, depth_modulo, limits: dict):
    """The ``precision`` section of summary.json: overall and per body, the predicted
    median standard deviations and the measured spread of the errors (1.4826 x MAD of
    reconstructed - truth: within a body it also holds the truth's bias variations)."""
    everywhere = np.ones(np.shape(u.velocity_std), bool)
    out = {
        "method": "first-order (delta method) propagation through the reconstruction; "
                  f"Monte Carlo: spread of {u.mc_batches} independent renders of every "
                  "capture with all its samples, the first the reported capture "
                  "(cross-capture covariance of common random numbers included); sensor: "
                  "the noise model's per-capture variance (shot, read, ADC, ambient), not "
                  "drawn; total = sqrt(mc^2 + sensor^2)",
        "mc_batches": u.mc_batches,
        "first_order_limit": FIRST_ORDER_LIMIT,
        "files": sorted(f"{k}.npy" for k in u.maps()),
        "std_nan_when": "no velocity (or depth) in the noise-free reconstruction",
        "std_inf_when": "first order fails: the homodyne amplitude's predicted standard "
                        f"deviation exceeds {FIRST_ORDER_LIMIT:g} of itself",
        "limits": limits,
        "overall": _precision_entry(u, recon.velocity, truth.velocity, recon.depth,
                                    truth.depth, everywhere, depth_modulo),
        "bodies": [],
    }
    for k, name in enumerate(bodies):
        entry = _precision_entry(u, recon.velocity, truth.velocity, recon.depth, truth.depth,
                                 truth.body == k, depth_modulo)
        out["bodies"].append({"name": name, **entry})
    return out


def apply_limits(recon, u: Uncertainty, max_velocity_std=None, max_depth_std=None):
    """NaN (reason code rec.TOO_UNCERTAIN) where the predicted total standard deviation
    exceeds the limit or is not finite (first order fails); returns the counts."""
    counts = {}
    for key, limit in (("velocity", max_velocity_std), ("depth", max_depth_std)):
        if limit is None:
            continue
        value, reasons, std = (getattr(recon, key), getattr(recon, f"{key}_reasons"),
                               getattr(u, f"{key}_std"))
        with np.errstate(invalid="ignore"):
            untrusted = (reasons == rec.VALID) & ~(std <= limit)
        setattr(recon, key, np.where(untrusted, np.nan, value))
        setattr(recon, f"{key}_reasons", np.where(untrusted, rec.TOO_UNCERTAIN, reasons))
        counts[key] = int(untrusted.sum())
    return counts


def optional_number(value):
    """``value`` as a float (NaN where it is not a number), or None: what option checks
    test their ranges on."""
    if value is None:
        return None
    try:
        return float(value)
    except (TypeError, ValueError):
        return math.nan


def check_limit(name: str, value):
    value = optional_number(value)
    if value is None:
        return None
    if not (value > 0 and math.isfinite(value)):
        raise PrecisionError(f"{name} must be a positive number, got {value}")
    return value


def render_batches(scene, spp: int, seed: int, params, batches: int, progress=None,
                   checkpoint=None, name: str = ""):
    """A capture rendered ``batches`` times independently with ``spp`` samples each
    (seeds :func:`batch_seeds`): (the first render's image (H, W, C) float32: the
    capture with ``seed``, bitwise as without batches; all renders' images (B, H, W,
    C) float32; the first's render seconds; the others' render seconds; the first's
    non-finite samples dropped). ``checkpoint``: a CaptureCheckpoint that keeps each
    render (named after the capture ``name``: checkpoint.batch_name)."""
    from ..render import render_result
    from .checkpoint import batch_name

    images, seconds = [], []
    for b, batch_seed in enumerate(batch_seeds(seed, batches)):
        result = render_result(scene, spp=spp, seed=batch_seed, params=params,
                               progress=progress, checkpoint=None if checkpoint is None
                               else checkpoint.path(batch_name(name, b)))
        if checkpoint is not None:
            checkpoint.count(result.metadata)
        images.append(result.image)
        seconds.append(result.metadata["render_seconds"])
        if len(images) == 1:
            dropped = result.metadata["nonfinite_samples_dropped"]
    return images[0], np.stack(images), seconds[0], sum(seconds[1:]), dropped


def error_bar_cost(records, batches: int) -> dict:
    """summary.json's precision "cost": the render time the error bars took, from the
    capture records (``render_seconds``: the reported renders; ``error_bar_render_
    seconds``: the B - 1 others)."""
    reported = sum(r["render_seconds"] for r in records)
    extra = sum(r.get("error_bar_render_seconds", 0.0) for r in records)
    return {"renders_per_capture": int(batches),
            "reported_render_seconds": round(reported, 3),
            "error_bar_render_seconds": round(extra, 3),
            "render_time_factor": round((reported + extra) / reported, 3) if reported else None,
            "accuracy": "none: the reported capture is the render with the capture's seed "
                        "and all its samples, bitwise as without error bars"}


def format_precision(summary: dict) -> str:
    """Readable lines of summary.json's ``precision`` section ('' without one)."""
    p = summary.get("precision")
    if not p:
        return ""

    def fmt(x, unit):
        return "n/a" if x is None else f"{x:.3g} {unit}"

    lines = []
    for label, entry in [("overall", p["overall"])] + [(b["name"], b) for b in p["bodies"]]:
        v, d = entry["velocity_m_s"], entry["depth_m"]
        lines.append(f"  precision {label}: velocity std {fmt(v['predicted_std_median'], 'm/s')}"
                     f" predicted (MC {fmt(v['predicted_std_mc_median'], 'm/s')}, sensor "
                     f"{fmt(v['predicted_std_sensor_median'], 'm/s')}), error spread "
                     f"{fmt(v['measured_error_spread'], 'm/s')}; depth std "
                     f"{fmt(d['predicted_std_median'], 'm')} predicted, error spread "
                     f"{fmt(d['measured_error_spread'], 'm')}")
    cost = p.get("cost")
    if cost:
        lines.append(f"  error bars: {cost['renders_per_capture']} independent renders per "
                     f"capture, {cost['error_bar_render_seconds']:.1f} s of renders beside the "
                     f"reported {cost['reported_render_seconds']:.1f} s ("
                     f"{cost['render_time_factor']:.2g}x the render time; the capture itself "
                     "is as without error bars)")
    masked = p["limits"].get("masked_pixels") or {}
    for key, n in masked.items():
        unit = "m/s" if key == "velocity" else "m"
        lines.append(f"  {key} NaN where the predicted std exceeds "
                     f"{p['limits'][f'max_{key}_std_' + unit.replace('/', '_')]:g} {unit}: "
                     f"{n} px")
    return "\n".join(lines)


def spread_ratio(predicted_variance, repeated) -> tuple:
    """Predicted against measured spread: the median over pixels of
    sqrt(predicted variance) / (standard deviation of the repetitions), over the pixels
    finite in every repetition and in the prediction; and that pixel count.

    ``predicted_variance`` (H, W), e.g. the mean over the repetitions of each one's
    predicted variance; ``repeated`` (R, H, W) the repeated reconstructions."""
    repeated = np.asarray(repeated, np.float64)
    predicted = np.asarray(predicted_variance, np.float64)
    measured = np.std(repeated, axis=0, ddof=1)
    ok = np.all(np.isfinite(repeated), axis=0) & np.isfinite(predicted) & (measured > 0)
    if not ok.any():
        return math.nan, 0
    return float(np.median(np.sqrt(predicted[ok]) / measured[ok])), int(ok.sum())
