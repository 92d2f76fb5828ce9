"""Clips in datasets (``clip_frames``, ``fps``): a sample is T frames of one scene whose
bodies and camera keep moving, every array (T, ...); the shards, verify, show and both
exports keep them; a resumed clip dataset is bitwise the uninterrupted one; one frame
hashes as before.

Tolerances: the poses are float64 arithmetic on numbers of order 1 to 10 (tens of
roundings: 1e-12); a body's keyframe matrix goes through the scene's XML as the
shortest exact decimal of each float64 entry, so it is read back exactly, and the
interpolated pose at the keyframe's own time is that keyframe (1e-12 again)."""

import copy
import json
import os

import numpy as np
import pytest

pytest.importorskip("h5py")

from dopplertof.dataset import Dataset, DatasetError  # noqa: E402
from test_dataset import TINY, _write_toml, in_process_client  # noqa: E402,F401

T, FPS = 3, 30.0
#: two samples of three frames, kinect-v2 at 16 x 12 (its 9 raw frames), moving bodies
#: and a moving, turning camera
CLIP = copy.deepcopy(TINY)
CLIP.update(samples=2, samples_per_shard=1, clip_frames=T)
CLIP["render"].update(resolution=[16, 12], spp=2, camera="kinect-v2", max_depth=3)
CLIP["objects"].update(count=[1, 2], shapes=["sphere", "cube"], materials=["diffuse"])
CLIP["motion"] = {"speed": [2.0, 4.0], "angular_speed": [1.0, 3.0]}
CLIP["camera"] = {"speed": [0.5, 1.0], "angular_speed": [0.2, 0.5]}


def run(folder, data, client):
    from dopplertof.dataset import load_config
    from dopplertof.dataset.driver import run_dataset

    config = _write_toml(folder / "clip.toml", data)
    summary = run_dataset(load_config(config), folder / "out", client=client, progress=False)
    assert summary.ok, summary
    return str(folder / "out")


@pytest.fixture(scope="module")
def clips(tmp_path_factory, in_process_client):
    return run(tmp_path_factory.mktemp("clips"), CLIP, in_process_client)


def test_a_clip_is_one_scene_moving_on_at_the_frame_rate(clips):
    import dopplertof
    from dopplertof.dataset.generate import camera_pose, object_matrix

    dopplertof.set_variant()
    ds = Dataset(clips)
    assert len(ds) == 2
    for item in range(len(ds)):
        sample, attributes = ds[item], ds.attributes(item)
        description = attributes["description"]  # frame 0's
        assert attributes["clip_frames"] == T and attributes["fps"] == FPS
        np.testing.assert_array_equal(attributes["clip_times_s"], np.arange(T) / FPS)
        assert len(set(attributes["clip_noise_seeds"])) == T  # each frame its own noise
        assert attributes["clip_noise_seeds"][0] == attributes["noise_seed"]
        assert np.shape(attributes["photons_per_unit"]) == (T,)
        for key, value in sample.items():
            if key not in ("index", "seed"):
                assert value.shape[0] == T, key
        assert sample["depth"].shape == (T, 12, 16) and sample["raw"].shape == (T, 9, 12, 16)
        mid = description["times_s"]["mid"]
        for k in range(T):
            # the camera's pose at frame k's mid-exposure: its motion k / fps on
            np.testing.assert_allclose(sample["pose"][k],
                                       camera_pose(description["camera"], k / FPS), atol=1e-12)
            scene = ds.scene(item, frame=k)
            for body in scene.bodies:
                obj = next(o for o in description["objects"] if o["id"] == body.names[0])
                np.testing.assert_allclose(body.motion.world_matrix(mid),
                                           object_matrix(obj, k / FPS), atol=1e-12)
        with pytest.raises(IndexError):
            ds.scene(item, frame=T)
        # frames differ: the bodies moved, and each frame drew its own noise
        assert not np.array_equal(sample["raw"][0], sample["raw"][1])


