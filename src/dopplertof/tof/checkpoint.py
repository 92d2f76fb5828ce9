"""A checkpoint folder of a run of several renders (``capture --checkpoint DIR``: a
frame's captures, a camera's raw frames, their error-bar batches).

Every render of the run keeps its own render checkpoint in the folder
(:class:`dopplertof.render.Checkpoint`: saved atomically after every pass; a complete one
returns its image at once, bitwise), so that a run stopped by Ctrl-C or a kill and
started again renders only what is missing, and its outputs are bitwise those of an
uninterrupted run. The folder's manifest holds the key of the whole run: the scene's
content digest (:func:`dopplertof.scene.inputs.content_digest`, the scene's
fingerprint) and every render's settings (name, exposure window, image-defining
parameters, spp, seed) and the variant; a run with another key is refused in one line
before anything renders. The reconstruction's own settings (sensor noise, --min-signal)
do not enter it: they change no render.
"""

from __future__ import annotations

import hashlib
import json
import os
import sys

#: the manifest of a checkpoint folder: its key and the render checkpoints it holds
MANIFEST = "capture_checkpoint.json"
#: the extension of each render's checkpoint file in the folder
RENDER_CHECKPOINT_EXT = ".ckpt"


def batch_name(name: str, batch: int) -> str:
    """The render name of error-bar batch ``batch`` of the capture ``name`` (batch 0
    is the capture itself)."""
    return name if batch == 0 else f"{name}_batch{batch}"


class CaptureCheckpoint:
    """The checkpoint folder of one run of renders; :meth:`open` checks or starts it."""

    def __init__(self, folder: str, names: list, key: str = ""):
        self.folder, self.names, self.key = folder, list(names), key
        self.reused, self.resumed, self.rendered = 0, 0, 0
        self.timed_out = 0  #: renders the timeout stopped (their checkpoints resume them)

    @classmethod
    def open(cls, folder, scene, renders) -> "CaptureCheckpoint":
        """The checkpoint folder ``folder`` for ``renders`` of ``scene`` (a list of
        (name, scene window, RenderParams, spp, seed), in render order): a folder of
        the same run is resumed; one of another run is a CheckpointError; else the
        manifest is written (atomically) and the renders start afresh."""
        from .. import file_formats, io
        from ..backend import require_variant
        from ..render import CheckpointError

        folder = io.check_output_folder(folder)
        key = hashlib.sha256(repr((
            scene.fingerprint or scene.source, require_variant().variant(),
            [(name, window, params.image_defining(), int(spp), int(seed))
             for name, window, params, spp, seed in renders])).encode()).hexdigest()
        names = [name for name, *_ in renders]
        manifest = os.path.join(folder, MANIFEST)
        saved = _read_manifest(manifest, CheckpointError)
        if saved is not None and saved.get("key") != key:
            raise CheckpointError(
                f"checkpoint folder {folder} holds the renders of another capture (the "
                "scene or a file it references, the parameters, spp, seed, camera or "
                "variant differ); delete it or choose another checkpoint folder")
        if saved is None:
            file_formats.write_json(manifest, {"key": key, "renders": names, "timed_out": 0})
        return cls(folder, names, key)

    def path(self, name: str) -> str:
        """The render checkpoint file of the render ``name``."""
        return os.path.join(self.folder, name + RENDER_CHECKPOINT_EXT)

    def count(self, metadata: dict) -> None:
        """Count a finished render by its metadata: reused (its checkpoint was complete),
        resumed (part of it was saved) or rendered afresh."""
        saved = metadata.get("resumed_from_samples")
        self.timed_out += bool(metadata.get("timed_out"))
        if saved is None:
            self.rendered += 1
        elif saved >= metadata["spp"]:
            self.reused += 1
        else:
            self.resumed += 1

    def report(self, what: str = "renders") -> None:
        """Say on stderr how many renders the checkpoint served, and record in the
        manifest how many the timeout stopped (:func:`remove_checkpoint` keeps the
        folder then)."""
        from .. import file_formats

        file_formats.write_json(os.path.join(self.folder, MANIFEST),
                      {"key": self.key, "renders": self.names, "timed_out": self.timed_out})
        stopped = (f", {self.timed_out} stopped by the timeout (the same command resumes "
                   "them)" if self.timed_out else "")
        print(f"dopplertof: checkpoint {self.folder}: {self.reused} of "
              f"{len(self.names)} {what} reused, {self.resumed} resumed part way, "
              f"{self.rendered} rendered{stopped}", file=sys.stderr, flush=True)


def _read_manifest(path: str, error):
    """The manifest at ``path`` ({"key", "renders"}), None when there is none; a file
    that is not one is ``error``."""
    if not os.path.exists(path):
        return None
    try:
        with open(path, encoding="utf-8") as f:
            saved = json.load(f)
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as e:
        raise error(f"{path} is not a dopplertof capture checkpoint manifest "
                    f"({' '.join(str(e).split())}); delete the checkpoint folder or choose "
                    "another") from None
    if not isinstance(saved, dict):
        raise error(f"{path} is not a dopplertof capture checkpoint manifest; delete the "
                    "checkpoint folder or choose another")
    return saved


def remove_checkpoint(folder) -> bool:
    """Delete a checkpoint folder's files (its manifest and the render checkpoints it
    names; nothing else), and the folder when that leaves it empty: what a finished run
    whose outputs are safe does. A folder whose last run the timeout stopped is kept
    (the same command resumes it; like ``render --checkpoint``), which it says on
    stderr: returns False then."""
    import contextlib

    from .. import io

    folder = os.path.abspath(os.fspath(folder))
    manifest = os.path.join(folder, MANIFEST)
    saved = _read_manifest(manifest, io.OutputError) or {}
    if saved.get("timed_out"):
        print(f"dopplertof: checkpoint {folder} kept: the timeout stopped "
              f"{saved['timed_out']} of its renders; the same command resumes them",
              file=sys.stderr)
        return False
    for name in saved.get("renders", []):
        with contextlib.suppress(FileNotFoundError):
            os.unlink(os.path.join(folder, os.path.basename(name) + RENDER_CHECKPOINT_EXT))
    with contextlib.suppress(FileNotFoundError):
        os.unlink(manifest)
    with contextlib.suppress(OSError):
        os.rmdir(folder)  # (only when empty)
    return True
