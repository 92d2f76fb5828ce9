"""``dopplertof dataset``: every shard not yet complete, one Dask task each.

Output folder::

    DIR/
      dataset.json            the configuration, its hash, the layout and units, the
                              shards, failed samples, the last run's samples per hour
      shard_00000.h5 ...      samples [0, S), [S, 2S), ... (S = samples_per_shard)
      meshes/                 a copy of the mesh folder (the scenes name meshes/NAME)
      logs/workers.log        the workers' stderr (local cluster)

A rerun with the same configuration skips the complete shards (a killed run resumes at
the first unfinished one; its samples depend on (configuration, seed, index) only, so
the result is bitwise the same). A shard is complete when it holds every sample planned
for it and every checksum matches (:func:`shards.shard_state`, every sample read): a
missing, truncated, damaged or misplaced shard, or one with a failed sample, is
rendered again. Another configuration in the same folder is refused.
dataset.json holds the SHA-256 of the rest of its content (``sha256``); a reader, verify
and export refuse one that does not match it, or whose shard list or units are not those
its own samples, samples_per_shard and layout plan (:func:`dataset_json_problem`); a rerun
writes it again.
A sample that raises is tried again ``retries`` times within its shard's task, then
its shard is written without it and dataset.json lists it with its error.
"""

from __future__ import annotations

import json
import os
import time
from dataclasses import dataclass, field

from ..experiments.cluster import DEFAULT_RETRIES, run_in_folder
from .config import DatasetConfig, DatasetError
from .shards import shard_name, shard_state

DATASET_JSON = "dataset.json"
#: dataset.json's key holding the SHA-256 of its other keys (:func:`json_digest`)
JSON_DIGEST = "sha256"
#: format of the folder (2: with the camera's outputs, incidence, grazing and
#: truth_valid, redrawn samples; 3: camera_depth_std and velocity_point, formerly
#: camera_confidence and velocity_along_ray; 4: camera_mask_unlit); a reader reads
#: READABLE_LAYOUTS
LAYOUT_VERSION = 4
READABLE_LAYOUTS = (1, 2, 3, 4)
#: the splits a reader offers: what ``raw`` is in each (docs/dataset.md)
SPLITS = {"full": "raw", "ideal": "raw_ideal", "direct": "raw_direct"}


@dataclass(frozen=True)
class ShardTask:
    """One shard: the samples it holds, rendered in order by one worker."""

    number: int
    name: str  #: shard_00000 (also the Dask task's name)
    path: str  #: absolute
    config: DatasetConfig
    indices: tuple
    config_hash: str
    variant: str
    sample_retries: int = DEFAULT_RETRIES
    threads: int | None = None

    @property
    def hash(self) -> str:
        return self.config_hash


@dataclass
class DatasetSummary:
    samples: int
    shards: int
    skipped_shards: int
    rendered: int = 0  #: samples rendered by this run
    failed: list = field(default_factory=list)  #: [{"index", "error"}], every run's
    failed_shards: list = field(default_factory=list)  #: (shard, error) of this run
    seconds: float = 0.0
    samples_per_hour: float | None = None
    output: str = ""

    @property
    def ok(self) -> bool:
        return not self.failed and not self.failed_shards


def config_hash(config: DatasetConfig, variant: str) -> str:
    """What defines the samples: the configuration, the camera preset's and the meshes'
    contents and the Mitsuba variant (not where the preset file lies: the same dataset
    from another checkout or install is the same dataset)."""
    from ..cameras.preset import load_preset
    from ..experiments.tasks import spec_hash

    preset = load_preset(config["render"]["camera"]).describe()
    for where in ("source_file", "file"):
        preset.pop(where, None)
    return spec_hash({"config": config.to_json(), "camera": preset,
                      "meshes": mesh_digests(config), "variant": variant,
                      "layout": LAYOUT_VERSION})


def mesh_digests(config: DatasetConfig) -> list:
    """[file name, sha256] of every mesh the configuration may draw."""
    from ..scene.inputs import file_sha256
    from .config import mesh_files
    from .generate import mesh_folder

    if "mesh" not in config["objects"]["shapes"]:
        return []
    return [[os.path.basename(path), file_sha256(path)]
            for path in mesh_files(mesh_folder(config))]


def copy_meshes(config: DatasetConfig, output: str) -> None:
    """The mesh folder's files into ``output/meshes`` (each atomically), so that the
    dataset holds everything its scenes reference."""
    import shutil

    from .. import io
    from .config import mesh_files
    from .generate import MESH_DIR, mesh_folder

    if "mesh" not in config["objects"]["shapes"]:
        return
    for path in mesh_files(mesh_folder(config)):
        with io.atomic_path(os.path.join(output, MESH_DIR, os.path.basename(path))) as tmp:
            shutil.copyfile(path, tmp)


