"""What would a camera need? Predicted precision over modulation frequency and exposure.

:func:`precision_study` renders one pilot frame per modulation frequency (small spp, a
few independent batches) and predicts, without drawing noise or rendering more, the
median per-pixel standard deviation of velocity and depth (:mod:`.precision`) at every
exposure of the grid. Between exposures the captures are rescaled, not re-rendered:
the homodyne and radiance captures are time averages (unchanged to first order) and
each heterodyne capture of a single path is r(T) H with
r(T) = Delta_omega / (2 pi h / T + Delta_omega), Delta_omega from the pilot's ratio. The
sensor is the noise model's: with the automatic photon scale the brightest pixel fills
``well_fill`` of the well at every exposure (an exposure control), with a fixed
``photons_per_unit`` longer exposures collect more light until the taps saturate (grid
points where most lit pixels would saturate are NaN). :func:`check_points` verifies a
few grid points by simulation: a real capture at that frequency and exposure and 32
sensor-noise repetitions.

The map is the camera's (sensor-limited) precision; the Monte Carlo error of the
simulation is reported beside it for the pilot's spp.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from . import precision as prec
from . import reconstruct as rec

#: the published setting (Kim et al.): 30 MHz, 1.5 ms exposure
PAPER_W_G_MHZ = 30.0
PAPER_EXPOSURE_S = 1.5e-3

#: sensor-noise repetitions of a check by simulation
CHECK_REPETITIONS = 32


def parse_range(text: str, name: str, unit_lo: float, unit_hi: float):
    """A number ('30') or a range 'LO:HI' (LO < HI) within [unit_lo, unit_hi]:
    returns a float or a (lo, hi) tuple; raises PrecisionError naming the problem."""
    parts = str(text).split(":")
    if len(parts) > 2:
        raise prec.PrecisionError(f"{name} must be a number or a range LO:HI, got {text!r}")
    try:
        values = [float(p) for p in parts]
    except ValueError:
        raise prec.PrecisionError(f"{name} must be a number or a range LO:HI, got {text!r}"
                                  ) from None
    for v in values:
        if not (math.isfinite(v) and unit_lo <= v <= unit_hi):
            raise prec.PrecisionError(f"{name} {v:g} is outside [{unit_lo:g}, {unit_hi:g}]")
    if len(values) == 2:
        if not values[0] < values[1]:
            raise prec.PrecisionError(f"{name} range {text!r} is empty: LO must be below HI")
        return (values[0], values[1])
    return values[0]


def _grid(value, steps):
    if isinstance(value, tuple):
        return np.geomspace(value[0], value[1], steps)
    return np.array([float(value)])


@dataclass
class StudyResult:
    w_g_mhz: np.ndarray  #: (F,)
    exposure_s: np.ndarray  #: (T,)
    velocity_std: np.ndarray  #: (F, T) median predicted sensor std of velocity, m/s
    depth_std: np.ndarray  #: (F, T) m
    velocity_std_mc: np.ndarray  #: (F,) the pilots' Monte Carlo median, m/s (at spp)
    depth_std_mc: np.ndarray  #: (F,)
    spp: int
    hetero_frequency: float
    noise: dict
    pixels: np.ndarray  #: (F,) pixels with a velocity in the pilot
    checks: list = field(default_factory=list)
    pilots: list = field(default_factory=list, repr=False)  #: CaptureResult per frequency

    def describe(self) -> dict:
        return {
            "w_g_MHz": self.w_g_mhz.tolist(), "exposure_s": self.exposure_s.tolist(),
            "velocity_std_median_m_s": _nan_to_none(self.velocity_std),
            "depth_std_median_m": _nan_to_none(self.depth_std),
            "velocity_std_mc_median_m_s": _nan_to_none(self.velocity_std_mc),
            "depth_std_mc_median_m": _nan_to_none(self.depth_std_mc),
            "spp": self.spp, "hetero_frequency": self.hetero_frequency,
            "noise": self.noise, "pixels": self.pixels.tolist(), "checks": self.checks,
            "method": "median over pixels with a velocity of the predicted sensor-noise "
                      "standard deviation (first order, the noise model's variance); one "
                      "pilot render per frequency, captures rescaled between exposures",
            "paper_setting": {"w_g_MHz": PAPER_W_G_MHZ, "exposure_s": PAPER_EXPOSURE_S},
        }


def _nan_to_none(a):
    a = np.asarray(a, np.float64)
    return [None if not np.isfinite(x) else float(x) for x in a.ravel()] if a.ndim <= 1 \
        else [_nan_to_none(row) for row in a]


def _rescaled(rendered, model, exposure, hetero):
    """Captures at ``exposure``: heterodyne = r(T) H for the pilot's Delta_omega."""
    H = [rendered[f"homodyne_{o:g}"].astype(np.float64) for o in rec.VELOCITY_OFFSETS]
    E = [rendered[f"heterodyne_{o:g}"].astype(np.float64) for o in rec.VELOCITY_OFFSETS]
    r, _ = rec.combined_ratio(H, E)
    with np.errstate(divide="ignore", invalid="ignore"):
        delta_omega = model.omega_d * r / (1.0 - r)
        r_new = delta_omega / (2 * math.pi * hetero / exposure + delta_omega)
    out = dict(rendered)
    for o, h in zip(rec.VELOCITY_OFFSETS, H):
        out[f"heterodyne_{o:g}"] = r_new * h
    return out


