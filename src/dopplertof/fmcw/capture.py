"""One FMCW frame of a scene: its spectra, range and radial velocity per pixel from
the up and down peaks, the exact truth and the errors (docs/fmcw.md).

The output folder (the set "fmcw" of :func:`dopplertof.io.output_folder`, all or
nothing, as a capture's): spectrum.npy (H, W, 2, M) float32, up chirp first (2 M
bins from -M / T with an I/Q receiver, :attr:`Chirp.iq`); frequencies.npy (M,) Hz;
range.npy and velocity.npy (H, W) m and m/s, NaN where a pixel's spectra have no peak;
range_gt.npy and velocity_point.npy (the truth: the hit point's velocity along the ray);
points.npy, the point cloud with velocity (K, 5: x, y, z, radial velocity, peak height);
with more than one return per pixel, returns_range.npy and returns_velocity.npy (H, W, N);
with speckle, speckle.npy (H, W, 2, M); previews of the four maps (.png); summary.json.
Each file is declared in :data:`dopplertof.outputs.FMCW`.
"""

from __future__ import annotations

import time as _time
from dataclasses import dataclass, field

import numpy as np

from .. import file_formats, io
from ..capture_summary import SUMMARY_JSON, write_summary
from ..outputs import FMCW, files, renamed
from ..tof.summary import STATIC_SURFACES, error_stats
from ..tof.ground_truth import ground_truth, light_colocation
from ..arguments import is_integer
from ..modulation import SPEED_OF_LIGHT
from .chirp import Chirp, FMCWError


#: every file an FMCW frame may write into its folder (the set "fmcw")
OUTPUT_FILES = files(FMCW)


@dataclass
class FMCWResult:
    """An FMCW frame (arrays as written, see the module docstring)."""

    spectrum: np.ndarray  #: (H, W, 2, M) float32, mean contribution per bin, up then down
    frequencies: np.ndarray  #: (M,) float64, bin centres, Hz
    range: np.ndarray  #: (H, W) float64, m
    velocity: np.ndarray  #: (H, W) float64, m/s, > 0 receding
    range_gt: np.ndarray  #: (H, W) the truth's depth along the pixel-centre ray, m
    #: (H, W) the truth's hit point velocity along the ray, relative to the camera, m/s
    velocity_point: np.ndarray
    peaks: np.ndarray  #: (H, W, 2) the strongest up and down peaks, Hz (NaN: none)
    summary: dict = field(default_factory=dict)
    #: (H, W, N) range and velocity of the N strongest returns (the first: range, velocity)
    returns_range: np.ndarray | None = None
    returns_velocity: np.ndarray | None = None
    #: (K, 5) x, y, z (m, world), radial velocity (m/s), peak height of every return
    points: np.ndarray | None = None
    #: (H, W, 2, M) float32 with speckle: each bin's |coherent sum of the paths'
    #: amplitudes at random phases|^2 / spp, whose expectation is ``spectrum``
    speckle: np.ndarray | None = None
    #: (H, W) bool: pixels whose beats fit the folded reading too (range from
    #: |f_up - f_down| / 2, speed from (f_up + f_down) / 2) within the scene's speeds
    #: (:func:`folding`); their range and velocity are one of two readings
    ambiguous: np.ndarray | None = None

    @property
    def velocity_gt(self) -> np.ndarray:
        """:attr:`velocity_point` under its former name (with a FutureWarning)."""
        renamed("fmcw", "velocity_gt", "FMCWResult")
        return self.velocity_point

    def write(self, folder) -> list:
        """Every file into ``folder`` (created if missing), all or nothing; returns the
        paths written."""
        with io.output_folder(io.check_output_set(folder, "fmcw", OUTPUT_FILES),
                              "fmcw") as staged:
            path = staged.path
            several = self.returns_range.shape[-1] > 1
            for output in FMCW.values():
                data = getattr(self, output.name, None)
                if output.dtype and data is not None and (several or not
                                                          output.name.startswith("returns_")):
                    file_formats.write_npy(path(output.npy), output.array(data))
            self._write_previews(path)
            write_summary(path(SUMMARY_JSON), "fmcw", self.summary)
        return staged.written


    def _write_previews(self, path) -> None:
        """range.png, velocity.png and their truth's, each pair on one colour scale."""
        from ..tof import figures

        c = self.summary["chirp"]
        chirp = (f"{c['wavelength_nm']:g} nm, B {c['bandwidth_GHz']:g} GHz over "
                 f"{c['chirp_time_us']:g} us")
        finite = np.concatenate([a[np.isfinite(a)] for a in (self.range, self.range_gt)])
        lo, hi = ((float(np.percentile(finite, 0.5)), float(np.percentile(finite, 99.5)))
                  if finite.size else (None, None))
        limit = figures.truth_limit(self.velocity_point, self.velocity)
        for name, title in (("range", f"FMCW range, strongest return ({chirp})"),
                            ("range_gt", "true distance along the pixel-centre ray")):
            figures.write_map(path(f"{name}.png"), getattr(self, name), title, "m",
                              vmin=lo, vmax=hi)
        for name, title in (("velocity", f"FMCW radial velocity ({chirp})"),
                            ("velocity_point", "true velocity along the ray u.d")):
            figures.write_map(path(f"{name}.png"), getattr(self, name), title,
                              "m/s (+ receding, - approaching)", cmap="RdBu_r", vmax=limit,
                              symmetric=True)


