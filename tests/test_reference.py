"""benchmarks/reference.py: the deep reference renders in resumable pieces."""

import importlib.util
import json
import os

import numpy as np
import pytest

from conftest import FIXTURES

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def reference_script():
    spec = importlib.util.spec_from_file_location(
        "reference_script", os.path.join(ROOT, "benchmarks", "reference.py"))
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_reference_resumes_bitwise_from_its_pieces_and_checkpoints(tmp_path, monkeypatch):
    """A tiny reference (8x8, 4 pieces of 16 spp) stopped after 1 piece, then killed
    inside a piece (after its first checkpoint), then resumed: the same image and hash
    as an uninterrupted run, the pieces of the first runs read back, not rendered."""
    import dopplertof

    script = reference_script()
    tiny = ["--res", "8", "--spp", "64", "--piece-spp", "16", "--fixtures", FIXTURES]
    assert script.main(["--out", str(tmp_path / "whole")] + tiny) == 0
    whole = json.loads((tmp_path / "whole" / "reference.json").read_text())

    parts = tmp_path / "parts"
    assert script.main(["--out", str(parts), "--max-pieces", "1"] + tiny) == 0
    assert sorted(os.listdir(parts)) == ["piece_0000.npy"]
    R = __import__("sys").modules["dopplertof.render"]
    original, calls = R.Checkpoint.save, {"n": 0}

    def save_then_die(self, *args):
        original(self, *args)
        calls["n"] += 1
        raise KeyboardInterrupt

    monkeypatch.setattr(R.Checkpoint, "save", save_then_die)
    monkeypatch.setattr(dopplertof, "render", _one_pass(dopplertof.render))
    with pytest.raises(KeyboardInterrupt):
        script.main(["--out", str(parts)] + tiny)
    assert os.path.exists(parts / "piece_0001.ckpt")
    monkeypatch.setattr(R.Checkpoint, "save", original)
    assert script.main(["--out", str(parts)] + tiny) == 0
    resumed = json.loads((parts / "reference.json").read_text())
    assert resumed["sha256"] == whole["sha256"]
    assert np.array_equal(np.load(parts / "reference.npy"),
                          np.load(tmp_path / "whole" / "reference.npy"))
    assert not os.path.exists(parts / "piece_0001.ckpt")  # removed once the piece is done
    assert resumed["own_noise_rmse"] > 0 and "rmse_against_published" not in resumed


def _one_pass(render):
    def render_one_chunk_per_pass(*args, **kwargs):
        return render(*args, pass_chunks=1, **kwargs)
    return render_one_chunk_per_pass


def test_reference_refuses_a_bad_piece_size(tmp_path, capsys):
    script = reference_script()
    assert script.main(["--out", str(tmp_path), "--spp", "100", "--piece-spp", "64"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--piece-spp 64" in err
    assert os.listdir(tmp_path) == []
