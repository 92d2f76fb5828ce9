"""Reading a dataset folder without PyTorch: ``Dataset(DIR, split=...)``."""

from __future__ import annotations

import json
import os

import numpy as np

from .config import DatasetError
from .driver import DATASET_JSON, LAYOUT_VERSION, SPLITS
from .shards import sample_group, shard_state


class Dataset:
    """The samples of a ``dopplertof dataset`` folder, in index order.

    ``len(ds)`` counts the samples present (a failed sample is listed in
    ``ds.failed``, not here); ``ds[i]`` is a dict of NumPy arrays (docs/dataset.md:
    ``raw``, ``raw_ideal``, ``raw_direct``, ``depth``, ``velocity_gt``, ``flow``...)
    plus ``index`` and ``seed``, where ``raw`` is the split's raw frames: ``full``
    (noise, global illumination), ``ideal`` (no noise) or ``direct`` (no multipath,
    no noise). ``ds.units[key]`` is each array's unit; ``ds.attributes(i)`` the
    sample's scene (XML), description, seeds and camera preset, ``ds.scene(i)`` the
    loaded scene. Files are opened per
    item, so that the object can be handed to forked loader processes."""

    def __init__(self, folder, split: str = "full"):
        if split not in SPLITS:
            raise DatasetError(f"unknown split {split!r}: one of {', '.join(SPLITS)}")
        self.folder, self.split = os.fspath(folder), split
        path = os.path.join(self.folder, DATASET_JSON)
        try:
            with open(path, encoding="utf-8") as f:
                self.info = json.load(f)
        except (OSError, ValueError) as e:
            raise DatasetError(f"{path}: not a dataset folder ({e})") from None
        if self.info.get("layout_version") != LAYOUT_VERSION:
            raise DatasetError(f"{path}: layout version {self.info.get('layout_version')!r}, "
                               f"this reader reads {LAYOUT_VERSION}")
        self.units = dict(self.info["units"])
        self._where, self.failed, self.missing_shards = [], [], []
        for shard in self.info["shards"]:
            shard_path = os.path.join(self.folder, shard["file"])
            state = shard_state(shard_path, self.info["config_hash"])
            if state is None:
                self.missing_shards.append(shard["file"])
                continue
            self._where += [(shard_path, i) for i in state[0]]
            self.failed += state[1]

    def __len__(self) -> int:
        return len(self._where)

    def _group(self, item: int):
        if not -len(self) <= item < len(self):
            raise IndexError(f"sample {item} of {len(self)}")
        return self._where[item]

    def __getitem__(self, item: int) -> dict:
        import h5py

        path, index = self._group(item)
        with h5py.File(path, "r") as f:
            group = f[sample_group(index)]
            sample = {key: group[key][()] for key in group}
            seed = int(group.attrs["render_seed"])
        sample["raw"] = sample[SPLITS[self.split]]
        sample.update(index=np.int64(index), seed=np.int64(seed))
        return sample

    def attributes(self, item: int) -> dict:
        """The sample's attributes: index, render_seed, noise_seed, scene_xml,
        description (parsed), camera_preset (parsed), photons_per_unit."""
        import h5py

        path, index = self._group(item)
        with h5py.File(path, "r") as f:
            attrs = {k: v.item() if hasattr(v, "item") else v
                     for k, v in f[sample_group(index)].attrs.items()}
        for key in ("description", "camera_preset"):
            attrs[key] = json.loads(attrs[key])
        return attrs

    def scene(self, item: int):
        """The sample's scene, loaded from its stored XML (a DopplerScene; its meshes are
        the dataset's copies): ``capture_camera(ds.scene(i), preset, spp,
        ds.attributes(i)["render_seed"], ...)`` renders it again, bitwise."""
        from ..scene import load_string

        return load_string(self.attributes(item)["scene_xml"], {},
                           source=f"{self.folder}: sample {item}", base_dir=self.folder)
