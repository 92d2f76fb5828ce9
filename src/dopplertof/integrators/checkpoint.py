"""A render's checkpoint file: the pipeline's accumulated sums saved atomically after
every pass (an .npz archive keyed by everything that defines the image), so that a
render stopped by Ctrl-C or a kill resumes bitwise where it stopped; anything else in
the file's place is a one-line :class:`CheckpointError`."""

from __future__ import annotations

import os

import numpy as np


def render_key(scene, params, spp: int, seed: int, variant: str, chunk: int,
               groups_per_chunk: int) -> str:
    """What must match for a checkpoint to be resumed (hex digest): the scene and its
    window, the image-defining parameters, spp, seed, variant and the chunking."""
    import hashlib

    parts = (scene.fingerprint or scene.source, params, spp, int(seed), variant, chunk,
             groups_per_chunk)
    if scene.shutter_window is not None:  # (a camera's raw frame: its own window)
        parts += (scene.shutter_window,)
    text = repr(parts)
    return hashlib.sha256(text.encode()).hexdigest()


class CheckpointError(ValueError):
    """A checkpoint that belongs to another render or cannot be read."""


#: the arrays of a checkpoint file (an .npz archive); "inputs" (the referenced files'
#: hashes) is optional: checkpoints saved before it was added have none
CHECKPOINT_ARRAYS = ("key", "total", "nonfinite", "next", "pilot_sums", "squares", "counts")


def _read_checkpoint(path) -> dict:
    """Every array of the checkpoint file ``path``; a file that is not one (random
    bytes, text, an image .npy, empty, truncated) is a one-line CheckpointError and is
    left as it is."""
    try:
        f = open(path, "rb")
    except OSError as e:  # (no permission, a folder...): the file's content is not at fault
        raise CheckpointError(f"checkpoint {path} cannot be read: {e.strerror or e}") from None
    with f:
        head = f.read(4)
        f.seek(0)
        try:
            return _checkpoint_arrays(f, head)
        except _NotACheckpoint as e:
            reason = str(e)
        except Exception as e:  # numpy's and zipfile's errors about what the bytes are
            reason = (f"truncated or damaged: {' '.join(str(e).split()) or type(e).__name__}"
                      if head == b"PK\x03\x04" else "not a NumPy .npz archive")
    raise CheckpointError(f"{path} is not a dopplertof checkpoint ({reason}); delete it or "
                          "choose another checkpoint file")


class _NotACheckpoint(Exception):
    """What a file that is not a checkpoint is instead (the reason, for the message)."""


def _checkpoint_arrays(f, head: bytes) -> dict:
    """The arrays of the open checkpoint file ``f`` (starting with the bytes ``head``)."""
    if not head:
        raise _NotACheckpoint("an empty file")
    data = np.load(f, allow_pickle=False)
    if not isinstance(data, np.lib.npyio.NpzFile):
        raise _NotACheckpoint("a NumPy array, not a checkpoint archive")
    with data:
        missing = [name for name in CHECKPOINT_ARRAYS if name not in data.files]
        if missing:
            raise _NotACheckpoint(f"an archive without the {missing[0]!r} array")
        return {name: data[name] for name in data.files}


def _load_checkpoint(path, key: str, inputs=()):
    """(total, nonfinite, next chunk, pilot sums, squares, counts) of the checkpoint
    ``path`` saved with ``key``; None when there is no file."""
    import json

    from ..scene.inputs import changed_input

    if not os.path.exists(path):
        return None
    data = _read_checkpoint(path)
    if str(data["key"]) != key:
        saved_inputs = json.loads(str(data["inputs"])) if "inputs" in data else None
        changed = None if saved_inputs is None else changed_input(saved_inputs, inputs)
        if changed is not None:
            raise CheckpointError(
                f"checkpoint {path} was saved before {changed.name} ({changed.path}) "
                "changed: resuming would blend two scenes; delete the checkpoint to render "
                "again")
        raise CheckpointError(
            f"checkpoint {path} belongs to a different render (scene, parameters, spp, seed "
            "or variant differ); delete it or choose another checkpoint file")
    try:
        return (data["total"], int(data["nonfinite"]), int(data["next"]),
                data["pilot_sums"], data["squares"], data["counts"])
    except (TypeError, ValueError) as e:
        raise CheckpointError(f"{path} is not a dopplertof checkpoint (damaged: {e}); "
                              "delete it or choose another checkpoint file") from None


def _save_checkpoint(path, key: str, total, nonfinite: int, next_chunk: int,
                     pilot_sums=None, squares=None, counts=None, inputs=()) -> None:
    """``pilot_sums``, ``squares`` and ``counts``: the adaptive pilot's sums of samples
    and of squared group sums, and the sample counts, when there are (else saved
    empty); ``inputs``: the scene's referenced files, whose hashes name a changed one
    when the key no longer matches."""
    from ..io import atomic_path
    from ..scene.inputs import manifest

    with atomic_path(path) as tmp:
        with open(tmp, "wb") as f:
            np.savez(f, key=np.array(key), total=total, nonfinite=np.array(nonfinite),
                     next=np.array(next_chunk),
                     pilot_sums=np.zeros(0) if pilot_sums is None else pilot_sums,
                     squares=np.zeros(0) if squares is None else squares,
                     counts=np.zeros(0, np.int64) if counts is None else counts,
                     inputs=np.array(manifest(inputs)))


class Checkpoint:
    """A render's accumulated state on disk (the pipeline's Accumulator), saved
    atomically after every pass.

    Resumed only by the same render (``key``: scene and the content of every file it
    references, image-defining parameters, spp, seed, variant, chunk size); anything
    else is a :class:`CheckpointError`, which names a referenced file (of ``inputs``,
    InputFile) that changed since the save."""

    def __init__(self, path, key: str, inputs=()):
        self.path, self.key, self.inputs = path, key, tuple(inputs)

    def load(self, accumulator):
        """Restore ``accumulator`` from the file; returns (next chunk, counts or None),
        or None when there is no file. Temporary files that a killed save left beside
        it are removed first."""
        from ..io import remove_temporaries

        remove_temporaries(self.path)
        saved = _load_checkpoint(self.path, self.key, self.inputs)
        if saved is None:
            return None
        total, nonfinite, next_chunk, pilot_sums, squares, counts = saved
        if not accumulator.adaptive:  # (the key holds the parameters)
            pilot_sums = squares = None
        accumulator.restore(total, nonfinite, pilot_sums, squares)
        return next_chunk, (counts if counts.size else None)

    def save(self, accumulator, next_chunk: int, counts) -> None:
        _save_checkpoint(self.path, self.key, accumulator.host_total(),
                         accumulator.nonfinite, next_chunk, accumulator.pilot_sums,
                         accumulator.squares, counts, self.inputs)