def plan_shards(config: DatasetConfig, output: str, variant: str,
                retries: int = DEFAULT_RETRIES) -> list:
    """Every shard of the dataset, in order."""
    digest = config_hash(config, variant)
    return [ShardTask(n, shard["file"][:-3], os.path.join(output, shard["file"]), config,
                      tuple(shard["samples"]), digest, variant, retries)
            for n, shard in enumerate(planned_shards(config.samples, config.shard_size))]


def check_variant(variant: str) -> None:
    """Refuse a Mitsuba variant the workers cannot render in, before dataset.json names
    it (a typo claimed the folder: the corrected rerun was refused as "another
    configuration"), or that this machine cannot run (a CUDA variant
    without a GPU, O09)."""
    import mitsuba

    from ..backend import cuda_problem, variant_problem

    problem = variant_problem(variant)
    if problem is None and variant not in mitsuba.variants():
        problem = (f"unknown variant {variant!r}: this Mitsuba has "
                   f"{', '.join(v for v in mitsuba.variants() if variant_problem(v) is None)}")
    if problem is None:  # (a CUDA variant without a GPU would fail every shard)
        problem = cuda_problem(mitsuba, variant)
    if problem:
        raise DatasetError(f"--variant: {problem}")


def check_same_config(output: str, digest: str, source: str) -> None:
    """Refuse a folder that holds a dataset of another configuration. A dataset.json
    edited after it was written (its checksum fails) does not decide: the folder is this
    configuration's when every shard in it is."""
    path = os.path.join(output, DATASET_JSON)
    if not os.path.isfile(path):
        return
    try:
        with open(path, encoding="utf-8") as f:
            info = json.load(f)
        previous = info.get("config_hash")
    except (OSError, ValueError, AttributeError):
        raise DatasetError(f"{path} is unreadable: not a dopplertof dataset folder "
                           "(choose another -o)") from None
    if previous != digest and info.get(JSON_DIGEST) not in (None, json_digest(info)):
        hashes = set(shard_hashes(output).values())
        if hashes <= {digest}:
            return  # (this configuration's shards: dataset.json is written again)
        raise DatasetError(f"{path} was edited after it was written (it does not match its "
                           "checksum) and the shards in the folder are of another "
                           f"configuration than {source}: use a new folder")
    layout = info.get("layout_version")
    if previous != digest and layout != LAYOUT_VERSION:
        raise DatasetError(f"{output} holds a dataset of layout {layout!r}, written by an "
                           f"earlier dopplertof; this one writes layout {LAYOUT_VERSION} "
                           "and adds no shard to it (its samples still read): render into "
                           "a new folder")
    if previous != digest:
        raise DatasetError(f"{output} holds a dataset of another configuration than "
                           f"{source} (config hash {str(previous)[:12]} vs {digest[:12]}): "
                           "use a new folder, or the configuration it was made with")


class EditedDatasetJson(DatasetError):
    """A dataset.json that does not match its checksum or its own plan."""


def json_digest(info: dict) -> str:
    """SHA-256 of dataset.json's content but its JSON_DIGEST key, as written (its
    canonical JSON: sorted keys, no spaces)."""
    import hashlib

    from .. import file_formats

    content = json.loads(json.dumps(file_formats.json_ready({k: v for k, v in info.items()
                                                   if k != JSON_DIGEST}),
                                    default=file_formats.json_default))
    text = json.dumps(content, sort_keys=True, separators=(",", ":"), allow_nan=True)
    return hashlib.sha256(text.encode("utf-8")).hexdigest()


def planned_shards(samples: int, per_shard: int) -> list:
    """[{"file", "samples"}] of ``samples`` samples, ``per_shard`` a shard."""
    return [{"file": shard_name(n), "samples": list(range(start, min(start + per_shard,
                                                                      samples)))}
            for n, start in enumerate(range(0, samples, per_shard))]


def shard_hashes(folder: str) -> dict:
    """{shard file: the config_hash it was written with} of the shards in ``folder``
    (None for one that cannot be read)."""
    import h5py

    out = {}
    for name in sorted(os.listdir(folder)):
        if name.startswith("shard_") and name.endswith(".h5"):
            try:
                with h5py.File(os.path.join(folder, name), "r") as f:
                    out[name] = f.attrs.get("config_hash")
            except (OSError, ValueError):
                out[name] = None
    return out


