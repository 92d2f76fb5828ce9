"""Camera streams: a camera preset's depth frames at its frame rate, one task per frame.

Frame k of a stream at F frames per second starts at t0 + k / F on the scene's clock
(t0 the scene's ``shutter_open``): its raw frames expose [t0 + k / F + start_j,
t0 + k / F + start_j + T_j], each raw frame's own start and integration time from the
preset, so the scene's motion runs on through the frames on one clock. Each frame is
what ``capture --camera`` writes (:func:`dopplertof.cameras.capture_camera` on the
scene with its shutter window moved by k / F), in ``frame_0000/`` and so on, plus the
radial velocity's truth (``velocity_gt.npy``) where the preset has no velocity of its
own. The sensor's noise of frame k is drawn from its own stream (the noise seed and k),
the renders use the one seed of every frame (as ``animate``'s).

A trajectory file (TUM RGB-D: :mod:`dopplertof.scene.trajectory`) moves the camera:
its first stamp is t0, and each frame's scene gets as its sensor's keyframes the poses
that bracket the frame's raw frames (the camera's illuminator rides with it). Beside the
frames, ``stream.json`` indexes them (times, poses, each frame's errors) and
``groundtruth.txt`` holds the camera's pose at each frame's truth time, in the TUM
format (on the trajectory's clock where one is given, else the scene's), and once every
frame is complete the stream's depth, velocity and amplitude as a video at its frame rate
(``video.mp4`` or ``video.gif``: :mod:`dopplertof.videos`), with ``previews`` a contact
sheet of its frames too.

Frames run on Dask as the animation's do (:mod:`.animate`): a frame with a valid
completion marker is not rendered again, and a resumed stream is bitwise the same as
one run uninterrupted.
"""

from __future__ import annotations

import math
import os
import sys
import time
from dataclasses import dataclass

import numpy as np

from ..capture_summary import SUMMARY_JSON, read_capture
from ..outputs import CAMERA, CAMERA_JSON
from ..scene.inputs import file_sha256
from .animate import AnimationSummary, frames_past_keyframes, run_frame_tasks
from .cluster import DEFAULT_RETRIES
from .config import ConfigError
from .tasks import (PARAMS_JSON, RENDER_LOCK, begin_task, check_unchanged, finish_task,
                    is_complete, package_versions, prepare_worker, spec_hash,
                    worker_identity)

STREAM_JSON = "stream.json"
GROUNDTRUTH_TXT = "groundtruth.txt"
#: the stream's video (.mp4 or .gif: dopplertof.videos) and its --previews contact sheet
STREAM_VIDEO, CONTACT_SHEET = "video", "contact_sheet.png"
#: files every complete frame folder holds
FRAME_FILES = (SUMMARY_JSON, CAMERA_JSON.name, *(CAMERA[name].npy for name in (
    "raw", "depth", "depth_gt", "velocity_gt")), PARAMS_JSON)


@dataclass(frozen=True)
class StreamFrameTask:
    """One depth frame of a stream."""

    index: int
    name: str  #: frame_0000
    folder: str  #: absolute
    scene: str
    scene_sha256: str  #: of the scene file and every file it references
    camera: str  #: the preset's file
    camera_sha256: str  #: of the preset's file
    defines: dict
    variant: str
    resolution: tuple | None  #: (width, height); None: the preset's
    params: dict  #: integrator parameter overrides
    spp: int | None  #: None: the scene's
    seed: int
    noise: bool
    noise_seed: int  #: this frame's sensor noise seed
    ambient_irradiance: float | None
    shutter_open: float  #: the frame's start t0 + k / F (s, scene clock)
    shutter_close: float  #: its raw frames' end (s, scene clock)
    camera_keyframes: dict | None = None  #: {"times", "matrices"} of the sensor, or None
    threads: int | None = None

    @property
    def outputs(self) -> tuple[str, ...]:
        return FRAME_FILES

    @property
    def hash(self) -> str:
        described = {k: v for k, v in vars(self).items()
                     if k not in ("index", "name", "folder", "threads")}
        return spec_hash({"kind": "stream frame", **described})


