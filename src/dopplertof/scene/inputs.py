"""What a scene reads besides its own description: the files it names (meshes,
textures, spectra: every ``filename``), resolved as Mitsuba resolves them, and the content
hash that covers them (the files a scene includes are read into it by :mod:`.includes`).

:func:`content_digest` is the one hash of "a scene and every file it references":
the scene's fingerprint (checkpoint keys), and the scene digest of sweep and
animation run markers (:func:`scene_file_digest`) are made by it, so that a changed
mesh invalidates a checkpoint and a run marker alike.
"""

from __future__ import annotations

import hashlib
import json
import os
from typing import NamedTuple

#: the property (XML ``<string name=...>``, dict key) and attribute that name a file
FILENAME = "filename"


class InputFile(NamedTuple):
    """A file a scene references: its name as written, where it resolved to, and the
    sha256 of its content ("missing" when it is not a file)."""

    name: str
    path: str
    sha256: str


def file_sha256(path) -> str:
    """The sha256 of a file's content (hex)."""
    digest = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def content_digest(description, inputs=()) -> str:
    """The content hash of a scene and every file it references (hex sha256): of
    ``description`` (the scene file's bytes, or the resolved description text) and of
    each InputFile's name as written and content. A scene that references no file
    hashes as its description alone; paths are left out, so that a moved folder
    keeps its hashes."""
    data = description.encode("utf-8") if isinstance(description, str) else bytes(description)
    digest = hashlib.sha256(data)
    if inputs:
        digest.update(json.dumps([[f.name, f.sha256] for f in inputs]).encode("utf-8"))
    return digest.hexdigest()


def scene_file_digest(path, scene) -> str:
    """The digest of a scene file as run markers record it: the file's bytes (read
    now) and the files that ``scene`` (loaded from it) references."""
    with open(path, "rb") as f:
        return content_digest(f.read(), scene.inputs)


def changed_input(saved: dict, inputs) -> InputFile | None:
    """The first of ``inputs`` whose content differs from ``saved`` ({name: sha256}, as
    :func:`manifest` writes it), or that ``saved`` does not name; None when all match."""
    for item in inputs:
        if saved.get(item.name) != item.sha256:
            return item
    return None


def manifest(inputs) -> str:
    """``inputs`` as JSON text {name: sha256} (what a checkpoint keeps beside its key)."""
    return json.dumps({f.name: f.sha256 for f in inputs}, sort_keys=True)


# ---- Resolving names as Mitsuba does ------------------------------------------------------

class Resolver:
    """Mitsuba's file resolution: a relative name is looked up in each folder in
    order (the first that holds it wins), else taken as it is (from the current
    folder)."""

    def __init__(self, folders):
        self.folders = tuple(os.fspath(f) for f in folders)

    @classmethod
    def of(cls, mi, base_dir: str | None = None) -> "Resolver":
        """Mitsuba's current file resolver, with ``base_dir`` first (how a scene file's
        folder is searched first)."""
        resolver = mi.file_resolver()
        folders = [str(resolver[i]) for i in range(len(resolver))]
        return cls(([base_dir] if base_dir else []) + folders)

    def inside(self, folder: str) -> "Resolver":
        """This resolver with ``folder`` searched first."""
        return Resolver((folder,) + self.folders)

    def resolve(self, name: str) -> str:
        if not os.path.isabs(name):
            for folder in self.folders:
                candidate = os.path.join(folder, name)
                if os.path.exists(candidate):
                    return os.path.abspath(candidate)
        return os.path.abspath(name)

    def input_file(self, name: str) -> InputFile:
        path = self.resolve(name)
        return InputFile(name, path, file_sha256(path) if os.path.isfile(path) else "missing")


# ---- The files a scene names ---------------------------------------------------------------

def _named_files(element):
    """Every file name an XML element tree names, in document order: a ``filename``
    attribute (<spectrum>) or a <string name="filename">."""
    for el in element.iter():
        if FILENAME in el.attrib:
            yield el.attrib[FILENAME]
        elif el.tag == "string" and el.get("name") == FILENAME and "value" in el.attrib:
            yield el.attrib["value"]


def xml_inputs(root, resolver: Resolver, folder: str | None = None) -> list:
    """Every InputFile an XML scene (``root``, its ``$`` values substituted and its
    includes read in; read from ``folder``, None for a string) references, resolved as
    Mitsuba's parser does: with ``resolver`` (the scene's folder first), a top-level
    <path> folder searched first for what follows it."""
    found = []
    for child in root:
        if child.tag == "path" and "value" in child.attrib:
            resolver = resolver.inside(_resource_folder(child.attrib["value"], resolver,
                                                        folder))
            continue
        found += [resolver.input_file(name) for name in _named_files(child)]
    return _unique(found)


def _resource_folder(name: str, resolver: Resolver, folder: str | None) -> str:
    """Where a <path value="name"> points: beside the file that names it (the current
    folder for a string), else where the resolver finds it."""
    beside = os.path.join(folder or "", name)
    return os.path.abspath(beside) if os.path.exists(beside) else resolver.resolve(name)


def dict_inputs(scene, resolver: Resolver) -> list:
    """Every InputFile a dict scene references: the value of each ``filename`` key of
    its (nested) dicts."""
    found = []

    def visit(value):
        if isinstance(value, dict):
            for key, item in value.items():
                if key == FILENAME and isinstance(item, (str, os.PathLike)):
                    found.append(resolver.input_file(os.fspath(item)))
                else:
                    visit(item)
        elif isinstance(value, (list, tuple)):
            for item in value:
                visit(item)

    visit(scene)
    return _unique(found)


def _unique(items) -> list:
    """``items`` without repeats (first occurrence kept)."""
    return list(dict.fromkeys(items))
