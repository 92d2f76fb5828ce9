"""Issue 41: `dopplertof dataset export DIR --format flat|torf -o OUT`, read back here with
each format's conventions written out (from the formats' own readers: NVlabs/FLAT's
README and sim/kinect_spec.py, benattal/torf's datasets/tof_dataset.py and utils), and
compared with the dataset's arrays."""

import copy
import json
import os

import numpy as np
import pytest

pytest.importorskip("h5py")

from dopplertof.dataset import Dataset  # noqa: E402
from test_dataset import TINY, _write_toml, in_process_client, tiny  # noqa: E402,F401

#: FLAT's Kinect channels: 3 k + j is frequency FREQUENCIES[k] at phase PHASES[j]
FREQUENCIES, PHASES = (80.0, 16.0, 120.0), (0.0, 120.0, 240.0)
SATURATED = 3500  # FLAT's map_max: a saturated value is written +3500 (before the row sign)


def flat_signs(rows):
    """FLAT's kinect_mask written out: +1, -1, +1, ... down the rows, except that rows
    rows/2 - 1 and rows/2 share their sign."""
    signs, sign = [], 1
    for row in range(rows):
        signs.append(sign)
        sign = sign if row == rows // 2 - 1 else -sign
    return np.array(signs)


def read_flat(path, rows, columns):
    """FLAT's README: np.fromfile(f, dtype=np.int32) reshaped (424, 512, 9)."""
    return np.fromfile(path, dtype=np.int32).reshape(rows, columns, 9)


def kinect_dataset(folder, client, resolution):
    from dopplertof.dataset import load_config
    from dopplertof.dataset.driver import run_dataset

    data = copy.deepcopy(TINY)
    data.update(samples=1)
    data["render"].update(resolution=list(resolution), spp=2, camera="kinect-v2", max_depth=3)
    data["objects"].update(count=[1, 1])
    config = _write_toml(folder / "kinect.toml", data)
    assert run_dataset(load_config(config), folder / "out", client=client, progress=False).ok
    return str(folder / "out")


@pytest.fixture(scope="module")
def small_kinect(tmp_path_factory, in_process_client):
    return kinect_dataset(tmp_path_factory.mktemp("kinect"), in_process_client, (16, 12))


def check_flat(dataset, out, rows, columns):
    """Every FLAT file read back with the conventions above equals the dataset."""
    ds = Dataset(dataset)
    sample, preset = ds[0], ds.attributes(0)["camera_preset"]
    frames = preset["frames"]
    offset, top = preset["sensor"]["offset_dn"], 2 ** preset["sensor"]["adc_bits"] - 1
    name = "dtof000000000000"
    assert (out / "kinect" / "list" / "all.txt").read_text() == name + "\n"
    for folder, ours, tolerance in (("full", "raw", 0), ("reflection", "raw_ideal", 0.5),
                                    ("ideal", "raw_direct", 0.5)):
        flat = read_flat(out / "kinect" / folder / name, rows, columns)
        unsigned = flat * flat_signs(rows)[:, None, None]
        for k, f_mhz in enumerate(FREQUENCIES):
            for j, phase in enumerate(PHASES):
                frame = next(i for i, f in enumerate(frames)
                             if f["frequency_mhz"] == f_mhz and f["phase_deg"] == phase)
                raw = sample[ours][frame].astype(np.float64)
                saturated = (raw <= 0) | (raw >= top)
                got = unsigned[..., 3 * k + j]
                assert np.all(got[saturated] == SATURATED)
                np.testing.assert_allclose(got[~saturated], (raw - offset)[~saturated],
                                           atol=tolerance, rtol=0)
    gt = np.fromfile(out / "kinect" / "gt" / name, dtype=np.float32).reshape(4 * rows,
                                                                           4 * columns)
    depth = np.nan_to_num(sample["depth"])
    for dy in range(4):
        for dx in range(4):
            np.testing.assert_array_equal(gt[dy::4, dx::4], depth)