def spectrum_peaks(spectrum: np.ndarray, chirp: Chirp, count: int = 1):
    """The ``count`` strongest peaks of each spectrum of ``spectrum`` (..., M): their
    beats (..., count) in Hz and their heights (the peak bins' values), strongest
    first. A peak is a bin above its left neighbour and not below its right one; its beat
    is the centroid of the bin and its two neighbours (exact for one beat split linearly
    between two bins). NaN beats and zero heights where a spectrum has fewer peaks."""
    s = spectrum.astype(np.float64)
    padded = np.concatenate([np.zeros(s.shape[:-1] + (1,)), s, np.zeros(s.shape[:-1] + (1,))],
                            axis=-1)
    peak = (s > padded[..., :-2]) & (s >= padded[..., 2:])
    order = np.argsort(np.where(peak, -s, np.inf), axis=-1, kind="stable")[..., :count]
    height = np.where(np.take_along_axis(peak, order, axis=-1),
                      np.take_along_axis(s, order, axis=-1), 0.0)
    index = order[..., None] + np.array([-1, 0, 1])  # (..., count, 3)
    weights = np.take_along_axis(padded[..., None, :], index + 1, axis=-1)
    with np.errstate(invalid="ignore", divide="ignore"):
        centre = (weights * index).sum(axis=-1) / weights.sum(axis=-1)
    return np.where(height > 0, (centre + chirp.first_bin) * chirp.bin_width, np.nan), height


def regions(scene, truth, range_: np.ndarray, velocity: np.ndarray) -> list:
    """Range and velocity errors per moving body and over the static surfaces (the
    pixels whose centre ray hits them; a body's silhouette mixes it with what is behind)."""
    parts = [(", ".join(body.names), truth.body == k) for k, body in enumerate(scene.bodies)]
    parts.append((STATIC_SURFACES, truth.body == -1))
    return [{"name": name, "pixels": int(on.sum()),
             "range_m": error_stats(range_[on], truth.depth[on]),
             "velocity_m_s": error_stats(velocity[on], truth.velocity_point[on]),
             "velocity_gt_median_m_s": float(np.median(truth.velocity_point[on]))}
            for name, on in parts if on.any()]


def point_cloud(truth, ranges: np.ndarray, velocities: np.ndarray, heights: np.ndarray):
    """(K, 5): x, y, z (m, world, at t0), radial velocity (m/s) and peak height of every
    return with a range, placed along its pixel-centre ray from the camera centre."""
    found = np.isfinite(ranges)  # (H, W, N)
    directions = np.broadcast_to(truth.direction[:, :, None, :], ranges.shape + (3,))
    points = truth.camera_origin + ranges[found][:, None] * directions[found]
    return np.column_stack([points, velocities[found], heights[found]])


