"""A D-ToF frame's summary: summary.json's entries (errors against the truth, per body
and for the static surfaces, the velocity and depth methods, units) and the lines the
capture command prints from it."""

from __future__ import annotations

import os

import numpy as np

from ..modulation import SPEED_OF_LIGHT
from ..params import RenderParams
from ..scene.scene import keyframe_coverage_warning
from . import reconstruct as rec
from .ground_truth import light_colocation


CALIBRATION_NOTES = {
    "none": "exact inversion of E/H; a change of brightness during the exposure is "
            "ignored (its first-order term cancels for sinusoids)",
    "inverse-square": "single-path model with brightness (d_mid / d(t))^2 (colocated point "
                      "light) solved per pixel with the reconstructed phase and depth; "
                      "needs the true distance: unwrap depth beyond the wrap distance; a "
                      "turning surface also changes brightness through its cosine, which it "
                      "does not model (docs/camera.md, Brightness changes)",
}

#: the note when the inverse-square calibration meets a rotating body (numbers: docs/camera.md)
ROTATION_NOTE = ("the inverse-square calibration does not model the brightness change of a "
                 "turning surface (its cosine term): expect a velocity bias of several "
                 "percent on {names} with this waveform (rectangular, examples/"
                 "rotating_cube.xml: -14% median); the sinusoidal waveform has none (+0.7%)")


def rotating_bodies(scene, base: RenderParams) -> list:
    """Names of the bodies whose orientation changes during the exposure."""
    from .ground_truth import mid_exposure

    start, _, end = mid_exposure(scene, base)
    names = []
    for body in scene.bodies:
        a = body.motion.relative_matrix(start)[:3, :3]
        b = body.motion.relative_matrix(end)[:3, :3]
        if not np.allclose(a, b, rtol=0, atol=1e-9):
            names.append(", ".join(body.names))
    return names


def error_stats(estimate, truth, modulo: float | None = None) -> dict:
    """Median, 95th percentile and mean of the absolute error and the mean signed error
    over pixels where both are finite; errors folded to [-modulo/2, modulo/2) if given."""
    estimate = np.asarray(estimate, np.float64)
    truth = np.asarray(truth, np.float64)
    valid = np.isfinite(estimate) & np.isfinite(truth)
    err = estimate[valid] - truth[valid]
    if modulo:
        err = np.mod(err + 0.5 * modulo, modulo) - 0.5 * modulo
    if not err.size:
        return {"pixels": 0, "median_abs": None, "p95_abs": None, "mean_abs": None,
                "mean_signed": None}
    a = np.abs(err)
    return {"pixels": int(valid.sum()), "median_abs": float(np.median(a)),
            "p95_abs": float(np.percentile(a, 95)), "mean_abs": float(a.mean()),
            "mean_signed": float(err.mean())}




def _errors(recon, truth, depth_modulo):
    return {
        "velocity_m_s": error_stats(recon.velocity, truth.velocity),
        "depth_m": error_stats(recon.depth, truth.depth, depth_modulo),
    }


#: name of the summary entry for the static surfaces (the pixels of no moving body)
STATIC_SURFACES = "static surfaces"

#: the note on static surfaces whose velocity error comes from multipath
MULTIPATH_NOTE = ("the static surfaces' velocity error is multipath, not noise: light "
                  "reflected off moving bodies reaches them along paths whose length changes; "
                  "max_depth=2 (direct light only) removes it")

#: the note on moving bodies whose velocity error comes (in part) from multipath
BODY_MULTIPATH_NOTE = ("{names}: with indirect light (max_depth {max_depth}) a moving body's "
                       "velocity error is multipath as well as noise: light that reaches it "
                       "after another bounce (off a static surface, another body or its own "
                       "concavities) carries other paths' lengths and Doppler shifts, a bias "
                       "and Monte Carlo noise far above the direct light's (a spinning bunny "
                       "at max_depth 3: median 18 m/s at 32 spp, 9 m/s at 128; at max_depth "
                       "2: 1.0 and 0.62 m/s); max_depth=2 (direct light only) leaves the "
                       "direct light's error alone")

#: the note on static surfaces whose velocity error is the sensor's noise
NOISE_NOTE = ("the static surfaces' velocity error is mostly the sensor's noise: its 95th "
              "percentile {p95:.3g} m/s, {clean:.3g} m/s without the noise (summary.json's "
              "static_surfaces_without_noise)")

#: what the truth means when the light is not at the camera
LIGHT_OFF_CAMERA_NOTE = ("the camera measures half the rate of change (and half the length) "
                         "of the whole path camera -> surface -> light; the truth is the "
                         "distance from the camera along the pixel's ray and its rate of "
                         "change, equal to it only for a light at the camera")


