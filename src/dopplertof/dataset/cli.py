"""The ``dataset`` command: ``add_subcommand(subparsers)`` adds it; exit 0 when every
sample is present, 1 when some failed (listed in dataset.json), 2 on bad input."""

from __future__ import annotations

import os
import sys

from ..cli_options import FOLDER_HELP, HELD_HELP, TERMINATED_EXIT, Terminated, sigterm_as_interrupt


def add_subcommand(subparsers) -> None:
    from ..experiments.cli import _cluster_options  # (the sweep's cluster options, as is)

    d = subparsers.add_parser(
        "dataset", help="randomized dynamic scenes rendered on Dask into HDF5 shards",
        description="Render a dataset of random moving scenes (raw frames of three splits, "
                    "depth, velocity, flow, instances, normals, albedo, K, pose). A rerun "
                    "resumes at the first unfinished shard. " + HELD_HELP)
    d.add_argument("config", help="dataset configuration (.toml; examples/dataset.toml), "
                                  "or `verify`, `show` or `export` with the dataset folder "
                                  "FOLDER")
    d.add_argument("folder", nargs="?", metavar="FOLDER",
                   help="`dopplertof dataset verify FOLDER`: every sample read and its "
                        "checksum compared; says what a rerun would render again (exit 0: "
                        "nothing, 1: something). `show FOLDER -o preview.png`: a row of "
                        "images per sample. `export FOLDER --format flat|torf -o OUT`")
    d.add_argument("-o", "--output", help=f"dataset folder ({FOLDER_HELP}); required "
                                          "to render; with show: the .png; with export: "
                                          "the folder written")
    d.add_argument("--samples", metavar="I,J,...", help="with show: the items to draw "
                   "(default: the first 4)")
    d.add_argument("--stats", action="store_true", help="with show: one page of the "
                   "dataset's statistics (depths, speeds, objects, valid fractions, the "
                   "camera's error per split) over --samples (default: every item)")
    d.add_argument("--split", default="full", help="with show: full (default), ideal or "
                   "direct")
    d.add_argument("--format", dest="export_format", metavar="flat|torf",
                   help="with export: FLAT's Kinect layout or TöRF's (docs/dataset.md)")
    d.add_argument("--skip-missing", action="store_true", help="with export: export the "
                   "samples present when some failed (listed in export.json's "
                   "missing_samples); without it such a dataset is refused")
    _cluster_options(d)
    d.set_defaults(func=cmd_dataset)


def cmd_dataset(args) -> int:
    from .config import DatasetError, load_config
    from .driver import run_dataset

    if args.config in ("verify", "show", "export") and args.folder is None \
            and not os.path.isfile(args.config):
        raise DatasetError(f"dataset {args.config} needs the dataset FOLDER: `dopplertof "
                           f"dataset {args.config} FOLDER"
                           + {"verify": "`", "show": " -o preview.png`",
                              "export": " --format flat|torf -o OUT`"}[args.config])
    if args.config == "verify" and args.folder is not None:
        return cmd_verify(args.folder)
    if args.config == "show" and args.folder is not None:
        return cmd_show(args)
    if args.config == "export" and args.folder is not None:
        return cmd_export(args)
    if args.folder is not None:
        raise DatasetError(f"unexpected argument {args.folder!r}: `dopplertof dataset CONFIG "
                           "-o DIR` renders, `dopplertof dataset verify DIR` checks, "
                           "`dopplertof dataset show DIR -o preview.png` draws, "
                           "`dopplertof dataset export DIR --format flat -o OUT` exports")
    if args.output is None:
        raise DatasetError("the dataset folder is missing: dopplertof dataset CONFIG -o DIR")
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


def cmd_verify(folder: str) -> int:
    """Check every shard of ``folder`` in full; one line per shard a rerun would render
    again, then the count. Exit 0 when nothing is to redo, 1 otherwise."""
    from .driver import EditedDatasetJson, verify_dataset
    from .shards import index_span

    try:
        checked = verify_dataset(folder)
    except EditedDatasetJson as exc:
        print(exc)
        print("verify: dataset.json edited or damaged, its shards not checked; a rerun "
              "would write dataset.json again and render what is not complete")
        return 1
    redo, present = [], 0
    for name, planned, state in checked:
        if state.problem is not None:
            print(f"{name} (samples {index_span(planned)}): {state.problem}: a rerun renders "
                  "it again")
        else:
            present += len(state.samples)
            for failure in state.failed:
                print(f"{name}: sample {failure['index']} failed ({failure['error']}): a "
                      "rerun tries it again")
        if not state.complete:
            redo.append(name)
    planned = sum(len(p) for _, p, _ in checked)
    print(f"verify: {len(checked)} shards, {len(checked) - len(redo)} complete; {present} of "
          f"{planned} samples present and intact; a rerun would render again: "
          f"{', '.join(redo) if redo else 'nothing'}")
    return 1 if redo else 0


def cmd_show(args) -> int:
    """Draw a row per sample of the dataset folder into the -o PNG."""
    import time

    from .config import DatasetError
    from .show import show_dataset

    if args.output is None:
        raise DatasetError("dataset show needs -o preview.png")
    started = time.perf_counter()
    show_dataset(args.folder, args.samples, args.output, args.split, args.stats)
    print(f"wrote {args.output} ({time.perf_counter() - started:.1f} s)")
    return 0


def cmd_export(args) -> int:
    """Write the dataset folder in FLAT's or TöRF's layout into the new folder -o."""
    from .config import DatasetError
    from .export import FORMATS, export_dataset

    if args.export_format is None:
        raise DatasetError(f"dataset export needs --format ({', '.join(FORMATS)})")
    try:
        with sigterm_as_interrupt():
            info = export_dataset(args.folder, args.export_format, args.output,
                                  args.skip_missing)
    except Terminated:
        print(f"dopplertof: dataset export interrupted (SIGTERM): {args.output} was not "
              f"written; the dataset {args.folder} and every earlier output are intact",
              file=sys.stderr)
        return TERMINATED_EXIT
    print(f"exported {info['samples']} samples as {info['format']} -> {args.output}")
    if info.get("missing_samples"):
        from .shards import index_span

        print(f"dopplertof: dataset export: sample(s) {index_span(info['missing_samples'])} "
              "missing (failed; --skip-missing): not exported", file=sys.stderr)
    return 0
