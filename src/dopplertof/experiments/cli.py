"""Command-line subcommands ``sweep``, ``report`` and ``animate``.

``add_subcommands(subparsers)`` adds them to the main parser; each sets ``func``, which
takes the parsed arguments and returns an exit code: 0 success, 1 when some tasks
failed (the others completed). Bad input raises an exception with a one-line message
before anything runs.
"""

from __future__ import annotations

import argparse
import sys

from ..cli_options import (FOLDER_HELP, HELD_HELP, RES_WITHOUT_CAMERA, add_camera_options,
                           add_defines_option, add_params_option, non_negative_int,
                           parse_pairs, positive_int)
from ..sampling import SEED_LIMIT


def _seconds(text: str) -> float:
    try:
        return float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected seconds (a number), got {text!r}") from None


def _seed_list(text: str) -> tuple:
    try:
        seeds = tuple(int(s) for s in text.split(",") if s.strip())
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"expected comma-separated seeds such as 0,1,2, got {text!r}") from None
    if not seeds or min(seeds) < 0 or max(seeds) >= SEED_LIMIT:
        raise argparse.ArgumentTypeError(f"expected seeds in [0, 2^64), got {text!r}")
    return seeds


def _cluster_options(p) -> None:
    g = p.add_argument_group("cluster")
    g.add_argument("--scheduler", metavar="ADDRESS",
                   help="address of a running Dask scheduler, e.g. tcp://host:8786 "
                        "(default: start a LocalCluster)")
    g.add_argument("--workers", type=positive_int, metavar="N",
                   help="LocalCluster worker processes (default: CPU count, at most 8)")
    g.add_argument("--retries", type=non_negative_int, default=2,
                   help="retries of a failing task before it is reported (default 2)")
    g.add_argument("--variant", help="Mitsuba variant of every worker (default llvm_ad_rgb)")
    g.add_argument("--quiet", action="store_true", help="no progress bar, no summary line")


def add_subcommands(subparsers) -> None:
    from .presets import PRESETS

    s = subparsers.add_parser(
        "sweep", help="render a grid of configurations on Dask (TOML file or --preset)",
        description="Render every point of a sweep grid as one Dask task. A rerun skips "
                    "what is complete. " + HELD_HELP)
    s.add_argument("config", nargs="?", help="sweep configuration (.toml)")
    s.add_argument("-o", "--output", required=True, help=f"results folder ({FOLDER_HELP})")
    s.add_argument("--preset", choices=PRESETS, help="one of the paper's experiments")
    s.add_argument("--scene", help="scene file of a --preset")
    s.add_argument("--spp", type=positive_int, help="samples per pixel of a --preset")
    s.add_argument("--reference-spp", type=positive_int,
                   help="samples per pixel of a --preset's references (default 4096)")
    s.add_argument("--seeds", type=_seed_list, default=(0,),
                   help="seeds of a --preset, comma-separated (default 0)")
    s.add_argument("--quick", action="store_true",
                   help="a --preset with a few values per axis")
    add_defines_option(s)
    s.add_argument("--dry-run", action="store_true",
                   help="check the configuration and list the tasks; render nothing")
    _cluster_options(s)
    s.set_defaults(func=cmd_sweep)

    r = subparsers.add_parser("report", help="figures and a Markdown summary of a sweep",
                              description="Read a sweep results folder; write figures, "
                                          "metrics.csv and summary.md.")
    r.add_argument("results", help="results folder of `dopplertof sweep`")
    r.add_argument("-o", "--output", required=True, help=f"report folder ({FOLDER_HELP})")
    r.set_defaults(func=cmd_report)

    _add_animate(subparsers)