def frame_noise_seed(noise_seed: int, index: int) -> int:
    """The sensor noise seed of frame ``index`` of a stream with ``noise_seed``: a 64-bit
    word of NumPy's SeedSequence of the two (independent draws per frame)."""
    return int(np.random.SeedSequence([int(noise_seed), int(index)])
               .generate_state(1, np.uint64)[0])


# ---- The frame task -------------------------------------------------------------------

def _keyframes(task: StreamFrameTask):
    from ..scene.motion import Keyframes

    if task.camera_keyframes is None:
        return None
    return Keyframes.create(task.camera_keyframes["times"], task.camera_keyframes["matrices"],
                            "rigid", f"{task.name}'s camera")


def run_stream_frame_task(task: StreamFrameTask) -> dict:
    """Capture one depth frame into its folder (runs on a worker)."""
    from .. import file_formats
    from ..cameras.capture import capture_camera
    from ..cameras.scene_view import load_scene_for_camera
    from ..cameras.preset import load_preset

    started = time.perf_counter()
    begin_task(task.folder)
    with RENDER_LOCK:
        prepare_worker(task.variant, task.threads)
        preset = load_preset(task.camera)
        if file_sha256(preset.source_file) != task.camera_sha256:
            raise RuntimeError(f"{task.camera} changed since the stream was planned; rerun it")
        scene = load_scene_for_camera(task.scene, preset, task.resolution, task.defines,
                                      camera_keyframes=_keyframes(task))
        check_unchanged(task.scene, scene, task.scene_sha256, "stream")
        scene = scene.with_shutter(task.shutter_open, task.shutter_close - task.shutter_open)
        result = capture_camera(scene, preset, spp=task.spp, seed=task.seed,
                                params=dict(task.params) or None, noise=task.noise,
                                noise_seed=task.noise_seed, progress=False,
                                ambient_irradiance=task.ambient_irradiance)
    written = [os.path.basename(p) for p in result.write(task.folder)]
    truth = CAMERA["velocity_gt"]
    if truth.npy not in written:  # (a preset without velocity: the truth still)
        file_formats.write_npy(os.path.join(task.folder, truth.npy), truth.array(result.velocity_gt))
    seconds = time.perf_counter() - started
    file_formats.write_json(os.path.join(task.folder, PARAMS_JSON), {
        "frame": task.index, "frame_start_s": task.shutter_open,
        "sequence_end_s": task.shutter_close, "camera": task.camera,
        "resolution": task.resolution, "params": task.params, "spp": task.spp,
        "seed": task.seed, "noise": task.noise, "noise_seed": task.noise_seed,
        "ambient_irradiance": task.ambient_irradiance, "scene": task.scene,
        "scene_sha256": task.scene_sha256, "defines": task.defines, "variant": task.variant,
        "trajectory_keyframes": task.camera_keyframes, "task_seconds": seconds,
        "versions": package_versions(), "worker": worker_identity(), "spec_hash": task.hash,
    })
    finish_task(task.folder, task.hash, task.outputs, seconds)
    return {"task": task.name, "seconds": seconds}


# ---- Planning ---------------------------------------------------------------------------

@dataclass(frozen=True)
class StreamPlan:
    """The checked tasks of a stream and what its index needs."""

    tasks: list
    fps: float
    camera: str  #: the preset's name
    trajectory: object = None  #: the Trajectory, or None
    warning: str | None = None
    #: the room lights the loader leaves out of every frame (an absolute preset's,
    #: :func:`dopplertof.cameras.scene_view.room_light_note`) and the note saying so
    left_out_lights: tuple = ()
    note: str | None = None