def folding(chirp: Chirp, truth, beats: np.ndarray):
    """Where the beats fold at zero (docs/fmcw.md section 3): a return from distance d
    moving at radial speed |v| >= B lambda d / (c T) (:meth:`Chirp.unambiguous_speed`)
    has a lower beat below zero, read as its magnitude, so that its pair gives range and
    velocity swapped. From the truth (the scene's largest speed V and the distances)
    and the strongest peaks ``beats`` (H, W, 2: up, down; Hz): (the summary's "folding"
    record, the (H, W) ambiguous mask, a warning or None). A pixel is ambiguous where
    both readings fit speeds up to V (within a velocity bin): the unfolded one (speed
    lambda |f_up - f_down| / 4) and the folded one (speed lambda (f_up + f_down) / 4)."""
    depth, speed = truth.depth, np.abs(truth.velocity_point)
    seen = np.isfinite(depth) & np.isfinite(speed)
    fastest = float(speed[seen].max()) if seen.any() else 0.0
    with np.errstate(invalid="ignore"):
        folded = seen & (speed >= chirp.unambiguous_speed(np.where(seen, depth, 0.0)))
        up, down = beats[..., 0], beats[..., 1]
        slack = fastest + 0.25 * chirp.wavelength * chirp.bin_width  # (one velocity bin)
        ambiguous = (np.isfinite(up) & np.isfinite(down)
                     & (0.25 * chirp.wavelength * np.abs(up - down) <= slack)
                     & (0.25 * chirp.wavelength * (up + down) <= slack))
    if chirp.iq:  # (signed beats: a beat below zero is read as such, nothing folds)
        folded, ambiguous = np.zeros_like(folded), np.zeros_like(ambiguous)
    beyond = 0.0 if chirp.iq else fastest / chirp.unambiguous_speed(1.0)
    record = {"max_speed_m_s": fastest, "unambiguous_beyond_m": beyond,
              "unambiguous_speed_at_nearest_m_s": (
                  None if chirp.iq or not seen.any()
                  else float(chirp.unambiguous_speed(depth[seen].min()))),
              "folded_pixels": int(folded.sum()), "ambiguous_pixels": int(ambiguous.sum()),
              "receiver": "I/Q" if chirp.iq else "real"}
    warning = None
    if folded.any() or ambiguous.any():
        warning = (f"the beats fold: {int(folded.sum())} pixel(s) move faster than B lambda "
                   f"d / (c T) at their distance d (the Doppler beat exceeds the range beat: "
                   f"the lower beat crosses zero and range and velocity read swapped); "
                   f"{int(ambiguous.sum())} pixel(s) ambiguous (the folded reading fits "
                   f"speeds up to the scene's {fastest:.3g} m/s as well: ambiguous.npy); "
                   f"this chirp reads {fastest:.3g} m/s unambiguously only beyond "
                   f"{beyond:.3g} m: raise B / T, or use an I/Q receiver (--iq, "
                   "fmcw_iq), which sees the beats' signs and does not fold")
    return record, ambiguous, warning


def check_round_trip(chirp: Chirp, depth: np.ndarray) -> None:
    """An FMCWError unless ``chirp`` lasts longer than the longest round trip of the
    pixels' direct returns (``depth``: the truth's distances along the pixel-centre rays,
    NaN where nothing is hit): a chirp must outlast its echoes for them to beat with it."""
    seen = depth[np.isfinite(depth)]
    if seen.size and chirp.chirp_time <= 2.0 * float(seen.max()) / SPEED_OF_LIGHT:
        trip = 2.0 * float(seen.max()) / SPEED_OF_LIGHT
        raise FMCWError(f"chirp_time T = {chirp.chirp_time:g} s ({chirp.chirp_time * 1e6:g} "
                        f"us) is not longer than the scene's longest round trip, 2 x "
                        f"{float(seen.max()):.4g} m / c = {trip:.4g} s: a chirp must "
                        "outlast its echoes")


def _arguments(scene, chirp, spp, seed, params, returns, beam, beam_intensity, speckle):
    """:func:`fmcw`'s arguments checked (a TypeError naming one of the wrong type, an
    FMCWError out of range) and resolved against the scene's parameters, with the
    warnings they call for (an intensity the flood beam ignores)."""
    from ..arguments import check_flag, check_params, check_scene, check_seed, check_spp
    from .trace import fmcw_params

    scene = check_scene(scene)
    spp, seed = check_spp(spp, error=FMCWError), check_seed(seed, error=FMCWError)
    if not is_integer(returns) or returns < 1:
        raise FMCWError(f"returns must be an integer >= 1, got {returns!r}")
    returns, speckle = int(returns), check_flag(speckle, "speckle")
    params, settings = fmcw_params(scene, check_params(params))
    chirp = Chirp.of_settings(settings) if chirp is None else chirp
    if not isinstance(chirp, Chirp):
        raise TypeError(f"chirp must be a dopplertof.fmcw.Chirp, got {type(chirp).__name__}")
    beam = settings.beam if beam is None else beam
    warnings = []
    if beam_intensity is not None and beam == "flood":  # (the command refuses it)
        warnings.append(f"beam_intensity {beam_intensity!r} is a collimated beam's: the "
                        "flood beam (the scene's lights) ignores it")
    beam_intensity = settings.beam_intensity if beam_intensity is None else beam_intensity
    return scene, chirp, spp, seed, params, returns, beam, beam_intensity, speckle, warnings


