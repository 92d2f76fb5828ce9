"""Command line: parse, call the library, print. Errors are one line and exit code 2."""

from __future__ import annotations

import argparse
import os
import sys

from .demo import DEMO_RES, DEMO_SPP
from .cli_options import (FOLDER_HELP, add_defines_option, add_params_option, add_variant_option,
                          parse_pairs, print_warnings)


class UsageError(Exception):
    pass


def _version() -> str:
    """The package's version (the one place it is written: dopplertof.__version__)."""
    from . import __version__

    return __version__


def _parser() -> argparse.ArgumentParser:
    """The ``dopplertof`` parser: the global options and one subcommand per command."""
    p = argparse.ArgumentParser(prog="dopplertof",
                                description="Doppler time-of-flight camera simulator",
                                epilog=f"Every command's output folder is {FOLDER_HELP}. A first "
                                "try: `dopplertof demo -o demo_out`; `dopplertof COMMAND "
                                "--help` for a command's options; README.md and docs/*.md "
                                "for the rest.")
    p.add_argument("--debug", action="store_true", help="show tracebacks on errors")
    p.add_argument("--version", action="version", version=f"%(prog)s {_version()}")
    sub = p.add_subparsers(dest="command", required=True)
    # ---- this module's commands (dispatched by name in main)
    _add_render_command(sub)
    _add_capture_command(sub)
    _add_precision_command(sub)
    _add_demo_command(sub)
    _add_figures_command(sub)
    # ---- the commands of the subpackages (each sets its own func)
    from .cameras import cli as cameras_cli
    from .dataset import cli as dataset_cli
    from .diff.cli import add_subcommand
    from .experiments.cli import add_subcommands
    from .fmcw import cli as fmcw_cli

    add_subcommands(sub)  # sweep, report, animate
    add_subcommand(sub)  # fit
    cameras_cli.add_subcommand(sub)  # cameras
    dataset_cli.add_subcommand(sub)  # dataset
    fmcw_cli.add_subcommand(sub)  # fmcw
    for command in set(sub.choices.values()):  # --debug after the command too
        command.add_argument("--debug", action="store_true", default=argparse.SUPPRESS,
                             help="show tracebacks on errors")
    return p


# ---- Options shared by several commands ----------------------------------------------------

def _add_scene_argument(p) -> None:
    """The positional scene file of render, capture and precision."""
    p.add_argument("scene", help="Mitsuba 3 XML scene (may contain <animation>)")


def _add_seed_option(p) -> None:
    """``--seed`` of render, capture and precision."""
    p.add_argument("--seed", type=int, default=0, help="random seed (default 0)")


def _add_noise_options(n) -> None:
    """The sensor model's options (capture and precision; _NOISE_OPTIONS reads them)."""
    n.add_argument("--photons-per-unit", type=float, metavar="K", help="photons/s at a pixel "
                   "per unit of rendered value (default: the brightest pixel fills half the "
                   "full well)")
    n.add_argument("--quantum-efficiency", type=float, metavar="QE", help="default 0.4")
    n.add_argument("--read-noise", type=float, metavar="E", help="electrons rms, default 5")
    n.add_argument("--full-well", type=float, metavar="E", help="electrons, default 20000")
    n.add_argument("--gain", type=float, metavar="E_PER_DN", help="electrons per DN, default 5")
    n.add_argument("--bits", type=int, help="ADC bits, default 12")
    n.add_argument("--ambient", type=float, metavar="PHOTONS_PER_S",
                   help="unmodulated background photons/s per pixel, default 0")
    n.add_argument("--noise-seed", type=int, metavar="S", help="default 0")


# ---- One function per command's arguments --------------------------------------------------