def predict_at(pilot, exposure: float, noise):
    """The predicted sensor-noise Uncertainty at ``exposure`` from a pilot
    CaptureResult (rendered at its own exposure); None where most lit pixels would
    saturate."""
    s = pilot.summary
    model, unmodulated = pilot.sensor_model()
    captures = _rescaled(pilot.rendered, model, exposure, model.hetero_frequency)
    resolved = noise.scaled_for(unmodulated, exposure)
    valid = pilot.noise_free.velocity_reasons == rec.VALID
    # taps that would saturate (fixed photon scale, long exposures): not measured
    taps = [resolved.tap_means(c, unmodulated, exposure) for c in captures.values()]
    full = np.zeros(valid.shape, bool)
    for a, b in taps:
        full |= (np.maximum(a, b) >= resolved.usable_range)
    if np.sum(valid & ~full) < 0.5 * np.sum(valid):
        return None
    model_t = replace(model, exposure=exposure)
    return prec.predict(captures, None, model_t, s["depth"]["unwrap_frequency_MHz"],
                     s["velocity"]["calibration"], pilot.noise_free.depth,
                     prec.capture_variances(captures, unmodulated, exposure, resolved),
                        valid & ~full, (pilot.noise_free.depth_reasons == rec.VALID) & ~full)


def precision_study(scene, w_g=None, exposure=None, *, spp: int = 64, steps: int = 6,
                    hetero_frequency=None, noise=None, mc_batches: int = 4, seed: int = 0,
                    params=None, progress=None, on_pilot=None) -> StudyResult:
    """Predicted precision of ``scene``'s camera over a grid of modulation frequencies
    ``w_g`` (MHz: a number or a (lo, hi) range, geometric steps) and ``exposure`` (s,
    likewise); defaults: the scene's. ``noise``: a NoiseModel (default the default
    one). ``on_pilot(index, w_g)`` is called before each pilot render."""
    from .capture import capture
    from .noise import NoiseModel

    noise = NoiseModel() if noise is None or noise is True else noise
    if isinstance(steps, bool) or not isinstance(steps, int) or not 2 <= steps <= 64:
        raise prec.PrecisionError(f"steps must be an integer in 2..64, got {steps!r}")
    base = dict(params or {})
    scene_params = scene.params
    w_g = scene_params.w_g if w_g is None else w_g
    reference = scene_params.exposure(scene.shutter_interval)
    exposure = reference if exposure is None else exposure
    freqs, times = _grid(w_g, steps), _grid(exposure, steps)
    pilot_exposure = reference if isinstance(exposure, tuple) else float(exposure)
    v = np.full((freqs.size, times.size), np.nan)
    d = np.full_like(v, np.nan)
    v_mc, d_mc, pixels, h = (np.full(freqs.size, np.nan), np.full(freqs.size, np.nan),
                             np.zeros(freqs.size, int), None)
    pilots = []
    for i, f in enumerate(freqs):
        if on_pilot is not None:
            on_pilot(i, f)
        pilot = capture(scene, spp=spp, seed=seed, params={**base, "w_g": float(f),
                                                           "time": pilot_exposure},
                        hetero_frequency=hetero_frequency, noise=noise,
                        mc_batches=mc_batches, progress=progress)
        h = pilot.summary["modulation"]["hetero_frequency"]
        overall = pilot.summary["precision"]["overall"]
        v_mc[i] = overall["velocity_m_s"]["predicted_std_mc_median"] or np.nan
        d_mc[i] = overall["depth_m"]["predicted_std_mc_median"] or np.nan
        pixels[i] = int(np.sum(pilot.noise_free.velocity_reasons == rec.VALID))
        pilots.append(pilot)
        for j, t in enumerate(times):
            u = predict_at(pilot, float(t), noise)
            if u is not None:
                v[i, j] = prec._median(u.velocity_std_sensor) or np.nan
                d[i, j] = prec._median(u.depth_std_sensor) or np.nan
    return StudyResult(freqs, times, v, d, v_mc, d_mc, spp, h, noise.describe(), pixels,
                       pilots=pilots)