def fmcw(scene, chirp: Chirp | None = None, spp: int | None = None, seed: int = 0,
         params=None, returns: int = 1, beam: str | None = None,
         beam_intensity: float | None = None, speckle: bool = False) -> FMCWResult:
    """The FMCW frame of ``scene`` (a DopplerScene) for ``chirp`` (None: the scene's,
    its integrator's fmcw_* parameters, by default 1550 nm, 1 GHz over 10 us, 256 bins)
    at ``spp`` samples per pixel (default: the scene's), with the ``returns`` strongest
    returns of every pixel, lit by ``beam`` (None: the scene's fmcw_beam, by default
    "flood"): "flood" (the scene's emitters) or "collimated" (each pixel's own beam of
    ``beam_intensity`` W/sr, None: the scene's fmcw_beam_intensity; :mod:`.beam`);
    ``speckle`` adds the spectra of random path phases summed coherently
    (:attr:`FMCWResult.speckle`). ``params`` (a mapping or RenderParams) override the
    scene's integrator parameters, a mapping the fmcw_* ones too (the scene's
    ``modality_settings["fmcw"]``); an argument given here overrides both."""
    from .trace import render_spectra

    scene, chirp, spp, seed, params, returns, beam, beam_intensity, speckle, warnings = \
        _arguments(scene, chirp, spp, seed, params, returns, beam, beam_intensity, speckle)
    truth = ground_truth(scene, params)
    check_round_trip(chirp, truth.depth)
    started = _time.perf_counter()
    spectrum, t0, speckled = render_spectra(scene, chirp, spp, seed, params, beam,
                                            beam_intensity, speckle)
    seconds = _time.perf_counter() - started
    if not np.isfinite(spectrum).all() or not np.isfinite(spectrum.astype(np.float32)).all():
        raise FMCWError(f"the spectra overflow float32 (a beam of {beam_intensity:g} W/sr or "
                        "an emitter too bright): nothing written")
    # the k-th strongest up peak pairs with the k-th strongest down one (a path has the
    # same power in both chirps)
    beats, heights = spectrum_peaks(spectrum, chirp, returns)  # (H, W, 2, N)
    ranges, velocities = chirp.range_and_velocity(beats[:, :, 0], beats[:, :, 1])
    range_, velocity = ranges[..., 0], velocities[..., 0]
    folding_record, ambiguous, warning = folding(chirp, truth, beats[..., 0])
    spp = scene.spp if spp is None else spp
    summary = {
        "scene": getattr(scene, "source", None), "spp": int(spp),
        "seed": int(seed), "resolution": [spectrum.shape[1], spectrum.shape[0]],
        "time_s": t0, "chirp": chirp.record(), "render_seconds": seconds,
        "light_at_camera": light_colocation(scene).get("colocated"),
        "velocity_sign": "positive receding (dL/dt > 0)",
        "errors": {"range_m": error_stats(range_, truth.depth),
                   "velocity_m_s": error_stats(velocity, truth.velocity_point)},
        "regions": regions(scene, truth, range_, velocity),
        "no_peak_pixels": int(np.isnan(range_).sum()),
        "beyond_max_range_pixels": int((truth.depth > 0.5 * chirp.max_path_length).sum()),
        "returns": returns, "points": int(np.isfinite(ranges).sum()),
        "speckle": bool(speckle),
        "folding": folding_record,
        "beam": {"kind": beam, "intensity_W_sr": beam_intensity if beam == "collimated"
                 else None},
    }
    warnings += [warning] if warning else []
    if warnings:
        summary["warnings"] = warnings
    return FMCWResult(spectrum.astype(np.float32), chirp.frequencies(), range_, velocity,
                      truth.depth, truth.velocity_point, beats[..., 0], summary,
                      ranges, velocities,
                      point_cloud(truth, ranges, velocities, heights[:, :, 0]),
                      None if speckled is None else speckled.astype(np.float32), ambiguous)
