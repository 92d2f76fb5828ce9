"""The render pipeline: passes of bounded memory, deterministic accumulation, progress.

The samples of every pixel are cut into fixed *chunks* (8 groups of K samples each).
A pass renders a whole number of chunks for all pixels; each chunk is summed on its
own in the kernel (a sequential block reduction) and the chunk sums are added in
float64 in chunk order. A sample's random
numbers depend only on (seed, pixel, sample index, dimension), so the image is bitwise
the same whatever the pass size.
"""

from __future__ import annotations

import sys
import time as _time
from dataclasses import dataclass, field

import numpy as np

from .. import allocation
from ..params import RenderParams
from ..sampling import check_sample_count
from ..scene.scene import keyframe_coverage_warning
from .checkpoint import Checkpoint, render_key

#: lanes per pass (memory bound: a few hundred MB of JIT state at most)
DEFAULT_MAX_LANES = 1 << 21

#: groups per accumulation chunk
GROUPS_PER_CHUNK = 8

#: the largest share of a render's samples that may be non-finite (NaN or infinite) and
#: dropped (a few stray samples); above it the render fails (docs/reliability.md)
MAX_NONFINITE_FRACTION = 0.01

#: phases (radians) beyond which float32 cannot evaluate the modulation: a sine of them
#: is noise or NaN (2^24: where float32's spacing reaches 1 radian)
FLOAT32_PHASE_LIMIT = float(1 << 24)


@dataclass
class RenderResult:
    """A rendered image and what produced it."""

    image: np.ndarray  #: float32 (H, W, C), the time-averaged measurement (signed)
    metadata: dict = field(default_factory=dict)
    #: samples traced per pixel (H, W) with adaptive_sampling, else None (spp everywhere)
    sample_counts: np.ndarray | None = None


def _show_progress(progress) -> bool:
    if progress is not None:
        return bool(progress)
    return sys.stderr.isatty()


def _resolve(scene, spp, seed, params):
    """The variant, the parameters (the scene's, overridden, ``auto`` resolved), the
    sample count and the seed of a render; checks what the kernel cannot."""
    from ..arguments import check_params, check_scene, check_seed, check_spp
    from ..backend import require_variant

    # ---- The arguments' types and ranges (one line naming the argument) ----
    check_scene(scene, "scene")
    spp, seed, params = check_spp(spp, "spp"), check_seed(seed, "seed"), check_params(params)
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
    spp = scene.spp if spp is None else spp
    check_sample_count(p.time_correlate_number, spp, p.path_group_size, p.samples_per_pass)
    return mi, p, spp, seed


def chunk_samples(spp: int, group_size: int) -> int:
    """Samples per chunk: GROUPS_PER_CHUNK groups of K (all of them when fewer)."""
    return min(spp, GROUPS_PER_CHUNK * group_size)


def pilot_samples(spp: int, group_size: int, params: RenderParams) -> int:
    """Samples per pixel in the adaptive pilot (0 without adaptive sampling)."""
    if not params.adaptive_sampling:
        return 0
    return allocation.pilot_samples(spp, chunk_samples(spp, group_size))


