"""HDF5 shards: one file per run of consecutive samples, one group per sample.

A shard is written whole into a temporary file and renamed into place
(:func:`dopplertof.io.atomic_path`). Its attributes name the dataset's configuration
hash (a shard of another configuration is not this dataset's), the samples it holds and
those that failed. Datasets are chunked, gzip-compressed (images) and carry HDF5's
fletcher32 checksum, with their unit as the ``units`` attribute; nothing in the file
records when it was written (h5py's groups and these datasets track no times), so that
the same samples give the same bytes.

Integrity: every sample group holds ``sha256``, the SHA-256 of its arrays
(dtype, shape, bytes), their units and its attributes, and the file holds ``sha256`` of
its own attributes and its samples' digests. :func:`shard_state` checks a shard against
what the dataset planned for it (present, readable, this configuration, the planned
samples, the digests): a shard that fails is named with the reason, and the driver
renders it again.
"""

from __future__ import annotations

import hashlib
import json
import os
from dataclasses import dataclass, field

import numpy as np

#: gzip level of the image datasets
COMPRESSION_LEVEL = 4
#: arrays smaller than this many elements are stored uncompressed (in one chunk: the
#: fletcher32 checksum needs chunks)
SMALL_ARRAY = 64
#: the attribute holding the SHA-256 of a sample group, and of a shard's attributes
DIGEST = "sha256"


def shard_name(number: int) -> str:
    return f"shard_{number:05d}.h5"


def sample_group(index: int) -> str:
    return f"sample_{index:08d}"


def write_shard(path: str, samples: list, failed: list, attributes: dict, units: dict) -> None:
    """Write ``samples`` [(arrays, attributes)] and ``failed`` [{"index", "error"}] to
    the shard ``path``, atomically."""
    import h5py

    from .. import io

    with io.atomic_path(path) as tmp:
        try:
            # no chunk cache (rdcc_nbytes=0): every chunk is placed in the file as it is
            # written, in the order below, never when a cached chunk happens to be evicted
            # or its dataset garbage-collected (which made a shard's bytes depend on the
            # process: same arrays, chunks in another order)
            with h5py.File(tmp, "w", libver=("v110", "v110"), track_order=False,
                           rdcc_nbytes=0) as f:
                for key, value in attributes.items():
                    f.attrs[key] = value
                f.attrs["samples"] = np.asarray([a["index"] for _, a in samples], np.int64)
                f.attrs["failed"] = json.dumps(failed)
                digests = [_write_sample(f, arrays, sample_attributes, units)
                           for arrays, sample_attributes in samples]
                f.attrs[DIGEST] = shard_digest(f.attrs, digests)
        except OSError as exc:
            raise io.write_error(path, exc) from exc


def _write_sample(f, arrays: dict, attributes: dict, units: dict) -> str:
    """One sample group; returns its digest (of what the file holds, read back)."""
    group = f.create_group(sample_group(attributes["index"]))
    for key, value in attributes.items():
        group.attrs[key] = value
    for key in sorted(arrays):
        array = np.asarray(arrays[key])
        options = {"chunks": array.shape} if array.size < SMALL_ARRAY else {
            "chunks": True, "compression": "gzip", "compression_opts": COMPRESSION_LEVEL,
            "shuffle": True}
        dataset = group.create_dataset(key, data=array, track_times=False, fletcher32=True,
                                       **options)
        dataset.attrs["units"] = units[key]
    group.attrs[DIGEST] = group_digest(group)
    return group.attrs[DIGEST]


def _hash_value(sha, kind: str, key: str, value) -> None:
    value = np.asarray(value)
    sha.update(json.dumps([kind, key, value.dtype.str, list(value.shape)]).encode("utf-8"))
    sha.update(np.ascontiguousarray(value).tobytes())


def group_digest(group) -> str:
    """SHA-256 of a sample group as stored (:func:`sample_digest`). Raises OSError where
    HDF5 cannot read a chunk (its fletcher32 checksum fails)."""
    return sample_digest(dict(group.attrs), {key: group[key][()] for key in group},
                         {key: group[key].attrs.get("units", "") for key in group})


def sample_digest(attributes: dict, arrays: dict, units: dict) -> str:
    """SHA-256 of a sample: its attributes (but its digest), and each array's dtype,
    shape, bytes and units."""
    sha = hashlib.sha256()
    for key in sorted(attributes):
        if key != DIGEST:
            _hash_value(sha, "attribute", key, attributes[key])
    for key in sorted(arrays):
        _hash_value(sha, "array", key, arrays[key])
        _hash_value(sha, "units", key, units.get(key, ""))
    return sha.hexdigest()