def _add_render_command(sub) -> None:
    """``render``: one D-ToF image of a scene."""
    r = sub.add_parser("render", help="render a D-ToF image of a scene")
    # ---- what to render, and where to
    _add_scene_argument(r)
    r.add_argument("-o", "--output", required=True,
                   help=f"output file: .exr, .npy or .png (its folder {FOLDER_HELP})")
    r.add_argument("--spp", type=int, help="samples per pixel (default: the scene's sampler)")
    _add_seed_option(r)
    add_defines_option(r)
    add_params_option(r, "override an integrator parameter, e.g. -P hetero_frequency=1")
    # ---- how it runs
    add_variant_option(r)
    r.add_argument("--quiet", action="store_true", help="no progress bar")
    # ---- files beside the image
    r.add_argument("--checkpoint", metavar="FILE",
                   help="save progress after every pass and resume from it after a kill "
                   f"(its folder {FOLDER_HELP})")
    r.add_argument("--sample-counts", metavar="FILE",
                   help="with -P adaptive_sampling=true: write the samples traced per pixel "
                   f"(.png map, .npy or .exr; its folder {FOLDER_HELP})")


def _add_capture_command(sub) -> None:
    """``capture``: one camera frame, its reconstruction and its precision and noise
    options."""
    c = sub.add_parser("capture", help="one D-ToF camera frame: captures, velocity and "
                       "depth reconstruction, exact truth, previews and summary.json")
    # ---- what to capture, and where to
    _add_scene_argument(c)
    c.add_argument("-o", "--output", required=True, help=f"output folder ({FOLDER_HELP}); "
                   "it holds camera.json (K, distortion, poses) with every capture")
    c.add_argument("--pointcloud", action="store_true",
                   help="also write pointcloud.ply: the camera's depth unprojected into the "
                   "world, one vertex per pixel (x, y, z, normal, radial velocity and its "
                   "truth, amplitude, valid)")
    c.add_argument("--spp", type=int, help="samples per pixel per capture (default: the "
                   "scene's sampler)")
    _add_seed_option(c)
    add_defines_option(c)
    add_params_option(c, "override an integrator parameter for every capture, e.g. -P w_g=20")
    # ---- the camera's modulation and reconstruction
    c.add_argument("--hetero-frequency", type=float, metavar="H",
                   help="beat periods per exposure of the heterodyne captures, a non-zero "
                   "integer (default: the scene's, else 1)")
    c.add_argument("--unwrap-frequency", type=float, metavar="MHZ",
                   help="second modulation frequency (MHz) to unwrap depth")
    c.add_argument("--min-signal", type=float, metavar="FRACTION",
                   help="velocity/depth are NaN where the homodyne signal is below this "
                   "fraction of the image's 99th percentile (default 0.01)")
    c.add_argument("--ambient-irradiance", type=float, metavar="UW_CM2_NM",
                   help="with --camera (an absolute preset): ambient light on every surface, "
                   "uW/cm^2/nm at the illuminator's wavelength (indoor 2.2, sunlight at "
                   "850 nm about 90; default: the preset's documented condition)")
    c.add_argument("--keep-mixed-pixels", action="store_true",
                   help="reconstruct the pixels whose footprint mixes surfaces (silhouettes: "
                   "a mixture of two surfaces' velocities) instead of NaN")
    # ---- how it runs
    add_variant_option(c)
    c.add_argument("--quiet", action="store_true", help="no progress bar, summary only")
    c.add_argument("--checkpoint", metavar="DIR",
                   help="keep every finished render (capture, raw frame, batch) in DIR; "
                   "after Ctrl-C or a kill the same command renders only the missing ones, "
                   "bitwise as an uninterrupted run (DIR is emptied when the outputs are "
                   f"written; its folder {FOLDER_HELP}); a capture holds DIR while it runs: "
                   "a second one with the same DIR is refused, naming the first")
    # ---- the groups: precision limits, sensor noise
    _add_capture_precision_options(c)
    n = c.add_argument_group("sensor noise (off unless --noise or any option below)")
    n.add_argument("--noise", action="store_true", help="add shot, read and ADC noise")
    _add_noise_options(n)
    from .cameras.cli import add_capture_options

    add_capture_options(c)


