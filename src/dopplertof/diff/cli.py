"""Command-line subcommand ``fit``: velocities fitted to a capture folder.

``add_subcommand(subparsers)`` adds it to the main parser and sets ``func``. Bad input
raises an exception with a one-line message before any work and any output.
"""

from __future__ import annotations

from ..cli_options import (add_defines_option, add_variant_option, parse_pairs, positive_int,
                           print_warnings)


def add_subcommand(sub) -> None:
    from .settings import FIT_SPP, JACOBIAN_SHARE

    f = sub.add_parser("fit", help="fit the moving bodies' velocities to a capture folder "
                       "through the renderer (fit.json, convergence.png)")
    f.add_argument("capture", help="folder written by `dopplertof capture`")
    f.add_argument("-o", "--output", required=True, help="output folder (created if missing)")
    f.add_argument("--spp", type=positive_int, default=FIT_SPP,
                   help=f"samples per pixel of the fit's renders (default {FIT_SPP})")
    f.add_argument("--jacobian-spp", type=positive_int, default=None,
                   help="samples per pixel of the Jacobian's renders (default "
                   f"{JACOBIAN_SHARE:g} of --spp)")
    f.add_argument("--seed", type=int, help="seed of the fit's renders (default: the "
                   "capture's + 1)")
    f.add_argument("--iterations", type=positive_int, default=12,
                   help="Gauss-Newton iterations at most (default 12)")
    f.add_argument("--angular", action="store_true", help="fit angular velocities too")
    f.add_argument("--reflectances", action="store_true", help="fit the scene's uniform "
                   "reflectances (<bsdf>.reflectance.value) too, from the scene's values, on "
                   "the homodyne captures beside the heterodyne ones")
    f.add_argument("--start", action="append", metavar="K=VX,VY,VZ",
                   help="start body K's linear velocity (m/s) here instead of the closed "
                   "form (repeatable)")
    add_defines_option(f, "-D values for the scene, over the capture's own (summary.json's "
                          "scene_defines; repeatable)")
    add_variant_option(f, "Mitsuba variant with automatic differentiation (_ad_)")
    f.add_argument("--quiet", action="store_true", help="no progress bar")
    f.set_defaults(func=run)


def parse_start(items) -> dict:
    from .fit_capture import FitError, check_start_velocity

    out = {}
    for item in items or []:
        try:
            k, values = item.split("=", 1)
            v = [float(x) for x in values.split(",")]
            if len(v) != 3:
                raise ValueError
            out[int(k)] = v
        except ValueError:
            raise FitError(f"--start expects K=VX,VY,VZ (body index, m/s), got {item!r}") from None
        out[int(k)] = check_start_velocity(v, f"--start {item}")
    return out


def run(args) -> int:
    import dopplertof
    from ..tof.output import prepare_folder
    from .fit import fit, format_fit, write_fit

    start = parse_start(args.start)
    prepare_folder(args.output)  # before any work: nothing written on bad input
    dopplertof.set_variant(args.variant)
    result = fit(args.capture, start=start or None, spp=args.spp, seed=args.seed,
                 iterations=args.iterations, angular=args.angular,
                 reflectances=args.reflectances, jacobian_spp=args.jacobian_spp,
                 defines=parse_pairs(args.defines, "-D"), progress=False if args.quiet else None)
    summary = format_fit(result)  # (before the files: a summary that fails writes none)
    paths = write_fit(result, args.output)
    print(summary)
    print(f"wrote {', '.join(paths)}")
    print_warnings(result.as_json())
    return 0