def _region(name, on, recon, truth) -> dict:
    """Per-pixel velocity error statistics over the pixels ``on`` (the same pixels for
    truth and measurement), with the spread of the truth there."""
    measured = recon.velocity[on & np.isfinite(recon.velocity)]
    true = truth.velocity[on & np.isfinite(truth.velocity)]
    return {
        "name": name, "pixels": int(on.sum()),
        "velocity_error_m_s": error_stats(recon.velocity[on], truth.velocity[on]),
        "velocity_gt_median_m_s": float(np.median(true)) if true.size else None,
        "velocity_gt_p5_m_s": float(np.percentile(true, 5)) if true.size else None,
        "velocity_gt_p95_m_s": float(np.percentile(true, 95)) if true.size else None,
        "velocity_median_m_s": float(np.median(measured)) if measured.size else None,
        "velocity_abs_error_median_m_s": error_stats(
            recon.velocity[on], truth.velocity[on])["median_abs"],
    }


def _bodies(scene, recon, truth):
    """One entry per moving body."""
    return [_region(", ".join(body.names), truth.body == k, recon, truth)
            for k, body in enumerate(scene.bodies)]


def _static_surfaces(recon, truth):
    """The same entry for the pixels that see a static surface (None when none does)."""
    static = truth.body == -1
    return _region(STATIC_SURFACES, static, recon, truth) if static.any() else None


#: summary.json's "units" entry
SUMMARY_UNITS = {
    "captures": "time-averaged correlation (1/T) * integral over the exposure, signed, "
                "scene radiance units, mean of the rendered channels (monochrome "
                "sensor); multiply by exposure_s for the integrated value",
    "radiance": "time-averaged radiance over the exposure (scene units, RGB)",
    "velocity": "m/s, radial: rate of change of the distance along the pixel's ray; "
                "> 0 receding (distance grows), < 0 approaching",
    "depth": "m, distance from the camera centre along the pixel-centre ray",
    "frequencies": "MHz", "times": "s", "angular frequencies": "rad/s",
}


def frame_summary(scene, settings, records, recon, noise_free, truth, noise_info,
                  seconds):
    """summary.json of one frame (without its "precision" section)."""
    from ..backend import require_variant

    height, width = truth.depth.shape
    base, model, unwrap = settings.base, settings.model, settings.unwrap
    depth_modulo = None if unwrap is not None else model.wrap_distance
    summary = {
        "scene": scene.source,
        "variant": require_variant().variant(),
        "resolution": [width, height],
        "spp_per_capture": int(settings.spp),
        "seed": int(settings.seed),
        "common_random_numbers": bool(settings.common_random_numbers),
        "units": dict(SUMMARY_UNITS),
        "modulation": {
            "w_g_MHz": base.w_g, "omega_g_rad_s": model.omega_g,
            "exposure_s": model.exposure, "hetero_frequency": model.hetero_frequency,
            "omega_d_rad_s": model.omega_d, "waveform": model.waveform,
            "g_0": base.g_0, "g_1": base.g_1,
            "low_frequency_component_only": base.low_frequency_component_only,
        },
        "render_params": {k: getattr(base, k) for k in RenderParams.names()},
        "captures": records,
        "velocity": _velocity_summary(scene, settings, recon, truth),
        "depth": _depth_summary(model, unwrap, recon, depth_modulo),
        "light": light_colocation(scene),
        "noise": noise_info,
        "errors": _errors(recon, truth, depth_modulo),
        "bodies": _bodies(scene, recon, truth),
        "static_surfaces": _static_surfaces(recon, truth),
        "speed_of_light_m_s": SPEED_OF_LIGHT,
        "seconds": {"render": round(sum(r["render_seconds"] for r in records), 3),
                    "total": round(seconds, 3)},
    }
    warning = keyframe_coverage_warning(scene.keyframe_span, scene.shutter_open,
                                        model.exposure)
    if warning:  # (the capture command prints it on stderr)
        summary["warnings"] = [warning]
    if noise_free is not None:
        summary["errors_without_noise"] = _errors(noise_free, truth, depth_modulo)
        summary["bodies_without_noise"] = _bodies(scene, noise_free, truth)
        summary["static_surfaces_without_noise"] = _static_surfaces(noise_free, truth)
    return summary