def _add_capture_precision_options(c) -> None:
    """The capture's group of predicted standard deviations and the limits set on them."""
    u = c.add_argument_group("precision (predicted per-pixel standard deviations)")
    u.add_argument("--mc-batches", type=int, metavar="B",
                   help="render every capture B times independently (the first is the "
                   "capture, as without) and write velocity_std*.npy / depth_std*.npy "
                   "(Monte Carlo and sensor noise): B x the render time")
    u.add_argument("--max-velocity-std", type=float, metavar="M_S",
                   help="velocity is NaN where its predicted standard deviation is larger "
                   "(implies --mc-batches 8)")
    u.add_argument("--max-depth-std", type=float, metavar="M",
                   help="depth is NaN where its predicted standard deviation is larger")


def _add_precision_command(sub) -> None:
    """``precision``: the predicted precision of a configuration, or a map over ranges."""
    s = sub.add_parser("precision", help="predicted velocity/depth precision of a camera "
                       "configuration; with ranges, a map over frequency x exposure")
    _add_scene_argument(s)
    # ---- the configuration, or the ranges of the map
    s.add_argument("--w-g", default=None, metavar="MHZ|LO:HI",
                   help="modulation frequency in MHz, or a range (default: the scene's)")
    s.add_argument("--exposure", default=None, metavar="S|LO:HI",
                   help="exposure in seconds, or a range (default: the scene's)")
    s.add_argument("--steps", type=int, default=6, help="grid steps per range (default 6)")
    # ---- the pilot frames and the check of the map
    s.add_argument("--spp", type=int, default=64, help="samples per pixel of each pilot "
                   "frame (default 64)")
    s.add_argument("--mc-batches", type=int, default=4, metavar="B",
                   help="independent batches of the pilots (default 4)")
    s.add_argument("--hetero-frequency", type=float, metavar="H",
                   help="beat periods per exposure (default: the scene's, else 1)")
    s.add_argument("--check", type=int, default=3, metavar="N",
                   help="with ranges: simulate N grid points to check the map (default 3)")
    s.add_argument("-o", "--output", metavar="MAP.png",
                   help="with ranges: the map (PNG) and its numbers beside it (.json; its "
                   f"folder {FOLDER_HELP})")
    add_defines_option(s)
    add_params_option(s, "override an integrator parameter")
    _add_seed_option(s)
    add_variant_option(s)
    s.add_argument("--quiet", action="store_true", help="no progress")
    _add_noise_options(s.add_argument_group("sensor (the default noise model unless set)"))


def _add_demo_command(sub) -> None:
    """``demo``: the built-in moving Cornell box."""
    d = sub.add_parser("demo", help="one camera frame of the built-in moving Cornell box")
    d.add_argument("-o", "--output", default="demo_out",
                   help=f"output folder ({FOLDER_HELP}; default demo_out)")
    d.add_argument("--spp", type=int, default=DEMO_SPP, help=f"default {DEMO_SPP}")
    d.add_argument("--res", type=int, default=DEMO_RES, help=f"default {DEMO_RES}")
    add_variant_option(d)
    d.add_argument("--noise", action="store_true", help="add sensor noise (default camera)")
    d.add_argument("--quiet", action="store_true")


def _add_figures_command(sub) -> None:
    """``figures``: the supplementary's analysis."""
    f = sub.add_parser("figures", help="the supplementary's analysis as figures")
    f.add_argument("-o", "--output", default="figures",
                   help=f"output folder ({FOLDER_HELP}; default figures)")
    f.add_argument("--quick", action="store_true", help="small settings")


def _load_scene(args):
    """Set the variant, load the scene with the -D values; say on stderr what the loader
    assumed (stdout is for results)."""
    import dopplertof
    from .scene.kinds import keep_common_alive

    dopplertof.set_variant(args.variant)
    keep_common_alive()  # (before the scene: kernels shared with scenes of other shapes)
    scene = dopplertof.load_file(args.scene, parse_pairs(args.defines, "-D"))
    for note in scene.notes:
        print(f"dopplertof: note: {note}", file=sys.stderr)
    return scene


def _check_before_loading(args, where: str) -> None:
    """What is wrong with the -P values, --spp and --seed, said before Mitsuba and the
    scene load (a usage error in well under a second, not after seconds of start-up);
    the library checks them again against the scene."""
    from .arguments import check_seed
    from .sampling import check_sample_count
    from .scene.parameters import render_values

    render_values(parse_pairs(args.params, "-P"), where)
    if args.spp is not None:
        check_sample_count(1, args.spp)
    check_seed(args.seed, "seed", UsageError)  # (all 64 bits key the random streams)


