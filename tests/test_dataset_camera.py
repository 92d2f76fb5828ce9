"""Issue 41: the camera's own outputs in every sample (each split), truth hygiene
(incidence, grazing, redrawn samples, mesh sizes)."""

import copy
import json
import math

import numpy as np
import pytest

pytest.importorskip("h5py")

from dopplertof.dataset import Dataset, DatasetError  # noqa: E402
from dopplertof.dataset.config import config_from_mapping  # noqa: E402
from test_dataset import (EXAMPLE, OCTAHEDRON, TINY, _config, _pixel_rays,  # noqa: E402,F401
                          _truth, _write_toml, in_process_client, tiny)

MASK_NAMES = ("mask_saturated", "mask_low_confidence", "mask_unwrap_failed",
              "mask_out_of_range", "mask_mixed_footprint", "mask_unlit")


def test_every_split_holds_the_cameras_outputs_and_the_reader_picks_them(tiny):
    """camera_valid is no mask set and exactly where camera_depth is finite; z depth is
    the range times the ray's cosine; the phase is wrapped; the noise-free direct split's
    depth is the truth's (modulo the camera's wrap); the reader's split picks its own
    camera outputs as it picks raw."""
    from dopplertof.dataset.sample import CAMERA_OUTPUTS, CAMERA_SPLITS, UNITS

    ds = Dataset(tiny[1])
    errors = []
    for i in range(len(ds)):
        s = ds[i]
        assert set(UNITS) <= set(s)
        np.testing.assert_array_equal(s["camera_frequencies"], [30.0])
        for suffix in CAMERA_SPLITS.values():
            masked = np.any([s[f"camera_{m}{suffix}"] for m in MASK_NAMES], axis=0)
            valid = s[f"camera_valid{suffix}"]
            assert valid.dtype == bool and np.array_equal(valid, ~masked)
            assert np.array_equal(np.isfinite(s[f"camera_depth{suffix}"]), valid)
            assert not np.isfinite(s[f"camera_radial_velocity{suffix}"][~valid]).any()
            np.testing.assert_allclose(s[f"camera_depth_z{suffix}"][valid],
                                       (s[f"camera_depth{suffix}"] * s["depth_z"]
                                        / s["depth"])[valid], rtol=1e-6)
            phase = s[f"camera_phase{suffix}"]
            assert phase.shape == (1,) + s["depth"].shape
            assert np.all((phase >= 0) & (phase < 2 * np.pi))
            assert np.all(s[f"camera_depth_std{suffix}"][valid] > 0)
        on = s["camera_valid_direct"]
        errors.append((s["camera_depth_direct"] - s["depth"])[on])
    # paper-dtof has one frequency (30 MHz): its depth wraps at c / (2 f) = 4.997 m
    wrap = 299792458.0 / (2 * 30e6)
    error = np.concatenate(errors)
    error = np.abs(error - wrap * np.round(error / wrap))
    assert error.size > 100 and np.median(error) < 0.05  # (no multipath, no noise)
    for split, suffix in CAMERA_SPLITS.items():
        picked = Dataset(tiny[1], split=split)[1]
        for name in CAMERA_OUTPUTS:
            np.testing.assert_array_equal(picked[f"camera_{name}"],
                                          picked[f"camera_{name}{suffix}"])
    assert ds.units["camera_depth"] == "m" and ds.units["camera_amplitude"] == "DN"


def test_every_key_has_its_unit_and_a_line_in_the_docs():
    import os

    from dopplertof.dataset.sample import CAMERA_OUTPUTS, CAMERA_SPLITS, UNITS

    with open(os.path.join(os.path.dirname(EXAMPLE), "..", "docs", "dataset.md")) as f:
        doc = f.read()
    # (the camera's outputs: one line for camera_NAME and its _ideal, _direct copies)
    per_split = {f"camera_{n}{s}" for n in CAMERA_OUTPUTS for s in CAMERA_SPLITS.values()}
    missing = [k for k in UNITS if k not in per_split and f"`{k}`" not in doc]
    missing += [f"camera_{n}" for n in CAMERA_OUTPUTS if f"`camera_{n}`" not in doc]
    assert "`camera_NAME_ideal`" in doc and "`camera_NAME_direct`" in doc
    assert not missing, missing


