"""Animations: a keyframed scene seen as a sequence of camera frames, one task per frame.

Frame k is an exposure of length T (the scene's, from ``time`` or its shutter) that
starts at ``start + k * frame_period`` (by default ``start`` is the scene's
``shutter_open`` and the period is T: back-to-back exposures). Each frame runs the
camera pipeline (:func:`dopplertof.tof.capture`: homodyne and heterodyne captures,
radiance, velocity and depth reconstruction, exact truth) and writes into
``frames/frame_0000/`` and so on; the driver then writes ``velocity.gif`` (radiance,
reconstructed and true radial velocity, side by side, one colour scale for the whole
animation) and ``animation.json`` beside the frame folders.

The renderer takes the exposure start from the sensor's ``shutter_open``; a frame's
scene is therefore loaded from the scene text with the sensor's ``shutter_open`` and
``shutter_close`` set to the frame's window, and the exposure passed as ``time`` so
that every frame has exactly the same T.
"""

from __future__ import annotations

import math
import os
import time
from dataclasses import dataclass, field

import numpy as np

from ..capture_summary import SUMMARY_JSON, write_summary
from ..outputs import DTOF
from .cluster import DEFAULT_RETRIES, run_in_folder
from .config import ConfigError, check_render_settings, load_scene_facts
from .tasks import (PARAMS_JSON, begin_task, check_unchanged, finish_task, is_complete,
                    package_versions, prepare_worker, remove_partial_files, spec_hash,
                    worker_identity, RENDER_LOCK)

ANIMATION_JSON = "animation.json"
VELOCITY_GIF = "velocity.gif"

#: arrays every frame folder holds (the captures' own .npy files come with them)
FRAME_ARRAYS = tuple(DTOF[name].npy for name in ("velocity", "velocity_gt", "depth",
                                                 "depth_gt", "radiance"))
FRAME_FILES = FRAME_ARRAYS + ("velocity.exr", SUMMARY_JSON, PARAMS_JSON)


@dataclass(frozen=True)
class FrameTask:
    """One frame: an exposure window of the animation, rendered by the camera pipeline."""

    index: int
    name: str  #: frame_0000
    folder: str  #: absolute
    scene: str
    scene_sha256: str  #: of the scene file and every file it references (SceneFacts.sha256)
    defines: dict
    variant: str
    params: dict  #: render parameters (with ``time`` = T)
    spp: int
    seed: int
    shutter_open: float  #: exposure start (s, scene clock)
    shutter_close: float
    previews: bool = False  #: also write the pipeline's PNG previews
    threads: int | None = None

    @property
    def outputs(self) -> tuple[str, ...]:
        return FRAME_FILES

    @property
    def hash(self) -> str:
        return spec_hash({"kind": "frame", "scene_sha256": self.scene_sha256,
                          "defines": self.defines, "variant": self.variant,
                          "params": self.params, "spp": self.spp, "seed": self.seed,
                          "shutter_open": self.shutter_open,
                          "shutter_close": self.shutter_close, "previews": self.previews})


@dataclass
class AnimationSummary:
    frames: int
    skipped: int
    done: int
    failed: list = field(default_factory=list)
    seconds: float = 0.0
    output: str = ""
    video: str | None = None
    warnings: list = field(default_factory=list)  #: for the caller to say (animate prints)

    @property
    def ok(self) -> bool:
        return not self.failed


# ---- Scene with a given exposure window -------------------------------------------------

def scene_text_with_shutter(text: str, shutter_open: float, shutter_close: float,
                            source: str) -> str:
    """The scene XML with its sensor's shutter set to [shutter_open, shutter_close]."""
    from ..scene.sensor_text import set_sensor_properties

    return set_sensor_properties(
        text, [("sensor", "float", "shutter_open", repr(float(shutter_open))),
               ("sensor", "float", "shutter_close", repr(float(shutter_close)))],
        source, "an animation", ConfigError)


def load_frame_scene(path: str, defines: dict, shutter_open: float, shutter_close: float):
    from ..scene import load_string

    with open(path, encoding="utf-8") as f:
        text = f.read()
    text = scene_text_with_shutter(text, shutter_open, shutter_close, path)
    return load_string(text, dict(defines), source=path,
                       base_dir=os.path.dirname(os.path.abspath(path)))