def dataset_json_problem(folder: str, info: dict) -> str | None:
    """What is wrong with dataset.json's content ``info`` (None: nothing): its checksum
    fails (named by key where the key can be told: the shard list against the one its
    samples and samples_per_shard plan, the units against the shards' units, the
    config_hash against the shards'), or, in a folder written before the checksum, the
    shard list or the units."""
    from .sample import UNITS

    try:
        planned = planned_shards(int(info["samples"]), int(info["samples_per_shard"]))
        listed = [{"file": s["file"], "samples": list(s["samples"])} for s in info["shards"]]
        units = dict(info["units"])
    except (KeyError, TypeError, ValueError) as exc:
        return f"key {exc} missing or malformed"
    if listed != planned:
        names = {s["file"] for s in listed}
        left_out = [s["file"] for s in planned if s["file"] not in names]
        return (f"'shards' lists {len(listed)} shard(s) where 'samples' "
                f"{info['samples']} at 'samples_per_shard' {info['samples_per_shard']} plan "
                f"{len(planned)}" + (f" ({', '.join(left_out)} left out)" if left_out else
                                     " (their samples differ)"))
    for key in sorted(set(units) & set(UNITS)):
        if units[key] != UNITS[key]:
            return f"'units.{key}' is {units[key]!r} where the shards store {UNITS[key]!r}"
    stored = info.get(JSON_DIGEST)
    if stored is None or stored == json_digest(info):
        return None
    others = {h for h in shard_hashes(folder).values() if h is not None}
    if others and info.get("config_hash") not in others:
        return (f"'config_hash' {str(info.get('config_hash'))[:12]} is not the one its "
                f"shards were written with ({', '.join(sorted(h[:12] for h in others))})")
    return "its content does not match its checksum 'sha256' (edited or damaged)"


def load_dataset_json(folder: str) -> dict:
    """``folder``'s dataset.json, of this layout and as written (a DatasetError naming
    the file; EditedDatasetJson where :func:`dataset_json_problem` finds it edited)."""
    path = os.path.join(folder, DATASET_JSON)
    try:
        with open(path, encoding="utf-8") as f:
            info = json.load(f)
    except (OSError, ValueError) as e:
        raise DatasetError(f"{path}: not a dataset folder ({e})") from None
    if not isinstance(info, dict) or info.get("layout_version") not in READABLE_LAYOUTS:
        version = info.get("layout_version") if isinstance(info, dict) else None
        raise DatasetError(f"{path}: layout version {version!r}, this reader reads "
                           f"{', '.join(map(str, READABLE_LAYOUTS))}")
    problem = dataset_json_problem(folder, info)
    if problem is not None:
        source = info.get("config_file") or "its configuration"
        raise EditedDatasetJson(f"{path}: {problem}: not read; a rerun of `dopplertof "
                                f"dataset {source} -o {folder}` writes it again")
    return info


def verify_dataset(folder) -> list:
    """Every shard of the dataset in ``folder`` checked in full (every sample read and
    its checksum compared): [(shard file, planned sample indices, ShardState)];
    EditedDatasetJson where dataset.json itself was edited."""
    from ..arguments import check_path

    folder = check_path(folder, "folder")
    info = load_dataset_json(folder)
    return [(shard["file"], shard["samples"],
             shard_state(os.path.join(folder, shard["file"]), info["config_hash"],
                         shard["samples"]))
            for shard in info["shards"]]


def given_up(task: ShardTask) -> bool:
    """Whether ``task``'s run gave it up: its Dask task was cancelled (the client's Ctrl-C)
    or its output folder is gone (deleted after the run was stopped): then it writes
    nothing (a shard written then, or the folder created again, outlived the run)."""
    from ..experiments.tasks import run_given_up

    return run_given_up(os.path.dirname(task.path))


def run_shard_task(task: ShardTask) -> dict:
    """Render the shard's samples and write the shard (runs on a worker); nothing
    written where the run gave the task up (:func:`given_up`, asked before each sample
    and before the write)."""
    from ..experiments.tasks import RENDER_LOCK, package_versions, prepare_worker
    from .sample import UNITS, render_sample
    from .shards import write_shard

    started = time.perf_counter()
    samples, failed = [], []
    abandoned = {"shard": task.name, "rendered": 0, "failed": [], "given_up": True,
                 "seconds": 0.0}
    with RENDER_LOCK:
        prepare_worker(task.variant, task.threads, common_kinds=False)  # (its own)
        for index in task.indices:
            if given_up(task):
                return abandoned
            error = None
            for _ in range(1 + task.sample_retries):
                try:
                    samples.append(render_sample(task.config, index,
                                                 os.path.dirname(task.path)))
                    error = None
                    break
                except Exception as exc:  # a failing sample is tried again, then listed
                    error = f"{type(exc).__name__}: {' '.join(str(exc).split())}"[:800]
            if error is not None:
                failed.append({"index": index, "error": error})
    versions = package_versions()
    if given_up(task):
        return abandoned
    write_shard(task.path, samples, failed,
                {"config_hash": task.config_hash, "variant": task.variant,
                 "mitsuba": versions["mitsuba"] or "", "dopplertof": versions["dopplertof"]
                 or "", "layout_version": LAYOUT_VERSION}, UNITS)
    return {"shard": task.name, "rendered": len(samples), "failed": failed,
            "seconds": time.perf_counter() - started}


