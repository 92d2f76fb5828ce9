"""Hints for error messages: the closest known names to a misspelled one."""

from __future__ import annotations

import difflib
import os
import re
import sys

#: how many names an unknown one's message lists (the nearest first)
NEAREST_COUNT = 3


def did_you_mean(name, known) -> str:
    """``", did you mean 'x'?"`` for the known name closest to ``name``, or ``""``."""
    close = difflib.get_close_matches(str(name), [str(k) for k in known], n=1, cutoff=0.6)
    return f", did you mean {close[0]!r}?" if close else ""


def nearest(name, known, count: int = NEAREST_COUNT) -> list:
    """The ``count`` known names most like ``name``, the nearest first."""
    return difflib.get_close_matches(str(name), sorted(str(k) for k in known), n=count,
                                     cutoff=0.0)


def unknown_key(table, known, prefix: str = "") -> str | None:
    """``"unknown key PREFIXx, did you mean 'y'?"`` for the first key of ``table`` (a
    config file's table) that is not one of ``known``, or None when every key is."""
    known = list(known)
    for key in table:
        if key not in known:
            return f"unknown key {prefix}{key}{did_you_mean(key, known)}"
    return None


def unknown_name(what: str, name, known) -> str:
    """``"unknown WHAT 'x', did you mean 'y'? (nearest: a, b, c; N in all)"``: the
    message for a name that is not one of ``known``, without listing them all."""
    known = sorted(str(k) for k in known)
    return (f"unknown {what} {name!r}{did_you_mean(name, known)} (nearest: "
            f"{', '.join(nearest(name, known))}; {len(known)} in all)")


# ---- Mitsuba's "Plugin not found" ----

_PLUGIN_NOT_FOUND = re.compile(r'Plugin "([^"]+)" not found!?')


def plugin_names(extra=()) -> tuple:
    """The plugin names of the loaded Mitsuba build (its plugins folder) and ``extra``
    (the plugins registered from Python, such as dopplertof's integrator)."""
    mitsuba = sys.modules.get("mitsuba")
    folder = os.path.join(os.path.dirname(getattr(mitsuba, "__file__", "") or ""), "plugins")
    try:
        files = os.listdir(folder)
    except OSError:
        files = []
    return tuple(sorted({f.split(".")[0] for f in files if f.endswith((".so", ".dll",
                                                                         ".dylib"))}
                        | set(extra)))


def with_plugin_hint(message: str, extra=()) -> str:
    """Mitsuba's message, with a did-you-mean after its 'Plugin "x" not found'."""
    found = _PLUGIN_NOT_FOUND.search(message)
    if not found:
        return message
    hint = did_you_mean(found.group(1), plugin_names(extra))
    if not hint:
        return message
    return message[:found.start()] + f'Plugin "{found.group(1)}" not found{hint}' \
        + message[found.end():]
