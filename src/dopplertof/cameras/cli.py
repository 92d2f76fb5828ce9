"""Command line of the cameras: ``dopplertof cameras [NAME]`` and ``capture --camera``.
Thin: parse, call the library, print."""

from __future__ import annotations

import os
import sys

#: capture options that the camera's preset replaces (its sensor, its reconstruction)
PRESET_OWNS = ("hetero_frequency", "unwrap_frequency", "min_signal", "mc_batches",
               "max_velocity_std", "max_depth_std", "photons_per_unit",
               "quantum_efficiency", "read_noise", "full_well", "gain", "bits", "ambient")


def add_subcommand(sub) -> None:
    """``cameras``: list the presets, or print one."""
    from ..cli_options import add_variant_option

    c = sub.add_parser("cameras", help="list the camera presets, or print one; its wiggling "
                       "figure; a scene through several cameras side by side")
    c.add_argument("name", nargs="?", help="a preset name or a preset file (.toml); "
                   "none: list the presets")
    c.add_argument("--list", action="store_true", help="list the presets (as with no NAME)")
    c.add_argument("--wiggling", metavar="FIG.png", help="with NAME: the noise-free depth "
                   "error against distance and (FIG.json) the calibration tables")
    c.add_argument("--compare", metavar="SCENE", help="capture SCENE through --with cameras "
                   "and write their range errors and velocities side by side (-o FIG.png)")
    c.add_argument("--with", dest="with_cameras", metavar="A,B,...",
                   help="with --compare: the cameras (default: every preset)")
    c.add_argument("--res", metavar="WIDTHxHEIGHT", help="with --compare: one resolution")
    c.add_argument("--spp", type=int, default=16, help="with --compare: samples per pixel "
                   "per raw frame (default 16)")
    c.add_argument("-o", "--output", metavar="FIG.png|MINE.toml",
                   help="with --compare: the figure; with --calibrate: the preset written")
    c.add_argument("--calibrate", metavar="TABLE.csv", help="with NAME (the base preset) "
                   "and -o MINE.toml: fit its illuminator power (and read noise where the "
                   "table constrains it) to measured wall noise: columns distance_m, albedo, "
                   "random_error_mm, optional angle_deg, ambient_uw_cm2_nm (docs/cameras.md)")
    c.add_argument("--figure", metavar="FIG.png", help="with --calibrate: measured and "
                   "simulated random error against distance")
    c.add_argument("--noiseless", action="store_true",
                   help="with --compare: no shot or read noise (rounding stays)")
    add_variant_option(c)
    c.set_defaults(func=run_cameras)


def add_capture_options(c) -> None:
    """``capture``'s camera group."""
    from ..cli_options import add_camera_options

    g = c.add_argument_group("real camera (a preset: its raw frames, sensor and depth)")
    g.add_argument("--camera", metavar="NAME|FILE.toml",
                   help="capture the preset's raw frame sequence, each frame in its own time "
                   "window (dopplertof cameras lists them); through an absolute preset "
                   "(azure-kinect, kinect-v2) the scene's room lights (area, environment, "
                   "directional) are left out, with a note, and the preset's illuminator "
                   "lights a scene with no other light (docs/own_scene.md)")
    add_camera_options(g)
    g.add_argument("--keep-view", action="store_true",
                   help="with --camera: keep the scene's field of view (its framing) with "
                   "the preset's sensor, instead of the preset's field of view")


def run_cameras(args) -> int:
    from .preset import format_preset, load_preset, preset_names

    if args.compare is not None:
        return _compare(args)
    if args.calibrate is not None or args.figure is not None:
        return _calibrate(args)
    if args.wiggling is not None:
        return _wiggling(args)
    if args.list and args.name is not None:
        from ..tof.capture import CaptureError

        raise CaptureError("--list takes no NAME: give one or the other")
    if args.name is None:
        for name in preset_names():
            print(f"{name:<26} {load_preset(name).description}")
        return 0
    print(format_preset(load_preset(args.name)))
    return 0


