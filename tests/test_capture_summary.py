"""summary.json: one writer (with the schema's kind and version) and one reader for the
three kinds of capture folder, which names a folder's kind whatever wrote it."""

import json
import re
import os

import pytest

from dopplertof.capture_summary import (SCHEMA_VERSION, CaptureFolderError, read_capture,
                                        write_summary)

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def test_every_capture_kind_writes_its_schema_and_reads_back(tmp_path):
    import dopplertof
    from dopplertof.cameras.capture import capture_through
    from dopplertof.fmcw import fmcw

    sphere = os.path.join(ROOT, "examples", "translating_sphere.xml")
    dopplertof.set_variant()
    dopplertof.capture(dopplertof.load_file(sphere, {"res": "6", "spp": "4"}), spp=4,
                       progress=False).write(str(tmp_path / "dtof"))
    camera, = capture_through(sphere, ["azure-kinect"], resolution=(6, 4), spp=4)
    camera.write(str(tmp_path / "camera"))
    street = dopplertof.load_file(os.path.join(ROOT, "examples", "fmcw_street.xml"),
                                  {"res": "4", "spp": "4"})
    fmcw(street).write(str(tmp_path / "fmcw"))
    for kind in ("dtof", "camera", "fmcw"):
        summary = read_capture(tmp_path / kind)
        written = json.loads((tmp_path / kind / "summary.json").read_text())
        assert written["schema"] == {"kind": kind, "version": SCHEMA_VERSION}
        assert summary.kind == kind and summary.version == SCHEMA_VERSION
        assert summary.resolution == {"dtof": (6, 6), "camera": (6, 4), "fmcw": (4, 4)}[kind]
    assert set(read_capture(tmp_path / "dtof").records) >= {"heterodyne_0", "homodyne_0"}
    with pytest.raises(CaptureFolderError, match="is a camera capture .* not a D-ToF"):
        read_capture(tmp_path / "camera", kind="dtof")


def test_a_folder_written_before_the_schema_is_read_by_its_keys(tmp_path):
    for key, kind in (("captures", "dtof"), ("camera", "camera"), ("chirp", "fmcw")):
        folder = tmp_path / kind
        folder.mkdir()
        (folder / "summary.json").write_text(json.dumps({key: [], "resolution": [3, 2]}))
        summary = read_capture(folder)
        assert (summary.kind, summary.version, summary.resolution) == (kind, 0, (3, 2))


@pytest.mark.parametrize("content, words", [
    (None, "has no summary.json: not a capture folder"),
    ("{not json", "cannot be read as JSON"),
    ("[1, 2]", "is not a capture summary (a JSON object)"),
    ('{"seed": 1}', "has no schema and none of a capture's keys"),
])
def test_what_is_not_a_capture_summary_is_named_in_one_line(tmp_path, content, words):
    if content is not None:
        (tmp_path / "summary.json").write_text(content)
    with pytest.raises(CaptureFolderError, match=re.escape(words)) as error:
        read_capture(tmp_path)
    assert "\n" not in str(error.value)
    with pytest.raises(CaptureFolderError, match="capture folder not found"):
        read_capture(tmp_path / "missing")


def test_a_missing_key_names_the_file_and_the_key(tmp_path):
    write_summary(str(tmp_path / "summary.json"), "dtof", {"resolution": [2, 2]})
    summary = read_capture(tmp_path)
    with pytest.raises(CaptureFolderError, match=r"summary.json has no 'render_params'"):
        summary["render_params"]
    with pytest.raises(ValueError, match="unknown capture kind"):
        write_summary(str(tmp_path / "other.json"), "lidar", {})
