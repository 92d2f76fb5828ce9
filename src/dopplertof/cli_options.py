"""Command-line pieces several commands share: integer argument types, ``--variant`` and
the repeatable ``-D``/``-P NAME=VALUE`` options with their one parser."""

from __future__ import annotations

import argparse
import contextlib
import sys

#: what every command's --help says about its output folder (io.make_output_folder)
FOLDER_HELP = "created, with missing parents, if missing"
#: what --res without --camera says to do instead
RES_WITHOUT_CAMERA = (" (a preset's pixel count); without a camera the scene's film sets the "
                      "resolution: -D res=N where the scene declares <default name=\"res\">")
#: what every command that holds its output folder while it runs says in its --help
HELD_HELP = ("A run holds its output folder until it ends: a second run into it is refused, "
             "naming the first (pid and command); after a kill or Ctrl-C the same command "
             "resumes.")


def int_at_least(minimum: int, wording: str):
    """An argparse type: an integer >= ``minimum``."""
    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            value = None
        if value is None or value < minimum:
            raise argparse.ArgumentTypeError(f"expected {wording}, got {text!r}")
        return value

    return parse


def add_variant_option(p, what: str = "Mitsuba variant") -> None:
    """``--variant``, of every command that renders (``what``: the kind it needs)."""
    p.add_argument("--variant", default=None, metavar="VARIANT",
                   help=f"{what} (default llvm_ad_rgb)")


def add_camera_options(g) -> None:
    """``--res`` and ``--noiseless`` of a camera preset's frames (``capture --camera``,
    ``animate --camera``), into the command's camera group ``g``."""
    g.add_argument("--res", metavar="WIDTHxHEIGHT",
                   help="with --camera: other resolution, same field of view")
    g.add_argument("--noiseless", action="store_true",
                   help="with --camera: no shot or read noise (rounding stays)")


def print_warnings(record: dict) -> None:
    """The "warnings" of a render's metadata or a summary, on stderr (also --quiet)."""
    for warning in record.get("warnings", ()):
        print(f"dopplertof: warning: {warning}", file=sys.stderr)


class Terminated(KeyboardInterrupt):
    """SIGTERM raised as an interrupt (:func:`sigterm_as_interrupt`)."""


#: a command's exit status after SIGTERM (128 + 15, as a shell reports it)
TERMINATED_EXIT = 143


@contextlib.contextmanager
def sigterm_as_interrupt():
    """While a command writes its output: SIGTERM raises :class:`Terminated` (a
    KeyboardInterrupt: the staged folder is removed on the way out as after Ctrl-C, and
    nothing is committed after it), where it ended the process at once without a word.
    Only in the main thread over the default action (a caller's handler is left alone);
    the command prints its one line."""
    import signal
    import threading

    from .backend import INTERRUPT_SEEN

    def on_term(signum, frame):
        INTERRUPT_SEEN.set()  # (outputs are not committed after it, if this raise is lost)
        raise Terminated

    if threading.current_thread() is not threading.main_thread() \
            or signal.getsignal(signal.SIGTERM) is not signal.SIG_DFL:
        yield
        return
    previous = signal.signal(signal.SIGTERM, on_term)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


positive_int = int_at_least(1, "a positive integer")
non_negative_int = int_at_least(0, "an integer >= 0")


def parse_pairs(items, flag: str) -> dict:
    """``NAME=VALUE`` items of a repeatable option (``flag``, for the message) as a dict
    of strings."""
    out = {}
    for item in items or []:
        name, sep, value = item.partition("=")
        if not sep or not name.strip():
            raise ValueError(f"{flag} expects name=value, got {item!r}")
        out[name.strip()] = value
    return out


def add_defines_option(p, help: str = "set a <default> value of the scene (repeatable)"
                       ) -> None:
    """``-D NAME=VALUE`` (repeatable; ``parse_pairs(args.defines, "-D")`` reads it)."""
    p.add_argument("-D", dest="defines", action="append", metavar="NAME=VALUE", help=help)


def add_params_option(p, help: str) -> None:
    """``-P NAME=VALUE`` (repeatable; ``parse_pairs(args.params, "-P")`` reads it), with
    the command's own ``help``."""
    p.add_argument("-P", dest="params", action="append", metavar="NAME=VALUE", help=help)
