"""Sweeps: plan every grid point (and its reference) as a task, run what is not done.

Results folder::

    results/
      sweep.json                   the configuration and the task list (read by the report)
      summary.json                 what the last run did: done, skipped, failed (with errors)
      logs/workers.log             the workers' stderr: Dask's logs, failing tasks' tracebacks
      runs/<name>/                 one folder per grid point, name = its grid values
        image.npy image.exr params.json complete.json
      reference/<name>/            one per distinct measurement (what errors are measured against)
"""

from __future__ import annotations

import json
import os
import time
from dataclasses import dataclass, field

from .cluster import DEFAULT_RETRIES, WORKER_LOG, dask_client, run_tasks
from .config import (SweepConfig, check_render_settings, load_scene_facts,
                     measurement_key, point_name, split_point)
from .tasks import (COMPLETE_MARKER, RenderTask, is_complete, remove_partial_files,
                    run_render_task)

SWEEP_JSON = "sweep.json"
SUMMARY_JSON = "summary.json"
RUNS_DIR = "runs"
REFERENCE_DIR = "reference"


@dataclass
class SweepSummary:
    total: int
    skipped: int  #: complete before this run
    done: int  #: completed by this run
    #: task folders an earlier run left without their completion marker (stopped or
    #: abandoned midway), rendered again by this run
    partial: list = field(default_factory=list)
    failed: list = field(default_factory=list)  #: (task name, error)
    seconds: float = 0.0
    output: str = ""
    worker_log: str = ""  #: the workers' stderr (Dask's logs, failing tasks' tracebacks)

    @property
    def ok(self) -> bool:
        return not self.failed

    def to_json(self) -> dict:
        return {"total": self.total, "skipped": self.skipped, "done": self.done,
                "partial_before": list(self.partial),
                "failed": [{"task": n, "error": e} for n, e in self.failed],
                "seconds": round(self.seconds, 3), "output": self.output,
                "worker_log": self.worker_log or None}


def plan_sweep(config: SweepConfig, output: str) -> list[RenderTask]:
    """Every task of the sweep, checked against the scene; raises ConfigError first."""
    from ..backend import DEFAULT_VARIANT

    output = os.path.abspath(output)
    variant = config.variant or DEFAULT_VARIANT
    facts = load_scene_facts(config.scene, config.defines, variant)
    varying_measurement = [k for k in config.grid if k in measurement_key(config.grid)]
    references: dict[str, RenderTask] = {}
    tasks = []
    for point in config.points():
        name = point_name(point)
        params, spp, seed = split_point(config, point)
        spp = facts.spp if spp is None else spp
        check_render_settings(params, spp, facts, f"{config.source}: grid point {name}")
        reference_folder = None
        if config.reference is not None:
            ref_name = point_name({k: point[k] for k in varying_measurement})
            if ref_name not in references:
                ref_params = {**measurement_key(params), **config.reference.params}
                check_render_settings(ref_params, config.reference.spp, facts,
                                      f"{config.source}: reference {ref_name}")
                references[ref_name] = RenderTask(
                    kind="reference", name=ref_name,
                    folder=os.path.join(output, REFERENCE_DIR, ref_name), scene=config.scene,
                    scene_sha256=facts.sha256, defines=config.defines, variant=variant,
                    params=ref_params, spp=config.reference.spp, seed=config.reference.seed,
                    grid_point={k: point[k] for k in varying_measurement})
            reference_folder = os.path.join(REFERENCE_DIR, ref_name)
        tasks.append(RenderTask(
            kind="run", name=name, folder=os.path.join(output, RUNS_DIR, name),
            scene=config.scene, scene_sha256=facts.sha256, defines=config.defines,
            variant=variant, params=params, spp=spp, seed=seed, grid_point=point,
            reference=reference_folder))
    # references first: the report needs them for every error
    return list(references.values()) + tasks


def check_output_folder(output: str) -> str:
    """The absolute results folder, checked before any work (created when written)."""
    from .. import io

    return io.check_output_folder(output)


def pending_tasks(tasks, clean: bool = True) -> list:
    """Tasks without a valid completion marker; with ``clean``, the temporary files an
    interrupted write left in their folders are removed."""
    pending = []
    for task in tasks:
        if is_complete(task.folder, task.hash, task.outputs):
            continue
        if clean and os.path.isdir(task.folder):
            remove_partial_files(task.folder)
        pending.append(task)
    return pending


def partial_tasks(tasks) -> list:
    """The names of the tasks whose folder an earlier run began and did not complete
    (no completion marker: a run stopped, killed or abandoned midway; a marker of other
    settings is a stale task, not a partial one); a run renders them again."""
    return [t.name for t in tasks if os.path.isdir(t.folder)
            and not os.path.isfile(os.path.join(t.folder, COMPLETE_MARKER))]


