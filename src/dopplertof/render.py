"""Render a D-ToF image: passes of bounded memory, deterministic accumulation, progress.

The samples of every pixel are cut into fixed *chunks* (8 groups of K samples each).
A pass renders a whole number of chunks for all pixels; each chunk is summed on its
own in the kernel (a sequential block reduction) and the chunk sums are added in
float64 in chunk order. A sample's random
numbers depend only on (seed, pixel, sample index, dimension), so the image is bitwise
the same whatever the pass size.
"""

from __future__ import annotations

import os
import sys
import time as _time
from dataclasses import dataclass, field

import numpy as np

from . import allocation, sampling
from .params import RenderParams
from .sampling import check_sample_count

#: lanes per pass (memory bound: a few hundred MB of JIT state at most)
DEFAULT_MAX_LANES = 1 << 21

#: groups per accumulation chunk
GROUPS_PER_CHUNK = 8


@dataclass
class RenderResult:
    """A rendered image and what produced it."""

    image: np.ndarray  #: float32 (H, W, C), the time-averaged measurement (signed)
    metadata: dict = field(default_factory=dict)
    #: samples traced per pixel (H, W) with adaptive_sampling, else None (spp everywhere)
    sample_counts: np.ndarray | None = None


@dataclass
class RenderSetup:
    """Everything the path tracing kernel reads, resolved for one render."""

    scene: object
    params: RenderParams
    modulation: object
    weight: object
    seed: object
    correlation_depth: object
    method: object
    antithetic_shift: object
    group_size: int
    groups_per_pixel: int
    stratify: bool
    shutter_open: float
    film_sampler: object
    camera: object  #: integrators.camera.Camera
    projection: object  #: PinholeProjection when pairs use the motion mapping, else None
    hide_emitters: bool


def _make_setup(mi, scene, params: RenderParams, spp: int, seed: int) -> RenderSetup:
    import drjit as dr

    from .integrators.camera import Camera, PinholeProjection, is_pinhole
    from .integrators.dtof_path import FilmSampler, ModulationWeight

    sensor = scene.sensor
    mod = params.modulation(scene.shutter_interval)
    K = params.time_correlate_number
    to_world = np.array(sensor.world_transform().matrix, dtype=np.float64).reshape(4, 4, -1)
    forward = to_world[:3, 2, 0]
    forward = forward / np.linalg.norm(forward)
    near_clip = float(sensor.near_clip()) if hasattr(sensor, "near_clip") else 0.0
    weight = ModulationWeight(mi, mod)
    projection = None
    if params.antithetic_mapping == "motion":
        if not is_pinhole(sensor):
            raise ValueError(
                "antithetic_mapping='motion' needs a pinhole perspective sensor, got "
                f"{sensor.class_name()}")
        projection = PinholeProjection(mi, sensor, scene.sensor_motion, near_clip)
    return RenderSetup(
        scene=scene, params=params, modulation=mod, weight=weight,
        seed=dr.opaque(mi.UInt32, seed & 0xFFFFFFFF),
        correlation_depth=dr.opaque(mi.UInt32, min(params.path_correlation_depth, 1 << 30)),
        method=dr.opaque(mi.UInt32, sampling.method_index(params.time_sampling_method)),
        antithetic_shift=dr.opaque(weight.F, mod.antithetic_shift),
        group_size=K, groups_per_pixel=spp // K,
        stratify=params.use_stratified_sampling_for_each_interval,
        shutter_open=scene.shutter_open, film_sampler=FilmSampler(sensor.film()),
        camera=Camera(mi, sensor, scene.sensor_motion, near_clip,
                      mi.Vector3f(*map(float, forward))),
        projection=projection,
        hide_emitters=params.hide_emitters,
    )


def _show_progress(progress) -> bool:
    if progress is not None:
        return bool(progress)
    return sys.stderr.isatty()


