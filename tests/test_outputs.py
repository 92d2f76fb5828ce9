"""The one output declaration (dopplertof/outputs.py): the docs' tables of output files
and dataset keys list exactly what it declares, with its units; the writers write what
it declares and nothing else; names that changed are still read, with a warning."""

import fnmatch
import os
import re
import warnings

import numpy as np
import pytest

from dopplertof import outputs

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def doc_table(doc: str, first_row: str) -> list:
    """The rows (lists of cells) of the table in docs/``doc`` whose first row after the
    header starts with ``first_row``."""
    with open(os.path.join(ROOT, "docs", doc), encoding="utf-8") as f:
        lines = f.read().splitlines()
    start = next(i for i, line in enumerate(lines) if line.startswith(first_row))
    rows = []
    for line in lines[start:]:
        if not line.startswith("|"):
            break
        rows.append([cell.strip() for cell in line.strip("|").split(" | ")])
    return rows


def named(cell: str) -> list:
    """The names in a table's first cell: each backticked name, ``a.npy/.png`` as
    ``a.npy`` and ``a.png``."""
    names = []
    for token in re.findall(r"`([^`]+)`", cell):
        stem, *extensions = re.split(r"/(?=\.)", token)
        base = stem.rsplit(".", 1)[0]
        names += [stem] + [base + e for e in extensions]
    return names


@pytest.mark.parametrize("doc,first_row,table", [
    ("camera.md", "| `homodyne_<o>.npy", outputs.DTOF),
    ("cameras.md", "| `raw.npy`", outputs.CAMERA),
    ("fmcw.md", "| `spectrum.npy`", outputs.FMCW),
])
def test_the_docs_list_every_file_a_capture_writes(doc, first_row, table):
    listed = [name for row in doc_table(doc, first_row) for name in named(row[0])]
    assert len(listed) == len(set(listed)), f"docs/{doc} lists a file twice"
    declared = outputs.files(table)
    assert ([f for f in declared if f not in listed], [f for f in listed if f not in declared]
            ) == ([], []), f"docs/{doc}: (declared in outputs.py, not listed; the other way)"


def test_the_docs_list_every_key_of_a_dataset_sample_with_its_unit():
    rows = doc_table("dataset.md", "| `raw` |") + doc_table("dataset.md", "| `camera_depth` |")
    listed = {}
    for row in rows:
        keys, units = named(row[0]), [u.strip() for u in row[2].split(",")]
        units = units if len(units) == len(keys) else units * len(keys)
        listed.update(zip(keys, (u.replace("²", "^2") for u in units)))
    # (a camera output's row stands for its _ideal and _direct copies too)
    declared = {k: v for k, v in outputs.SAMPLE.items()
                if not k.endswith(("_ideal", "_direct")) or k.startswith("raw_")}
    assert listed == declared


def test_the_docs_list_every_file_of_a_torf_scan_and_what_of_ours_fills_it():
    listed = {}
    for row in doc_table("dataset.md", "| `sample_<index>/tof/0000.npy`"):
        first, *others = named(row[0])
        folder = os.path.dirname(first.removeprefix("sample_<index>/"))
        for name in [first.removeprefix("sample_<index>/")] + [f"{folder}/{o}"
                                                               for o in others]:
            listed[name] = [k for k in named(row[2]) if k in outputs.SAMPLE]
    assert sorted(listed) == sorted(outputs.TORF)
    for name, keys in outputs.TORF.items():
        assert set(keys) <= set(outputs.SAMPLE), name
        # (the docs name what fills the file; camera_valid is "where the camera reports
        # nothing", camera_frequencies' wrap the depth_range)
        assert set(listed[name]) <= set(keys) and listed[name], name


def test_a_capture_and_a_dataset_name_one_quantity_alike():
    """Every camera output a dataset stores under camera_NAME is the capture's NAME.npy
    (the velocity aside: camera_velocity is the camera's own motion there), and every
    other declared dataset key is one of the sample's."""
    for output in outputs.CAMERA.values():
        if output.dataset is None:
            continue
        assert output.dataset in outputs.SAMPLE, output.name
        assert outputs.SAMPLE[output.dataset] == output.unit, output.name
        if output.dataset.startswith("camera_") and output.name != "velocity":
            assert output.dataset == f"camera_{output.name}"
    assert outputs.DTOF["velocity_point"].unit == outputs.SAMPLE["velocity_point"] == "m/s"
    assert outputs.FMCW["velocity_point"].what.startswith("true u . d")