def test_grazing_truth_is_flagged_and_what_is_left_is_bounded_by_the_motion():
    """examples/dataset.toml's sample 0 has a radial velocity truth of 346 m/s on a
    grazing cube face (objects at most 9.4 m/s); incidence is the angle between the ray
    and the normal, grazing past render.grazing_deg; on objects where truth_valid holds,
    |velocity_gt| <= (|v| + |w| r) / cos(grazing_deg) (r the bounding radius)."""
    import dopplertof
    from dopplertof.cameras.preset import load_preset
    from dopplertof.dataset import load_config
    from dopplertof.dataset.config import bounding_radius
    from dopplertof.dataset.sample import drawn_sample

    dopplertof.set_variant()
    config = load_config(EXAMPLE)
    limit = config["render"]["grazing_deg"]
    description, _, _, truth = drawn_sample(config, 0, load_preset("paper-dtof"), ".")
    assert np.nanmax(np.abs(truth["velocity_gt"])) > 300
    rays = _pixel_rays(truth)
    hit = truth["mask"]
    cosine = np.abs(np.sum(truth["normals"] * rays, -1))
    np.testing.assert_allclose(np.cos(np.radians(truth["incidence"][hit])), cosine[hit],
                               atol=1e-5)
    assert np.isnan(truth["incidence"][~hit]).all()
    assert np.array_equal(truth["grazing"], hit & (truth["incidence"] > limit))
    assert np.array_equal(truth["truth_valid"], hit & ~truth["grazing"])
    assert truth["grazing"].sum() > 0
    for k, obj in enumerate(description["objects"]):
        on = truth["truth_valid"] & (truth["instance"] == k + 1)
        fastest = (np.linalg.norm(obj["velocity_m_s"]) + np.linalg.norm(
            obj["angular_velocity_rad_s"]) * bounding_radius(obj["shape"], obj["size_m"]))
        speed = np.abs(truth["velocity_gt"][on]).max(initial=0)
        assert speed <= fastest / math.cos(math.radians(limit)) * 1.001, (k, speed, fastest)


def test_objects_enclosing_the_camera_or_nothing_visible_are_drawn_again_or_refused(
        tmp_path, capsys):
    import dopplertof
    from dopplertof.cameras.preset import load_preset
    from dopplertof.cli import main
    from dopplertof.dataset.config import bounding_radius
    from dopplertof.dataset.sample import drawn_sample

    enclosing = copy.deepcopy(TINY)
    enclosing["objects"].update(distance=[0.01, 0.01])
    code = main(["dataset", _write_toml(tmp_path / "enclosing.toml", enclosing), "-o",
                 str(tmp_path / "out")])
    err = capsys.readouterr().err.strip()
    assert code == 2 and len(err.splitlines()) == 1 and "objects.distance" in err
    assert "enclose" in err and "Traceback" not in err and not (tmp_path / "out").exists()
    # near objects: the draws that enclose the camera are drawn again
    dopplertof.set_variant()
    preset = load_preset("paper-dtof")
    near = _config({"objects": {"distance": [0.2, 2.0], "size": [0.4, 0.5], "count": [3, 3],
                                "shapes": ["sphere", "cube"]}})
    draws = []
    for index in range(6):
        description, _, _, truth = drawn_sample(near, index, preset, ".")
        draws.append(description["draw"])
        centre = np.asarray(description["camera"]["rest"])[:3, 3]
        for obj in description["objects"]:
            gap = np.linalg.norm(np.asarray(obj["centre_m"]) - centre)
            assert gap > bounding_radius(obj["shape"], obj["size_m"])
        assert (truth["instance"] >= 1).any()
    assert max(draws) > 0  # (some were drawn again)
    # nothing in view at all: refused at load (issue 39, D46) and, past that check,
    # after MAX_DRAWS, saying why
    with pytest.raises(DatasetError, match="backdrop.kind = 'none' with objects.count "
                       r"\[0, 0\]: a sample without objects has nothing to see"):
        _config({"objects": {"count": [0, 0]}, "backdrop": {"kind": "none"}})
    empty = _config({"backdrop": {"kind": "none"}})
    empty.values["objects"]["count"] = [0, 0]
    with pytest.raises(DatasetError, match="sample 0: drawn 16 times.*no pixel sees anything"):
        drawn_sample(empty, 0, preset, ".")