def _cmd_render(args) -> int:
    import dopplertof
    from . import io
    from . import image_files

    _check_before_loading(args, "render parameters")
    io.check_output_path(args.output)
    if args.sample_counts:
        io.check_output_path(args.sample_counts)
    if args.checkpoint:
        io.check_output_folder(os.path.dirname(os.path.abspath(args.checkpoint)))
    if not os.path.isfile(args.scene):
        raise UsageError(f"scene file not found: {args.scene}")
    scene = _load_scene(args)
    params = parse_pairs(args.params, "-P") or None
    if args.sample_counts and not dopplertof.RenderParams.from_mapping(
            params or {}, where="render parameters", base=scene.params).adaptive_sampling:
        raise UsageError("--sample-counts needs adaptive sample counts: add "
                         "-P adaptive_sampling=true (or set it in the scene)")
    result = dopplertof.render_result(scene, spp=args.spp, seed=args.seed,
                                      params=params,
                                      progress=False if args.quiet else None,
                                      checkpoint=args.checkpoint)
    image_files.write_image(args.output, result.image, result.metadata,
                   **({"title": image_files.render_title(result.metadata)}
                      if args.output.lower().endswith(".png") else {}))
    if args.sample_counts:
        image_files.write_image(args.sample_counts, result.sample_counts.astype("float32"),
                       title="samples per pixel (adaptive)", label="samples",
                       cmap="viridis", signed=False)
    print_warnings(result.metadata)
    if "resumed_from_samples" in result.metadata:
        print(f"dopplertof: resumed from checkpoint {args.checkpoint}: "
              f"{result.metadata['resumed_from_samples']:g} of {result.metadata['spp']} "
              "samples per pixel were saved there", file=sys.stderr)
    if args.checkpoint and not result.metadata["timed_out"]:  # the output is safe:
        os.unlink(args.checkpoint)  # the checkpoint has served (a timed-out one resumes)
    md = result.metadata
    if not args.quiet:
        print(f"wrote {args.output}: {result.image.shape[1]}x{result.image.shape[0]}, "
              f"{md['spp']} spp"
              + (f" (adaptive: {md['sample_counts']['min']}-{md['sample_counts']['max']} "
                 "per pixel)" if "sample_counts" in md else "")
              + f", {md['render_seconds']:.1f} s")
    return 0


_NOISE_OPTIONS = {"photons_per_unit": "photons_per_unit",
                  "quantum_efficiency": "quantum_efficiency", "read_noise": "read_noise",
                  "full_well": "full_well", "gain": "gain", "bits": "bits",
                  "ambient": "ambient", "noise_seed": "seed"}


def _cmd_capture(args) -> int:
    from . import io

    _check_before_loading(args, "capture parameters")
    from .cameras import cli as cameras_cli

    if not os.path.isfile(args.scene):
        raise UsageError(f"scene file not found: {args.scene}")
    cameras_cli.check_capture_options(args)
    if not args.checkpoint:
        return _capture(args, cameras_cli)
    io.check_output_folder(args.checkpoint)
    with io.held_folder(args.checkpoint, remove_empty=True):  # one run at a time in it
        return _capture(args, cameras_cli)