def _written(folder) -> list:
    return sorted(f for f in os.listdir(folder) if not f.startswith("."))


def _check_declared(written: list, table: dict, conditional_written=()) -> None:
    """``written`` (file names) are each a declared file of ``table`` (patterns
    <...> match any text), and every unconditional one is among them."""
    declared = outputs.files(table)
    patterns = [re.sub(r"<[^>]+>", "*", f) for f in declared]
    stray = [f for f in written if not any(fnmatch.fnmatchcase(f, p) for p in patterns)]
    assert not stray, f"written but not declared in outputs.py: {stray}"
    always = [f for o in table.values() if not o.when and "<" not in o.name
              for f in o.files]
    missing = [f for f in always + list(conditional_written) if f not in written]
    assert not missing, f"declared but not written: {missing}"


def test_a_dtof_capture_writes_what_is_declared(tmp_path):
    import dopplertof
    from dopplertof.tof.output import write_result

    scene = dopplertof.load_file(os.path.join(ROOT, "tests", "fixtures",
                                              "cornell_box_moving.xml"), resx="4", resy="4")
    frame = dopplertof.capture(scene, spp=4, seed=1, mc_batches=2, progress=False)
    write_result(frame, tmp_path, pointcloud=True)
    written = _written(tmp_path)
    _check_declared(written, outputs.DTOF, ["pointcloud.ply", "velocity_std.npy",
                                            "depth_std_mc.npy"])
    for name in ("velocity", "depth_gt", "velocity_std"):
        assert np.load(tmp_path / f"{name}.npy").dtype == outputs.DTOF[name].dtype


def test_a_camera_capture_writes_what_is_declared(tmp_path):
    from dopplertof.cameras.capture import capture_through
    from dopplertof.cameras.output import write_camera_result

    result, = capture_through(os.path.join(ROOT, "examples", "translating_sphere.xml"),
                              ["paper-dtof"], resolution=(6, 4), spp=2, seed=1,
                              progress=False)
    write_camera_result(result, tmp_path)
    written = _written(tmp_path)
    _check_declared(written, outputs.CAMERA, ["velocity.npy", "velocity_gt.png"])
    for name in ("raw_ideal", "depth_std", "mask_edge", "velocity"):
        assert np.load(tmp_path / f"{name}.npy").dtype == outputs.CAMERA[name].dtype


def test_an_fmcw_frame_writes_what_is_declared_and_reads_its_former_name(tmp_path):
    import dopplertof
    from dopplertof.fmcw import fmcw

    street = dopplertof.load_file(os.path.join(ROOT, "examples", "fmcw_street.xml"),
                                  {"res": "4", "spp": "2"})
    result = fmcw(street, seed=1, returns=2)
    result.write(tmp_path)
    _check_declared(_written(tmp_path), outputs.FMCW, ["returns_range.npy"])
    with pytest.warns(FutureWarning, match="'velocity_gt' is now named 'velocity_point'"):
        former = result.velocity_gt
    assert former is result.velocity_point


def test_a_sample_answers_a_former_key_with_a_warning():
    from dopplertof.dataset.reader import Sample, _new_name

    sample = Sample({"camera_depth_std_ideal": np.ones(2), "velocity_point": np.zeros(2)})
    with pytest.warns(FutureWarning, match="'camera_confidence' is now named "
                                           "'camera_depth_std'"):
        assert sample["camera_confidence_ideal"] is sample["camera_depth_std_ideal"]
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert _new_name("velocity_along_ray") == "velocity_point"
        assert _new_name("camera_depth") is None
    with pytest.raises(KeyError):
        sample["camera_confidence"]  # (renamed, but this sample has no such array)


def test_an_fmcw_folder_of_the_former_names_is_read_under_the_present_ones(tmp_path):
    import shutil

    from dopplertof.capture_summary import read_capture, write_summary

    write_summary(str(tmp_path / "summary.json"), "fmcw", {"chirp": {}})
    np.save(tmp_path / "velocity_gt.npy", np.arange(4.0))
    capture = read_capture(tmp_path, "fmcw")
    with pytest.warns(FutureWarning, match="'velocity_gt' is now named 'velocity_point'"):
        np.testing.assert_array_equal(capture.array("velocity_point"), np.arange(4.0))
    shutil.move(tmp_path / "velocity_gt.npy", tmp_path / "velocity_point.npy")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        np.testing.assert_array_equal(capture.array("velocity_point"), np.arange(4.0))
    with pytest.raises(ValueError, match="range.npy: cannot be read"):
        capture.array("range")
