"""One FMCW frame of a scene: its spectra, range and radial velocity per pixel from
the up and down peaks, the exact truth and the errors (docs/fmcw.md; issue 43).

The output folder (the set "fmcw" of :func:`dopplertof.io.output_folder`, all or
nothing, as a capture's): spectrum.npy (H, W, 2, M) float32, up chirp first;
frequencies.npy (M,) Hz; range.npy and velocity.npy (H, W) m and m/s, NaN where a
pixel's spectra have no peak; range_gt.npy and velocity_gt.npy; summary.json.
"""

from __future__ import annotations

import time as _time
from dataclasses import dataclass, field

import numpy as np

from .. import io
from ..tof.capture import error_stats
from ..tof.ground_truth import ground_truth, light_colocation
from ..tof.output import prepare_folder
from .chirp import Chirp


@dataclass
class FMCWResult:
    """An FMCW frame (arrays as written, see the module docstring)."""

    spectrum: np.ndarray  #: (H, W, 2, M) float32, mean contribution per bin, up then down
    frequencies: np.ndarray  #: (M,) float64, bin centres, Hz
    range: np.ndarray  #: (H, W) float64, m
    velocity: np.ndarray  #: (H, W) float64, m/s, > 0 receding
    range_gt: np.ndarray  #: (H, W) the truth's depth along the pixel-centre ray, m
    #: (H, W) the truth's hit point velocity along the ray, relative to the camera, m/s
    velocity_gt: np.ndarray
    peaks: np.ndarray  #: (H, W, 2) the up and down peaks, Hz (NaN: none)
    summary: dict = field(default_factory=dict)

    def write(self, folder) -> list:
        """Every file into ``folder`` (created if missing), all or nothing; returns the
        paths written."""
        with io.output_folder(prepare_folder(folder), "fmcw") as staged:
            path = staged.path
            for name in ("spectrum", "frequencies", "range", "velocity", "range_gt",
                         "velocity_gt"):
                io.write_npy(path(f"{name}.npy"), getattr(self, name))
            io.write_json(path("summary.json"), self.summary)
        return staged.written


def spectrum_peaks(spectrum: np.ndarray, chirp: Chirp) -> np.ndarray:
    """(..., 2) the strongest beat (Hz) of each spectrum of ``spectrum`` (..., 2, M): the
    centroid of the highest bin and its two neighbours (exact for one beat split
    linearly between two bins); NaN where a spectrum is zero."""
    m = np.argmax(spectrum, axis=-1)
    lo, hi = np.maximum(m - 1, 0), np.minimum(m + 1, chirp.bins - 1)
    index = np.stack([lo, m, hi], axis=-1)
    weights = np.take_along_axis(spectrum, index, axis=-1).astype(np.float64)
    weights[..., 0] = np.where(lo < m, weights[..., 0], 0.0)  # (no bin twice at an edge)
    weights[..., 2] = np.where(hi > m, weights[..., 2], 0.0)
    total = weights.sum(axis=-1)
    with np.errstate(invalid="ignore", divide="ignore"):
        centre = (weights * index).sum(axis=-1) / total
    return np.where(total > 0, centre * chirp.bin_width, np.nan)


def fmcw(scene, chirp: Chirp | None = None, spp: int | None = None, seed: int = 0,
         params=None) -> FMCWResult:
    """The FMCW frame of ``scene`` (a DopplerScene) for ``chirp`` (default: 1550 nm,
    1 GHz over 10 us, 256 bins) at ``spp`` samples per pixel (default: the scene's)."""
    from .trace import fmcw_params, render_spectra

    chirp = Chirp() if chirp is None else chirp
    if not isinstance(chirp, Chirp):
        raise TypeError(f"chirp must be a dopplertof.fmcw.Chirp, got {type(chirp).__name__}")
    params = fmcw_params(scene, params)
    started = _time.perf_counter()
    spectrum, t0 = render_spectra(scene, chirp, spp, seed, params)
    seconds = _time.perf_counter() - started
    peaks = spectrum_peaks(spectrum, chirp)
    range_, velocity = chirp.range_and_velocity(peaks[..., 0], peaks[..., 1])
    truth = ground_truth(scene, params)
    spp = scene.spp if spp is None else spp
    summary = {
        "issue": 43, "scene": getattr(scene, "source", None), "spp": int(spp),
        "seed": int(seed), "resolution": [spectrum.shape[1], spectrum.shape[0]],
        "time_s": t0, "chirp": chirp.record(), "render_seconds": seconds,
        "light_at_camera": light_colocation(scene).get("colocated"),
        "velocity_sign": "positive receding (dL/dt > 0)",
        "errors": {"range_m": error_stats(range_, truth.depth),
                   "velocity_m_s": error_stats(velocity, truth.velocity_point)},
        "no_peak_pixels": int(np.isnan(range_).sum()),
        "beyond_max_range_pixels": int((truth.depth > 0.5 * chirp.max_path_length).sum()),
    }
    return FMCWResult(spectrum.astype(np.float32), chirp.frequencies(), range_, velocity,
                      truth.depth, truth.velocity_point, peaks, summary)
