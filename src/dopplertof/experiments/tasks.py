"""What a worker does for one task, and how a task folder says it is complete.

A task writes into its own folder. Every file is written atomically (a temporary
file renamed into place) and the completion marker ``complete.json`` is written
last: a folder without a marker, or with a marker for another task description
(its ``spec_hash`` differs), is redone by the next run. A run kills nothing that
is complete.

These functions run inside Dask worker processes: each one sets its own Mitsuba
variant (a variant is per process) and renders under a process-wide lock, since
Dr.Jit already uses every core of the process.
"""

from __future__ import annotations

import glob
import hashlib
import json
import os
import platform
import socket
import threading
import time
from dataclasses import dataclass, field

from ..scene.inputs import scene_file_digest

#: written last into a task folder; its presence (with the right spec hash) means "done"
COMPLETE_MARKER = "complete.json"

#: files of a rendered sweep point
IMAGE_NPY = "image.npy"
IMAGE_EXR = "image.exr"
PARAMS_JSON = "params.json"

#: packages whose versions every task records
RECORDED_PACKAGES = ("dopplertof", "mitsuba", "drjit", "numpy", "dask", "distributed")

#: one render at a time per process: Dr.Jit already uses every core it is given
RENDER_LOCK = threading.Lock()
_SCENE_CACHE: dict = {}
_SCENE_CACHE_SIZE = 4


def spec_hash(description: dict) -> str:
    """A stable hash of what defines a task's result (not where or how fast it runs)."""
    text = json.dumps(description, sort_keys=True, separators=(",", ":"), default=str)
    return hashlib.sha256(text.encode("utf-8")).hexdigest()


@dataclass(frozen=True)
class RenderTask:
    """One render of a sweep: a grid point or a reference."""

    kind: str  #: "run" (a grid point) or "reference"
    name: str  #: folder name, reads as the parameters
    folder: str  #: absolute path of the task folder
    scene: str  #: absolute path of the scene file
    scene_sha256: str  #: of the scene file and every file it references (SceneFacts.sha256)
    defines: dict  #: scene <default> values
    variant: str
    params: dict  #: render parameters given by the configuration (typed)
    spp: int
    seed: int
    grid_point: dict = field(default_factory=dict)  #: the grid values of this point
    reference: str | None = None  #: folder of the reference this run is measured against
    threads: int | None = None  #: Dr.Jit threads in the worker (None: all cores)

    @property
    def outputs(self) -> tuple[str, ...]:
        return (IMAGE_NPY, IMAGE_EXR, PARAMS_JSON)

    def result_description(self) -> dict:
        """Everything the image depends on."""
        return {"kind": "render", "scene_sha256": self.scene_sha256, "defines": self.defines,
                "variant": self.variant, "params": self.params, "spp": self.spp,
                "seed": self.seed}

    @property
    def hash(self) -> str:
        return spec_hash(self.result_description())


# ---- Completion ------------------------------------------------------------------

def is_complete(folder: str, expected_hash: str, outputs) -> bool:
    """True when ``folder`` holds a marker for this task and every listed output."""
    marker = os.path.join(folder, COMPLETE_MARKER)
    try:
        with open(marker, encoding="utf-8") as f:
            info = json.load(f)
    except (OSError, ValueError):
        return False
    if not isinstance(info, dict) or info.get("spec_hash") != expected_hash:
        return False
    return all(os.path.isfile(os.path.join(folder, name)) for name in outputs)


def remove_partial_files(folder: str) -> list[str]:
    """Delete temporary files left by an interrupted atomic write (``.name.XXXX.tmp.ext``).

    Called by the driver before it submits a task, never by a worker: a worker could
    otherwise delete the temporary file of a duplicate of itself still running.
    """
    removed = []
    for path in glob.glob(os.path.join(glob.escape(folder), ".*.tmp*")):
        try:
            os.unlink(path)
            removed.append(path)
        except OSError:
            pass
    return removed


def begin_task(folder: str) -> None:
    """Create the folder and drop an old marker, so that a task killed while it
    rewrites its files is never taken for complete."""
    os.makedirs(folder, exist_ok=True)
    try:
        os.unlink(os.path.join(folder, COMPLETE_MARKER))
    except FileNotFoundError:
        pass


def finish_task(folder: str, task_hash: str, outputs, seconds: float) -> None:
    from .. import file_formats

    file_formats.write_json(os.path.join(folder, COMPLETE_MARKER), {
        "spec_hash": task_hash, "outputs": list(outputs), "seconds": seconds,
        "finished": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
    })


# ---- A run that gave its task up ---------------------------------------------------

def task_abandoned() -> bool:
    """Whether the Dask task this code runs in was given up by its run: the scheduler
    released its key (the client cancelled it on Ctrl-C, or went away), so its result
    would be thrown away; a task then stops before it writes. False outside a Dask task
    (or where this distributed cannot tell)."""
    try:
        from distributed import get_worker

        worker = get_worker()
        key = worker.get_current_task()
        state = worker.state.tasks.get(key)
    except (ImportError, ValueError, AttributeError, KeyError):  # (not on a worker)
        return False
    return state is None or state.state in ("cancelled", "released", "forgotten")