def render_result(scene, spp: int | None = None, seed: int = 0, params=None, *,
                  progress: bool | None = None, max_lanes: int = DEFAULT_MAX_LANES,
                  pass_chunks: int | None = None, checkpoint=None) -> RenderResult:
    """Render ``scene`` (a DopplerScene); see :func:`render`.

    ``checkpoint`` (a path) saves the accumulated chunks after every pass and resumes
    from them: the final image is bitwise the one of an uninterrupted render. It is
    refused for a different render (scene, parameters, spp, seed, variant). A complete
    checkpoint returns the image at once; delete the file when the output is safe.
    """
    from .backend import require_variant

    mi = require_variant()
    if scene.variant != mi.variant():
        raise RuntimeError(
            f"the scene was loaded with variant {scene.variant!r} but {mi.variant()!r} is set"
        )
    p = scene.params
    if params is not None:
        p = params if isinstance(params, RenderParams) else RenderParams.from_mapping(
            dict(params), where="render parameters", base=p)
    p = p.resolved(scene.shutter_interval)
    spp = scene.spp if spp is None else int(spp)
    if not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ValueError(f"seed must be a non-negative integer, got {seed!r}")
    check_sample_count(p.time_correlate_number, spp)

    film = scene.sensor.film()
    width, height = (int(v) for v in film.crop_size())
    n_pixels = width * height
    setup = _make_setup(mi, scene, p, spp, int(seed))

    # ---- Pass plan: whole chunks per pass ----
    K = setup.group_size
    chunk = min(spp, GROUPS_PER_CHUNK * K)
    n_chunks = -(-spp // chunk)
    pilot_chunks = (allocation.pilot_samples(spp, chunk) // chunk
                    if p.adaptive_sampling else 0)
    if pass_chunks is None:
        pass_chunks = max(1, max_lanes // (n_pixels * chunk))
    pass_chunks = max(1, min(int(pass_chunks), n_chunks))
    from . import budget

    cost = budget.check(budget.estimate(width, height, _spectrum_channels(mi), spp, chunk,
                                        pass_chunks, p.adaptive_sampling))
    if progress is not False and cost.seconds > budget.LONG_RENDER_SECONDS:
        print(f"dopplertof: rendering {cost.describe()}", file=sys.stderr, flush=True)

    from tqdm import tqdm

    from .integrators.dtof_path import PassLayout, trace_pass

    channels_out = _spectrum_channels(mi)
    total = np.zeros((n_pixels, channels_out), dtype=np.float64)
    # adaptive sampling: the pilot's sums of squared group sums, then the counts
    squares = np.zeros_like(total) if p.adaptive_sampling else None
    counts = None
    nonfinite = 0
    next_chunk = 0
    key = _render_key(scene, p, spp, seed, mi.variant(), chunk)
    if checkpoint is not None:
        saved = _load_checkpoint(checkpoint, key)
        if saved is not None:
            total, nonfinite, next_chunk, saved_squares, saved_counts = saved
            if p.adaptive_sampling:  # (the key holds the parameters: saved adaptively)
                squares, counts = saved_squares, (saved_counts if saved_counts.size else None)
    started = _time.perf_counter()
    done = (min(spp, next_chunk * chunk) if counts is None
            else float(np.minimum(counts, next_chunk * chunk).mean()))
    bar = tqdm(total=spp, initial=done, unit="spp", desc="rendering",
               disable=not _show_progress(progress), leave=False, file=sys.stderr)
    import drjit as dr

    def trace_chunks(first_chunk, end_chunk):
        """Trace chunks [first_chunk, end_chunk) of every pixel that has them and add
        them to ``total`` (and in the pilot, to ``squares``)."""
        nonlocal nonfinite
        s0 = first_chunk * chunk
        if counts is None:
            s1 = min(spp, end_chunk * chunk)
            samples = s1 - s0
            chunk_size = min(chunk, samples)
            layout = PassLayout(mi, n_pixels, samples, dr.opaque(mi.UInt32, s0), K)
            block_pixel = np.repeat(np.arange(n_pixels), samples // chunk_size)
            lanes = n_pixels * samples
        else:  # each pixel its own number of chunks: lanes from host arrays
            chunk_size = chunk
            per_pixel = np.clip(counts - s0, 0, (end_chunk - first_chunk) * chunk)
            pixels = np.flatnonzero(per_pixel)
            per_pixel = per_pixel[pixels]
            lane_pixel = np.repeat(pixels, per_pixel)
            first_lane = np.repeat(np.cumsum(per_pixel) - per_pixel, per_pixel)
            lane_sample = s0 + np.arange(lane_pixel.size) - first_lane
            layout = PassLayout.of_lanes(mi, lane_pixel, lane_sample, K)
            block_pixel = lane_pixel[::chunk]
            lanes = lane_pixel.size
        value = trace_pass(mi, setup, layout)
        dr.eval(value)  # one path tracing kernel for all channels
        # ---- Drop non-finite samples and sum each chunk (sequential reductions) ----
        channels = [value[c] for c in range(_channels(value))]
        finite = dr.isfinite(channels[0])
        for v in channels[1:]:
            finite &= dr.isfinite(v)
        dropped = dr.count(~finite)
        channels = [dr.select(finite, v, 0.0) for v in channels]
        sums = [dr.block_sum(v, chunk_size, mode="evaluated") for v in channels]
        pilot = squares is not None and first_chunk < pilot_chunks
        if pilot:  # squared sums of the groups (K samples), summed per chunk
            sums += [dr.block_sum(dr.square(dr.block_sum(v, K, mode="evaluated")),
                                  chunk_size // K, mode="evaluated") for v in channels]
        dr.eval(dropped, sums)
        nonfinite += int(dropped[0])
        parts = np.stack([np.asarray(v) for v in sums], axis=-1).astype(np.float64)
        # chunk order per pixel, whatever the passes: the image ignores pass sizes
        position = np.arange(block_pixel.size) - np.searchsorted(block_pixel, block_pixel)
        for j in range(int(position.max()) + 1 if position.size else 0):
            rows = position == j
            total[block_pixel[rows]] += parts[rows, :channels_out]
            if pilot:
                squares[block_pixel[rows]] += parts[rows, channels_out:]
        bar.update(lanes / n_pixels)
        if checkpoint is not None:
            _save_checkpoint(checkpoint, key, total, nonfinite, end_chunk, squares, counts)

    try:
        if not p.adaptive_sampling:
            # The last chunk may be short: it gets a pass of its own, so that every
            # pass sums chunks of one size.
            full_chunks = spp // chunk
            plan = [(c0, min(full_chunks, c0 + pass_chunks)) for c0 in
                    range(next_chunk, full_chunks, pass_chunks)]
            if full_chunks < n_chunks and next_chunk <= full_chunks:
                plan.append((full_chunks, n_chunks))
            for first_chunk, end_chunk in plan:
                trace_chunks(first_chunk, end_chunk)
        else:
            # ---- Pilot: the first chunks of every pixel ----
            for c0 in range(next_chunk, pilot_chunks, pass_chunks):
                trace_chunks(c0, min(pilot_chunks, c0 + pass_chunks))
            # ---- Counts from the neighbours' pilot variance, then the rest ----
            if counts is None:
                counts = _adaptive_counts(total, squares, pilot_chunks * chunk, K, spp,
                                          chunk, (height, width))
            for first_chunk, end_chunk in _adaptive_plan(
                    counts // chunk, max(next_chunk, pilot_chunks), pass_chunks * n_pixels):
                trace_chunks(first_chunk, end_chunk)
    finally:
        bar.close()

    per_pixel = (np.full(n_pixels, spp) if counts is None else counts).astype(np.float64)
    image = (total / per_pixel[:, None]).astype(np.float32).reshape(height, width, -1)
    mod = setup.modulation
    metadata = {
        "measurement": "time-averaged correlation (1/T) * integral over the exposure; "
                       "multiply by exposure_s for the integrated value",
        "exposure_s": mod.exposure,
        "omega_g_rad_s": mod.omega_g,
        "omega_d_rad_s": mod.omega_d,
        "psi_rad": mod.psi,
        "spp": spp,
        "seed": int(seed),
        "variant": mi.variant(),
        "nonfinite_samples_dropped": nonfinite,
        "render_seconds": _time.perf_counter() - started,
        "params": {k: getattr(p, k) for k in RenderParams.names()},
    }
    sample_counts = None
    if counts is not None:
        sample_counts = counts.reshape(height, width)
        metadata["sample_counts"] = {"pilot": pilot_chunks * chunk, "min": int(counts.min()),
                                     "max": int(counts.max()),
                                     "mean": float(counts.mean())}
    return RenderResult(image, metadata, sample_counts)


def _adaptive_plan(chunks, first: int, chunks_per_pass: int) -> list:
    """Passes (first_chunk, end_chunk) over the chunk columns from ``first`` on, for
    pixels with ``chunks`` chunks each: as many columns per pass as fit in
    ``chunks_per_pass`` pixel-chunks (at least one)."""
    # pixels that still have chunk c (c = 0, 1, ...)
    remaining = chunks.size - np.cumsum(np.bincount(chunks))
    plan, c0 = [], first
    while c0 < remaining.size - 1:
        c1, used = c0 + 1, remaining[c0]
        while c1 < remaining.size - 1 and used + remaining[c1] <= chunks_per_pass:
            used += remaining[c1]
            c1 += 1
        plan.append((c0, c1))
        c0 = c1
    return plan


def _adaptive_counts(total, squares, pilot: int, group_size: int, spp: int, chunk: int,
                     shape) -> np.ndarray:
    """Samples per pixel from the pilot: each pixel's variance of its group sums
    (averaged over channels) goes to allocation.sample_counts."""
    groups = pilot // group_size
    variance = (squares - total * total / groups) / max(groups - 1, 1)
    variance = variance.mean(axis=-1).reshape(shape)
    return allocation.sample_counts(variance, spp, pilot, chunk).reshape(-1)


# ---- Checkpoints ----------------------------------------------------------------

def _render_key(scene, params: RenderParams, spp: int, seed: int, variant: str,
                chunk: int) -> str:
    """What must match for a checkpoint to be resumed (hex digest)."""
    import hashlib

    text = repr((scene.fingerprint or scene.source, params, spp, int(seed), variant, chunk,
                 GROUPS_PER_CHUNK))
    return hashlib.sha256(text.encode()).hexdigest()


class CheckpointError(ValueError):
    """A checkpoint that belongs to another render or cannot be read."""


def _load_checkpoint(path, key: str):
    if not os.path.exists(path):
        return None
    try:
        with np.load(path, allow_pickle=False) as data:
            saved_key = str(data["key"])
            total, nonfinite, next_chunk = data["total"], int(data["nonfinite"]), int(data["next"])
            squares, counts = data["squares"], data["counts"]
    except Exception as e:
        raise CheckpointError(f"checkpoint {path} cannot be read: {e}") from None
    if saved_key != key:
        raise CheckpointError(
            f"checkpoint {path} belongs to a different render (scene, parameters, spp, seed "
            "or variant differ); delete it or choose another checkpoint file")
    return total, nonfinite, next_chunk, squares, counts


def _save_checkpoint(path, key: str, total, nonfinite: int, next_chunk: int, squares=None,
                     counts=None) -> None:
    """``squares`` and ``counts``: the adaptive pilot's sums and the sample counts, when
    there are (else saved empty)."""
    from .io import atomic_path

    with atomic_path(path) as tmp:
        with open(tmp, "wb") as f:
            np.savez(f, key=np.array(key), total=total, nonfinite=np.array(nonfinite),
                     next=np.array(next_chunk),
                     squares=np.zeros(0) if squares is None else squares,
                     counts=np.zeros(0, np.int64) if counts is None else counts)


def _spectrum_channels(mi) -> int:
    """Channels of a sample's value: RGB for spectral variants (converted per sample),
    else the variant's Spectrum (3 for RGB, 1 for mono)."""
    return 3 if mi.is_spectral else _channels(mi.Spectrum(0.0))


def _channels(value) -> int:
    try:
        return len(value)
    except TypeError:
        return 1


def render(scene, spp: int | None = None, seed: int = 0, params=None, **kwargs) -> np.ndarray:
    """Render a D-ToF image: float32 (H, W, C), the time-averaged measurement.

    ``spp`` defaults to the scene's sampler count; ``params`` (a dict or RenderParams)
    overrides integrator parameters of the scene. The value is signed and equals
    (1/T) * the integral over the exposure; multiply by T for the integrated charge.
    """
    return render_result(scene, spp, seed, params, **kwargs).image
