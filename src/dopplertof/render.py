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
    path_group_size: int  #: Kp, samples sharing one path stream
    stratify: bool
    shutter_open: float
    film_sampler: object  #: integrators.film.FilmSampler: film positions in a pixel
    splat: object  #: integrators.film.SplatFilter, or None for the importance film
    camera: object  #: integrators.camera.Camera
    projection: object  #: PinholeProjection when pairs use the motion mapping, else None
    hide_emitters: bool
    analytic: bool = False  #: time_sampling_method "analytic" (integrators/analytic.py)


def _make_setup(mi, scene, params: RenderParams, spp: int, seed: int) -> RenderSetup:
    import drjit as dr

    from .integrators.camera import Camera, PinholeProjection, is_pinhole
    from .integrators.dtof_path import ModulationWeight
    from .integrators.film import FilmSampler, SplatFilter

    sensor = scene.sensor
    mod = params.modulation(scene.shutter_interval)
    K = params.time_correlate_number
    to_world = np.array(sensor.world_transform().matrix, dtype=np.float64).reshape(4, 4, -1)
    forward = to_world[:3, 2, 0]
    forward = forward / np.linalg.norm(forward)
    near_clip = float(sensor.near_clip()) if hasattr(sensor, "near_clip") else 0.0
    weight = ModulationWeight(mi, mod)
    analytic = params.time_sampling_method == sampling.ANALYTIC
    splat = params.film_sampling == "splat"
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
        # Kp = 1: every sample its own path stream, whatever the depth (independent paths)
        # (analytic: a sample's two paths share everything, and samples nothing)
        correlation_depth=dr.opaque(mi.UInt32, 0 if params.path_group_size == 1 or analytic
                                    else min(params.path_correlation_depth, 1 << 30)),
        method=dr.opaque(mi.UInt32, 0 if analytic
                         else sampling.method_index(params.time_sampling_method)),
        antithetic_shift=dr.opaque(weight.F, mod.antithetic_shift),
        group_size=K, groups_per_pixel=spp // K, path_group_size=params.path_group_size,
        stratify=params.use_stratified_sampling_for_each_interval,
        shutter_open=scene.shutter_open,
        film_sampler=FilmSampler.uniform() if splat else FilmSampler(sensor.film()),
        splat=SplatFilter(sensor.film()) if splat else None,
        camera=Camera(mi, sensor, scene.sensor_motion, near_clip,
                      mi.Vector3f(*map(float, forward))),
        projection=projection,
        hide_emitters=params.hide_emitters, analytic=analytic,
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
    check_sample_count(p.time_correlate_number, spp, p.path_group_size, p.samples_per_pass)

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
        if p.samples_per_pass > 0:  # the published pass size, in whole chunks, within memory
            pass_chunks = min(pass_chunks, -(-p.samples_per_pass // chunk))
    pass_chunks = max(1, min(int(pass_chunks), n_chunks))

    from tqdm import tqdm

    from .integrators.dtof_path import PassLayout, trace_pass

    channels_out = _spectrum_channels(mi)
    # ---- Accumulators (float64, by source pixel) ----
    # total: per pixel and film offset, each channel's sum of filter weight x value
    # (importance film: one offset, weight 1), then, with film_normalization="weights",
    # each offset's sum of weights
    splat = setup.splat
    offsets = 1 if splat is None else len(splat.offsets)
    columns = offsets * channels_out
    # (a box weighs every sample 1 in its own pixel: both normalizations are the count)
    normalization = "expected" if offsets == 1 else p.film_normalization
    if normalization == "weights":
        columns += offsets
    from . import budget  # refuse what cannot fit before allocating anything

    cost = budget.check(budget.estimate(
        width, height, channels_out, spp, chunk, pass_chunks, p.adaptive_sampling, columns,
        device_columns=columns if splat is not None and offsets > 1 else 0))
    if progress is not False and cost.seconds > budget.LONG_RENDER_SECONDS:
        print(f"dopplertof: rendering {cost.describe()}", file=sys.stderr, flush=True)
    total = np.zeros((n_pixels, columns), dtype=np.float64)
    # adaptive sampling: the pilot's sums of samples and of squared group sums
    pilot_sums = np.zeros((n_pixels, channels_out)) if p.adaptive_sampling else None
    squares = np.zeros_like(pilot_sums) if p.adaptive_sampling else None
    counts = None
    nonfinite = 0
    next_chunk = 0
    key = _render_key(scene, p.image_defining(), spp, seed, mi.variant(), chunk)
    if checkpoint is not None:
        saved = _load_checkpoint(checkpoint, key)
        if saved is not None:
            total, nonfinite, next_chunk, saved_pilot, saved_squares, saved_counts = saved
            if p.adaptive_sampling:  # (the key holds the parameters: saved adaptively)
                pilot_sums, squares = saved_pilot, saved_squares
                counts = saved_counts if saved_counts.size else None
    started = _time.perf_counter()
    done = (min(spp, next_chunk * chunk) if counts is None
            else float(np.minimum(counts, next_chunk * chunk).mean()))
    bar = tqdm(total=spp, initial=done, unit="spp", desc="rendering",
               disable=not _show_progress(progress), leave=False, file=sys.stderr)
    import drjit as dr

    # the splat film's totals stay in Dr.Jit (float64, one array per column) between
    # passes; the importance film's chunk sums are added on the host
    weighted = splat is not None and offsets > 1
    device_total = None  # column-major: column c of pixel p at c * n_pixels + p
    if weighted:
        device_total = (mi.Float64(total.T.ravel()) if next_chunk else
                        dr.zeros(mi.Float64, columns * n_pixels))

    def host_total():
        if weighted:
            return np.asarray(device_total).reshape(columns, n_pixels).T
        return total

    def trace_chunks(first_chunk, end_chunk):
        """Trace chunks [first_chunk, end_chunk) of every pixel that has them and add
        them to the totals (and in the pilot, to ``pilot_sums`` and ``squares``)."""
        nonlocal nonfinite, device_total
        s0 = first_chunk * chunk
        if counts is None:
            s1 = min(spp, end_chunk * chunk)
            samples = s1 - s0
            chunk_size = min(chunk, samples)
            layout = PassLayout(mi, n_pixels, samples, dr.opaque(mi.UInt32, s0), K)
            block_pixel = np.repeat(np.arange(n_pixels), samples // chunk_size)
            pixels, per_pixel = np.arange(n_pixels), np.full(n_pixels, samples)
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
        value, film_offset = trace_pass(mi, setup, layout)
        dr.eval(value, film_offset if weighted else None)  # one path tracing kernel
        # ---- Drop non-finite samples and sum each chunk (sequential reductions) ----
        raw = [value[c] for c in range(_channels(value))]
        finite = dr.isfinite(raw[0])
        for v in raw[1:]:
            finite &= dr.isfinite(v)
        dropped = dr.count(~finite)
        channels = [dr.select(finite, v, 0.0) for v in raw]

        def chunk_sums(values):
            return [dr.block_sum(v, chunk_size, mode="evaluated") for v in values]

        if weighted:  # the splat: per film offset, weight x value (and the weights)
            device_total = splat.accumulate(
                mi, device_total, raw, film_offset, pixels, np.cumsum(per_pixel) - per_pixel,
                per_pixel, chunk_size, columns, normalization == "weights")
            sums = []
        else:
            sums = chunk_sums(channels)
        pilot = squares is not None and first_chunk < pilot_chunks
        if pilot:  # the samples' sums, and the squared sums of the groups (K samples)
            sums += chunk_sums(channels) if weighted else []
            sums += [dr.block_sum(dr.square(dr.block_sum(v, K, mode="evaluated")),
                                  chunk_size // K, mode="evaluated") for v in channels]
        dr.eval(dropped, sums)
        nonfinite += int(dropped[0])
        parts = np.empty((block_pixel.size, len(sums)))
        for i, v in enumerate(sums):
            parts[:, i] = np.asarray(v)
        # chunk order per pixel, whatever the passes: the image ignores pass sizes
        # (the importance film's sums are both its total and, in the pilot, the pixel's
        # own sums; the squared group sums come last)
        for pixels_j, rows in (_chunk_columns(block_pixel, n_pixels) if sums else ()):
            if not weighted:
                total[pixels_j] += parts[rows, :columns]
            if pilot:
                pilot_sums[pixels_j] += parts[rows, :channels_out]
                squares[pixels_j] += parts[rows, -channels_out:]
        bar.update(lanes / n_pixels)
        if checkpoint is not None:
            _save_checkpoint(checkpoint, key, host_total(), nonfinite, end_chunk, pilot_sums,
                             squares, counts)

    reached = next_chunk  # chunks of every pixel traced so far (where it has them)

    def trace_pass_then_check_time(first_chunk, end_chunk):
        """A pass, then the timeout: it stops the render after the pass it expires in."""
        nonlocal reached
        trace_chunks(first_chunk, end_chunk)
        reached = end_chunk
        if p.timeout >= 0 and _time.perf_counter() - started > p.timeout:
            raise _TimedOut

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
                trace_pass_then_check_time(first_chunk, end_chunk)
        else:
            # ---- Pilot: the first chunks of every pixel ----
            for c0 in range(next_chunk, pilot_chunks, pass_chunks):
                trace_pass_then_check_time(c0, min(pilot_chunks, c0 + pass_chunks))
            # ---- Counts from the neighbours' pilot variance, then the rest ----
            if counts is None:
                counts = _adaptive_counts(pilot_sums, squares, pilot_chunks * chunk, K, spp,
                                          chunk, (height, width))
            for first_chunk, end_chunk in _adaptive_plan(
                    counts // chunk, max(next_chunk, pilot_chunks), pass_chunks * n_pixels):
                trace_pass_then_check_time(first_chunk, end_chunk)
    except _TimedOut:
        pass
    finally:
        bar.close()

    total = host_total()
    # normalized by the samples taken: all of them, unless the timeout stopped the render
    wanted = np.full(n_pixels, spp) if counts is None else counts
    per_pixel = np.minimum(wanted, reached * chunk).astype(np.float64)
    timed_out = bool(np.any(per_pixel < wanted))
    if timed_out:
        print(f"dopplertof: timeout of {p.timeout:g} s expired: stopped after "
              f"{per_pixel.mean():g} of {spp} samples per pixel; the image is normalized by "
              "the samples taken" + ("; the checkpoint resumes the render"
                                     if checkpoint is not None else ""), file=sys.stderr)
    if splat is None:
        image = (total / per_pixel[:, None]).astype(np.float32).reshape(height, width, -1)
    else:
        image = _develop_splat(splat, total, per_pixel, channels_out, (height, width),
                               normalization).astype(np.float32)
    mod = setup.modulation
    metadata = {
        "measurement": "time-averaged correlation (1/T) * integral over the exposure; "
                       "multiply by exposure_s for the integrated value",
        "exposure_s": mod.exposure,
        "omega_g_rad_s": mod.omega_g,
        "omega_d_rad_s": mod.omega_d,
        "psi_rad": mod.psi,
        "spp": spp,
        "samples_taken": float(per_pixel.mean()),  # per pixel; below spp after a timeout
        "timed_out": timed_out,
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


def _chunk_columns(block_pixel, n_pixels: int):
    """(pixels, rows) per chunk column j: the rows of the pass's chunk sums that hold
    chunk j of their pixel (``block_pixel``: each row's pixel, pixel-major). Slices
    when every pixel has the same number of chunks (views, no copies), else index
    arrays."""
    per_pixel = block_pixel.size // n_pixels
    if per_pixel and np.array_equal(block_pixel, np.repeat(np.arange(n_pixels), per_pixel)):
        for j in range(per_pixel):
            yield slice(None), slice(j, None, per_pixel)
        return
    position = np.arange(block_pixel.size) - np.searchsorted(block_pixel, block_pixel)
    for j in range(int(position.max()) + 1 if position.size else 0):
        rows = position == j
        yield block_pixel[rows], rows


def _develop_splat(splat, total, per_pixel, channels: int, shape, normalization: str):
    """The image (H, W, C) from the splat film's sums by source pixel (``total``:
    pixels x columns): each source pixel's sums divided by its own sample count (so
    that an adaptive count, set without the pixel's samples, leaves every term
    unbiased), shifted into the target pixels and divided by the expected weight (or,
    ``"weights"``, the sampled one)."""
    offsets = len(splat.offsets)
    mean = total.T / per_pixel[None, :]  # columns x pixels
    values = splat.shift_add(mean[:offsets * channels], shape)
    if normalization == "weights":
        weight = splat.shift_add(mean[offsets * channels:], shape)[..., 0]
    else:
        weight = splat.expected_weights(shape)
    return values / weight[..., None]


class _TimedOut(Exception):
    """The render's timeout expired (raised between passes)."""


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
            if saved_key == key:
                total, nonfinite = data["total"], int(data["nonfinite"])
                next_chunk, pilot_sums = int(data["next"]), data["pilot_sums"]
                squares, counts = data["squares"], data["counts"]
    except Exception as e:
        raise CheckpointError(f"checkpoint {path} cannot be read: {e}") from None
    if saved_key != key:
        raise CheckpointError(
            f"checkpoint {path} belongs to a different render (scene, parameters, spp, seed "
            "or variant differ); delete it or choose another checkpoint file")
    return total, nonfinite, next_chunk, pilot_sums, squares, counts


def _save_checkpoint(path, key: str, total, nonfinite: int, next_chunk: int,
                     pilot_sums=None, squares=None, counts=None) -> None:
    """``pilot_sums``, ``squares`` and ``counts``: the adaptive pilot's sums of samples
    and of squared group sums, and the sample counts, when there are (else saved
    empty)."""
    from .io import atomic_path

    with atomic_path(path) as tmp:
        with open(tmp, "wb") as f:
            np.savez(f, key=np.array(key), total=total, nonfinite=np.array(nonfinite),
                     next=np.array(next_chunk),
                     pilot_sums=np.zeros(0) if pilot_sums is None else pilot_sums,
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