def _binary_ply(path, points):
    """A binary little-endian PLY of ``points`` and one face (written out here)."""
    header = ("ply\nformat binary_little_endian 1.0\n"
              f"element vertex {len(points)}\nproperty float x\nproperty float y\n"
              "property float z\nelement face 1\nproperty list uchar int vertex_indices\n"
              "end_header\n")
    face = np.array([3], np.uint8).tobytes() + np.array([0, 1, 2], "<i4").tobytes()
    path.write_bytes(header.encode() + np.asarray(points, "<f4").tobytes() + face)


@pytest.mark.parametrize("scale, shift", [(50.0, [0.0, 40.0, 5.0]),  # centimetres
                                          (0.08, [-0.02, 0.11, 0.0])])  # the bunny's size
def test_a_mesh_in_any_unit_is_normalised_to_the_objects_size(tmp_path, scale, shift):
    """A mesh folder's meshes come in any unit and placement: the Stanford bunny (0.16 m
    across about (-0.02, 0.11, 0)) became a 3 cm object, a mesh in centimetres was
    refused. Each is normalised (its bounding box centred, its largest half-extent 1)
    and scaled by objects.size as a cube: its box's centre at the object's centre and,
    in the loaded scene, its farthest vertex between size and sqrt(3) size from it."""
    import dopplertof
    from dopplertof.cameras.preset import load_preset
    from dopplertof.dataset.generate import draw_scene, mesh_normalisation
    from dopplertof.dataset.scene_text import scene_xml
    from dopplertof.scene.meshes import mesh_file_bounds

    shapes = tmp_path / "shapes"
    shapes.mkdir()
    points = np.array([[-1.0, -0.8, -0.1], [1.0, -0.8, -0.1], [0.0, 0.8, 0.1]]) * scale + shift
    _binary_ply(shapes / "mesh.ply", points)
    bounds = mesh_file_bounds(str(shapes / "mesh.ply")).astype(np.float64)
    normalise = mesh_normalisation(str(shapes / "mesh.ply"))
    corners = normalise[:3, :3] @ bounds.T + normalise[:3, 3:]
    # float32 vertices: their box's centre to 0 and its half-extent to 1, to rounding
    np.testing.assert_allclose(corners.sum(axis=1), 0.0, atol=1e-12)
    assert np.max(corners[:, 1] - corners[:, 0]) == pytest.approx(2.0, rel=1e-12)
    data = copy.deepcopy(TINY)
    data["objects"].update(shapes=["mesh"], mesh_folder="shapes", count=[1, 1],
                           size=[0.3, 0.3])
    config = config_from_mapping(data, "<test>", str(tmp_path))
    dopplertof.set_variant()
    description = draw_scene(config, 0, load_preset(config["render"]["camera"]))
    obj, = description["objects"]
    rest = np.asarray(obj["rest"])
    centre = rest[:3, :3] @ bounds.mean(axis=0) + rest[:3, 3]
    np.testing.assert_allclose(centre, obj["centre_m"], atol=1e-9)
    (tmp_path / "meshes").mkdir()
    (tmp_path / "meshes" / "mesh.ply").write_bytes((shapes / "mesh.ply").read_bytes())
    scene = dopplertof.scene.load_string(scene_xml(description, 4, 4), {},
                                         base_dir=str(tmp_path))
    import mitsuba as mi

    vertices = np.asarray(mi.traverse(scene.bodies[0].scene)[
        next(k for k in mi.traverse(scene.bodies[0].scene).keys()
             if k.endswith("vertex_positions"))], np.float64).reshape(-1, 3)
    reach = np.linalg.norm(vertices - obj["centre_m"], axis=1).max()
    assert 0.3 * (1 - 1e-6) <= reach <= math.sqrt(3) * 0.3 * (1 + 1e-6)