# ---- The frame task ---------------------------------------------------------------------

def run_frame_task(task: FrameTask) -> dict:
    """Render and reconstruct one frame into its folder (runs on a worker)."""
    from .. import file_formats
    from .. import image_files
    from ..tof import capture

    started = time.perf_counter()
    begin_task(task.folder)
    with RENDER_LOCK:
        prepare_worker(task.variant, task.threads)
        scene = load_frame_scene(task.scene, task.defines, task.shutter_open,
                                 task.shutter_close)
        check_unchanged(task.scene, scene, task.scene_sha256, "animation")
        result = capture(scene, spp=task.spp, seed=task.seed, params=dict(task.params),
                         progress=False)
    if task.previews:
        result.write(task.folder)
    else:
        for name, image in result.captures.items():
            file_formats.write_npy(os.path.join(task.folder, f"{name}.npy"), image)
        arrays = {"velocity": result.velocity, "velocity_gt": result.velocity_gt,
                  "depth": result.depth, "depth_gt": result.depth_gt,
                  "radiance": result.radiance}
        for name, array in arrays.items():
            file_formats.write_npy(os.path.join(task.folder, DTOF[name].npy), DTOF[name].array(array))
        write_summary(os.path.join(task.folder, SUMMARY_JSON), "dtof", result.summary)
    image_files.write_exr(os.path.join(task.folder, "velocity.exr"),
                 np.asarray(result.velocity, dtype=np.float32),
                 {"quantity": "radial velocity, m/s, > 0 receding",
                  "exposure_start_s": task.shutter_open})
    seconds = time.perf_counter() - started
    file_formats.write_json(os.path.join(task.folder, PARAMS_JSON), {
        "frame": task.index, "exposure_start_s": task.shutter_open,
        "exposure_end_s": task.shutter_close, "params": task.params, "spp": task.spp,
        "seed": task.seed, "scene": task.scene, "scene_sha256": task.scene_sha256,
        "defines": task.defines, "variant": task.variant, "task_seconds": seconds,
        "versions": package_versions(), "worker": worker_identity(), "spec_hash": task.hash,
    })
    finish_task(task.folder, task.hash, task.outputs, seconds)
    return {"task": task.name, "seconds": seconds}


# ---- Planning and running -----------------------------------------------------------------

def plan_animation(scene, output, frames: int, *, frame_period: float | None = None,
                   start: float | None = None, spp: int | None = None, seed: int = 0,
                   defines: dict | None = None, params: dict | None = None,
                   variant: str | None = None, previews: bool = False) -> list[FrameTask]:
    """Every frame task, checked (scene, parameters, times) before anything runs."""
    from ..arguments import check_seed
    from ..backend import DEFAULT_VARIANT
    from ..params import RenderParams

    scene = os.path.abspath(os.fspath(scene))
    if not os.path.isfile(scene):
        raise ConfigError(f"scene file not found: {scene}")
    if isinstance(frames, bool) or not isinstance(frames, int) or frames < 1:
        raise ConfigError(f"--frames must be a positive integer, got {frames!r}")
    seed = check_seed(seed, "--seed", ConfigError)
    variant = variant or DEFAULT_VARIANT
    defines = {k: str(v) for k, v in (defines or {}).items()}
    facts = load_scene_facts(scene, defines, variant)
    spp = facts.spp if spp is None else spp
    if isinstance(spp, bool) or not isinstance(spp, int) or spp < 1:
        raise ConfigError(f"--spp must be a positive integer, got {spp!r}")
    resolved = check_render_settings(dict(params or {}), spp, facts, "animation parameters")
    exposure = resolved.exposure(facts.shutter_interval)
    period = exposure if frame_period is None else float(frame_period)
    if not (math.isfinite(period) and period > 0):
        raise ConfigError(f"--frame-period must be > 0 seconds, got {frame_period!r}")
    first = facts.shutter_open if start is None else float(start)
    if not math.isfinite(first):
        raise ConfigError(f"--start must be a finite time in seconds, got {start!r}")
    given = {k: getattr(resolved, k) for k in RenderParams.names()
             if k in (params or {})}
    given["time"] = exposure
    output = os.path.abspath(os.fspath(output))
    tasks = []
    for k in range(frames):
        opens = first + k * period
        name = f"frame_{k:04d}"
        tasks.append(FrameTask(index=k, name=name, folder=os.path.join(output, name),
                               scene=scene, scene_sha256=facts.sha256, defines=defines,
                               variant=variant, params=given, spp=spp, seed=seed,
                               shutter_open=opens, shutter_close=opens + exposure,
                               previews=previews))
    return tasks


