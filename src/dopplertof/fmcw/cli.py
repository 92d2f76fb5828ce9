"""``dopplertof fmcw SCENE.xml -o DIR``: one FMCW lidar frame (docs/fmcw.md).

Imports nothing heavy at module level: the command line's parser builds this command
without NumPy or Mitsuba.
"""

from __future__ import annotations

import argparse
import os

from ..cli_options import (FOLDER_HELP, add_defines_option, add_params_option,
                           int_at_least, parse_pairs, print_warnings)


def add_subcommand(sub) -> None:
    """``fmcw``: the up and down beat spectra of every pixel, range and velocity."""
    f = sub.add_parser("fmcw", help="an FMCW lidar frame: beat spectra of the up and down "
                       "chirps per pixel, range and radial velocity, truth and errors",
                       description=PRECEDENCE)
    f.add_argument("scene", help="Mitsuba 3 XML scene (may contain <animation>)")
    f.add_argument("-o", "--output", required=True, metavar="DIR",
                   help=f"output folder ({FOLDER_HELP})")
    f.add_argument("--spp", type=int_at_least(1, "a positive integer"),
                   help="samples per pixel (default: the scene's sampler)")
    f.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    g = f.add_argument_group("the chirp pair and the beam (each: this option, else the "
                             "scene's fmcw_* parameter, else the default)")
    g.add_argument("--wavelength", type=float, metavar="NM",
                   help="laser wavelength lambda, nm (fmcw_wavelength; default 1550; "
                   "200 nm - 20 um)")
    g.add_argument("--bandwidth", type=float, metavar="GHZ",
                   help="optical frequency sweep B of one chirp, GHz (fmcw_bandwidth; "
                   "default 1)")
    g.add_argument("--chirp-time", type=float, metavar="US",
                   help="duration T of one chirp, microseconds (fmcw_chirp_time; default 10)")
    g.add_argument("--bins", type=int, metavar="M",
                   help="spectrum bins of width 1/T, M >= 2 (fmcw_bins; default 256)")
    g.add_argument("--beam", choices=("flood", "collimated"),
                   help="flood: the scene's lights light everything; collimated: each pixel "
                   "its own beam from the camera centre, no other light (fmcw_beam; "
                   "default flood)")
    g.add_argument("--beam-intensity", type=_positive_float, metavar="W_SR",
                   help="with a collimated beam: its radiant intensity within each pixel's "
                   "cone, W/sr (fmcw_beam_intensity; default 1)")
    g.add_argument("--iq", action=argparse.BooleanOptionalAction, default=None,
                   help="an I/Q (complex) receiver: it sees the beats' signs, so a Doppler "
                   "beat larger than the range beat does not fold (spectra of 2 M bins "
                   "from -M/T; fmcw_iq; --no-iq: a real receiver, |beat|, the default)")
    f.add_argument("--speckle", action="store_true",
                   help="also speckle.npy: each path at a random phase, summed coherently "
                   "per bin (its expectation is spectrum.npy)")
    f.add_argument("--returns", type=int_at_least(1, "a positive integer"), default=1,
                   metavar="N", help="the N strongest returns of every pixel "
                   "(returns_range.npy, returns_velocity.npy and points.npy; default 1)")
    add_defines_option(f)
    add_params_option(f, "override an integrator parameter, e.g. -P max_depth=3")
    f.add_argument("--variant", default=None, help="Mitsuba variant (default llvm_ad_rgb)")
    f.set_defaults(func=run_fmcw)


def _positive_float(text: str) -> float:
    """An argparse type: a finite number > 0."""
    import argparse
    import math

    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not (math.isfinite(value) and value > 0):
        raise argparse.ArgumentTypeError(f"expected a number > 0, got {text!r}")
    return value


#: where the chirp and the beam come from (the command's --help; docs/fmcw.md section 4)
PRECEDENCE = ("The chirp pair and the beam, each parameter on its own: the option given "
              "here (--wavelength, --bandwidth, --chirp-time, --bins, --beam, "
              "--beam-intensity, --iq or --no-iq), else -P fmcw_...=VALUE, else the "
              "scene's <integrator> parameter (fmcw_wavelength in nm, fmcw_bandwidth in "
              "GHz, fmcw_chirp_time in us, fmcw_bins, fmcw_beam, fmcw_beam_intensity in "
              "W/sr, fmcw_iq true or false), else the default.")