def run_dataset(config: DatasetConfig, output, *, scheduler: str | None = None,
                workers: int | None = None, client=None, retries: int = DEFAULT_RETRIES,
                variant: str | None = None, progress=None) -> DatasetSummary:
    """Render every shard of ``config`` not complete in ``output``; write dataset.json."""
    from .. import io
    from ..backend import DEFAULT_VARIANT

    started = time.perf_counter()
    output = io.check_output_folder(os.fspath(output))
    variant = variant or DEFAULT_VARIANT
    check_variant(variant)  # (before the folder is claimed for it)
    tasks = plan_shards(config, output, variant, retries)
    check_same_config(output, tasks[0].config_hash, config.source)
    with io.held_folder(output):  # (another run's folder: refused before any change)
        summary = DatasetSummary(samples=config.samples, shards=len(tasks), skipped_shards=0,
                                 output=output)
        write_dataset_json(output, config, tasks, summary)  # (claims the folder first)
        copy_meshes(config, output)
        pending = []
        for task in tasks:
            if not shard_state(task.path, task.config_hash, task.indices).complete:
                io.remove_temporaries(task.path)  # (a killed writer's)
                pending.append(task)
        summary.skipped_shards = len(tasks) - len(pending)
        if pending:
            announce_time(config, sum(len(t.indices) for t in pending))
            outcome = run_in_folder(run_shard_task, pending, output, scheduler=scheduler,
                                    workers=workers, client=client, retries=retries,
                                    progress=progress, description="shards",
                                    already_done=summary.skipped_shards)
            summary.rendered = sum(r["rendered"] for r in outcome.done)
            summary.failed_shards = outcome.failed
            if summary.rendered:
                summary.samples_per_hour = summary.rendered * 3600.0 / outcome.seconds
        summary.failed = [f for t in tasks for f in shard_state(
            t.path, t.config_hash, t.indices, full=False).failed]
        summary.seconds = time.perf_counter() - started
        write_dataset_json(output, config, tasks, summary)
        return summary


def announce_time(config: DatasetConfig, samples: int) -> None:
    """Say on stderr what the samples to render take when it is long, as `render` does
    (a dataset with spp = 10**9 ran without a word)."""
    import sys

    from .. import budget
    from ..cameras.preset import load_preset
    from .config import describe_sample, sample_seconds

    frames = len(load_preset(config["render"]["camera"]).frames) * config.clip_frames
    seconds = sample_seconds(config["render"], frames) * samples
    if seconds > budget.LONG_RENDER_SECONDS:
        print(f"dopplertof: dataset: {samples} sample(s), each "
              f"{describe_sample(config['render'], frames)}: roughly "
              f"{budget.duration(seconds)} in all on one worker", file=sys.stderr,
              flush=True)


def write_dataset_json(output: str, config: DatasetConfig, tasks, summary) -> None:
    """dataset.json: what the folder is, how to read it and what the last run did."""
    from .. import file_formats, io
    from .sample import UNITS

    with io.output_folder(output, "dataset") as staged:
        info = {
            "layout_version": LAYOUT_VERSION, "config_hash": tasks[0].config_hash,
            "config": config.to_json(), "config_file": config.source,
            "samples": config.samples, "samples_per_shard": config.shard_size,
            "shards": [{"file": os.path.basename(t.path), "samples": list(t.indices)}
                       for t in tasks],
            "groups": "sample_<index, 8 digits> in each shard",
            "units": UNITS, "splits": SPLITS, "variant": tasks[0].variant,
            "failed_samples": summary.failed,
            "last_run": {"rendered": summary.rendered, "skipped_shards": summary.skipped_shards,
                         "failed_shards": [{"shard": n, "error": e}
                                           for n, e in summary.failed_shards],
                         "seconds": round(summary.seconds, 3),
                         "samples_per_hour": summary.samples_per_hour},
            "documentation": "docs/dataset.md",
        }
        file_formats.write_json(staged.path(DATASET_JSON), {**info, JSON_DIGEST: json_digest(info)})
