"""The one validator of the package's TOML files (camera presets: cameras/preset.py;
dataset configurations: dataset/config.py; sweep configurations, whose tables of render
parameters are free-form: experiments/config.py): each section's keys declared with
their kind, range, meaning and default, checked strictly. An unknown or misspelt key (with
the nearest known name), a missing key, a value of the wrong kind or out of its range is
one line naming the file and the key, raised as the caller's error class.

A schema is ``{section: {key: Key}}``, section "" the top level.
(file_formats.read_toml reads the files.)
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable

from .hints import unknown_key

#: the default of a key that must be given
REQUIRED = object()


@dataclass(frozen=True)
class Key:
    """One key of a section: its ``kind`` (a :data:`KINDS` name), what it means (for
    the messages), the ``check`` of its range (None: any value of its kind) and its
    ``default`` (REQUIRED: none, the key must be given)."""

    kind: str
    meaning: str
    check: Callable | None = None
    default: object = REQUIRED


def _number(x) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool)


def _integer(x) -> bool:
    return isinstance(x, int) and not isinstance(x, bool)


def _numbers(v) -> bool:
    return isinstance(v, list) and all(_number(x) and math.isfinite(x) for x in v)


#: each kind of value: (what a value of it is, how the messages say it); a float is
#: also given as an integer (``5`` for 5.0), never as a bool, and must be finite
KINDS = {
    "string": (lambda v: isinstance(v, str), "a string"),
    "integer": (_integer, "an integer"),
    "float": (_number, "a number"),
    "bool": (lambda v: isinstance(v, bool), "true or false"),
    "list": (lambda v: isinstance(v, list), "a list"),
    "range": (_numbers, "[low, high]"),
    "floats": (_numbers, "a list of numbers"),
    "ints": (lambda v: isinstance(v, list) and all(map(_integer, v)), "a list of integers"),
    "names": (lambda v: isinstance(v, list) and bool(v) and all(isinstance(x, str) for x in v),
              "a non-empty list of names"),
}


def typed(value, key: Key, where: str, error: type):
    """``value`` checked against ``key`` (numbers of a float, range or list of numbers
    as floats); ``error`` (one line starting with ``where``, the file and the key)."""
    is_kind, said = KINDS[key.kind]
    if not is_kind(value):
        raise error(f"{where} must be {said} ({key.meaning}), got {value!r}")
    if key.kind == "float":
        if not math.isfinite(value):
            raise error(f"{where} must be finite, got {value!r}")
        value = float(value)
    elif key.kind in ("range", "floats"):
        value = [float(x) for x in value]
    if key.check is not None and not key.check(value):
        raise error(f"{where} out of range ({key.meaning}), got {value!r}")
    return value


def section(values: dict, keys: dict, source: str, error: type, label: str = "",
            extra=()) -> dict:
    """The keys of one section (``values``, a TOML table) checked against ``keys``
    ({key: Key}), the defaults of those not given filled in; ``label``: the section's
    name in the messages ("sensor", "frames[2]"; "": the top level); ``extra``: the
    names of sub-tables allowed beside the keys. ``error`` on the first problem."""
    prefix = f"{label}." if label else ""
    problem = unknown_key(values, list(keys) + list(extra), prefix)
    if problem:
        raise error(f"{source}: {problem}")
    out = {}
    for name, key in keys.items():
        if name in values:
            out[name] = typed(values[name], key, f"{source}: {prefix}{name}", error)
        elif key.default is REQUIRED:
            raise error(f"{source}: missing key {prefix}{name} ({key.meaning})")
        else:
            out[name] = key.default
    return out


def table(data: dict, name: str, source: str, error: type, required: bool = True) -> dict:
    """``data``'s table ``name`` ({} when absent and not ``required``); ``error``
    when it is missing or no table."""
    value = data.get(name)
    if value is None:
        if required:
            raise error(f"{source}: [{name}] is missing")
        return {}
    if not isinstance(value, dict):
        raise error(f"{source}: [{name}] must be a table, got {value!r}")
    return value