def test_a_mesh_without_an_extent_is_one_line_naming_the_file(tmp_path, capsys):
    from dopplertof.cli import main

    shapes = tmp_path / "shapes"
    shapes.mkdir()
    (shapes / "unit.obj").write_text(OCTAHEDRON)
    _binary_ply(shapes / "zz_point.ply", [[1.0, 2.0, 3.0]] * 3)
    data = copy.deepcopy(TINY)
    data["objects"].update(shapes=["mesh"], mesh_folder="shapes")
    code = main(["dataset", _write_toml(tmp_path / "meshes.toml", data), "-o",
                 str(tmp_path / "out")])
    err = capsys.readouterr().err.strip()
    assert code == 2 and len(err.splitlines()) == 1, err
    assert "zz_point.ply spans 0 x 0 x 0: a mesh needs an extent" in err
    assert "Traceback" not in err and not (tmp_path / "out").exists()
    (shapes / "zz_point.ply").unlink()
    config_from_mapping(data, "<test>", str(tmp_path))  # (the unit mesh alone is fine)


def test_dataset_show_draws_a_row_per_sample_quickly_and_refuses_bad_input(tiny, tmp_path,
                                                                            capsys):
    """`dopplertof dataset show DIR --samples ... -o preview.png`: a row of 8 panels per
    sample (raw, camera depth, truth, error, velocity truth, camera velocity, flow,
    instances), hatched NaN, in well under 5 s; a wrong item or output is one line, exit 2, nothing written."""
    import time

    from PIL import Image

    from dopplertof.cli import main
    from dopplertof.previews import NO_SIGNAL_COLOUR

    one, three = tmp_path / "one.png", tmp_path / "three.png"
    started = time.perf_counter()
    assert main(["dataset", "show", tiny[1], "--samples", "1", "-o", str(one)]) == 0
    assert main(["dataset", "show", tiny[1], "-o", str(three)]) == 0
    assert time.perf_counter() - started < 5.0
    small, big = Image.open(one), Image.open(three)
    assert abs(big.width - small.width) < 0.1 * small.width and big.height > 2 * small.height
    pixels = np.asarray(big.convert("RGB")).reshape(-1, 3)
    magenta = [int(NO_SIGNAL_COLOUR[k:k + 2], 16) for k in (1, 3, 5)]
    assert np.all(pixels == magenta, axis=1).sum() > 50  # (the hatching of masked pixels)
    stats = tmp_path / "stats.png"
    assert main(["dataset", "show", tiny[1], "--stats", "-o", str(stats)]) == 0
    assert Image.open(stats).width > 600
    capsys.readouterr()
    for argv, words in ((["--samples", "0,7"], "--samples 0,7: the dataset holds items 0-2"),
                        (["--samples", "a"], "--samples must be item numbers"),
                        (["-o", str(tmp_path / "x.jpg")], "-o must be a .png file")):
        argv = argv if "-o" in argv else argv + ["-o", str(tmp_path / "bad.png")]
        assert main(["dataset", "show", tiny[1]] + argv) == 2
        err = capsys.readouterr().err.strip()
        assert len(err.splitlines()) == 1 and words in err and "Traceback" not in err, err
    assert not (tmp_path / "bad.png").exists() and not (tmp_path / "x.jpg").exists()


def test_the_docs_pytorch_loop_runs(tiny):
    """docs/dataset.md's PyTorch block, as written (its folder: the test's dataset; worker
    processes: 0), one epoch."""
    import os
    import re

    torch = pytest.importorskip("torch", reason="PyTorch is not installed (not a "
                                "dependency of dopplertof): the docs' loop is not run")
    with open(os.path.join(os.path.dirname(EXAMPLE), "..", "docs", "dataset.md")) as f:
        blocks = re.findall(r"```python\n(.*?)```", f.read(), re.S)
    code = next(b for b in blocks if "class DopplerToF" in b)
    code = code.replace('"out/dataset"', repr(tiny[1])).replace("num_workers=2",
                                                                 "num_workers=0")
    namespace = {}
    exec(compile(code, "docs/dataset.md", "exec"), namespace)
    assert namespace["inputs"].shape[1] == 6 + 1 and namespace["target"].dtype == torch.float32
    assert len(namespace["loader"].dataset) == 3


