"""Command line: parse, call the library, print. Errors are one line and exit code 2."""

from __future__ import annotations

import argparse
import os
import sys


class UsageError(Exception):
    pass


def _overrides(pairs) -> dict:
    """``["name=value", ...]`` (from -D or -P) as a dict."""
    out = {}
    for item in pairs or []:
        if "=" not in item:
            raise UsageError(f"-D expects name=value, got {item!r}")
        name, value = item.split("=", 1)
        if not name:
            raise UsageError(f"-D expects name=value, got {item!r}")
        out[name.strip()] = value
    return out


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="dopplertof",
                                description="Doppler time-of-flight camera simulator")
    p.add_argument("--debug", action="store_true", help="show tracebacks on errors")
    sub = p.add_subparsers(dest="command", required=True)

    r = sub.add_parser("render", help="render a D-ToF image of a scene")
    r.add_argument("scene", help="Mitsuba 3 XML scene (may contain <animation>)")
    r.add_argument("-o", "--output", required=True, help="output file: .exr, .npy or .png")
    r.add_argument("--spp", type=int, help="samples per pixel (default: the scene's sampler)")
    r.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    r.add_argument("-D", dest="defines", action="append", metavar="NAME=VALUE",
                   help="set a <default> value of the scene (repeatable)")
    r.add_argument("-P", dest="params", action="append", metavar="NAME=VALUE",
                   help="override an integrator parameter, e.g. -P hetero_frequency=1")
    r.add_argument("--variant", default=None, help="Mitsuba variant (default llvm_ad_rgb)")
    r.add_argument("--quiet", action="store_true", help="no progress bar")

    d = sub.add_parser("demo", help="render the built-in moving Cornell box")
    d.add_argument("-o", "--output", default="demo_out", help="output folder")
    d.add_argument("--spp", type=int, default=64)
    d.add_argument("--res", type=int, default=128)
    d.add_argument("--variant", default=None)
    d.add_argument("--quiet", action="store_true")

    f = sub.add_parser("figures", help="the supplementary's analysis as figures")
    f.add_argument("-o", "--output", default="figures", help="output folder")
    f.add_argument("--quick", action="store_true", help="small settings")
    return p


def _cmd_render(args) -> int:
    import dopplertof
    from . import io

    io.check_output_path(args.output)
    if not os.path.isfile(args.scene):
        raise UsageError(f"scene file not found: {args.scene}")
    dopplertof.set_variant(args.variant)
    scene = dopplertof.load_file(args.scene, _overrides(args.defines))
    result = dopplertof.render_result(scene, spp=args.spp, seed=args.seed,
                                      params=_overrides(args.params) or None,
                                      progress=False if args.quiet else None)
    io.write_image(args.output, result.image, result.metadata)
    md = result.metadata
    if not args.quiet:
        print(f"wrote {args.output}: {result.image.shape[1]}x{result.image.shape[0]}, "
              f"{md['spp']} spp, {md['render_seconds']:.1f} s"
              + (f", {md['nonfinite_samples_dropped']} non-finite samples dropped"
                 if md["nonfinite_samples_dropped"] else ""))
    return 0


def _cmd_demo(args) -> int:
    from .demo import run_demo

    run_demo(args.output, spp=args.spp, res=args.res, variant=args.variant,
             progress=False if args.quiet else None)
    return 0


def _cmd_figures(args) -> int:
    from .analysis import write_figures

    paths = write_figures(args.output, quick=args.quick)
    print(f"wrote {len(paths)} files to {args.output}")
    return 0


def main(argv=None) -> int:
    parser = _parser()
    args = parser.parse_args(argv)
    try:
        return {"render": _cmd_render, "demo": _cmd_demo, "figures": _cmd_figures}[
            args.command](args)
    except KeyboardInterrupt:
        print("dopplertof: interrupted", file=sys.stderr)
        return 130
    except Exception as exc:  # one line for the user; --debug for the traceback
        if args.debug:
            raise
        msg = " ".join(str(exc).split()) or type(exc).__name__
        print(f"dopplertof: error: {msg}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