def _stream_fps(preset, fps) -> float:
    if fps is None:
        if preset.frame_rate_hz is None:
            raise ConfigError(f"{preset.source_file}: no frame_rate_hz: give the stream's "
                              "--fps")
        fps = preset.frame_rate_hz
    if isinstance(fps, bool) or not isinstance(fps, (int, float)) \
            or not (math.isfinite(fps) and fps > 0):
        raise ConfigError(f"--fps must be a positive number of frames per second, got {fps!r}")
    from ..cameras.preset import sequence_too_long

    problem = sequence_too_long(preset, float(fps))
    if problem:
        raise ConfigError(f"{preset.source_file}: {problem}")
    return float(fps)


def _check_capture(scene, preset, spp, seed, params, noise, noise_seed, ambient) -> None:
    """What :func:`dopplertof.cameras.capture_camera` would refuse of every frame, now."""
    from ..arguments import check_camera_capture
    from ..cameras.capture import _ambient_irradiance, _base_params
    from ..cameras.preset import CameraPreset
    from ..tof.capture import check_spp_seed

    check_camera_capture(scene, preset, spp, seed, params or None, noise, noise_seed, None,
                         None, CameraPreset)
    _ambient_irradiance(preset, ambient)
    check_spp_seed(_base_params(scene, preset, params or None),
                   scene.spp if spp is None else spp, seed)


def _frame_keyframes(trajectory, k: int, fps: float, window, t0: float):
    """The sensor's keyframes of frame k as plain lists (None without a trajectory)."""
    if trajectory is None:
        return None
    kf = trajectory.keyframes(k / fps + window[0], k / fps + window[1], t0)
    return {"times": list(kf.times), "matrices": [list(map(list, m)) for m in kf.matrices]}


def _moving_span(scene):
    """(first, last) keyframe time of what moves on its own (bodies, keyframed lights),
    the camera's own motion left out (a trajectory's stretch is no scene's end)."""
    motions = [b.motion for b in scene.bodies] + [m for _, m in scene.light_motions
                                                  if m is not scene.sensor_motion]
    if not motions:
        return None
    return (min(float(m.times[0]) for m in motions), max(float(m.times[-1]) for m in motions))


def plan_stream(scene, output, frames: int, camera, *, fps=None, trajectory=None,
                resolution=None, spp=None, seed: int = 0, noise: bool = True,
                noise_seed: int = 0, ambient_irradiance=None, defines=None, params=None,
                variant=None) -> StreamPlan:
    """Every frame task, checked (scene, preset, frame rate, trajectory) before anything
    runs; a bad value raises one line naming it. ``resolution``: (width, height) or
    ``"WIDTHxHEIGHT"``; None: the preset's."""
    from ..arguments import check_seed
    from ..backend import DEFAULT_VARIANT
    from ..cameras.scene_view import load_scene_for_camera, parse_resolution, room_light_note
    from ..cameras.preset import load_preset, sequence_window
    from ..scene.inputs import scene_file_digest
    from ..scene.trajectory import read_tum

    scene = os.path.abspath(os.fspath(scene))
    if not os.path.isfile(scene):
        raise ConfigError(f"scene file not found: {scene}")
    if isinstance(frames, bool) or not isinstance(frames, int) or frames < 1:
        raise ConfigError(f"--frames must be a positive integer, got {frames!r}")
    seed = check_seed(seed, "--seed", ConfigError)
    noise_seed = check_seed(noise_seed, "--noise-seed", ConfigError)
    if isinstance(resolution, str):
        resolution = parse_resolution(resolution)
    preset = load_preset(camera)
    fps = _stream_fps(preset, fps)
    path = trajectory
    trajectory = None if path is None else read_tum(path)
    variant = variant or DEFAULT_VARIANT
    defines = {k: str(v) for k, v in (defines or {}).items()}
    window = sequence_window(preset)
    import dopplertof
    from ..scene.kinds import keep_common_alive

    dopplertof.set_variant(variant)
    keep_common_alive()  # (before the scene: kernels shared with the capture command's)
    probe = load_scene_for_camera(scene, preset, resolution, defines)
    _check_capture(probe, preset, spp, seed, params, noise, noise_seed, ambient_irradiance)
    t0 = probe.shutter_open
    keyframes = [_frame_keyframes(trajectory, k, fps, window, t0) for k in range(frames)]
    if trajectory is not None:  # (the scene with the camera's motion: it loads)
        load_scene_for_camera(scene, preset, resolution, defines,
                              camera_keyframes=trajectory.keyframes(*window, t0))
    output = os.path.abspath(os.fspath(output))
    tasks = [StreamFrameTask(
        index=k, name=f"frame_{k:04d}", folder=os.path.join(output, f"frame_{k:04d}"),
        scene=scene, scene_sha256=scene_file_digest(scene, probe),
        camera=preset.source_file, camera_sha256=file_sha256(preset.source_file),
        defines=defines, variant=variant,
        resolution=None if resolution is None else tuple(int(v) for v in resolution),
        params={k2: v for k2, v in (params or {}).items()}, spp=spp, seed=seed,
        noise=bool(noise), noise_seed=frame_noise_seed(noise_seed, k),
        ambient_irradiance=ambient_irradiance, shutter_open=t0 + k / fps,
        shutter_close=t0 + k / fps + window[1],
        camera_keyframes=keyframes[k]) for k in range(frames)]
    warning = frames_past_keyframes(tasks, _moving_span(probe))
    return StreamPlan(tasks, fps, preset.name, trajectory, warning, probe.left_out_lights,
                      room_light_note(probe, preset))