def test_flat_export_reads_back_with_flats_conventions(small_kinect, tmp_path, monkeypatch,
                                                       capsys):
    """FLAT's layout at the test's small resolution (its Kinect shape patched; the shape
    itself is checked below and at 512 x 424 in the slow test)."""
    from dopplertof.cli import main
    from dopplertof.dataset import export

    out = tmp_path / "flat"
    assert main(["dataset", "export", small_kinect, "--format", "flat", "-o", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert "needs the Kinect's 512 x 424 pixels" in err and len(err.splitlines()) == 1
    assert not out.exists()
    monkeypatch.setattr(export, "FLAT_SHAPE", (12, 16))
    assert main(["dataset", "export", small_kinect, "--format", "flat", "-o", str(out)]) == 0
    check_flat(small_kinect, out, 12, 16)
    info = json.loads((out / "export.json").read_text())
    assert info["format"] == "flat" and info["samples"] == 1
    # OUT exists now: nothing is overwritten
    before = (out / "kinect" / "full" / "dtof000000000000").read_bytes()
    assert main(["dataset", "export", small_kinect, "--format", "flat", "-o", str(out)]) == 2
    assert "not empty" in capsys.readouterr().err
    assert (out / "kinect" / "full" / "dtof000000000000").read_bytes() == before


@pytest.mark.slow
def test_flat_export_at_the_kinects_own_resolution(tmp_path, in_process_client):
    """kinect-v2 at 512 x 424 (one sample, about 45 s on 2 cores)."""
    from dopplertof.cli import main

    dataset = kinect_dataset(tmp_path, in_process_client, (512, 424))
    out = tmp_path / "flat"
    assert main(["dataset", "export", dataset, "--format", "flat", "-o", str(out)]) == 0
    check_flat(dataset, out, 424, 512)


def test_flat_export_refuses_another_camera_and_torf_reads_back(tiny, tmp_path, capsys):
    """paper-dtof has no Kinect frames (one line, exit 2, nothing written); TöRF's layout,
    read as its loader does: tof/0000.npy (real, imaginary, amplitude) with depth =
    (atan2(im, re) mod 2 pi) depth_range / (4 pi); cams/*_extrinsics.npy world to camera
    in NeRF axes (get_rays_np: direction ((i - W/2) / f, -(j - H/2) / f, -1) through
    camera-to-world = inv(extrinsics))."""
    from dopplertof.cli import main

    bad = tmp_path / "flat"
    assert main(["dataset", "export", tiny[1], "--format", "flat", "-o", str(bad)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "render.camera = 'kinect-v2'" in err
    assert not bad.exists() and not [n for n in os.listdir(tmp_path) if "staging" in n]
    assert main(["dataset", "export", tiny[1], "--format", "mp4", "-o", str(bad)]) == 2
    assert "--format must be one of flat, torf" in capsys.readouterr().err
    out = tmp_path / "torf"
    assert main(["dataset", "export", tiny[1], "--format", "torf", "-o", str(out)]) == 0
    ds = Dataset(tiny[1])
    for item in range(len(ds)):
        sample = ds[item]
        scan = out / f"sample_{item:08d}"
        tof = np.load(scan / "tof" / "0000.npy")
        depth_range = float(np.load(scan / "cams" / "depth_range.npy"))
        assert depth_range == pytest.approx(299792458.0 / 30e6, rel=1e-6)
        phase = np.arctan2(tof[..., 1], tof[..., 0])
        phase[phase < 0] += 2 * np.pi
        valid = sample["camera_valid"]
        np.testing.assert_allclose((phase * depth_range / (4 * np.pi))[valid],
                                   sample["camera_depth"][valid], atol=1e-4)
        np.testing.assert_allclose(tof[..., 2][valid], sample["camera_amplitude"][valid],
                                   rtol=1e-6)
        assert not tof[~valid].any()  # 0 where the camera reports nothing
        np.testing.assert_array_equal(np.load(scan / "depth" / "0000.npy"),
                                      np.nan_to_num(sample["depth"]))
        K = np.load(scan / "cams" / "tof_intrinsics.npy")
        np.testing.assert_allclose(K, sample["K"], rtol=1e-6)
        to_world = np.linalg.inv(np.load(scan / "cams" / "tof_extrinsics.npy")[0])
        height, width = sample["depth"].shape
        i, j = np.meshgrid(np.arange(width) + 0.5, np.arange(height) + 0.5)
        nerf = np.stack([(i - width / 2) / K[0, 0], -(j - height / 2) / K[1, 1],
                         -np.ones_like(i)], -1) @ to_world[:3, :3].T
        ours = np.stack([i, j, np.ones_like(i)], -1) @ np.linalg.inv(sample["K"]).T \
            @ sample["pose"][:3, :3].T
        np.testing.assert_allclose(nerf, ours, atol=1e-5)
        np.testing.assert_allclose(to_world[:3, 3], sample["pose"][:3, 3], atol=1e-5)
        light = np.linalg.inv(np.load(scan / "cams" / "tof_light_extrinsics.npy")[0])
        np.testing.assert_allclose(light[:3, 3], sample["pose"][:3, 3], atol=1e-5)  # on it


def test_torf_amplitude_is_zero_where_the_camera_reports_nothing():
    """A masked pixel keeps its measured amplitude in the dataset (camera_amplitude > 0,
    camera_valid false): TöRF's image is 0 there, as the docs say, and (A cos phi,
    A sin phi, A) elsewhere."""
    from dopplertof.dataset.export import torf_tof

    phase = np.array([[0.5, 1.0], [np.nan, 2.0]])
    amplitude = np.array([[3.0, 4.0], [5.0, np.nan]])
    valid = np.array([[True, False], [False, True]])
    tof = torf_tof(phase, amplitude, valid)
    np.testing.assert_array_equal(tof[0, 0], np.float32([3 * np.cos(0.5), 3 * np.sin(0.5), 3]))
    assert not tof[0, 1].any() and not tof[1, 0].any() and not tof[1, 1].any()