def _velocity_summary(scene, settings, recon, truth) -> dict:
    """summary.json's "velocity" entry: the method, its calibration, why pixels are NaN."""
    model, calibration = settings.model, settings.calibration
    fraction = (rec.DEFAULT_MIN_SIGNAL_FRACTION if settings.min_signal_fraction is None
                else float(settings.min_signal_fraction))
    return {
        "file": "velocity.npy",
        "method": "r = sum H_i E_i / sum H_i^2 over the offsets 0 and 0.25 (least "
                  "squares); E/H = Delta_omega / (omega_d + Delta_omega) for a single "
                  "path of constant brightness, every waveform, integer "
                  "hetero_frequency; v = c Delta_omega / (2 omega_g)",
        "calibration": calibration,
        "calibration_note": CALIBRATION_NOTES[calibration],
        "rotating_bodies": rotating_bodies(scene, settings.base),
        "velocity_per_ratio_m_s": model.omega_d * model.velocity_per_delta_omega(),
        "nan_when": {rec.reason_name(code): text
                     for code, text in rec.INVALID_REASONS.items()},
        "nan_pixels": rec.reason_counts(recon.velocity_reasons),
        "min_signal_fraction": fraction,
        "mixed_pixels": "kept" if settings.keep_mixed_pixels else "NaN",
        "mixed_footprints": int(truth.mixed.sum()) if truth.mixed is not None else None,
        "ground_truth": "velocity_gt.npy: (u . n) / (d . n) at mid-exposure from the "
                        "analytic motion; velocity_point.npy: u . d",
        "ground_truth_time_s": truth.time,
    }


def _depth_summary(model, unwrap, recon, depth_modulo) -> dict:
    """summary.json's "depth" entry: the method, the wrap and unambiguous ranges, why
    pixels are NaN."""
    wrap = model.wrap_distance
    return {
        "file": "depth.npy",
        "method": "phi = atan2(H(0.75) - H(0.25), H(0) - H(0.5)) (calibrated for "
                  "non-sinusoidal waveforms), depth = c phi / (2 omega_g): half the "
                  "path length, the distance for a colocated light",
        "wrap_distance_m": wrap,
        "unwrap_frequency_MHz": unwrap,
        "unambiguous_range_m": (rec.unambiguous_range(model.frequency_hz, unwrap * 1e6)
                                if unwrap is not None else wrap),
        "nan_pixels": rec.reason_counts(recon.depth_reasons),
        "error_modulo_m": depth_modulo,
        "ground_truth": "depth_gt.npy: distance to the first hit along the pixel-centre "
                        "ray at mid-exposure",
    }


#: speeds below this print as 0 in the summary lines (m/s)
SPEED_RESOLUTION = 1e-3
#: the static surfaces' 95th-percentile velocity error above which the multipath note is
#: printed (m/s): salt-and-pepper, not Monte Carlo noise at the usual spp
MULTIPATH_P95_M_S = 0.5


def _static_p95(region) -> float:
    """The 95th percentile of a region's absolute velocity error (0 when none)."""
    return ((region or {}).get("velocity_error_m_s") or {}).get("p95_abs") or 0.0


def _speed(v: float) -> str:
    return "0" if abs(v) < SPEED_RESOLUTION else f"{v:+.3g}"


def body_lines(summary: dict) -> list:
    """Per body (and the static surfaces): the per-pixel velocity error over the pixels
    where both truth and measurement exist, and the spread of the truth; the meaning of
    the truth when the light is not at the camera; the multipath note."""
    lines = []
    bodies = summary["bodies"]
    static = summary.get("static_surfaces")
    for body in bodies + ([static] if static else []):
        err = body.get("velocity_error_m_s") or {}
        if not body["pixels"] or not err.get("pixels"):
            continue
        lo, hi = body["velocity_gt_p5_m_s"], body["velocity_gt_p95_m_s"]
        truth = (f"truth {_speed(lo)} m/s"
                 if abs(hi - lo) < max(0.005 * max(abs(lo), abs(hi)), SPEED_RESOLUTION)
                 else f"truth {_speed(lo)} to {_speed(hi)} m/s (5th-95th percentile)")
        lines.append(f"  {body['name']}: velocity error median {err['median_abs']:.3g} m/s, "
                     f"95th percentile {err['p95_abs']:.3g} m/s, mean {err['mean_signed']:+.3g}"
                     f" m/s over {err['pixels']} of {body['pixels']} pixels; {truth}")
    max_depth = summary.get("render_params", {}).get("max_depth", -1)
    # with sensor noise, the noise-free reconstruction says what multipath alone does
    # (a noisy capture's static error was blamed on multipath)
    clean = summary.get("static_surfaces_without_noise", static)
    multipath = (static and bodies and (max_depth == -1 or max_depth > 2)
                 and _static_p95(clean) > MULTIPATH_P95_M_S)
    if static and _static_p95(static) > max(MULTIPATH_P95_M_S, 2 * _static_p95(clean)):
        lines.append("  note: " + NOISE_NOTE.format(p95=_static_p95(static),
                                                    clean=_static_p95(clean))
                     + ("; what remains without it is multipath, which -P max_depth=2 "
                        "removes" if multipath else ""))
    elif multipath:
        lines.append(f"  note: {MULTIPATH_NOTE} (-P max_depth=2)")
    lines += _body_multipath_lines(summary, max_depth)
    rotating = summary.get("velocity", {}).get("rotating_bodies")
    if rotating and summary["velocity"].get("calibration") == "inverse-square":
        lines.append("  note: " + ROTATION_NOTE.format(names=", ".join(rotating)))
    light = summary.get("light") or {}
    if light and not light.get("colocated", True):
        offsets = [e["offset_from_camera_m"] for e in light.get("lights", [])
                   if "offset_from_camera_m" in e]
        where = (f" ({max(offsets):.3g} m from it)" if offsets else "")
        lines.append(f"  note: the light is not at the camera{where}: {LIGHT_OFF_CAMERA_NOTE}")
    return lines