class PassPlanner:
    """How a render's samples are cut into passes of whole chunks (8 groups of K).

    Every pixel's samples form the same chunks whatever the passes; a pass traces a
    range of chunk indices [first, end) of every pixel that has them."""

    def __init__(self, spp: int, group_size: int, n_pixels: int, params: RenderParams,
                 max_lanes: int, pass_chunks: int | None):
        self.spp, self.group_size, self.n_pixels = spp, group_size, n_pixels
        self.chunk = chunk_samples(spp, group_size)
        self.n_chunks = -(-spp // self.chunk)
        self.pilot_chunks = pilot_samples(spp, group_size, params) // self.chunk
        if pass_chunks is None:
            pass_chunks = max(1, max_lanes // (n_pixels * self.chunk))
            if params.samples_per_pass > 0:  # the published pass size, in whole chunks
                pass_chunks = min(pass_chunks, -(-params.samples_per_pass // self.chunk))
        self.pass_chunks = max(1, min(int(pass_chunks), self.n_chunks))

    def uniform(self, next_chunk: int) -> list:
        """Passes from ``next_chunk`` on, every pixel at spp. The last chunk may be
        short: it gets a pass of its own, so that every pass sums chunks of one size."""
        full_chunks = self.spp // self.chunk
        plan = [(c0, min(full_chunks, c0 + self.pass_chunks))
                for c0 in range(next_chunk, full_chunks, self.pass_chunks)]
        if full_chunks < self.n_chunks and next_chunk <= full_chunks:
            plan.append((full_chunks, self.n_chunks))
        return plan

    def pilot(self, next_chunk: int) -> list:
        """Passes over the adaptive pilot's chunks (every pixel has them)."""
        return [(c0, min(self.pilot_chunks, c0 + self.pass_chunks))
                for c0 in range(next_chunk, self.pilot_chunks, self.pass_chunks)]

    def adaptive(self, counts, next_chunk: int) -> list:
        """Passes after the pilot, for per-pixel sample ``counts``."""
        return _adaptive_plan(counts // self.chunk, max(next_chunk, self.pilot_chunks),
                              self.pass_chunks * self.n_pixels)

    def lanes(self, mi, first_chunk: int, end_chunk: int, counts):
        """The pass [first_chunk, end_chunk): its PassLayout, chunk size, and per pixel
        with samples in it (pixel-major lanes) the pixel, its first lane and its lane
        count."""
        import drjit as dr

        from .path_steps import PassLayout

        K, chunk, n_pixels = self.group_size, self.chunk, self.n_pixels
        s0 = first_chunk * chunk
        if counts is None:
            samples = min(self.spp, end_chunk * chunk) - s0
            chunk_size = min(chunk, samples)
            layout = PassLayout(mi, n_pixels, samples, dr.opaque(mi.UInt32, s0), K)
            pixels, per_pixel = np.arange(n_pixels), np.full(n_pixels, samples)
        else:  # each pixel its own number of chunks: lanes from host arrays
            chunk_size = chunk
            per_pixel = np.clip(counts - s0, 0, (end_chunk - first_chunk) * chunk)
            pixels = np.flatnonzero(per_pixel)
            per_pixel = per_pixel[pixels]
            lane_pixel = np.repeat(pixels, per_pixel)
            first_lane = np.repeat(np.cumsum(per_pixel) - per_pixel, per_pixel)
            lane_sample = s0 + np.arange(lane_pixel.size) - first_lane
            layout = PassLayout.of_lanes(mi, lane_pixel, lane_sample, K)
        return layout, chunk_size, (pixels, np.cumsum(per_pixel) - per_pixel, per_pixel)


class Accumulator:
    """A render's sums, by source pixel, deterministic whatever the passes.

    ``total``: per pixel and film offset, each channel's sum of filter weight x value
    (importance film: one offset, weight 1), then, with the sampled-weight
    normalization, each offset's sum of weights. The splat film keeps it in Dr.Jit
    between passes (integrators/film.py); the importance film's chunk sums are added
    on the host in float64, in chunk order. In the adaptive pilot, each pixel's own
    sums and sums of squared group sums (``pilot_sums``, ``squares``)."""

    def __init__(self, mi, setup, n_pixels: int, channels: int, adaptive: bool):
        self.mi, self.n_pixels, self.channels = mi, n_pixels, channels
        self.splat = setup.splat
        offsets = 1 if self.splat is None else len(self.splat.offsets)
        self.columns = offsets * channels
        # (a box weighs every sample 1 in its own pixel: both normalizations are the count)
        self.normalization = ("expected" if offsets == 1
                              else setup.params.film_normalization)
        if self.normalization == "weights":
            self.columns += offsets
        #: whether samples are weighted into their neighbours (the splat film, wider than
        #: a box): the sums then live on the device
        self.weighted = self.splat is not None and offsets > 1
        self.group_size = setup.group_size
        self.adaptive = adaptive

    def start(self):
        """Zero sums (allocated here, after the budget check)."""
        n, c = self.n_pixels, self.channels
        self.restore(np.zeros((n, self.columns)), 0, np.zeros((n, c)) if self.adaptive else None,
                     np.zeros((n, c)) if self.adaptive else None, fresh=True)

    def restore(self, total, nonfinite, pilot_sums, squares, fresh=False):
        import drjit as dr

        from ..backend import aligned_host_array

        self.total, self.nonfinite = total, nonfinite
        self.pilot_sums, self.squares = pilot_sums, squares
        self.device_total = None  # one Float64 array over the pixels per column
        if self.weighted:
            self.device_total = [dr.zeros(self.mi.Float64, self.n_pixels) if fresh
                                 else self.mi.Float64(aligned_host_array(column, np.float64))
                                 for column in total.T]

    def host_total(self):
        if self.weighted:
            return np.stack([np.asarray(t) for t in self.device_total], axis=-1)
        return self.total

    def add(self, value, film_offset, chunk_size: int, threads, pilot: bool):
        """Add a pass's per-lane values (and film offsets) to the sums; ``threads``:
        per pixel with samples in the pass, the pixel, its first lane and its lanes."""
        import drjit as dr

        mi, K, n_pixels = self.mi, self.group_size, self.n_pixels
        pixels, _, lanes = threads
        block_pixel = np.repeat(pixels, lanes // chunk_size)  # each chunk's pixel
        dr.eval(value, film_offset if self.weighted else None)  # one path tracing kernel
        # ---- Drop non-finite samples and sum each chunk (sequential reductions) ----
        raw = [value[c] for c in range(_channels(value))]
        finite = dr.isfinite(raw[0])
        for v in raw[1:]:
            finite &= dr.isfinite(v)
        dropped = dr.count(~finite)
        channels = [dr.select(finite, v, 0.0) for v in raw]

        def chunk_sums(values):
            return [dr.block_sum(v, chunk_size, mode="evaluated") for v in values]

        if self.weighted:  # the splat: per film offset, weight x value (and the weights)
            self.device_total = self.splat.accumulate(
                mi, self.device_total, raw, film_offset, *threads, chunk_size,
                self.normalization == "weights")
            sums = []
        else:
            sums = chunk_sums(channels)
        if pilot:  # the samples' sums, and the squared sums of the groups (K samples)
            sums += chunk_sums(channels) if self.weighted else []
            sums += [dr.block_sum(dr.square(dr.block_sum(v, K, mode="evaluated")),
                                  chunk_size // K, mode="evaluated") for v in channels]
        dr.eval(dropped, sums)
        self.nonfinite += int(dropped[0])
        parts = np.empty((block_pixel.size, len(sums)))
        for i, v in enumerate(sums):
            parts[:, i] = np.asarray(v)
        # chunk order per pixel, whatever the passes: the image ignores pass sizes
        # (the importance film's sums are both its total and, in the pilot, the pixel's
        # own sums; the squared group sums come last)
        c = self.channels
        for pixels_j, rows in (_chunk_columns(block_pixel, n_pixels) if sums else ()):
            if not self.weighted:
                self.total[pixels_j] += parts[rows, :self.columns]
            if pilot:
                self.pilot_sums[pixels_j] += parts[rows, :c]
                self.squares[pixels_j] += parts[rows, -c:]

    def splat_weight(self, per_pixel, shape) -> np.ndarray:
        """(H, W): the splat film's normalizing weight of every pixel (weighted sums)."""
        mean = self.host_total().T / per_pixel[None, :]
        return splat_weight(self.splat, mean, self.channels, shape, self.normalization)

    def image(self, per_pixel, shape) -> np.ndarray:
        """float32 (H, W, C): the sums divided by ``per_pixel`` samples (and, splat
        film, the filter's weights)."""
        total = self.host_total()
        if self.splat is None:
            return (total / per_pixel[:, None]).astype(np.float32).reshape(*shape, -1)
        return _develop_splat(self.splat, total, per_pixel, self.channels, shape,
                              self.normalization).astype(np.float32)


def render_result(integrator, scene, spp: int | None = None, seed: int = 0, params=None, *,
                  progress: bool | None = None, max_lanes: int = DEFAULT_MAX_LANES,
                  pass_chunks: int | None = None, checkpoint=None) -> RenderResult:
    """Render ``scene`` (a DopplerScene) with ``integrator`` (a DopplerToFPath: the
    render traces passes with its :meth:`prepared` copy); see :func:`dopplertof.render`.

    ``checkpoint`` (a path) saves the accumulated chunks after every pass and resumes
    from them: the final image is bitwise the one of an uninterrupted render. It is
    refused for a different render (scene and the content of every file it references,
    parameters, spp, seed, variant). A complete checkpoint returns the image at once;
    delete the file when the output is safe.
    """
    mi, p, spp, seed = _resolve(scene, spp, seed, params)
    width, height = (int(v) for v in scene.sensor.film().crop_size())
    setup = integrator.prepared(scene, p, spp, int(seed))
    plan = PassPlanner(spp, setup.group_size, width * height, p, max_lanes, pass_chunks)
    channels = _spectrum_channels(mi)
    sums = Accumulator(mi, setup, width * height, channels, p.adaptive_sampling)

    _check_budget(width, height, channels, spp, plan, p, sums, progress)
    sums.start()

    # ---- Resume ----
    saved = None if checkpoint is None else Checkpoint(checkpoint, render_key(
        scene, p.image_defining(), spp, seed, mi.variant(), plan.chunk, GROUPS_PER_CHUNK),
        scene.inputs)
    next_chunk, counts = (saved and saved.load(sums)) or (0, None)
    render = _Passes(mi, setup, plan, sums, saved, counts if p.adaptive_sampling else None,
                     next_chunk, progress)

    # ---- Trace: every pixel at spp, or the adaptive pilot, the counts, the rest ----
    try:
        if not p.adaptive_sampling:
            render.run(plan.uniform(next_chunk))
        else:
            render.run(plan.pilot(next_chunk))  # the first chunks of every pixel
            if render.counts is None:  # from the neighbours' pilot variance
                render.counts = _adaptive_counts(
                    sums.pilot_sums, sums.squares, plan.pilot_chunks * plan.chunk,
                    setup.group_size, spp, plan.chunk, (height, width))
            render.run(plan.adaptive(render.counts, next_chunk))
    except _TimedOut:
        pass
    finally:
        render.bar.close()
    return render.result(seed, (height, width))


class _Passes:
    """A render's passes traced into its sums, with a progress bar, a checkpoint after
    every pass and the timeout (checked between passes); then its result."""

    def __init__(self, mi, setup, plan: PassPlanner, sums: Accumulator, saved, counts,
                 next_chunk: int, progress):
        from tqdm import tqdm

        self.mi, self.setup, self.plan, self.sums, self.saved = mi, setup, plan, sums, saved
        self.counts = counts  #: samples per pixel (adaptive, once known), else None
        self.reached = next_chunk  #: chunks of every pixel traced so far (where it has them)
        self.started = _time.perf_counter()
        spp, chunk = plan.spp, plan.chunk
        done = (min(spp, next_chunk * chunk) if counts is None
                else float(np.minimum(counts, next_chunk * chunk).mean()))
        #: samples per pixel (mean) that a resumed checkpoint held, else None
        self.resumed_from = done if next_chunk else None
        self.bar = tqdm(total=spp, initial=done, unit="spp", desc="rendering",
                        disable=not _show_progress(progress), leave=False, file=sys.stderr)

    def run(self, passes) -> None:
        """Trace the passes; the timeout stops the render after the pass it expires in."""
        plan, sums, timeout = self.plan, self.sums, self.setup.params.timeout
        for first_chunk, end_chunk in passes:
            layout, chunk_size, threads = plan.lanes(self.mi, first_chunk, end_chunk,
                                                     self.counts)
            value, film_offset = self.setup.trace(layout)
            sums.add(value, film_offset, chunk_size, threads,
                     pilot=sums.squares is not None and first_chunk < plan.pilot_chunks)
            self.bar.update(threads[2].sum() / plan.n_pixels)
            if self.saved is not None:
                self.saved.save(sums, end_chunk, self.counts)
            self.reached = end_chunk
            if timeout >= 0 and _time.perf_counter() - self.started > timeout:
                raise _TimedOut

    def result(self, seed: int, shape) -> RenderResult:
        """The image, normalized by the samples taken, and its metadata."""
        p, spp, chunk, counts = self.setup.params, self.plan.spp, self.plan.chunk, self.counts
        per_pixel, timed_out = _samples_taken(
            np.full(self.plan.n_pixels, spp) if counts is None else counts, spp,
            self.reached * chunk, p.timeout, self.saved is not None)
        _check_nonfinite(self.sums.nonfinite, float(per_pixel.sum()), self.setup.modulation)
        image = self.sums.image(per_pixel, shape)
        metadata = _metadata(self.mi, self.setup, p, spp, seed, per_pixel, timed_out,
                             self.sums.nonfinite, self.started)
        warning = keyframe_coverage_warning(self.setup.scene.keyframe_span,
                                            self.setup.shutter_open, metadata["exposure_s"])
        if warning:  # (for the caller to say: the render command prints it)
            metadata["warnings"] = [warning]
        if self.resumed_from is not None:  # (the render command says it resumed)
            metadata["resumed_from_samples"] = self.resumed_from
        if counts is None:
            return RenderResult(image, metadata)
        metadata["sample_counts"] = {"pilot": self.plan.pilot_chunks * chunk,
                                     "min": int(counts.min()), "max": int(counts.max()),
                                     "mean": float(counts.mean())}
        return RenderResult(image, metadata, counts.reshape(shape))


def _check_budget(width, height, channels, spp, plan, p, sums, progress) -> None:
    """Refuse what cannot fit before allocating anything; announce long renders."""
    from .. import budget

    cost = budget.check(budget.estimate(
        width, height, channels, spp, plan.chunk, plan.pass_chunks, p.adaptive_sampling,
        sums.columns, device_columns=sums.columns if sums.weighted else 0))
    if progress is not False and cost.seconds > budget.LONG_RENDER_SECONDS:
        print(f"dopplertof: rendering {cost.describe()}", file=sys.stderr, flush=True)


def _check_nonfinite(dropped: int, traced: float, modulation) -> None:
    """Say on stderr how many of the ``traced`` samples were non-finite and dropped
    (whenever any were); above MAX_NONFINITE_FRACTION of them the image is not a
    measurement: a ParameterError or SceneError naming the count and the likely cause."""
    if not dropped:
        return
    share = dropped / max(traced, 1.0)
    counted = (f"{dropped} of {traced:.0f} samples ({share:.2%}) were non-finite (NaN or "
               "infinite)")
    if share <= MAX_NONFINITE_FRACTION:
        print(f"dopplertof: {counted} and dropped", file=sys.stderr, flush=True)
        return
    error, cause = _nonfinite_cause(modulation)
    raise error(f"{counted}, more than the {MAX_NONFINITE_FRACTION:.0%} a render may drop; "
                f"likely cause: {cause}")


def _nonfinite_cause(modulation):
    """(error class, text) of what most likely made a render's samples non-finite: a
    modulation phase float32 cannot evaluate, else the scene's values."""
    from ..params import ParameterError
    from ..scene.scene import SceneError

    beat_phase = abs(modulation.omega_d) * modulation.exposure
    if beat_phase > FLOAT32_PHASE_LIMIT:
        return ParameterError, (
            f"hetero_frequency {modulation.hetero_frequency:g} beat periods per exposure: "
            f"the sensor's phase reaches {beat_phase:.3g} rad, beyond what float32 "
            f"evaluates ({FLOAT32_PHASE_LIMIT:.3g} rad); use a smaller hetero_frequency")
    if abs(modulation.psi) > FLOAT32_PHASE_LIMIT:
        return ParameterError, (f"the sensor phase offset {modulation.psi:.3g} rad is beyond "
                                f"what float32 evaluates ({FLOAT32_PHASE_LIMIT:.3g} rad)")
    return SceneError, ("NaN or infinite values in the scene (a texture, an emitter, a "
                        "mesh) or in its parameters")


def _samples_taken(wanted, spp: int, reached: int, timeout: float, resumable: bool):
    """Samples per pixel to normalize by (float64): ``wanted``, unless the timeout
    stopped the render after ``reached`` samples of every pixel; and whether it did."""
    per_pixel = np.minimum(wanted, reached).astype(np.float64)
    timed_out = bool(np.any(per_pixel < wanted))
    if timed_out:
        print(f"dopplertof: timeout of {timeout:g} s expired: stopped after "
              f"{per_pixel.mean():g} of {spp} samples per pixel; the image is "
              "normalized by the samples taken" + ("; the checkpoint resumes the render"
                                                   if resumable else ""), file=sys.stderr)
    return per_pixel, timed_out


def _metadata(mi, setup, p, spp, seed, per_pixel, timed_out, nonfinite, started) -> dict:
    mod = setup.modulation
    return {
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
    return values / splat_weight(splat, mean, channels, shape, normalization)[..., None]


def splat_weight(splat, mean, channels: int, shape, normalization: str):
    """(H, W): each pixel's normalizing weight, the sampled weights' sum shifted into it
    (``mean``: the splat sums by source pixel over their sample counts, columns x
    pixels), or, ``"expected"``, its exact expectation."""
    if normalization == "weights":
        return splat.shift_add(mean[len(splat.offsets) * channels:], shape)[..., 0]
    return splat.expected_weights(shape)


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


def _spectrum_channels(mi) -> int:
    """Channels of a sample's value: RGB for spectral variants (converted per sample),
    else the variant's Spectrum (3 for RGB, 1 for mono)."""
    return 3 if mi.is_spectral else _channels(mi.Spectrum(0.0))


def _channels(value) -> int:
    try:
        return len(value)
    except TypeError:
        return 1