def _add_animate(subparsers) -> None:
    a = subparsers.add_parser(
        "animate", help="render a keyframed scene as a sequence of camera frames on Dask",
        description="Frame k exposes [start + k * period, start + k * period + T]; each "
                    "frame runs the camera pipeline; velocity.gif is written beside them (with "
                    "--camera: a stream at the preset's frame rate, video.mp4 or video.gif, "
                    "docs/cameras.md). " + HELD_HELP)
    a.add_argument("scene", help="Mitsuba 3 XML scene with <animation> keyframes")
    a.add_argument("--frames", type=positive_int, required=True, help="number of frames")
    a.add_argument("-o", "--output", required=True, help=f"frames folder ({FOLDER_HELP})")
    a.add_argument("--frame-period", type=_seconds, metavar="SECONDS",
                   help="time between exposure starts (default: the exposure T)")
    a.add_argument("--start", type=_seconds, metavar="SECONDS",
                   help="exposure start of frame 0 (default: the sensor's shutter_open)")
    a.add_argument("--spp", type=positive_int, help="samples per pixel per capture")
    a.add_argument("--seed", type=non_negative_int, default=0,
                   help="seed of every frame (default 0: noise coherent across frames)")
    a.add_argument("--fps", type=float, help="frames per second of the GIF (default 10); "
                   "with --camera, of the stream (default: the preset's frame_rate_hz)")
    a.add_argument("--previews", action="store_true",
                   help="also write every frame's PNG previews; with --camera (whose "
                   "frames always have theirs), a contact sheet of the stream (contact_sheet.png: its frames' depth, velocity and "
                   "amplitude side by side)")
    add_defines_option(a)
    add_params_option(a, "override an integrator parameter (repeatable)")
    _stream_options(a)
    _cluster_options(a)
    a.set_defaults(func=cmd_animate)


def _stream_options(a) -> None:
    g = a.add_argument_group("camera stream (a preset's depth frames at its frame rate)")
    g.add_argument("--camera", metavar="NAME|FILE.toml",
                   help="a stream of the preset's depth frames: frame k's raw frames start "
                   "at k / fps plus their own start (dopplertof cameras lists them)")
    g.add_argument("--trajectory", metavar="FILE",
                   help="with --camera: the camera's poses, TUM RGB-D format (timestamp tx "
                   "ty tz qx qy qz qw), its first stamp at the scene's shutter_open")
    add_camera_options(g)
    g.add_argument("--noise-seed", type=non_negative_int, metavar="S",
                   help="with --camera: the sensor noise's seed (default 0; each frame "
                   "draws its own from it)")
    g.add_argument("--ambient-irradiance", type=float, metavar="UW_CM2_NM",
                   help="with --camera (an absolute preset): ambient light, uW/cm^2/nm "
                   "(default: the preset's documented condition)")


def _progress(args):
    return False if args.quiet else None


def _sweep_config(args):
    from .config import ConfigError, load_config
    from .presets import preset_config

    defines = parse_pairs(args.defines, "-D")
    if args.preset:
        if args.config:
            raise ConfigError("give a configuration file or --preset, not both")
        return preset_config(args.preset, args.scene, spp=args.spp,
                             reference_spp=args.reference_spp, defines=defines,
                             seeds=args.seeds, quick=args.quick, variant=args.variant)
    if not args.config:
        raise ConfigError("give a sweep configuration (.toml) or --preset NAME --scene SCENE")
    misplaced = [flag for flag, value in (("--scene", args.scene), ("--spp", args.spp),
                                          ("--reference-spp", args.reference_spp),
                                          ("--quick", args.quick or None),
                                          ("--seeds", None if args.seeds == (0,) else 1))
                 if value is not None]
    if misplaced:
        raise ConfigError(f"{misplaced[0]} applies to --preset; set it in the configuration "
                          f"file {args.config} instead")
    config = load_config(args.config)
    if defines or args.variant:
        from dataclasses import replace

        config = replace(config, defines={**config.defines, **defines},
                         variant=args.variant or config.variant)
    return config


def cmd_sweep(args) -> int:
    from .sweep import check_output_folder, partial_tasks, pending_count, run_sweep

    config = _sweep_config(args)
    if args.dry_run:
        check_output_folder(args.output)
        tasks, pending = pending_count(config, args.output)
        print(f"sweep {config.name}: {len(tasks)} tasks "
              f"(references: {sum(t.kind == 'reference' for t in tasks)}), "
              f"{len(pending)} to run, {len(tasks) - len(pending)} complete")
        _print_partial(partial_tasks(tasks), "a run renders them again")
        for task in pending[:20]:
            print(f"  {task.kind}: {task.name}")
        if len(pending) > 20:
            print(f"  ... and {len(pending) - 20} more")
        return 0
    summary = run_sweep(config, args.output, scheduler=args.scheduler, workers=args.workers,
                        retries=args.retries, progress=_progress(args))
    if not args.quiet:
        print(f"sweep {config.name}: {summary.total} tasks: {summary.done} done now, "
              f"{summary.skipped} already complete, {len(summary.failed)} failed "
              f"({summary.seconds:.1f} s) -> {summary.output}")
        _print_partial(summary.partial, "rendered again")
    for name, error in summary.failed:
        print(f"dopplertof: task failed: {name}: {error}", file=sys.stderr)
    return 0 if summary.ok else 1


