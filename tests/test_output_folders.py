"""One output-folder rule for every command (issue 15, item 1): missing folders are
created, with their parents, when the first output is written; --help says so; a path
that cannot become a folder is refused before any work."""

import os

import numpy as np
import pytest

from dopplertof import file_formats, io
from dopplertof.cli import _parser, main
from dopplertof.cli_options import FOLDER_HELP
from dopplertof.demo import demo_scene_path

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SCENE = demo_scene_path()
TINY = ["-D", "res=4", "--spp", "2", "--quiet"]


def _subparsers():
    parser = _parser()
    action = next(a for a in parser._actions if a.dest == "command")
    return action.choices


@pytest.mark.parametrize("command", ["render", "capture", "demo", "figures", "sweep",
                                     "report", "animate", "fmcw"])
def test_every_command_help_states_the_folder_rule(command):
    text = " ".join(_subparsers()[command].format_help().split())
    assert FOLDER_HELP in text


def test_render_creates_missing_folders(tmp_path, capsys):
    out = tmp_path / "a" / "b" / "image.npy"
    assert main(["render", SCENE, *TINY, "-o", str(out)]) == 0
    assert np.load(out).shape == (4, 4, 3)


def test_capture_creates_missing_folders(tmp_path, capsys):
    out = tmp_path / "a" / "b"
    assert main(["capture", SCENE, *TINY, "-o", str(out)]) == 0
    assert (out / "velocity.npy").is_file() and (out / "summary.json").is_file()


def test_sweep_accepts_a_missing_parent_as_the_readme_runs_it(tmp_path, capsys):
    """`dopplertof sweep examples/sweep_tiny.toml -o results/tiny` in a fresh clone."""
    out = tmp_path / "results" / "tiny"
    code = main(["sweep", os.path.join(ROOT, "examples", "sweep_tiny.toml"), "-o", str(out),
                 "--dry-run"])
    assert code == 0 and "5 to run" in capsys.readouterr().out
    assert not out.exists()  # a dry run writes nothing


def test_a_file_in_the_way_is_refused_before_any_work(tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("x")
    with pytest.raises(io.OutputError, match="is a file"):
        io.check_output_folder(blocker / "sub" / "folder")
    with pytest.raises(io.OutputError, match="not a folder"):
        io.check_output_folder(blocker)
    assert blocker.read_text() == "x"


def test_atomic_writes_create_the_folder(tmp_path):
    target = tmp_path / "x" / "y" / "data.json"
    file_formats.write_json(target, {"a": 1})
    assert target.read_text().strip().startswith("{")
    assert os.listdir(target.parent) == ["data.json"]