def _png_path(path, option: str) -> str:
    from .. import io
    from ..tof.capture import CaptureError

    if path is None or not path.lower().endswith(".png"):
        raise CaptureError(f"{option} needs a .png figure path, got {path!r}")
    io.check_output_path(path)
    return path


def _calibrate(args) -> int:
    """``cameras BASE --calibrate TABLE.csv -o MINE.toml [--figure FIG.png]``."""
    from .calibration import POOR_FIT, fit_table, rms_log_residual, write_calibration_figure
    from .preset import PresetError, load_preset
    from .preset_file import write_preset

    from ..tof.capture import CaptureError

    if args.calibrate is None:
        raise CaptureError("--figure needs --calibrate TABLE.csv")
    if args.name is None:
        raise CaptureError("--calibrate needs the base preset: dopplertof cameras BASE "
                           "--calibrate TABLE.csv -o MINE.toml")
    if args.output is None or not args.output.lower().endswith(".toml"):
        raise CaptureError(f"--calibrate needs -o MINE.toml (the preset written), got "
                           f"{args.output!r}")
    from .. import io

    io.check_output_folder(os.path.dirname(os.path.abspath(args.output)))
    if os.path.isdir(args.output):
        raise PresetError(f"{args.output}: is a folder, not a preset file")
    figure = _png_path(args.figure, "--figure") if args.figure is not None else None
    base = load_preset(args.name)
    import dopplertof

    dopplertof.set_variant(args.variant)
    calibration = fit_table(base, args.calibrate)
    stem = os.path.splitext(os.path.basename(args.output))[0]
    from dataclasses import replace

    preset = replace(calibration.preset, name=stem)
    print(f"{base.name} calibrated to {args.calibrate} ({len(calibration.rows)} rows):")
    for line in calibration.lines():
        print(f"  {line}")
    write_preset(preset, args.output)
    written = [args.output]
    if figure is not None:
        calibration.preset = preset
        write_calibration_figure(figure, calibration)
        written.append(figure)
    if rms_log_residual(calibration) > POOR_FIT:
        print(f"dopplertof: note: {base.name}'s noise model does not follow {args.calibrate} "
              f"(rms log residual {rms_log_residual(calibration):.2f}, over {POOR_FIT:g}): "
              "the camera's noise has a shape the base lacks (a noise floor, a dynamic-range "
              "scheme); the preset follows the rows only on average", file=sys.stderr)
    print(f"wrote {' and '.join(written)} (capture with --camera {args.output})")
    return 0


def _wiggling(args) -> int:
    from .figures import write_wiggling
    from .preset import load_preset

    from ..tof.capture import CaptureError

    if args.name is None:
        raise CaptureError("--wiggling needs a camera NAME")
    path = _png_path(args.wiggling, "--wiggling")
    numbers = write_wiggling(path, load_preset(args.name))
    print(f"{numbers['camera']}: noise-free depth error up to "
          f"{numbers['max_abs_error_uncalibrated_m'] * 1e3:.3g} mm without calibration, "
          f"{numbers['max_abs_error_reported_m'] * 1e3:.3g} mm as reported "
          f"({'table applied' if numbers['calibration_applied'] else 'no table'}); wrote {path}")
    return 0