def _capture(args, cameras_cli) -> int:
    """``capture`` once its arguments are checked (and its checkpoint folder held)."""
    import dopplertof
    from .tof import format_summary, prepare_folder
    from .tof.checkpoint import remove_checkpoint

    if args.camera is not None:
        return cameras_cli.run_camera_capture(args, parse_pairs(args.defines, "-D"))
    noise = _noise_model(args, args.noise)
    prepare_folder(args.output)
    scene = _load_scene(args)
    from .integrators.camera import is_pinhole

    if args.pointcloud and not is_pinhole(scene.sensor):
        raise UsageError(f"--pointcloud needs a pinhole (perspective) sensor; {args.scene} "
                         f"has a {scene.sensor.class_name()}")

    def report(spec, seconds):
        if not args.quiet:
            print(f"  {spec.name:<16} {seconds:6.1f} s", flush=True)

    settings = dopplertof.CaptureSettings(
        spp=args.spp, seed=args.seed, params=parse_pairs(args.params, "-P") or None,
        hetero_frequency=args.hetero_frequency, unwrap_frequency=args.unwrap_frequency,
        noise=noise, min_signal_fraction=args.min_signal,
        progress=False if args.quiet else None, on_capture=report,
        mc_batches=args.mc_batches, max_velocity_std=args.max_velocity_std,
        max_depth_std=args.max_depth_std, keep_mixed_pixels=args.keep_mixed_pixels,
        checkpoint=args.checkpoint)
    result = dopplertof.capture(scene, settings=settings)
    if args.defines:  # dopplertof fit loads the scene again with them
        result.summary["scene_defines"] = parse_pairs(args.defines, "-D")
    result.write(args.output, pointcloud=args.pointcloud)
    if args.checkpoint:  # the outputs are safe: the checkpoint has served (unless timed out)
        remove_checkpoint(args.checkpoint)
    print_warnings(result.summary)
    print(format_summary(result.summary, args.output))
    from .tof.precision import format_precision

    if result.uncertainty is not None:
        print(format_precision(result.summary))
    return 0


def _noise_model(args, default: bool):
    from .tof import NoiseModel

    noise_args = {field: getattr(args, opt) for opt, field in _NOISE_OPTIONS.items()
                  if getattr(args, opt) is not None}
    return NoiseModel(**noise_args) if (default or noise_args) else None


def _cmd_precision(args) -> int:
    from . import file_formats, io
    from .params import FREQUENCY_RANGE_MHZ
    from .tof import study

    _check_before_loading(args, "precision parameters")
    if not os.path.isfile(args.scene):
        raise UsageError(f"scene file not found: {args.scene}")
    w_g = (None if args.w_g is None else
           study.parse_range(args.w_g, "--w-g (MHz)", *FREQUENCY_RANGE_MHZ))
    exposure = (None if args.exposure is None else
                study.parse_range(args.exposure, "--exposure (s)", 1e-7, 10.0))
    ranged = isinstance(w_g, tuple) or isinstance(exposure, tuple)
    if ranged and not args.output:
        raise UsageError("ranges need -o MAP.png for the precision map")
    if args.output:
        if not args.output.lower().endswith(".png"):
            raise UsageError(f"the precision map is a PNG: -o must end in .png, got "
                             f"{args.output}")
        io.check_output_path(args.output)
    if args.check < 0:
        raise UsageError(f"--check must be >= 0, got {args.check}")
    noise = _noise_model(args, True)
    scene = _load_scene(args)
    params = parse_pairs(args.params, "-P") or None

    def report(i, f):
        if not args.quiet:
            print(f"  pilot {i + 1}: {f:.4g} MHz", flush=True)

    result = study.precision_study(scene, w_g, exposure, spp=args.spp,
                                   steps=args.steps if ranged else 2,
                                   hetero_frequency=args.hetero_frequency, noise=noise,
                                   mc_batches=args.mc_batches, seed=args.seed, params=params,
                                   progress=False if args.quiet else None, on_pilot=report)
    if ranged and args.check:
        study.check_points(scene, result, study.default_check_points(result, args.check),
                           noise=noise, seed=args.seed, params=params,
                           progress=False if args.quiet else None)
    print(f"{os.path.basename(args.scene)}: {result.spp} spp pilots; sensor: "
          f"{noise.full_well:g} e- well, {noise.gain:g} e-/DN, "
          f"{'auto photon scale' if noise.photons_per_unit is None else 'fixed photon scale'}")
    print(study.format_study(result))
    if args.output:
        scale = ("auto photon scale" if noise.photons_per_unit is None else
                 f"{noise.photons_per_unit:.3g} photons/s per unit")
        folder, map_name = os.path.split(os.path.abspath(args.output))
        stem = os.path.splitext(map_name)[0]
        with io.output_folder(folder, f"precision-{stem}") as staged:  # the map and its numbers
            study.write_map(staged.path(map_name), result, f"{os.path.basename(args.scene)}: "
                            f"predicted velocity precision (sensor: {noise.full_well:g} e- "
                            f"well, {scale})")
            file_formats.write_json(staged.path(stem + ".json"), result.describe())
        print(f"wrote {args.output}")
    return 0


