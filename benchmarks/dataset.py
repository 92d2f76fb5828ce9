"""Samples per hour of ``dopplertof dataset`` at 128x128 on this machine, 1 and 2 workers.

The example configuration (examples/dataset.toml) at ``--res`` and ``--spp``, rendered
into a fresh folder by a LocalCluster of 1 and then of N workers (the command's own
path: one Dask task per shard, one shard per sample so that the workers share the
load). Each run starts its own cluster; its samples per hour count the render phase
(run_tasks' time: cluster start-up excluded, each worker's first kernels included), so
a longer run (--samples) says more about a long dataset. Printed side by side, with
the speed-up and the per-worker efficiency.

    .venv/bin/python benchmarks/dataset.py [--res 128] [--spp 16] [--samples 8] [--workers 2]
"""

from __future__ import annotations

import argparse
import os
import shutil
import tempfile
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
EXAMPLE = os.path.join(ROOT, "examples", "dataset.toml")


def run_once(res: int, spp: int, samples: int, workers: int) -> dict:
    """One dataset into a temporary folder: samples per hour and wall seconds."""
    from dataclasses import replace

    from dopplertof.dataset import load_config
    from dopplertof.dataset.driver import run_dataset

    config = load_config(EXAMPLE)
    values = {section: dict(keys) for section, keys in config.values.items()}
    values[""].update(samples=samples, samples_per_shard=1)
    values["render"].update(resolution=[res, res], spp=spp)
    config = replace(config, values=values)
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


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--res", type=int, default=128)
    ap.add_argument("--spp", type=int, default=16)
    ap.add_argument("--samples", type=int, default=8)
    ap.add_argument("--workers", type=int, default=2, help="the second run's workers")
    args = ap.parse_args(argv)

    rows = [run_once(args.res, args.spp, args.samples, n) for n in (1, args.workers)]
    print(f"dopplertof dataset: examples/dataset.toml at {args.res}x{args.res}, {args.spp} spp "
          f"per raw frame, {args.samples} samples, {os.cpu_count()} CPUs")
    print(f"{'workers':>8} {'samples/h':>10} {'wall s':>8} {'speed-up':>9} {'per worker':>11}")
    base = rows[0]["samples_per_hour"]
    for row in rows:
        speedup = row["samples_per_hour"] / base
        print(f"{row['workers']:>8} {row['samples_per_hour']:>10.0f} {row['wall_s']:>8.1f} "
              f"{speedup:>8.2f}x {speedup / row['workers']:>10.0%}")


if __name__ == "__main__":
    main()