def multipath_bodies(summary: dict, max_depth: int) -> list:
    """The names of the moving bodies whose median velocity error without the sensor's
    noise passes :data:`MULTIPATH_P95_M_S` where indirect light is rendered (max_depth
    unbounded or above 2): part of it can be multipath (one capture cannot tell how much;
    the same capture at max_depth 2 can)."""
    if not (max_depth == -1 or max_depth > 2):
        return []
    bodies = summary.get("bodies_without_noise") or summary.get("bodies") or []
    return [b["name"] for b in bodies
            if ((b.get("velocity_error_m_s") or {}).get("median_abs") or 0.0)
            > MULTIPATH_P95_M_S]


def _body_multipath_lines(summary: dict, max_depth: int) -> list:
    """The multipath note on the moving bodies (:func:`multipath_bodies`), if any."""
    names = multipath_bodies(summary, max_depth)
    depth = "unbounded" if max_depth == -1 else max_depth
    return ([f"  note: {BODY_MULTIPATH_NOTE.format(names=', '.join(names), max_depth=depth)}"
             " (-P max_depth=2)"] if names else [])


def format_summary(summary: dict, folder: str | None = None) -> str:
    """A few readable lines of a capture summary."""
    mod = summary["modulation"]
    w, h = summary["resolution"]
    depth = summary["depth"]
    lines = [
        f"{os.path.basename(summary['scene'])}: {w}x{h}, {summary['spp_per_capture']} spp x "
        f"{len(summary['captures'])} captures, {summary['seconds']['total']:.1f} s"
        + (f" -> {folder}" if folder else ""),
        f"  modulation: {mod['w_g_MHz']:g} MHz {mod['waveform']}, exposure "
        f"{mod['exposure_s'] * 1e3:g} ms, heterodyne {mod['hetero_frequency']:g} beat "
        f"period(s)/exposure; depth wraps at {depth['wrap_distance_m']:.3f} m"
        + (f", unwrapped with {depth['unwrap_frequency_MHz']:g} MHz up to "
           f"{depth['unambiguous_range_m']:.1f} m" if depth["unwrap_frequency_MHz"] else ""),
    ]
    if summary["noise"]:
        n = summary["noise"]
        lines.append(f"  noise: QE {n['quantum_efficiency']:g}, read {n['read_noise_electrons']:g}"
                     f" e-, full well {n['full_well_electrons']:g} e-, {n['bits']} bits at "
                     f"{n['gain_electrons_per_DN']:g} e-/DN, {n['photons_per_unit']:.3g} "
                     f"photons/s per unit, {n['saturated_pixels']} saturated pixels")

    def error_lines(errors, label):
        v, d = errors["velocity_m_s"], errors["depth_m"]
        out = []
        if v["pixels"]:
            out.append(f"  velocity error{label}: median {v['median_abs']:.3g} m/s, 95th "
                       f"percentile {v['p95_abs']:.3g} m/s over {v['pixels']} pixels")
        else:
            out.append(f"  velocity error{label}: no valid pixels")
        if d["pixels"]:
            mod_note = (f" (modulo {depth['error_modulo_m']:.3f} m)"
                        if depth["error_modulo_m"] else "")
            out.append(f"  depth error{label}: median {d['median_abs']:.3g} m, 95th percentile "
                       f"{d['p95_abs']:.3g} m{mod_note}")
        return out

    lines += error_lines(summary["errors"], "")
    if "errors_without_noise" in summary:
        lines += error_lines(summary["errors_without_noise"], " without noise")
    nan = summary["velocity"]["nan_pixels"]
    if nan:
        lines.append("  velocity NaN: " + ", ".join(f"{n} px {why}" for why, n in nan.items()))
    lines += body_lines(summary)
    return "\n".join(lines)
