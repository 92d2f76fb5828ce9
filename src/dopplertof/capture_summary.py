"""A capture folder's summary.json: one writer and one reader for every kind of capture
(a D-ToF frame, a camera preset's frame, an FMCW frame).

The writer adds the schema, ``"schema": {"kind": KIND, "version": N}``; the reader
names the kind of a folder whatever wrote it (folders written before the schema are
recognised by their keys) and turns a missing key into one line naming the file and the
key, so that no reader of a summary indexes it by strings of its own.
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass

from . import file_formats

#: the file name of a capture's summary
SUMMARY_JSON = "summary.json"
#: the summary's schema version (the keys below "schema": what each kind's writer writes)
SCHEMA_VERSION = 1
#: the kinds of capture folder and the command that writes each
KINDS = {
    "dtof": "`dopplertof capture SCENE -o DIR`",
    "camera": "`dopplertof capture SCENE --camera NAME -o DIR`",
    "fmcw": "`dopplertof fmcw SCENE -o DIR`",
}
#: each kind in words, with its article
KIND_NAMES = {"dtof": "a D-ToF capture", "camera": "a camera capture",
              "fmcw": "an FMCW capture"}
#: a key only one kind's summary has: the kind of a summary written without a schema
_LEGACY_KEYS = (("captures", "dtof"), ("camera", "camera"), ("chirp", "fmcw"))


class CaptureFolderError(ValueError):
    """A folder that is not a capture folder of the kind asked for, or a summary without
    a key a reader needs; the message names the file and the key."""


def write_summary(path: str, kind: str, summary: dict) -> None:
    """Write ``summary`` to ``path`` (atomically) with the schema of ``kind``."""
    if kind not in KINDS:
        raise ValueError(f"unknown capture kind {kind!r}: expected one of {', '.join(KINDS)}")
    file_formats.write_json(path, {"schema": {"kind": kind, "version": SCHEMA_VERSION}, **summary})


@dataclass(frozen=True)
class CaptureSummary:
    """A capture folder's summary as written, and what kind of capture it is."""

    folder: str  #: the capture folder (absolute)
    path: str  #: its summary.json
    kind: str  #: one of KINDS
    version: int  #: the schema version (0: written before the schema)
    data: dict  #: the summary's content

    def __getitem__(self, key: str):
        try:
            return self.data[key]
        except KeyError:
            raise CaptureFolderError(
                f"{self.path} has no {key!r}: not the whole summary of "
                f"{KIND_NAMES[self.kind]} (write the folder again with "
                f"{KINDS[self.kind]})") from None

    def get(self, key: str, default=None):
        return self.data.get(key, default)

    @property
    def resolution(self) -> tuple:
        """(width, height) of the capture's images."""
        try:
            width, height = (int(v) for v in self["resolution"])
        except (TypeError, ValueError):
            raise CaptureFolderError(f"{self.path}: 'resolution' must be [width, height], "
                                     f"got {self.data.get('resolution')!r}") from None
        return width, height

    @property
    def records(self) -> dict:
        """A D-ToF frame's capture records by name (its summary's "captures")."""
        try:
            return {r["name"]: r for r in self["captures"]}
        except (KeyError, TypeError):
            raise CaptureFolderError(f"{self.path}: 'captures' must be a list of records "
                                     "with a 'name' each") from None

    def file(self, name: str) -> str:
        """The path of the file ``name`` in the capture folder."""
        return os.path.join(self.folder, name)

    def array(self, name: str):
        """The array ``name`` (``NAME.npy``, :mod:`dopplertof.outputs`) of the capture; in
        a folder written before the array was renamed, its file under the former name
        (with a FutureWarning)."""
        import numpy as np

        from .outputs import RENAMED, renamed

        path = self.file(f"{name}.npy")
        former = [old for (kind, old), new in RENAMED.items()
                  if kind == self.kind and new == name]
        old = self.file(f"{former[0]}.npy") if former else None
        if not os.path.isfile(path) and old and os.path.isfile(old):
            renamed(self.kind, former[0], self.folder)
            path = old
        try:
            return np.load(path, allow_pickle=False)
        except (OSError, ValueError) as e:
            raise CaptureFolderError(f"{path}: cannot be read as an array "
                                     f"({' '.join(str(e).split())})") from None


def read_capture(folder, kind: str | None = None) -> CaptureSummary:
    """The summary of the capture folder ``folder``; with ``kind``, a
    CaptureFolderError unless the folder is a capture of that kind (naming the command
    that wrote it and the one that writes the kind asked for)."""
    folder = os.path.abspath(os.fspath(folder))
    path = os.path.join(folder, SUMMARY_JSON)
    if not os.path.isdir(folder):
        raise CaptureFolderError(f"capture folder not found: {folder}")
    if not os.path.isfile(path):
        raise CaptureFolderError(f"{folder} has no {SUMMARY_JSON}: not a capture folder "
                                 f"(written by {KINDS['dtof']}, {KINDS['camera']} or "
                                 f"{KINDS['fmcw']})")
    try:
        with open(path, encoding="utf-8") as f:
            data = json.load(f)
    except (OSError, UnicodeDecodeError, ValueError) as e:
        raise CaptureFolderError(f"{path} cannot be read as JSON: {e}") from None
    if not isinstance(data, dict):
        raise CaptureFolderError(f"{path} is not a capture summary (a JSON object)")
    schema = data.get("schema")
    if isinstance(schema, dict) and schema.get("kind") in KINDS:
        found, version = schema["kind"], int(schema.get("version", 0))
    else:
        found = next((k for key, k in _LEGACY_KEYS if key in data), None)
        version = 0
        if found is None:
            raise CaptureFolderError(f"{path} is not a capture summary: it has no schema "
                                     "and none of a capture's keys")
    if kind is not None and found != kind:
        raise CaptureFolderError(f"{path} is {KIND_NAMES[found]} ({KINDS[found]}), not "
                                 f"{KIND_NAMES[kind]} ({KINDS[kind]})")
    return CaptureSummary(folder, path, found, version, data)