def run_given_up(output: str) -> bool:
    """Whether the run a task belongs to gave it up: its Dask task was cancelled (the
    client's Ctrl-C: :func:`task_abandoned`) or the run's output folder ``output`` is
    gone (deleted after the run was stopped). A task then writes nothing: a file written
    then, or the folder made again, would outlive the run."""
    return task_abandoned() or not os.path.isdir(output)



# ---- Worker environment ------------------------------------------------------------

def package_versions() -> dict:
    from importlib import metadata

    versions = {"python": platform.python_version()}
    for name in RECORDED_PACKAGES:
        try:
            versions[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            versions[name] = None
    return versions


def worker_identity() -> dict:
    return {"host": socket.gethostname(), "pid": os.getpid()}


def prepare_worker(variant: str, threads: int | None, common_kinds: bool = True) -> None:
    """Set this process's Mitsuba variant (once) and Dr.Jit's thread count; with
    ``common_kinds``, keep the common kinds alive (scene/kinds.py) before any scene."""
    import mitsuba as mi

    import dopplertof
    from ..scene.kinds import keep_common_alive

    if mi.variant() != variant:
        dopplertof.set_variant(variant)
    if common_kinds:  # (before any scene: kernels shared with the capture command's)
        keep_common_alive()
    if threads:
        import drjit as dr

        if dr.thread_count() != threads:
            dr.set_thread_count(int(threads))


def cached_scene(path: str, sha256: str, defines: dict, variant: str):
    """The loaded scene, kept per worker process across tasks of the same scene."""
    import dopplertof

    key = (path, sha256, tuple(sorted((k, str(v)) for k, v in defines.items())), variant)
    scene = _SCENE_CACHE.get(key)
    if scene is None:
        scene = dopplertof.load_file(path, dict(defines))
        check_unchanged(path, scene, sha256, "sweep")
        while len(_SCENE_CACHE) >= _SCENE_CACHE_SIZE:
            _SCENE_CACHE.pop(next(iter(_SCENE_CACHE)))
        _SCENE_CACHE[key] = scene
    return scene


def check_unchanged(path: str, scene, sha256: str, what: str) -> None:
    """Refuse to render ``scene`` (loaded from ``path``) when the scene file or a file
    it references changed since the ``what`` was planned with digest ``sha256``."""
    if scene_file_digest(path, scene) != sha256:
        raise RuntimeError(f"{path} or a file it references changed since the {what} was "
                           "planned; rerun it")


# ---- The sweep task -----------------------------------------------------------------

def run_render_task(task: RenderTask) -> dict:
    """Render one sweep point into its folder (runs on a worker); nothing written where
    the sweep gave the task up (its Dask task cancelled, or the sweep's folder deleted:
    :func:`run_given_up`, asked before the render and before the writes)."""
    import dopplertof
    from .. import file_formats, image_files

    started = time.perf_counter()
    sweep_folder = os.path.dirname(os.path.dirname(task.folder))  # (runs/NAME, reference/NAME)
    given_up = {"task": task.name, "seconds": 0.0, "given_up": True}
    if run_given_up(sweep_folder):
        return given_up
    begin_task(task.folder)
    with RENDER_LOCK:
        prepare_worker(task.variant, task.threads)
        scene = cached_scene(task.scene, task.scene_sha256, task.defines, task.variant)
        result = dopplertof.render_result(scene, spp=task.spp, seed=task.seed,
                                          params=dict(task.params), progress=False)
    if run_given_up(sweep_folder):
        return given_up
    image = result.image
    file_formats.write_npy(os.path.join(task.folder, IMAGE_NPY), image)
    image_files.write_exr(os.path.join(task.folder, IMAGE_EXR), image, result.metadata)
    seconds = time.perf_counter() - started
    record = {
        "task": task.name,
        "kind": task.kind,
        "grid_point": task.grid_point,
        "given_params": task.params,
        "params": result.metadata.get("params"),
        "spp": task.spp,
        "seed": task.seed,
        "scene": task.scene,
        "scene_sha256": task.scene_sha256,
        "defines": task.defines,
        "variant": task.variant,
        "reference": task.reference,
        "image_shape": list(image.shape),
        "render_seconds": result.metadata.get("render_seconds"),
        "task_seconds": seconds,
        "render_metadata": result.metadata,
        "versions": package_versions(),
        "worker": worker_identity(),
        "spec_hash": task.hash,
    }
    file_formats.write_json(os.path.join(task.folder, PARAMS_JSON), record)
    finish_task(task.folder, task.hash, task.outputs, seconds)
    return {"task": task.name, "seconds": seconds, "worker": record["worker"]}