def _cmd_demo(args) -> int:
    from .demo import run_demo

    run_demo(args.output, spp=args.spp, res=args.res, variant=args.variant,
             progress=False if args.quiet else None, noise=True if args.noise else None,
             quiet=args.quiet)
    return 0


def _cmd_figures(args) -> int:
    from .analysis import write_figures

    paths = write_figures(args.output, quick=args.quick)
    print(f"wrote {len(paths)} files to {args.output}")
    return 0


def main(argv=None) -> int:
    interrupt, args = _InterruptWatch(), None
    try:
        with interrupt:
            args = _parser().parse_args(argv)
            commands = {"render": _cmd_render, "capture": _cmd_capture, "demo": _cmd_demo,
                        "precision": _cmd_precision,
                        "figures": _cmd_figures}
            code = commands[args.command](args) if args.command in commands else \
                args.func(args)
        return _interrupted() if interrupt.seen else code  # (a KeyboardInterrupt lost)
    except KeyboardInterrupt:
        return _interrupted()
    except Exception as exc:  # one line for the user; --debug for the traceback
        if interrupt.seen or _caused_by_interrupt(exc):
            return _interrupted()  # Dr.Jit and Mitsuba wrap the KeyboardInterrupt
        if args is None or args.debug:
            raise
        msg = " ".join(str(exc).split()) or type(exc).__name__
        print(f"dopplertof: error: {msg}", file=sys.stderr)
        return 2


def _interrupted() -> int:
    print("dopplertof: interrupted", file=sys.stderr)
    return 130


class _InterruptWatch:
    """While a command runs, Ctrl-C (SIGINT) raises KeyboardInterrupt as usual and is
    remembered: Dr.Jit turns a KeyboardInterrupt raised inside its loops into
    ``dr.while_loop(): encountered an exception (see above)``, with nothing above, and
    an exception that follows an interrupt is the interrupt's doing. Only in the main
    thread, and only over Python's own handler (a caller's handler is left alone)."""

    def __init__(self):
        self.seen = False
        self._previous = None

    def _on_sigint(self, signum, frame):
        from .backend import INTERRUPT_SEEN

        self.seen = True
        INTERRUPT_SEEN.set()  # (outputs are not committed after it, if this raise is lost)
        raise KeyboardInterrupt

    def __enter__(self):
        import signal
        import threading

        from .backend import INTERRUPT_SEEN

        INTERRUPT_SEEN.clear()  # (an earlier command's, in this process)
        if threading.current_thread() is threading.main_thread() and \
                signal.getsignal(signal.SIGINT) is signal.default_int_handler:
            self._previous = signal.signal(signal.SIGINT, self._on_sigint)
            self._previous_hook, sys.unraisablehook = sys.unraisablehook, self._unraisable
        return self

    def _unraisable(self, info):
        """Python's report of an exception it had to drop: a KeyboardInterrupt lost in a
        weakref callback is ours (the command stops at its next output), not a traceback."""
        if not (self.seen and issubclass(info.exc_type, KeyboardInterrupt)):
            self._previous_hook(info)

    def __exit__(self, *exc_info):
        import signal

        from .backend import INTERRUPT_SEEN

        INTERRUPT_SEEN.clear()  # the command is over: a later one in this process commits
        if self._previous is not None:
            signal.signal(signal.SIGINT, self._previous)
            sys.unraisablehook = self._previous_hook
        return False


def _caused_by_interrupt(exc: BaseException) -> bool:
    """Whether a KeyboardInterrupt is in ``exc``'s chain (its causes and contexts)."""
    seen = set()
    while exc is not None and id(exc) not in seen:
        if isinstance(exc, KeyboardInterrupt):
            return True
        seen.add(id(exc))
        exc = exc.__cause__ or exc.__context__
    return False


if __name__ == "__main__":
    sys.exit(main())
