"""HDF5 shards: one file per run of consecutive samples, one group per sample.

A shard is written whole into a temporary file and renamed into place
(:func:`dopplertof.io.atomic_path`): a shard file that exists is complete. Its
attributes name the dataset's configuration hash (a shard of another configuration is
not this dataset's), the samples it holds and those that failed. Datasets are chunked
and gzip-compressed (images) with their unit as the ``units`` attribute; nothing in
the file records when it was written (h5py's groups and these datasets track no
times), so that the same samples give the same bytes.
"""

from __future__ import annotations

import json
import os

import numpy as np

#: gzip level of the image datasets
COMPRESSION_LEVEL = 4
#: arrays smaller than this many elements are stored contiguous and uncompressed
SMALL_ARRAY = 64


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
                for arrays, sample_attributes in samples:
                    _write_sample(f, arrays, sample_attributes, units)
        except OSError as exc:
            raise io.write_error(path, exc) from exc


def _write_sample(f, arrays: dict, attributes: dict, units: dict) -> None:
    group = f.create_group(sample_group(attributes["index"]))
    for key, value in attributes.items():
        group.attrs[key] = value
    for key in sorted(arrays):
        array = np.asarray(arrays[key])
        options = {} if array.size < SMALL_ARRAY else {
            "chunks": True, "compression": "gzip", "compression_opts": COMPRESSION_LEVEL,
            "shuffle": True}
        dataset = group.create_dataset(key, data=array, track_times=False, **options)
        dataset.attrs["units"] = units[key]


def shard_state(path: str, config_hash: str):
    """None when ``path`` is not a complete shard of this configuration, else its
    (sample indices, failed [{"index", "error"}])."""
    import h5py

    if not os.path.isfile(path):
        return None
    try:
        with h5py.File(path, "r") as f:
            if f.attrs.get("config_hash") != config_hash:
                return None
            return [int(i) for i in f.attrs["samples"]], json.loads(f.attrs["failed"])
    except (OSError, KeyError, ValueError):
        return None
