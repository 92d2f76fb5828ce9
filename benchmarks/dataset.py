"""Samples per hour of ``dopplertof dataset`` at 128x128 on this machine, 1 and 2 workers.

The example configuration (examples/dataset.toml) at ``--res`` and ``--spp``, rendered
into a fresh folder by a LocalCluster of 1 and then of N workers (the command's own
path: one Dask task per shard, one shard per sample so that the workers share the
load). Each run starts its own cluster; its samples per hour count the render phase
(run_tasks' time: cluster start-up excluded, each worker's first kernels included), so
a longer run (--samples) says more about a long dataset. Printed side by side, with
the speed-up and the per-worker efficiency.

    .venv/bin/python benchmarks/dataset.py [--res 128] [--spp 16] [--samples 8] [--workers 2]

``--profile`` (issue 40) times the phases of one sample (scene load, renders, readout,
ground truth, the rest of the sample, HDF5 write; and the kernels' compile time in each)
in one process from an empty kernel cache: sample 0, sample 1 right after it, sample 1
again (warm), side by side, with rendering's share of the warm sample (target: 60%).

    .venv/bin/python benchmarks/dataset.py --profile [--camera kinect-v2] [--res 128]

``--cold`` (issue 40) starts from an empty Dr.Jit kernel cache (a temporary folder, for
this process and its workers) and renders, one worker each: the dataset of ``--seed``
(every kernel compiled), the dataset of the next seed right after it (the cache holds
the first one's kernels: what a user's next dataset costs), and that second dataset
again into another folder (warm: every kernel cached). Printed side by side, with the
ratios: the new seed over its warm rerun (target: at most 1.3) and the empty cache over
the warm rerun, and the kernels each run added to the cache (what it compiled: a count
that a shared machine's load does not move, as it moves the seconds).

    .venv/bin/python benchmarks/dataset.py --cold [--camera kinect-v2] [--res 64x53] \
        [--spp 16] [--samples 6]
"""

from __future__ import annotations

import argparse
import os
import shutil
import tempfile
import time

from timing import cache_size, empty_kernel_cache  # (benchmarks/timing.py, beside this script)

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
EXAMPLE = os.path.join(ROOT, "examples", "dataset.toml")


def example_config(res, spp: int, samples: int, seed: int | None = None,
                   camera: str | None = None):
    """examples/dataset.toml at ``res`` ([width, height]) and ``spp``, ``samples`` samples
    one per shard (``seed`` and ``camera``: the example's unless given)."""
    from dataclasses import replace

    from dopplertof.dataset import load_config

    config = load_config(EXAMPLE)
    values = {section: dict(keys) for section, keys in config.values.items()}
    values[""].update(samples=samples, samples_per_shard=1)
    values[""].update({} if seed is None else {"seed": seed})
    values["render"].update(resolution=list(res), spp=spp)
    values["render"].update({} if camera is None else {"camera": camera})
    return replace(config, values=values)


def run_once(res, spp: int, samples: int, workers: int, seed: int | None = None,
             camera: str | None = None) -> dict:
    """One dataset of :func:`example_config` into a temporary folder: samples per hour
    and wall seconds."""
    from dopplertof.dataset.driver import run_dataset

    config = example_config(res, spp, samples, seed, camera)
    folder = tempfile.mkdtemp(prefix="dopplertof-dataset-bench-")
    try:
        started = time.perf_counter()
        summary = run_dataset(config, folder, workers=workers, progress=False)
        wall = time.perf_counter() - started
    finally:
        shutil.rmtree(folder, ignore_errors=True)
    if not summary.ok:
        raise SystemExit(f"{workers} worker(s): failed: {summary.failed or summary.failed_shards}")
    return {"workers": workers, "samples_per_hour": summary.samples_per_hour, "wall_s": wall}