def _compare(args) -> int:
    import dopplertof

    from ..cli_options import print_warnings
    from ..scene.kinds import keep_common_alive
    from .capture import capture_through, format_camera_summary
    from .scene_view import parse_resolution
    from .figures import write_camera_comparison
    from .preset import load_preset, preset_names

    from ..tof.capture import CaptureError

    if not os.path.isfile(args.compare):
        raise CaptureError(f"scene file not found: {args.compare}")
    path = _png_path(args.output, "--compare -o")
    names = args.with_cameras.split(",") if args.with_cameras else preset_names()
    presets = [load_preset(n.strip()) for n in names]
    for preset in presets:
        note = preset.uncalibrated_note()
        if note and not args.noiseless:
            print(f"dopplertof: note: {note}", file=sys.stderr)
    resolution = parse_resolution(args.res) if args.res else None
    dopplertof.set_variant(args.variant)
    keep_common_alive()  # (before the scenes: kernels shared with the capture command's)
    results = capture_through(args.compare, presets, resolution, spp=args.spp,
                              noise=not args.noiseless, progress=False)
    for result in results:
        print(format_camera_summary(result.summary))
        print_warnings(result.summary)
    write_camera_comparison(path, results, f"{os.path.basename(args.compare)} through "
                            f"{len(results)} cameras, {args.spp} spp per raw frame"
                            + (", no shot or read noise" if args.noiseless else ""))
    print(f"wrote {path} and {path[:-4]}.json (each camera's errors and masked pixels)")
    return 0


def check_capture_options(args) -> None:
    """--res and --noiseless need --camera; with it, the options its preset replaces
    are refused (one line naming them)."""
    from ..cli_options import RES_WITHOUT_CAMERA
    from ..tof.capture import CaptureError

    if args.camera is None:
        for option in ("res", "noiseless", "ambient_irradiance", "keep_view"):
            if getattr(args, option, None) not in (None, False):
                raise CaptureError(f"--{option.replace('_', '-')} needs --camera"
                                   + (RES_WITHOUT_CAMERA if option == "res" else ""))
        return
    given = [o for o in PRESET_OWNS if getattr(args, o, None) is not None]
    given += ["noise"] if args.noise else []
    if given:
        raise CaptureError("--camera takes the sensor and reconstruction from its preset: "
                           "drop " + ", ".join("--" + o.replace("_", "-") for o in given))


def run_camera_capture(args, load_defines) -> int:
    """``capture SCENE --camera NAME -o DIR``; ``load_defines``: the -D values."""
    import dopplertof

    from ..cli_options import parse_pairs, print_warnings
    from ..scene.kinds import keep_common_alive
    from ..tof import prepare_folder
    from .capture import capture_camera, format_camera_summary
    from .scene_view import load_scene_for_camera, parse_resolution, preset_with_scene_view
    from .preset import load_preset

    preset = load_preset(args.camera)
    resolution = parse_resolution(args.res) if args.res else None
    prepare_folder(args.output)
    dopplertof.set_variant(args.variant)
    keep_common_alive()  # (before the scene: kernels shared with scenes of other shapes)
    if args.keep_view:
        preset = preset_with_scene_view(args.scene, preset, resolution, load_defines)
    scene = load_scene_for_camera(args.scene, preset, resolution, load_defines,
                                  keep_view=args.keep_view)
    for note in scene.notes + (preset.uncalibrated_note(),):
        if note:
            print(f"dopplertof: note: {note}", file=sys.stderr)

    def report(spec, seconds):
        if not args.quiet:
            print(f"  {spec.name:<8} {seconds:6.1f} s", flush=True)

    result = capture_camera(scene, preset, spp=args.spp, seed=args.seed,
                            params=parse_pairs(args.params, "-P") or None,
                            noise=not args.noiseless,
                            noise_seed=args.noise_seed if args.noise_seed is not None else 0,
                            progress=False if args.quiet else None, on_frame=report,
                            checkpoint=args.checkpoint,
                            keep_mixed_pixels=args.keep_mixed_pixels,
                            ambient_irradiance=args.ambient_irradiance)
    result.write(args.output, pointcloud=args.pointcloud)
    if args.checkpoint:  # the outputs are safe: the checkpoint has served (unless timed out)
        from ..tof.checkpoint import remove_checkpoint

        remove_checkpoint(args.checkpoint)
    print(format_camera_summary(result.summary, os.fspath(args.output)))
    print_warnings(result.summary)
    return 0