# ---- Running ----------------------------------------------------------------------------

def run_stream(scene, output, frames: int, camera, *, scheduler=None, workers=None,
               client=None, retries: int = DEFAULT_RETRIES, progress=None,
               previews: bool = False, **options) -> AnimationSummary:
    """Capture every frame not already complete, then write stream.json,
    groundtruth.txt and the video (when every frame is complete; ``previews``: also the
    contact sheet). ``options``: those of :func:`plan_stream`."""
    from .. import io

    started = time.perf_counter()
    output = io.check_output_folder(os.fspath(output))
    plan = plan_stream(scene, output, frames, camera, **options)
    if plan.note:  # (once for the stream; every frame's summary.json lists them)
        print(f"dopplertof: note: {plan.note}", file=sys.stderr)
    with io.held_folder(output):  # (another run's folder: refused before any change)
        summary = run_frame_tasks(run_stream_frame_task, plan.tasks, output,
                                  [plan.warning] if plan.warning else [], scheduler=scheduler,
                                  workers=workers, client=client, retries=retries,
                                  progress=progress)
        with io.output_folder(output, "stream") as staged:
            entries = [] if summary.failed else [_frame_entry(t, plan) for t in plan.tasks]
            if entries:
                written = write_stream_video(staged.path, plan, entries, previews)
                summary.video = os.path.join(output, written[0])
            summary.seconds = time.perf_counter() - started
            write_stream_index(staged.path, plan, summary)
        return summary


def write_stream_video(path, plan: StreamPlan, entries, sheet: bool) -> list:
    """The stream's depth, velocity and amplitude as a video at its frame rate (and with
    ``sheet`` a contact sheet of up to SHEET_FRAMES frames), each at ``path(name)``;
    returns the names written."""
    from ..videos import (depth_velocity_amplitude, draw_frames, sheet_indices,
                          video_extension, write_contact_sheet, write_video)

    folders = [os.path.join(os.path.dirname(plan.tasks[0].folder), e["folder"])
               for e in entries]
    load = lambda name: np.stack([np.load(os.path.join(f, CAMERA[name].npy))  # noqa: E731
                                  for f in folders])
    measured = os.path.isfile(os.path.join(folders[0], CAMERA["velocity"].npy))
    maps = depth_velocity_amplitude(load("depth"), load("velocity" if measured else
                                                        "velocity_gt"),
                                    load("amplitude"), not measured, load("depth_gt"))
    times = [f"frame {e['index']}, t = {e['truth_time_s']:.4f} s" for e in entries]
    names = [STREAM_VIDEO + video_extension()]
    write_video(path(names[0]), draw_frames(maps, [f"{plan.camera}: {t}" for t in times]),
                plan.fps)
    if sheet:
        names.append(CONTACT_SHEET)
        write_contact_sheet(path(CONTACT_SHEET), maps,
                            {k: times[k] for k in sheet_indices(len(entries))},
                            f"{plan.camera}: {len(entries)} frames at {plan.fps:g} fps")
    return names