def cold_and_warm(args) -> None:
    """--cold: a dataset from an empty kernel cache, the next seed's right after, and
    that one again (warm), one worker each; printed side by side with their ratios."""
    with empty_kernel_cache() as cache:
        runs = [(f"seed {args.seed}, empty kernel cache", args.seed),
                (f"seed {args.seed + 1}, right after", args.seed + 1),
                (f"seed {args.seed + 1} again (warm)", args.seed + 1)]
        rows = []
        for _, seed in runs:  # (the kernels in the cache after each run: what it compiled)
            rows.append(run_once(args.res, args.spp, args.samples, 1, seed, args.camera))
            rows[-1]["kernels"] = cache_size(cache)[0]
        kernels, megabytes = cache_size(cache)
    width, height = args.res
    print(f"dopplertof dataset: examples/dataset.toml with {args.camera or 'its camera'} at "
          f"{width}x{height}, {args.spp} spp per raw frame, {args.samples} samples, 1 worker, "
          f"{os.cpu_count()} CPUs; the kernel cache ends with {kernels} kernels "
          f"({megabytes:.1f} MB)")
    warm = rows[-1]["wall_s"]
    print(f"{'run':<36} {'wall s':>8} {'samples/h':>10} {'/ warm':>7} {'new kernels':>12}")
    cached = 0
    for (name, _), row in zip(runs, rows):
        print(f"{name:<36} {row['wall_s']:>8.1f} {row['samples_per_hour']:>10.0f} "
              f"{row['wall_s'] / warm:>6.2f}x {row['kernels'] - cached:>12}")
        cached = row["kernels"]
    print(f"new seed / its warm rerun: {rows[1]['wall_s'] / warm:.2f}x (target <= 1.3x); "
          f"empty cache / warm: {rows[0]['wall_s'] / warm:.2f}x")


class PhaseClock:
    """Exclusive wall seconds and kernel compile seconds (Dr.Jit's kernel history: the
    backend's time of the kernels launched) per phase of one dataset sample; a phase
    inside another counts only in itself."""

    def __init__(self):
        self.seconds, self.compile = {}, {}
        self._stack = []  # [name, started, seconds of the phases inside it]

    def _drain(self, name: str) -> None:
        import drjit as dr

        compiled = sum(k.get("backend_time", 0.0) for k in dr.kernel_history()
                       if k["type"] == dr.KernelType.JIT) / 1000
        self.compile[name] = self.compile.get(name, 0.0) + compiled

    def wrap(self, name: str, function):
        """``function``, timed as phase ``name``."""
        def timed(*args, **kwargs):
            if self._stack:
                self._drain(self._stack[-1][0])
            self._stack.append([name, time.perf_counter(), 0.0])
            try:
                return function(*args, **kwargs)
            finally:
                self._drain(name)
                _, started, inner = self._stack.pop()
                spent = time.perf_counter() - started
                self.seconds[name] = self.seconds.get(name, 0.0) + spent - inner
                if self._stack:
                    self._stack[-1][2] += spent
        return timed


#: what the profile times: (phase, module, function name) patched while it runs
PHASES = (("scene load", "dopplertof.scene", "load_string"),
          ("render", "dopplertof.render", "render_result"),
          ("readout", "dopplertof.cameras.sensor", "read_frames"),
          ("ground truth", "dopplertof.dataset.sample", "sample_truth"))


def profiled_sample(config, index: int, folder: str) -> PhaseClock:
    """One sample rendered and written to an HDF5 shard of its own, each phase timed
    (the rest of render_sample as 'other': the scene's draw, demodulation, flows)."""
    import importlib

    import drjit as dr

    from dopplertof.dataset.sample import UNITS, render_sample
    from dopplertof.dataset.shards import write_shard

    clock = PhaseClock()
    saved = []
    for phase, module_name, name in PHASES:
        module = importlib.import_module(module_name)
        saved.append((module, name, getattr(module, name)))
        setattr(module, name, clock.wrap(phase, getattr(module, name)))
    try:
        with dr.scoped_set_flag(dr.JitFlag.KernelHistory, True):
            dr.kernel_history_clear()
            sample = clock.wrap("other", render_sample)(config, index, folder)
            clock.wrap("HDF5 write", write_shard)(
                os.path.join(folder, f"profile-{index}.h5"), [sample], [],
                {"config_hash": "profile"}, UNITS)
    finally:
        for module, name, function in saved:
            setattr(module, name, function)
    return clock