def check_points(scene, study: StudyResult, points, *, noise=None, seed: int = 0,
                 params=None, progress=None) -> list:
    """Simulate grid points (i, j): a capture at that frequency and exposure and
    CHECK_REPETITIONS sensor-noise draws. Reports the map's medians, the predicted and
    measured medians over the pixels where both exist and, per pixel, predicted (from the pilot, rescaled) / measured standard
    deviation, its median over pixels (:func:`.precision.spread_ratio`). Appends to
    ``study.checks``."""
    from .capture import capture, reconstruct_noisy
    from .noise import NoiseModel

    noise = NoiseModel() if noise is None or noise is True else noise
    for i, j in points:
        f, t = float(study.w_g_mhz[i]), float(study.exposure_s[j])
        result = capture(scene, spp=study.spp, seed=seed, params={**dict(params or {}),
                                                                  "w_g": f, "time": t},
                         hetero_frequency=study.hetero_frequency, noise=noise, mc_batches=2,
                         progress=progress)
        runs = [reconstruct_noisy(result, replace(noise, seed=int(noise.seed) + 1 + k))
                for k in range(CHECK_REPETITIONS)]
        u = predict_at(study.pilots[i], t, noise)
        entry = {"w_g_MHz": f, "exposure_s": t, "repetitions": CHECK_REPETITIONS,
                 "map_velocity_std_m_s": float(study.velocity_std[i, j]),
                 "map_depth_std_m": float(study.depth_std[i, j]),
                 # the map extrapolates the motion at constant velocity; a scene whose
                 # keyframes end at its shutter has its bodies stop there in the check
                 "beyond_scene_shutter": bool(t > scene.shutter_interval * (1 + 1e-9))}
        for key, unit in (("velocity", "m_s"), ("depth", "m")):
            repeated = np.asarray([getattr(r, key) for r in runs], np.float64)
            measured = np.std(repeated, axis=0, ddof=1)
            predicted = (np.full(measured.shape, np.nan) if u is None else
                         getattr(u, f"{key}_std_sensor").astype(np.float64))
            both = np.isfinite(predicted) & np.isfinite(measured)  # the same pixels
            entry[f"{key}_std_predicted_{unit}"] = prec._median(predicted[both])
            entry[f"{key}_std_measured_{unit}"] = prec._median(measured[both])
            entry[f"{key}_predicted_over_measured_median"] = (
                prec.spread_ratio(predicted ** 2, repeated)[0] if u is not None else None)
        study.checks.append(entry)
    return study.checks


def default_check_points(study: StudyResult, count: int) -> list:
    """``count`` grid points along the diagonal (both ends and between)."""
    nf, nt = study.velocity_std.shape
    if count <= 0:
        return []
    ks = np.linspace(0, 1, count) if count > 1 else np.array([0.5])
    return sorted({(int(round(k * (nf - 1))), int(round(k * (nt - 1)))) for k in ks})


