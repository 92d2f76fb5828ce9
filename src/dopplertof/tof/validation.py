"""Predicted precision against the spread measured by repeating captures: the check
behind tests/test_precision.py and benchmarks/precision.py (apart from
:mod:`.precision`, which :mod:`.capture` uses, so that neither imports the other)."""

from __future__ import annotations

import numpy as np

from .precision import PrecisionError, _median, spread_ratio

#: repetitions of a validation (Monte Carlo seeds or sensor-noise seeds)
REPETITIONS = 32


def repetition_check(scene, spp: int, mc_batches: int, source: str = "mc", noise=None,
                     repetitions: int = REPETITIONS, seed: int = 0, **capture_kwargs) -> dict:
    """Predicted against measured spread by repetition.

    source "mc": captures with seeds seed..seed+R-1, no sensor noise; "sensor": one
    capture, R sensor-noise draws (seeds noise.seed + 1 ...) of its noise-free captures;
    "total": both at once (seed and noise seed vary together). Returns, for velocity
    and depth, :func:`spread_ratio` (the median over pixels of predicted / measured
    standard deviation; the prediction averaged over the repetitions for "mc" and
    "total"), the pixels compared, the medians of the predicted and measured
    standard deviations, and ``single_capture_median``: the median over pixels and
    repetitions of one capture's own predicted / measured standard deviation (below 1
    where the errors are heavy-tailed: a few seeds' outliers dominate the variance,
    and the B batches of one capture rarely hold one)."""
    from dataclasses import replace

    from .capture import capture, reconstruct_noisy
    from .noise import NoiseModel

    if source not in ("mc", "sensor", "total"):
        raise PrecisionError(f"source must be 'mc', 'sensor' or 'total', got {source!r}")
    noise = NoiseModel() if noise is None and source != "mc" else noise
    values = {"velocity": [], "depth": []}
    predicted = {"velocity": [], "depth": []}
    part = {"mc": "_std_mc", "sensor": "_std_sensor", "total": "_std"}[source]
    if source == "sensor":
        result = capture(scene, spp=spp, seed=seed, mc_batches=mc_batches, noise=noise,
                         **capture_kwargs)
        for k in range(repetitions):
            recon = reconstruct_noisy(result, replace(noise, seed=int(noise.seed) + 1 + k))
            for key in values:
                values[key].append(getattr(recon, key))
        for key in values:
            predicted[key].append(getattr(result.uncertainty, key + part))
    else:
        for k in range(repetitions):
            result = capture(scene, spp=spp, seed=seed + k, mc_batches=mc_batches,
                             noise=None if source == "mc" else replace(
                                 noise, seed=int(noise.seed) + k), **capture_kwargs)
            for key in values:
                values[key].append(getattr(result, key))
                predicted[key].append(getattr(result.uncertainty, key + part))
    out = {"source": source, "repetitions": repetitions, "mc_batches": mc_batches, "spp": spp}
    for key in values:
        variance = np.mean(np.square(np.asarray(predicted[key], np.float64)), axis=0)
        ratio, pixels = spread_ratio(variance, values[key])
        measured = np.std(np.asarray(values[key], np.float64), axis=0, ddof=1)
        with np.errstate(divide="ignore", invalid="ignore"):
            single = np.asarray(predicted[key], np.float64) / measured[None]
        out[key] = {"predicted_over_measured_median": ratio, "pixels": pixels,
                    "single_capture_median": _median(single),
                    "predicted_std_median": _median(np.sqrt(variance)),
                    "measured_std_median": _median(measured)}
    return out