def profile(args) -> None:
    """--profile: sample 0 from an empty kernel cache, sample 1 right after it and sample
    1 again (warm), in one process, phase by phase."""
    with empty_kernel_cache():
        import dopplertof

        dopplertof.set_variant("llvm_ad_rgb")
        config = example_config(args.res, args.spp, 2, args.seed, args.camera)
        folder = tempfile.mkdtemp(prefix="dopplertof-dataset-profile-")
        try:
            clocks = [profiled_sample(config, index, folder) for index in (0, 1, 1)]
        finally:
            shutil.rmtree(folder, ignore_errors=True)
    width, height = args.res
    print(f"one sample of examples/dataset.toml with {args.camera or 'its camera'} at "
          f"{width}x{height}, {args.spp} spp per raw frame (seconds; compile: the kernels' "
          f"LLVM compile time inside the phase)")
    names = ["sample 0, empty cache", "sample 1, right after", "sample 1 again (warm)"]
    print(f"{'phase':<14}" + "".join(f"{n:>24}" for n in names))
    phases = [p for p, _, _ in PHASES] + ["other", "HDF5 write"]
    for phase in phases:
        print(f"{phase:<14}" + "".join(
            f"{c.seconds.get(phase, 0.0):>11.2f} (compile {c.compile.get(phase, 0.0):4.1f})"
            for c in clocks))
    totals = [sum(c.seconds.values()) for c in clocks]
    print(f"{'total':<14}" + "".join(f"{t:>11.2f} (compile {sum(c.compile.values()):4.1f})"
                                     for t, c in zip(totals, clocks)))
    warm = clocks[-1]
    share = (warm.seconds["render"] - warm.compile.get("render", 0.0)) / totals[-1]
    print(f"rendering's share of the warm sample: {share:.0%} (target >= 60%); next sample / "
          f"warm: {totals[1] / totals[2]:.2f}x")


def _resolution(text: str) -> tuple:
    """'128' or '64x53': (width, height)."""
    width, _, height = text.partition("x")
    return int(width), int(height or width)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--res", type=_resolution, default=(128, 128), help="N or WIDTHxHEIGHT")
    ap.add_argument("--spp", type=int, default=16)
    ap.add_argument("--samples", type=int, default=8)
    ap.add_argument("--workers", type=int, default=2, help="the second run's workers")
    ap.add_argument("--cold", action="store_true",
                    help="empty kernel cache, next seed, warm rerun (one worker each)")
    ap.add_argument("--seed", type=int, default=0, help="--cold: the first dataset's seed")
    ap.add_argument("--camera", default=None, help="a camera preset (default: the example's)")
    ap.add_argument("--profile", action="store_true",
                    help="one sample's phases: empty cache, the next sample, warm")
    args = ap.parse_args(argv)
    if args.profile:
        return profile(args)
    if args.cold:
        return cold_and_warm(args)

    rows = [run_once(args.res, args.spp, args.samples, n, camera=args.camera)
            for n in (1, args.workers)]
    width, height = args.res
    print(f"dopplertof dataset: examples/dataset.toml at {width}x{height}, {args.spp} spp "
          f"per raw frame, {args.samples} samples, {os.cpu_count()} CPUs")
    print(f"{'workers':>8} {'samples/h':>10} {'wall s':>8} {'speed-up':>9} {'per worker':>11}")
    base = rows[0]["samples_per_hour"]
    for row in rows:
        speedup = row["samples_per_hour"] / base
        print(f"{row['workers']:>8} {row['samples_per_hour']:>10.0f} {row['wall_s']:>8.1f} "
              f"{speedup:>8.2f}x {speedup / row['workers']:>10.0%}")


if __name__ == "__main__":
    main()