def format_study(study: StudyResult) -> str:
    lines = []
    nf, nt = study.velocity_std.shape
    if nf == 1 and nt == 1:
        lines.append(f"  {study.w_g_mhz[0]:g} MHz, exposure {study.exposure_s[0] * 1e3:g} ms, "
                     f"h = {study.hetero_frequency:g}: predicted median precision (sensor) "
                     f"velocity {study.velocity_std[0, 0]:.3g} m/s, depth "
                     f"{study.depth_std[0, 0]:.3g} m; Monte Carlo at {study.spp} spp: "
                     f"velocity {study.velocity_std_mc[0]:.3g} m/s, depth "
                     f"{study.depth_std_mc[0]:.3g} m")
    else:
        header = "  w_g MHz \\ exposure ms " + " ".join(f"{t * 1e3:9.3g}"
                                                       for t in study.exposure_s)
        lines.append("  predicted median velocity precision (sensor), m/s:")
        lines.append(header)
        for i, f in enumerate(study.w_g_mhz):
            lines.append(f"  {f:21.4g} " + " ".join(f"{x:9.3g}" for x in study.velocity_std[i]))
    for c in study.checks:
        lines.append(f"  check {c['w_g_MHz']:.4g} MHz, {c['exposure_s'] * 1e3:.3g} ms: velocity "
                     f"predicted {c['velocity_std_predicted_m_s']:.3g} m/s, measured "
                     f"{c['velocity_std_measured_m_s']:.3g} m/s; depth predicted "
                     f"{c['depth_std_predicted_m']:.3g} m, measured "
                     f"{c['depth_std_measured_m']:.3g} m ({c['repetitions']} noise draws); "
                     "per pixel predicted/measured: velocity "
                     f"{c['velocity_predicted_over_measured_median']:.3f}, depth "
                     f"{c['depth_predicted_over_measured_median']:.3f} (median)"
                     + ("; beyond the scene's shutter (its keyframes may stop the motion)"
                        if c["beyond_scene_shutter"] else ""))
    return "\n".join(lines)


def write_map(path, study: StudyResult, title: str) -> None:
    """The velocity precision over frequency x exposure (log colours, contours at 1 and
    0.1 m/s, the paper's setting marked), atomically."""
    import matplotlib.colors as colors

    from ..image_files import pyplot, save_figure

    plt = pyplot()
    fig, ax = plt.subplots(figsize=(7.0, 5.2), dpi=100)
    data = np.ma.masked_invalid(study.velocity_std)
    finite = study.velocity_std[np.isfinite(study.velocity_std)]
    norm = colors.LogNorm(vmin=float(finite.min()), vmax=float(finite.max())) \
        if finite.size else None
    T, F = np.meshgrid(study.exposure_s * 1e3, study.w_g_mhz)
    mesh = ax.pcolormesh(T, F, data, norm=norm, cmap="viridis_r", shading="gouraud")
    bar = fig.colorbar(mesh, ax=ax)
    bar.set_label("median velocity std (m/s), sensor noise, log scale")
    levels = [x for x in (0.1, 1.0, 10.0, 100.0)
              if finite.size and finite.min() < x < finite.max()]
    if levels and min(study.velocity_std.shape) > 1:
        cs = ax.contour(T, F, study.velocity_std, levels=levels, colors="white",
                        linewidths=1.2)
        ax.clabel(cs, fmt=lambda x: f"{x:g} m/s", fontsize=8)
    ax.plot([PAPER_EXPOSURE_S * 1e3], [PAPER_W_G_MHZ], marker="*", markersize=14,
            color="red", markeredgecolor="black", linestyle="none",
            label="paper: 30 MHz, 1.5 ms")
    for k, c in enumerate(study.checks):  # (one legend entry for all of them)
        ax.plot([c["exposure_s"] * 1e3], [c["w_g_MHz"]], marker="o", color="white",
                markeredgecolor="black", linestyle="none",
                label="checked by simulating the noise" if k == 0 else None)
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("exposure (ms)")
    ax.set_ylabel("modulation frequency w_g (MHz)")
    ax.set_title(title, fontsize=10)
    ax.legend(loc="lower left", fontsize=8)
    fig.tight_layout()
    save_figure(fig, path, None)
