"""The ``dataset`` command: ``add_subcommand(subparsers)`` adds it; exit 0 when every
sample is present, 1 when some failed (listed in dataset.json), 2 on bad input."""

from __future__ import annotations

import sys

from ..cli_options import FOLDER_HELP


def add_subcommand(subparsers) -> None:
    from ..experiments.cli import _cluster_options  # (the sweep's cluster options, as is)

    d = subparsers.add_parser(
        "dataset", help="randomized dynamic scenes rendered on Dask into HDF5 shards",
        description="Render a dataset of random moving scenes (raw frames of three splits, "
                    "depth, velocity, flow, instances, normals, albedo, K, pose). A rerun "
                    "resumes at the first unfinished shard.")
    d.add_argument("config", help="dataset configuration (.toml; examples/dataset.toml)")
    d.add_argument("-o", "--output", required=True, help=f"dataset folder ({FOLDER_HELP})")
    _cluster_options(d)
    d.set_defaults(func=cmd_dataset)


def cmd_dataset(args) -> int:
    from .config import load_config
    from .driver import run_dataset

    config = load_config(args.config)
    summary = run_dataset(config, args.output, scheduler=args.scheduler,
                          workers=args.workers, retries=args.retries, variant=args.variant,
                          progress=False if args.quiet else None)
    if not args.quiet:
        rate = (f", {summary.samples_per_hour:.0f} samples per hour"
                if summary.samples_per_hour else "")
        print(f"dataset: {summary.samples} samples in {summary.shards} shards: "
              f"{summary.rendered} rendered now, {summary.skipped_shards} shards already "
              f"complete, {len(summary.failed)} samples failed ({summary.seconds:.1f} s"
              f"{rate}) -> {summary.output}")
    for failure in summary.failed:
        print(f"dopplertof: sample failed: {failure['index']}: {failure['error']}",
              file=sys.stderr)
    for name, error in summary.failed_shards:
        print(f"dopplertof: shard failed: {name}: {error}", file=sys.stderr)
    return 0 if summary.ok else 1