def _frame_entry(task: StreamFrameTask, plan: StreamPlan) -> dict:
    """stream.json's entry of a complete frame: its times, its pose at the truth's time
    and its errors (from its summary.json and camera.json)."""
    import json

    summary = read_capture(task.folder, "camera")
    with open(os.path.join(task.folder, "camera.json"), encoding="utf-8") as f:
        geometry = json.load(f)
    truth_time = float(summary["ground_truth_time_s"])
    return {"index": task.index, "folder": task.name,
            "frame_start_s": task.shutter_open, "sequence_s": summary["sequence_s"],
            "truth_time_s": truth_time, "timestamp": _stamp(plan, truth_time, task),
            "pose_camera_to_world": geometry["pose_camera_to_world"],
            "raw_frames": [{"name": f["name"], "window_s": f["window_s"],
                            "pose_camera_to_world": f["pose_camera_to_world"]}
                           for f in geometry.get("frames", [])],
            "noise_seed": task.noise_seed, "errors": summary["errors"]}


def _stamp(plan: StreamPlan, scene_time: float, task: StreamFrameTask):
    """A frame's timestamp: on the trajectory's clock (its first stamp at the scene's
    t0), else the scene's (s)."""
    from decimal import Decimal

    if plan.trajectory is None:
        return Decimal(repr(scene_time))
    t0 = plan.tasks[0].shutter_open
    return plan.trajectory.first_stamp + Decimal(repr(scene_time - t0))


def write_stream_index(path, plan: StreamPlan, summary: AnimationSummary) -> None:
    """stream.json and groundtruth.txt (``path(name)``: where each goes) of the frames
    complete now (the failed ones are listed, not indexed)."""
    from .. import file_formats
    from ..scene.trajectory import write_tum

    failed = {name for name, _ in summary.failed}
    entries = [_frame_entry(t, plan) for t in plan.tasks
               if t.name not in failed and is_complete(t.folder, t.hash, t.outputs)]
    write_tum(path(GROUNDTRUTH_TXT), [(e["timestamp"], np.asarray(e["pose_camera_to_world"]))
                                      for e in entries])
    first = plan.tasks[0]
    file_formats.write_json(path(STREAM_JSON), {
        "scene": first.scene, "camera": plan.camera, "camera_file": first.camera,
        "fps": plan.fps, "frame_count": len(plan.tasks), "t0_s": first.shutter_open,
        "clock": ("timestamps on the trajectory's clock: its first stamp is the scene's "
                  "t0_s" if plan.trajectory is not None else "timestamps on the scene's "
                  "clock (s)"),
        "trajectory": None if plan.trajectory is None else plan.trajectory.path,
        "groundtruth": GROUNDTRUTH_TXT,
        "video": os.path.basename(summary.video) if summary.video else None,
        "spp": first.spp, "seed": first.seed,
        "noise": first.noise, "resolution": first.resolution, "params": first.params,
        "frames": [{**e, "timestamp": f"{e['timestamp']:.9f}"} for e in entries],
        "warnings": summary.warnings,
        **({"room_lights_left_out": list(plan.left_out_lights)} if plan.left_out_lights
           else {}),
        "last_run": {"done": summary.done, "skipped": summary.skipped,
                     "failed": [{"task": n, "error": e} for n, e in summary.failed],
                     "seconds": round(summary.seconds, 3)},
    })

