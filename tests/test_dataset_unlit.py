"""A dataset sample through a preset whose illuminator lights less than the view carries
the camera's unlit mask (camera_mask_unlit, each split; a clip's (T, H, W)), the same
mask ``dopplertof capture --camera`` writes for the sample's scene; an older layout's
folder, without it, reads it as absent."""

import json
import math
import shutil

import numpy as np
import pytest

pytest.importorskip("h5py")

from dopplertof.dataset import Dataset  # noqa: E402
from test_dataset import _write_toml, in_process_client  # noqa: E402,F401

#: azure-kinect-nfov-binned (illuminator 75 x 65 deg, pinhole 75 deg wide) at 40 x 36,
#: its aspect: the view spans 2 atan(tan 37.5 deg x 36/40) = 69.27 deg vertically; a row
#: is wholly outside the lit 65 deg where its edge nearest the axis lies beyond
#: f tan 32.5 deg = 16.59 px from the centre (f = 20 / tan 37.5 deg = 26.06 px): row 0
#: (17 px) and row 35, none of the others (row 1: 16 px)
UNLIT = {"samples": 2, "samples_per_shard": 1, "seed": 3, "clip_frames": 1,
         "render": {"resolution": [40, 36], "spp": 2, "max_depth": 2,
                    "camera": "azure-kinect-nfov-binned"},
         "objects": {"count": [1, 1], "shapes": ["sphere"], "materials": ["diffuse"]}}
SUFFIXES = ("", "_ideal", "_direct")


def _expected_rows(width: int = 40, height: int = 36) -> list:
    focal = 0.5 * width / math.tan(math.radians(37.5))
    edge = focal * math.tan(math.radians(32.5))
    return [r for r in range(height) if abs(r + 0.5 - height / 2) - 0.5 > edge]


@pytest.fixture(scope="module")
def unlit(tmp_path_factory, in_process_client):
    """Two samples of UNLIT and one clip of two frames: their folders."""
    from dopplertof.dataset import load_config
    from dopplertof.dataset.driver import run_dataset

    folders = {}
    for name, changes in (("frames", {}), ("clip", {"samples": 1, "clip_frames": 2})):
        root = tmp_path_factory.mktemp(f"unlit_{name}")
        config_file = _write_toml(root / "unlit.toml", {**UNLIT, **changes})
        summary = run_dataset(load_config(config_file), root / "out",
                              client=in_process_client, progress=False)
        assert summary.ok, summary
        folders[name] = str(root / "out")
    return folders


def test_the_rows_outside_the_illuminators_field_are_masked_in_every_split(unlit):
    rows = _expected_rows()
    assert rows == [0, 35]
    expected = np.zeros((36, 40), bool)
    expected[rows] = True
    ds = Dataset(unlit["frames"])
    assert ds.units["camera_mask_unlit"] == "1"
    for i in range(len(ds)):
        sample = ds[i]
        for suffix in SUFFIXES:
            mask = sample[f"camera_mask_unlit{suffix}"]
            assert mask.dtype == np.bool_ and mask.shape == (36, 40)
            assert np.array_equal(mask, expected)
            assert not sample[f"camera_valid{suffix}"][mask].any()
            assert not np.isfinite(sample[f"camera_depth{suffix}"][mask]).any()
    for split, suffix in (("ideal", "_ideal"), ("direct", "_direct")):
        picked = Dataset(unlit["frames"], split=split)[0]
        assert np.array_equal(picked["camera_mask_unlit"], picked[f"camera_mask_unlit{suffix}"])


def test_a_clip_holds_the_mask_of_every_frame(unlit):
    sample = Dataset(unlit["clip"])[0]
    for suffix in SUFFIXES:
        mask = sample[f"camera_mask_unlit{suffix}"]
        assert mask.dtype == np.bool_ and mask.shape == (2, 36, 40)
        assert np.array_equal(np.flatnonzero(mask.all(axis=(0, 2))), [0, 35])
        assert mask.sum() == 2 * 2 * 40