def chirp_of(args, settings=None):
    """The chirp of the options over ``settings``' (FMCWSettings: the scene's; None: the
    defaults); an FMCWError, one line, when a value is out of range."""
    from .chirp import Chirp

    given = (args.wavelength, args.bandwidth, args.chirp_time)
    wavelength, bandwidth, chirp_time = (None if v is None else convert(v) for v, convert in zip(
        given, (lambda nm: nm / 1e9, lambda ghz: ghz * 1e9, lambda us: us / 1e6)))
    # a unit mistake named as given: the option (GHz, us), else the scene's key
    names = {"bandwidth": ("--bandwidth" if args.bandwidth is not None else "fmcw_bandwidth",
                           "GHz", 1e9),
             "chirp_time": ("--chirp-time" if args.chirp_time is not None
                            else "fmcw_chirp_time", "us", 1e-6)}
    return Chirp.of_settings(settings, names=names, wavelength=wavelength,
                             bandwidth=bandwidth, chirp_time=chirp_time, bins=args.bins,
                             iq=args.iq)


def run_fmcw(args) -> int:
    from ..scene.parameters import coerced

    chirp_of(args)  # (the options given, before anything loads)
    coerced(parse_pairs(args.params, "-P"), "fmcw parameters")
    if not os.path.isfile(args.scene):
        raise ValueError(f"scene file not found: {args.scene}")
    import dopplertof

    from .. import io
    from .capture import OUTPUT_FILES, fmcw
    from .trace import fmcw_params

    io.check_output_set(args.output, "fmcw", OUTPUT_FILES)  # before any work
    from ..scene.kinds import keep_common_alive
    from ..scene.xml import load_file

    dopplertof.set_variant(args.variant)
    keep_common_alive()  # (before the scene: kernels shared with scenes of other shapes)
    beam = args.beam or parse_pairs(args.params, "-P").get("fmcw_beam")
    scene = load_file(args.scene, parse_pairs(args.defines, "-D"),  # (a beam lights it)
                      params={"fmcw_beam": beam} if beam else None)
    given = parse_pairs(args.params, "-P") or None  # (D-ToF and fmcw_* names)
    settings = fmcw_params(scene, given)[1]
    if args.beam_intensity is not None and (args.beam or settings.beam) != "collimated":
        raise ValueError("--beam-intensity is a collimated beam's: the flood beam (the "
                         "scene's lights) ignores it; add --beam collimated or leave it out")
    result = fmcw(scene, chirp_of(args, settings), spp=args.spp, seed=args.seed,
                  params=given, returns=args.returns, beam=args.beam,
                  beam_intensity=args.beam_intensity, speckle=args.speckle)
    result.write(args.output)
    print(format_summary(result.summary, args.output))
    print_warnings(result.summary)
    return 0


def format_summary(summary: dict, folder: str) -> str:
    """A few readable lines of an FMCW frame's summary."""
    c, e = summary["chirp"], summary["errors"]

    def stat(entry, unit):
        if entry["median_abs"] is None:
            return "no pixel with a peak and a truth"
        return (f"median |error| {entry['median_abs']:.4g} {unit}, 95th percentile "
                f"{entry['p95_abs']:.4g} {unit} over {entry['pixels']} pixels")

    return "\n".join([
        f"FMCW {c['wavelength_nm']:g} nm, B {c['bandwidth_GHz']:g} GHz over "
        f"{c['chirp_time_us']:g} us, {c['bins']} bins of {c['bin_width_Hz']:g} Hz "
        f"(range {c['range_per_bin_m']:.4g} m and velocity {c['velocity_per_bin_m_s']:.4g} "
        f"m/s per bin, up to {c['max_range_m']:.4g} m)"
        + (", I/Q receiver" if c.get("receiver", "").startswith("I/Q") else "")
        + f"; {summary['render_seconds']:.1f} s",
        f"  range:    {stat(e['range_m'], 'm')}",
        f"  velocity: {stat(e['velocity_m_s'], 'm/s')}",
        *(f"  {r['name']}: velocity {stat(r['velocity_m_s'], 'm/s')} (truth median "
          f"{r['velocity_gt_median_m_s']:.3g} m/s)" for r in summary["regions"]),
        f"wrote {folder}",
    ])
