"""Reading a dataset folder without PyTorch: ``Dataset(DIR, split=...)``."""

from __future__ import annotations

import json
import os
import warnings

import numpy as np

from ..arguments import check_choice, check_index, check_path
from .config import DatasetError
from .driver import SPLITS, load_dataset_json
from ..outputs import RENAMED, renamed
from .sample import CAMERA_OUTPUTS, CAMERA_SPLITS
from .shards import DamagedSample, index_span, read_group, sample_group, shard_state

#: what the reader does with a missing, damaged or misplaced shard
ON_DAMAGE = ("error", "skip")


def clip_frames(attributes: dict) -> int:
    """How many frames a sample holds (``clip_frames``; 1 without the attribute)."""
    return int(attributes.get("clip_frames", 1))


def clip_frame(sample: dict, frame: int) -> dict:
    """Frame ``frame`` of a clip's sample (every (T, ...) array's entry ``frame``; the
    0-d values, index and seed, kept)."""
    return {key: value[frame] if np.ndim(value) else value for key, value in sample.items()}


class Dataset:
    """The samples of a ``dopplertof dataset`` folder, in index order.

    ``len(ds)`` counts the samples present (a failed sample is listed in
    ``ds.failed``, not here); ``ds[i]`` is a dict of NumPy arrays (docs/dataset.md:
    ``raw``, ``raw_ideal``, ``raw_direct``, ``depth``, ``velocity_gt``, ``flow``...)
    plus ``index`` and ``seed``, where ``raw`` is the split's raw frames: ``full``
    (noise, global illumination), ``ideal`` (no noise) or ``direct`` (no multipath,
    no noise), and the ``camera_*`` outputs (camera_depth, camera_amplitude...) are the
    split's reconstruction by the camera. ``ds.units[key]`` is each array's unit;
    ``ds.attributes(i)`` the sample's scene (XML), description, seeds and camera preset,
    ``ds.scene(i)`` the loaded scene. Files are opened per
    item, so that the object can be handed to forked loader processes.

    Integrity: a shard that is missing, truncated, damaged, of another
    configuration or holds other samples than planned is named when the folder is
    opened (a DatasetError; ``on_damage="skip"``: a warning, its samples left out and
    the shard listed in ``missing_shards``); every sample read is checked against its
    checksum (a DatasetError naming the shard and the sample). ``dopplertof dataset
    verify DIR`` checks every sample, and a rerun renders such shards again."""

    def __init__(self, folder, split: str = "full", on_damage: str = "error"):
        folder = check_path(folder, "folder")
        split = check_choice(split, SPLITS, "split", DatasetError)
        on_damage = check_choice(on_damage, ON_DAMAGE, "on_damage", DatasetError)
        self.folder, self.split = folder, split
        self.info = load_dataset_json(folder)
        #: a key written under a name that changed since (an older layout) -> its name
        self._renamed = {old: _new_name(old) for old in self.info["units"]
                         if _new_name(old) is not None}
        if self._renamed:
            warnings.warn(f"{folder}: written with the former names of "
                          f"{', '.join(f'{v} ({k})' for k, v in self._renamed.items())}: "
                          "read under their present names", FutureWarning, stacklevel=2)
        self.units = {self._renamed.get(k, k): v for k, v in self.info["units"].items()}
        self._where, self.failed, self.missing_shards = [], [], []
        for shard in self.info["shards"]:
            shard_path = os.path.join(self.folder, shard["file"])
            state = shard_state(shard_path, self.info["config_hash"], shard["samples"],
                                full=False)
            if state.problem is not None:
                problem = (f"{shard_path} (samples {index_span(shard['samples'])}): "
                           f"{state.problem}")
                if on_damage == "error":
                    raise DatasetError(
                        f"{problem}: a rerun of the dataset renders it again (`dopplertof "
                        f"dataset verify {self.folder}` lists what it redoes); "
                        "Dataset(..., on_damage='skip') reads the other shards")
                warnings.warn(f"{problem}: skipped", stacklevel=2)
                self.missing_shards.append(shard["file"])
                continue
            self._where += [(shard_path, i) for i in state.samples]
            self.failed += state.failed

    def __len__(self) -> int:
        return len(self._where)

    def _read(self, item) -> tuple[dict, dict]:
        """The arrays and attributes of item ``item``, checked against their checksum."""
        import h5py

        item = check_index(item, len(self), "Dataset item")
        path, index = self._where[item]
        try:
            with h5py.File(path, "r") as f:
                return read_group(f[sample_group(index)], index, path)
        except DamagedSample as exc:
            raise DatasetError(f"{exc}: a rerun of the dataset renders its shard "
                               "again") from None
        except (OSError, KeyError) as exc:
            raise DatasetError(f"{path}: sample {index}: unreadable, damaged "
                               f"({' '.join(str(exc).split())}): a rerun of the dataset "
                               "renders its shard again") from None

    def __getitem__(self, item: int) -> dict:
        sample, attributes = self._read(item)
        sample = Sample({self._renamed.get(k, k): v for k, v in sample.items()})
        sample["raw"] = sample[SPLITS[self.split]]
        suffix = CAMERA_SPLITS[self.split]
        for name in CAMERA_OUTPUTS if suffix else ():  # the split's camera outputs
            if f"camera_{name}{suffix}" in sample:
                sample[f"camera_{name}"] = sample[f"camera_{name}{suffix}"]
        sample.update(index=np.int64(attributes["index"]),
                      seed=np.int64(attributes["render_seed"]))
        return sample

    def attributes(self, item: int) -> dict:
        """The sample's attributes: index, render_seed, noise_seed, scene_xml,
        description (parsed), camera_preset (parsed), photons_per_unit; a clip's also
        clip_frames, fps, clip_times_s, clip_noise_seeds and clip_scene_xml (arrays of a
        value per frame; photons_per_unit too)."""
        attrs = {k: v.item() if hasattr(v, "item") and np.size(v) == 1 else v
                 for k, v in self._read(item)[1].items()}
        for key in ("description", "camera_preset"):
            attrs[key] = json.loads(attrs[key])
        return attrs

    def scene(self, item: int, frame: int = 0):
        """The sample's scene (a clip's: frame ``frame``'s), loaded from its stored XML
        (a DopplerScene; its meshes are the dataset's copies): ``capture_camera(
        ds.scene(i), preset, spp, ds.attributes(i)["render_seed"], ...)`` renders it
        again, bitwise."""
        from ..scene import load_string

        attributes = self.attributes(item)
        frame = check_index(frame, clip_frames(attributes), "frame")
        if "clip_scene_xml" not in attributes:
            return load_string(attributes["scene_xml"], {},
                               source=f"{self.folder}: sample {item}", base_dir=self.folder)
        return load_string(json.loads(attributes["clip_scene_xml"])[frame], {},
                           source=f"{self.folder}: sample {item}, frame {frame}",
                           base_dir=self.folder)



def _new_name(key: str, source: str | None = None) -> str | None:
    """The present name of a sample's ``key`` written under a name that changed since
    (None: not renamed); with ``source``, a FutureWarning names the change."""
    suffix = next((s for s in CAMERA_SPLITS.values() if s and key.endswith(s)), "")
    base = key[:len(key) - len(suffix)]
    if ("dataset", base) not in RENAMED:
        return None
    return (renamed("dataset", base, source) if source else RENAMED[("dataset", base)]) + suffix


class Sample(dict):
    """A sample's arrays by key; a key's former name (:data:`dopplertof.outputs.RENAMED`)
    reads it too, with a FutureWarning naming the present one."""

    def __missing__(self, key):
        new = _new_name(key) if isinstance(key, str) else None
        if new is None or new not in self:
            raise KeyError(key)
        return self[_new_name(key, "a dataset sample")]  # (with the warning)