def test_one_frame_hashes_as_before_and_bad_clips_are_one_line(tmp_path):
    from dopplertof.dataset.config import config_from_mapping
    from dopplertof.dataset.driver import config_hash

    one = config_from_mapping(copy.deepcopy(TINY), "<test>")
    explicit = config_from_mapping({**copy.deepcopy(TINY), "clip_frames": 1}, "<test>")
    clip = config_from_mapping({**copy.deepcopy(TINY), "clip_frames": 2, "fps": 10.0},
                               "<test>")
    assert "clip_frames" not in one.to_json()["dataset"] and "fps" not in one.to_json()["dataset"]
    assert config_hash(one, "llvm_ad_rgb") == config_hash(explicit, "llvm_ad_rgb")
    assert config_hash(clip, "llvm_ad_rgb") != config_hash(one, "llvm_ad_rgb")
    # paper-dtof gives no frame rate; kinect-v2's sequence does not fit 1 / 1000 s
    for changes, words in (({"clip_frames": 2}, "clip_frames = 2 needs fps"),
                           ({"clip_frames": 2, "fps": 1000.0, "render": {
                               **TINY["render"], "camera": "kinect-v2"}}, "fps = 1000"),
                           ({"clip_frames": 0}, "clip_frames out of range")):
        with pytest.raises(DatasetError) as error:
            config_from_mapping({**copy.deepcopy(TINY), **changes}, "<clip>")
        message = str(error.value)
        assert words in message and message.startswith("<clip>") and "\n" not in message


def test_verify_show_and_both_exports_keep_clips(clips, tmp_path, monkeypatch, capsys):
    from PIL import Image

    from dopplertof.cli import main
    from dopplertof.dataset import export
    from dopplertof.dataset.export import flat_channel_frames, flat_name, flat_raw, torf_extrinsics
    from dopplertof.videos import video_extension

    assert main(["dataset", "verify", clips]) == 0
    assert "2 of 2 samples present and intact" in capsys.readouterr().out
    # show: frame 0's row per item and a video of each clip beside the PNG
    png = tmp_path / "show.png"
    assert main(["dataset", "show", clips, "-o", str(png), "--samples", "0,1"]) == 0
    assert png.is_file()
    for item in (0, 1):
        video = tmp_path / f"show_item{item}{video_extension()}"
        assert video.is_file()
        if video.suffix == ".gif":
            assert Image.open(video).n_frames == T
    stats = tmp_path / "stats.png"  # (every frame of every clip)
    assert main(["dataset", "show", clips, "--stats", "-o", str(stats)]) == 0
    assert stats.is_file()
    ds = Dataset(clips)
    # TöRF: a scan per clip, a view per frame, the extrinsics each frame's
    out = tmp_path / "torf"
    assert main(["dataset", "export", clips, "--format", "torf", "-o", str(out)]) == 0
    for item in range(len(ds)):
        sample = ds[item]
        scan = out / f"sample_{item:08d}"
        assert sorted(os.listdir(scan / "tof")) == [f"{k:04d}.npy" for k in range(T)]
        extrinsics = np.load(scan / "cams" / "tof_extrinsics.npy")
        assert extrinsics.shape == (T, 4, 4)
        for k in range(T):
            np.testing.assert_allclose(extrinsics[k], torf_extrinsics(sample["pose"][k]),
                                       rtol=1e-6, atol=1e-6)
            np.testing.assert_array_equal(np.load(scan / "depth" / f"{k:04d}.npy"),
                                          np.nan_to_num(sample["depth"][k]))
    # FLAT (its Kinect shape patched to the test's): a scene file per frame
    monkeypatch.setattr(export, "FLAT_SHAPE", (12, 16))
    out = tmp_path / "flat"
    assert main(["dataset", "export", clips, "--format", "flat", "-o", str(out)]) == 0
    names = [flat_name(i, k) for i in range(len(ds)) for k in range(T)]
    assert (out / "kinect" / "list" / "all.txt").read_text() == "".join(n + "\n" for n in names)
    assert all(len(n) == 16 for n in names) and names[1] == "dtof000000000001"
    preset = ds.attributes(1)["camera_preset"]
    order = flat_channel_frames(preset, "test")
    expected = flat_raw(ds[1]["raw"][2], order, preset["sensor"])
    got = np.fromfile(out / "kinect" / "full" / flat_name(1, 2), np.int32).reshape(expected.shape)
    np.testing.assert_array_equal(got, expected)
    info = json.loads((out / "export.json").read_text())
    assert info["samples"] == 2 and len(info["files"]) == 2 * T


def test_an_interrupted_clip_dataset_resumes_bitwise(clips, tmp_path, in_process_client):
    """Shard 1 lost (a kill before its rename): the rerun renders it alone, and every
    shard's bytes equal the uninterrupted run's."""
    import shutil

    out = tmp_path / "out"
    shutil.copytree(clips, out)
    os.unlink(out / "shard_00001.h5")
    again = run(tmp_path, CLIP, in_process_client)
    for name in ("shard_00000.h5", "shard_00001.h5"):
        assert (out / name).read_bytes() == open(os.path.join(clips, name), "rb").read()
    assert again == str(out)