def shard_digest(attributes, sample_digests: list) -> str:
    """SHA-256 of a shard's attributes (but its digest) and its samples' digests."""
    sha = hashlib.sha256()
    for key in sorted(attributes):
        if key != DIGEST:
            _hash_value(sha, "attribute", key, attributes[key])
    _hash_value(sha, "samples", "", np.asarray(sample_digests, dtype=str))
    return sha.hexdigest()


class DamagedSample(OSError):
    """A sample group whose arrays or attributes do not match its digest, or that HDF5
    cannot read; ``sample_problem`` says which sample and why, without the file."""

    def __init__(self, path: str, index: int, reason: str):
        self.sample_problem = f"sample {index}: {reason}"
        super().__init__(f"{path}: {self.sample_problem}")


def read_group(group, index: int, path: str):
    """The sample group's arrays and attributes (its digest left out), checked against
    its digest: a DamagedSample naming the shard and the sample when they differ."""
    try:
        arrays = {key: group[key][()] for key in group}
        units = {key: group[key].attrs.get("units", "") for key in group}
        attributes = dict(group.attrs)
        stored = attributes.pop(DIGEST, None)
        matches = stored is not None and sample_digest(attributes, arrays, units) == stored
    except (OSError, KeyError, ValueError) as exc:  # a chunk whose fletcher32 fails
        raise DamagedSample(path, index, "unreadable, damaged "
                            f"({' '.join(str(exc).split())})") from None
    if not matches:
        raise DamagedSample(path, index, "its arrays or attributes do not match its "
                            "checksum (damaged)")
    return arrays, attributes


@dataclass
class ShardState:
    """What a shard file holds, checked against what the dataset planned for it."""

    samples: list = field(default_factory=list)  #: the indices present, in order
    failed: list = field(default_factory=list)  #: [{"index", "error"}]
    problem: str | None = None  #: why the shard cannot be used (None: it can)

    @property
    def complete(self) -> bool:
        """Usable and without a failed sample (nothing for a rerun to redo)."""
        return self.problem is None and not self.failed


def shard_state(path: str, config_hash: str, indices=None, full: bool = True) -> ShardState:
    """Check the shard ``path`` of the configuration ``config_hash`` planned to hold the
    samples ``indices`` (None: not checked): its ``problem`` names what is wrong
    (missing, unreadable or truncated, another configuration, other samples than
    planned, written without checksums, a digest that does not match). ``full``: every
    sample's arrays and attributes are read and checked too, else the shard's
    attributes and the samples' digests only."""
    import h5py

    if not os.path.isfile(path):
        return ShardState(problem="missing")
    try:
        with h5py.File(path, "r") as f:
            return _check_shard(f, path, config_hash, indices, full)
    except DamagedSample as exc:
        return ShardState(problem=exc.sample_problem)
    except (OSError, KeyError, ValueError, TypeError) as exc:
        return ShardState(problem="unreadable, truncated or damaged "
                                  f"({' '.join(str(exc).split())})")


def _check_shard(f, path: str, config_hash: str, indices, full: bool) -> ShardState:
    attributes = dict(f.attrs)
    if attributes.get("config_hash") != config_hash:
        return ShardState(problem="a shard of another configuration")
    samples = [int(i) for i in attributes["samples"]]
    failed = json.loads(attributes["failed"])
    state = ShardState(samples, failed)
    if DIGEST not in attributes:
        state.problem = "written without checksums (by an older dopplertof)"
        return state
    groups = sorted(f)
    digests = [f[sample_group(i)].attrs.get(DIGEST, "") if sample_group(i) in f else ""
               for i in samples]
    if (groups != sorted(sample_group(i) for i in samples)
            or shard_digest(attributes, digests) != attributes[DIGEST]):
        state.problem = "its attributes or sample list do not match its checksum (damaged)"
        return state
    held = sorted(samples + [int(x["index"]) for x in failed])
    if indices is not None and held != sorted(int(i) for i in indices):
        state.problem = (f"holds samples {index_span(held)} where samples {index_span(indices)} belong "
                         "(misplaced)")
        return state
    if full:
        for index in samples:
            read_group(f[sample_group(index)], index, path)
    return state


def index_span(indices) -> str:
    """Sample indices as a reader says them: 4-7, or 1, 3."""
    indices = sorted(int(i) for i in indices)
    if not indices:
        return "none"
    if indices == list(range(indices[0], indices[-1] + 1)) and len(indices) > 2:
        return f"{indices[0]}-{indices[-1]}"
    return ", ".join(map(str, indices))
