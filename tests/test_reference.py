"""benchmarks/reference.py: the deep reference renders in resumable pieces."""

import json
import os

import numpy as np
import pytest

from conftest import FIXTURES, load_script


def reference_script():
    return load_script("benchmarks/reference.py")


def test_reference_resumes_bitwise_from_its_pieces(tmp_path, monkeypatch):
    """A tiny reference (8x8, 4 pieces of 16 spp) stopped after 1 piece, then killed
    inside the third (KeyboardInterrupt from its render), then resumed: the same image
    and hash as an uninterrupted run, the finished pieces read back, not rendered."""
    import dopplertof

    script = reference_script()
    tiny = ["--res", "8", "--spp", "64", "--piece-spp", "16", "--fixtures", FIXTURES]
    assert script.main(["--out", str(tmp_path / "whole")] + tiny) == 0
    whole = json.loads((tmp_path / "whole" / "reference.json").read_text())

    parts = tmp_path / "parts"
    assert script.main(["--out", str(parts), "--max-pieces", "1"] + tiny) == 0
    assert sorted(os.listdir(parts)) == ["piece_0000.npy"]
    render, seeds = dopplertof.render, []

    def render_then_die_in_the_third(*args, **kwargs):
        seeds.append(kwargs["seed"])
        if len(seeds) == 2:
            raise KeyboardInterrupt
        return render(*args, **kwargs)

    monkeypatch.setattr(dopplertof, "render", render_then_die_in_the_third)
    with pytest.raises(KeyboardInterrupt):
        script.main(["--out", str(parts)] + tiny)
    assert sorted(os.listdir(parts)) == ["piece_0000.npy", "piece_0001.npy"]
    seeds.clear()
    monkeypatch.setattr(dopplertof, "render", lambda *a, **k: seeds.append(k) or render(*a, **k))
    assert script.main(["--out", str(parts)] + tiny) == 0
    assert [k["seed"] - script.SEED_BASE for k in seeds] == [2, 3]  # only the missing ones
    resumed = json.loads((parts / "reference.json").read_text())
    assert resumed["sha256"] == whole["sha256"]
    assert np.array_equal(np.load(parts / "reference.npy"),
                          np.load(tmp_path / "whole" / "reference.npy"))
    assert resumed["own_noise_rmse"] > 0 and "rmse_against_published" not in resumed


def test_reference_refuses_a_bad_piece_size(tmp_path, capsys):
    script = reference_script()
    assert script.main(["--out", str(tmp_path), "--spp", "100", "--piece-spp", "64"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--piece-spp 64" in err
    assert os.listdir(tmp_path) == []