def test_the_statistics_page_counts_what_the_samples_hold(tiny):
    from dopplertof.dataset.show import dataset_statistics

    ds = Dataset(tiny[1])
    stats = dataset_statistics(ds, [0, 2])
    samples = [ds[0], ds[2]]
    np.testing.assert_allclose(stats["valid"]["truth"], [s["truth_valid"].mean() for s in samples])
    np.testing.assert_allclose(stats["valid"]["ideal"],
                               [s["camera_valid_ideal"].mean() for s in samples])
    assert len(stats["distance"]) == 4  # (TINY: two objects a sample)
    wrap = 299792458.0 / (2 * 30e6)  # paper-dtof: one frequency
    errors = np.concatenate(stats["error"]["direct"])
    assert errors.max() <= wrap / 2 + 1e-6 and np.median(errors) < 0.05


def test_a_layout_1_folder_is_still_read_and_an_unknown_layout_is_named(tiny, tmp_path):
    """Layout 2 (issue 41) adds keys only: a reader reads layout 1's folders (without
    the camera's outputs) and names a layout it does not know; layout 3 renames two keys
    (outputs.RENAMED), which a folder of layout 2 holds under their former names: read
    under the present ones, with a FutureWarning naming them; layout 4 adds
    camera_mask_unlit (test_dataset_unlit.py reads a folder of layout 3 without it)."""
    import json
    import shutil

    for version, ok in ((1, True), (2, True), (5, False)):
        folder = tmp_path / f"layout{version}"
        shutil.copytree(tiny[1], folder)
        info = json.loads((folder / "dataset.json").read_text())
        info["layout_version"] = version
        info.pop("sha256")  # (written before dataset.json held its checksum)
        if version == 2:
            info["units"] = {{"velocity_point": "velocity_along_ray",
                              "camera_depth_std_ideal": "camera_confidence_ideal"}.get(k, k): v
                             for k, v in info["units"].items()}
        (folder / "dataset.json").write_text(json.dumps(info))
        if version == 2:
            with pytest.warns(FutureWarning, match=r"velocity_point \(velocity_along_ray\)"
                              ) as caught:
                ds = Dataset(folder)
            assert "camera_depth_std_ideal (camera_confidence_ideal)" in str(caught[0].message)
            assert ds.units["velocity_point"] == "m/s" and "velocity_along_ray" not in ds.units
        elif ok:
            assert len(Dataset(folder)) == 3
        else:
            with pytest.raises(DatasetError,
                               match="layout version 5, this reader reads 1, 2, 3, 4"):
                Dataset(folder)


def test_a_sample_the_camera_barely_reports_is_drawn_again(monkeypatch):
    """A sample held two one-pixel objects and 2 valid camera pixels without a word:
    render.min_valid_share (default 0.01) is the least share of pixels the camera
    reports (camera_valid); a drawing below it is drawn again, and after MAX_DRAWS the
    sample fails naming the share. TINY's sample 2 reports 0.75 of its pixels at its
    first drawing (kept with the threshold 0): with 0.76 a later drawing is kept."""
    import dopplertof
    from dopplertof.dataset import generate
    from dopplertof.dataset.sample import render_sample, too_few_valid

    assert too_few_valid(np.array([True, False, False, False]), 0.25) is None
    assert too_few_valid(np.array([True, False, False, False]), 0.3) == (
        "the camera reports 1 of 4 pixels (25.00%, below render.min_valid_share 0.3)")
    dopplertof.set_variant()
    arrays, attributes = render_sample(_config({"render": {"min_valid_share": 0.76}}), 2, ".")
    assert json.loads(attributes["description"])["draw"] >= 1
    assert arrays["camera_valid"].mean() >= 0.76
    monkeypatch.setattr(generate, "MAX_DRAWS", 2)
    with pytest.raises(DatasetError, match=r"sample 0: drawn 2 times, never usable; the "
                       r"last: the camera reports \d+ of 120 pixels \(.*below "
                       r"render.min_valid_share 1\)"):
        render_sample(_config({"render": {"min_valid_share": 1.0}}), 0, ".")