def test_the_shards_mask_is_what_capture_camera_writes_for_the_samples_scene(unlit, tmp_path):
    """The sample's stored scene through ``dopplertof capture --camera`` at the sample's
    resolution, spp and render seed: its mask_unlit.npy is the shard's."""
    from dopplertof.cli import main

    ds = Dataset(unlit["frames"])
    attributes = ds.attributes(0)
    scene = tmp_path / "sample.xml"
    scene.write_text(attributes["scene_xml"])
    out = tmp_path / "capture"
    assert main(["capture", str(scene), "--camera", "azure-kinect-nfov-binned", "--res",
                 "40x36", "--spp", "2", "--seed", str(attributes["render_seed"]),
                 "-o", str(out)]) == 0
    written = np.load(out / "mask_unlit.npy")
    assert written.dtype == np.bool_ and written.any()
    assert np.array_equal(written, ds[0]["camera_mask_unlit"])


def test_a_folder_of_layout_3_without_the_mask_reads_it_as_absent(unlit, tmp_path):
    """Layout 3 had no camera_mask_unlit: a folder of it (the keys taken out of every
    group and of dataset.json's units, every checksum written again as that layout wrote
    them) is read and verified, the key absent in every split."""
    import h5py

    from dopplertof.dataset.driver import JSON_DIGEST, json_digest, verify_dataset
    from dopplertof.dataset.shards import DIGEST, group_digest, shard_digest

    folder = tmp_path / "layout3"
    shutil.copytree(unlit["frames"], folder)
    info = json.loads((folder / "dataset.json").read_text())
    for shard in info["shards"]:
        with h5py.File(folder / shard["file"], "a") as f:
            for name in f:
                for suffix in SUFFIXES:
                    del f[name][f"camera_mask_unlit{suffix}"]
                f[name].attrs[DIGEST] = group_digest(f[name])
            f.attrs[DIGEST] = shard_digest(f.attrs, [f[n].attrs[DIGEST] for n in
                                                     [f"sample_{i:08d}" for i in
                                                      f.attrs["samples"]]])
    info["layout_version"] = 3
    info["units"] = {k: v for k, v in info["units"].items()
                     if not k.startswith("camera_mask_unlit")}
    info[JSON_DIGEST] = json_digest(info)  # (as layout 3 wrote it)
    (folder / "dataset.json").write_text(json.dumps(info))
    assert all(state.problem is None for _, _, state in verify_dataset(str(folder)))
    for split in ("full", "ideal", "direct"):
        ds = Dataset(str(folder), split=split)
        sample = ds[0]
        assert not any(k.startswith("camera_mask_unlit") for k in sample)
        assert "camera_mask_unlit" not in ds.units
        assert sample["camera_valid"].shape == (36, 40)


def test_a_folder_of_layout_3_is_refused_as_such_not_as_another_configuration(tmp_path,
                                                                              capsys):
    """A layout 3 folder (its dataset.json as layout 3 wrote it for this very
    configuration) is not added to by a layout 4 run: one line naming the layout, not
    "another configuration ... or the configuration it was made with" (the one given);
    dataset.json untouched."""
    from dopplertof.backend import DEFAULT_VARIANT
    from dopplertof.cli import main
    from dopplertof.dataset import driver, load_config

    config_file = _write_toml(tmp_path / "unlit.toml", UNLIT)
    config = load_config(config_file)
    written = driver.LAYOUT_VERSION
    try:
        driver.LAYOUT_VERSION = 3
        old_hash = driver.config_hash(config, DEFAULT_VARIANT)
    finally:
        driver.LAYOUT_VERSION = written
    assert old_hash != driver.config_hash(config, DEFAULT_VARIANT)
    info = {"layout_version": 3, "config_hash": old_hash, "samples": 2}
    info[driver.JSON_DIGEST] = driver.json_digest(info)
    (tmp_path / "out").mkdir()
    (tmp_path / "out" / "dataset.json").write_text(json.dumps(info))
    before = (tmp_path / "out" / "dataset.json").read_bytes()
    assert main(["dataset", config_file, "-o", str(tmp_path / "out")]) == 2
    lines = capsys.readouterr().err.splitlines()
    assert len(lines) == 1 and "holds a dataset of layout 3" in lines[0], lines
    assert "another configuration" not in lines[0] and "writes layout 4" in lines[0]
    assert (tmp_path / "out" / "dataset.json").read_bytes() == before
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == ["dataset.json"]