def _print_partial(names: list, what: str) -> None:
    """The sweep's line on the task folders an earlier run left incomplete."""
    if names:
        shown = ", ".join(names[:5]) + (f" and {len(names) - 5} more" if len(names) > 5 else "")
        print(f"  {len(names)} left incomplete by an earlier run (stopped or abandoned "
              f"midway: no complete.json): {shown}; {what}")


def cmd_report(args) -> int:
    from .report import write_report

    report = write_report(args.results, args.output)
    print(f"report: {len(report.files)} files -> {report.output} ({report.runs} runs, "
          f"{report.with_errors} with errors against a reference, {len(report.missing)} "
          f"incomplete tasks, {len(report.stale)} stale tasks excluded"
          + (", listed in summary.md)" if report.stale else ")"))
    return 0


#: animate's options that a camera stream takes, and those it refuses
STREAM_ONLY = ("trajectory", "res", "noiseless", "noise_seed", "ambient_irradiance")
NOT_STREAM = ("frame_period", "start")


def _check_stream_options(args) -> None:
    from .config import ConfigError

    given = lambda name: getattr(args, name) not in (None, False)  # noqa: E731
    if args.camera is None:
        wrong = [n for n in STREAM_ONLY if given(n)]
        if wrong:
            raise ConfigError(f"--{wrong[0].replace('_', '-')} needs --camera"
                              + (RES_WITHOUT_CAMERA if wrong[0] == "res" else ""))
        return
    wrong = [n for n in NOT_STREAM if given(n)]
    if wrong:
        raise ConfigError(f"--{wrong[0].replace('_', '-')} does not apply to a camera stream "
                          "(its frames start at k / fps; the preset says the rest)")


def _stream(args):
    from .stream import run_stream

    return run_stream(args.scene, args.output, args.frames, args.camera, fps=args.fps,
                      trajectory=args.trajectory, resolution=args.res,
                      spp=args.spp, seed=args.seed, noise=not args.noiseless,
                      noise_seed=args.noise_seed or 0,
                      ambient_irradiance=args.ambient_irradiance,
                      defines=parse_pairs(args.defines, "-D"),
                      params=parse_pairs(args.params, "-P"), variant=args.variant,
                      scheduler=args.scheduler, workers=args.workers, retries=args.retries,
                      progress=_progress(args), previews=args.previews)


def cmd_animate(args) -> int:
    from .animate import run_animation

    _check_stream_options(args)
    if args.camera is not None:
        summary = _stream(args)
        if not args.quiet:
            print(f"animate: a stream of {summary.frames} frames through {args.camera}: "
                  f"{summary.done} done now, {summary.skipped} already complete, "
                  f"{len(summary.failed)} failed ({summary.seconds:.1f} s) -> "
                  f"{summary.video or summary.output}")
        return _report(summary)
    summary = run_animation(args.scene, args.output, args.frames,
                            frame_period=args.frame_period, start=args.start, spp=args.spp,
                            seed=args.seed, defines=parse_pairs(args.defines, "-D"),
                            params=parse_pairs(args.params, "-P"), variant=args.variant,
                            previews=args.previews,
                            fps=10.0 if args.fps is None else args.fps, scheduler=args.scheduler,
                            workers=args.workers, retries=args.retries,
                            progress=_progress(args))
    if not args.quiet:
        print(f"animate: {summary.frames} frames: {summary.done} done now, {summary.skipped} "
              f"already complete, {len(summary.failed)} failed ({summary.seconds:.1f} s)"
              + (f" -> {summary.video}" if summary.video else f" -> {summary.output}"))
    return _report(summary)


def _report(summary) -> int:
    """The warnings and failed frames of an animation or a stream; the exit code."""
    for warning in summary.warnings:
        print(f"dopplertof: warning: {warning}", file=sys.stderr)
    for name, error in summary.failed:
        print(f"dopplertof: frame failed: {name}: {error}", file=sys.stderr)
    return 0 if summary.ok else 1