def frames_past_keyframes(tasks, span) -> str | None:
    """A warning naming the frames whose exposure ends after the last keyframe (``span``:
    the scene's first and last keyframe times; None: nothing moves), else None: there
    everything holds its last pose and the motion stops, as precision's check points
    beyond the scene's shutter may."""
    if span is None:
        return None
    slack = 1e-6 * (tasks[0].shutter_close - tasks[0].shutter_open)  # (rounding)
    past = [t.index for t in tasks if t.shutter_close > span[1] + slack]
    if not past:
        return None
    which = f"frame {past[0]}" if len(past) == 1 else f"frames {past[0]} to {past[-1]}"
    return (f"{which} of {len(tasks)} end after the last keyframe ({span[1]:g} s): there "
            "everything holds its last pose and the motion stops (velocity 0)")


def run_animation(scene, output, frames: int, *, frame_period: float | None = None,
                  start: float | None = None, spp: int | None = None, seed: int = 0,
                  defines: dict | None = None, params: dict | None = None,
                  variant: str | None = None, previews: bool = False, fps: float = 10.0,
                  scheduler: str | None = None, workers: int | None = None, client=None,
                  retries: int = DEFAULT_RETRIES, progress=None) -> AnimationSummary:
    """Render every frame not already complete, then write the velocity GIF."""
    from .. import io
    from .sweep import check_output_folder

    started = time.perf_counter()
    if not (isinstance(fps, (int, float)) and math.isfinite(fps) and fps > 0):
        raise ConfigError(f"--fps must be > 0, got {fps!r}")
    output = check_output_folder(os.fspath(output))
    tasks = plan_animation(scene, output, frames, frame_period=frame_period, start=start,
                           spp=spp, seed=seed, defines=defines, params=params,
                           variant=variant, previews=previews)
    with io.held_folder(output):  # the frames' folders go in it; no other run meanwhile
        warning = frames_past_keyframes(tasks, load_scene_facts(
            tasks[0].scene, tasks[0].defines, tasks[0].variant).keyframe_span)
        summary = run_frame_tasks(run_frame_task, tasks, output, [warning] if warning else [],
                                  scheduler=scheduler, workers=workers, client=client,
                                  retries=retries, progress=progress)
        # ---- the video and animation.json: one output set, all or nothing (no video of an
        # earlier run stays beside an animation.json without one)
        with io.output_folder(output, "animation") as staged:
            if summary.ok:
                write_velocity_gif(tasks, staged.path(VELOCITY_GIF), fps)
                summary.video = os.path.join(output, VELOCITY_GIF)
            summary.seconds = time.perf_counter() - started
            _write_animation_json(staged.path(ANIMATION_JSON), tasks, summary, fps,
                                  frame_period)
    return summary


def run_frame_tasks(run_task, tasks, output: str, warnings: list, *, scheduler, workers,
                    client, retries: int, progress) -> AnimationSummary:
    """Run ``run_task`` on every frame task not already complete (a partial folder's
    files removed first), on Dask; the run's summary (its seconds still to set)."""
    pending = []
    for task in tasks:
        if is_complete(task.folder, task.hash, task.outputs):
            continue
        if os.path.isdir(task.folder):
            remove_partial_files(task.folder)
        pending.append(task)
    summary = AnimationSummary(frames=len(tasks), skipped=len(tasks) - len(pending), done=0,
                               output=output, warnings=warnings)
    if pending:
        outcome = run_in_folder(run_task, pending, output, scheduler=scheduler,
                                workers=workers, client=client, retries=retries,
                                progress=progress, description="frames",
                                already_done=summary.skipped)
        summary.done = len(outcome.done)
        summary.failed = outcome.failed
    return summary