def pending_count(config: SweepConfig, output) -> tuple[list, list]:
    """(every task, the tasks a run would start): checks everything, writes nothing."""
    tasks = plan_sweep(config, check_output_folder(os.fspath(output)))
    return tasks, pending_tasks(tasks, clean=False)


def write_sweep_files(config: SweepConfig, tasks, output: str, summary=None) -> None:
    """sweep.json (the plan) and, at the end of a run, its summary.json: one output set
    (:func:`dopplertof.io.output_folder`), so that a summary.json never stays beside the
    plan of another run (at the start, the previous run's goes)."""
    from .. import file_formats, io

    with io.output_folder(output, "sweep") as staged:
        write_sweep_json(config, tasks, output, staged.path(SWEEP_JSON))
        if summary is not None:
            file_formats.write_json(staged.path(SUMMARY_JSON), summary.to_json())


def write_sweep_json(config: SweepConfig, tasks, output: str, path: str) -> None:
    from .. import file_formats

    file_formats.write_json(path, {
        "config": config.to_json(),
        "tasks": [{"kind": t.kind, "name": t.name,
                   "folder": os.path.relpath(t.folder, output), "grid_point": t.grid_point,
                   "reference": t.reference, "spp": t.spp, "seed": t.seed,
                   "spec_hash": t.hash}  # (the report calls a run of another spec stale)
                  for t in tasks],
    })


def run_sweep(config: SweepConfig, output, *, scheduler: str | None = None,
              workers: int | None = None, client=None, retries: int = DEFAULT_RETRIES,
              progress=None) -> SweepSummary:
    """Run every task of ``config`` not already complete in ``output``.

    Nothing starts before the whole configuration is checked (against the scene
    too). No cluster is started when everything is complete. The run holds ``output``
    (:func:`dopplertof.io.held_folder`): another run into it is refused meanwhile.
    """
    from .. import io

    started = time.perf_counter()
    output = check_output_folder(os.fspath(output))
    tasks = plan_sweep(config, output)
    with io.held_folder(output):  # (another run's folder: refused before any change)
        write_sweep_files(config, tasks, output)
        partial = partial_tasks(tasks)
        pending = pending_tasks(tasks)
        summary = SweepSummary(total=len(tasks), skipped=len(tasks) - len(pending), done=0,
                               output=output, partial=partial)
        summary_path = os.path.join(output, SUMMARY_JSON)
        if pending:
            reserve_summary(summary_path, summary, len(pending))
            summary.worker_log = os.path.join(output, WORKER_LOG) if client is None else ""
            with dask_client(scheduler, workers, client, summary.worker_log or None) as \
                    (dask, threads):
                if threads:
                    pending = [_with_threads(t, threads) for t in pending]
                outcome = run_tasks(dask, run_render_task, pending, retries=retries,
                                    progress=progress, description="sweep",
                                    already_done=summary.skipped)
            summary.done = len(outcome.done)
            summary.failed = outcome.failed
        summary.seconds = time.perf_counter() - started
        write_summary(config, tasks, output, summary)
        return summary


#: bytes of summary.json kept per pending task, for its failure (task name and error)
SUMMARY_BYTES_PER_TASK = 1024


def reserve_summary(path: str, summary: SweepSummary, pending: int) -> None:
    """Before any task runs: summary.json of this run (nothing done yet), padded with
    spaces to the size the final one takes when every pending task fails, so that a disk
    the tasks fill up still takes the final summary (:func:`write_summary`)."""
    from .. import file_formats, io

    text = json.dumps(file_formats.json_ready(summary.to_json()), indent=2, sort_keys=True)
    with io.atomic_path(path) as tmp:
        with open(tmp, "w", encoding="utf-8") as f:
            f.write(text + "\n" + " " * (SUMMARY_BYTES_PER_TASK * pending) + "\n")


def write_summary(config: SweepConfig, tasks, output: str, summary: SweepSummary) -> None:
    """sweep.json and summary.json, all or nothing (:func:`write_sweep_files`); on a full
    disk, summary.json over the space :func:`reserve_summary` kept (in place: the one
    write that is not atomic, and only when nothing else can be written)."""
    from .. import file_formats, io

    path = os.path.join(output, SUMMARY_JSON)
    try:
        write_sweep_files(config, tasks, output, summary)
    except (OSError, io.WriteError) as e:
        if not io.is_disk_full(e) or not os.path.isfile(path):
            raise
        text = json.dumps(file_formats.json_ready(summary.to_json()), indent=2, sort_keys=True,
                          default=str) + "\n"
        with open(path, "r+", encoding="utf-8") as f:
            f.write(text)
            f.truncate()


def _with_threads(task: RenderTask, threads: int) -> RenderTask:
    from dataclasses import replace

    return replace(task, threads=threads)
