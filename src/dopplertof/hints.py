"""Hints for error messages: the closest known name to a misspelled one."""

from __future__ import annotations

import difflib


def did_you_mean(name, known) -> str:
    """``", did you mean 'x'?"`` for the known name closest to ``name``, or ``""``."""
    close = difflib.get_close_matches(str(name), [str(k) for k in known], n=1, cutoff=0.6)
    return f", did you mean {close[0]!r}?" if close else ""