def _write_animation_json(path, tasks, summary, fps, frame_period) -> None:
    from .. import file_formats

    file_formats.write_json(path, {
        "scene": tasks[0].scene, "frames": len(tasks), "fps": fps,
        "exposure_s": tasks[0].params["time"],
        "frame_period_s": (tasks[1].shutter_open - tasks[0].shutter_open
                           if len(tasks) > 1 else frame_period),
        "exposure_starts_s": [t.shutter_open for t in tasks],
        "spp": tasks[0].spp, "seed": tasks[0].seed, "params": tasks[0].params,
        "video": os.path.basename(summary.video) if summary.video else None,
        "warnings": summary.warnings,
        "last_run": {"done": summary.done, "skipped": summary.skipped,
                     "failed": [{"task": n, "error": e} for n, e in summary.failed],
                     "seconds": round(summary.seconds, 3)},
    })


# ---- The video ------------------------------------------------------------------------------

def _velocity_limit(frames_gt, frames_rec) -> float:
    for stack in (frames_gt, frames_rec):
        values = np.abs(np.concatenate([f.ravel() for f in stack]))
        values = values[np.isfinite(values) & (values > 0)]
        if values.size:
            return 1.25 * float(np.percentile(values, 99.5))
    return 1.0


def write_velocity_gif(tasks, path: str, fps: float) -> str:
    """Radiance, reconstructed and true radial velocity per frame, as an animated GIF."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    from PIL import Image

    from .. import image_files, previews
    from ..tof.figures import RADIANCE_GAMMA_LABEL, radiance_norm, radiance_top
    from ..videos import write_gif

    load = lambda t, name: np.load(os.path.join(t.folder, name))  # noqa: E731
    velocity = [load(t, "velocity.npy") for t in tasks]
    truth = [load(t, "velocity_gt.npy") for t in tasks]
    radiance = [np.asarray(load(t, "radiance.npy"), np.float64) for t in tasks]
    radiance = [r.mean(axis=-1) if r.ndim == 3 else r for r in radiance]
    vlim = _velocity_limit(truth, velocity)
    extend = previews.colorbar_extend(np.concatenate([np.ravel(v) for v in velocity + truth]),
                                      -vlim, vlim)  # (the same bar, arrows by every frame)
    norm = radiance_norm(radiance_top(*radiance))
    images = []
    for task, rad, vel, gt in zip(tasks, radiance, velocity, truth):
        fig = Figure(figsize=(9.6, 3.4), dpi=90, layout="constrained")
        FigureCanvasAgg(fig)
        axes = fig.subplots(1, 3)
        shown = axes[0].imshow(rad, cmap="gray", norm=norm, interpolation="nearest")
        axes[0].set_title(f"radiance ({RADIANCE_GAMMA_LABEL})", fontsize=9)
        for ax, data, title in ((axes[1], vel, "reconstructed radial velocity"),
                                (axes[2], gt, "true radial velocity")):
            image_files.show_no_signal(ax, data.shape)
            shown = ax.imshow(np.ma.masked_invalid(data), cmap=image_files.no_signal_colours("RdBu_r"),
                              vmin=-vlim, vmax=vlim, interpolation="nearest", zorder=1)
            ax.set_title(title, fontsize=9)
        for ax in axes:
            ax.set_axis_off()
        bar = fig.colorbar(shown, ax=list(axes[1:]), shrink=0.85, extend=extend)
        bar.set_label("m/s (+ receding, − approaching;\nhatched magenta: NaN)", fontsize=8)
        fig.suptitle(f"frame {task.index}: exposure {task.shutter_open * 1e3:.4g}–"
                     f"{task.shutter_close * 1e3:.4g} ms", fontsize=10)
        image_files.wrap_texts(fig)  # (the label fits the frame's height, whatever its size)
        fig.canvas.draw()
        rgba = np.asarray(fig.canvas.buffer_rgba())
        images.append(Image.fromarray(rgba[..., :3].copy()))
    write_gif(path, images, fps)
    return path
