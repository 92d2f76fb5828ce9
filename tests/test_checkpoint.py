"""Resumable renders: a killed render resumes to the bitwise-identical image."""

import signal
import subprocess
import sys

import numpy as np
import pytest

import dopplertof
from conftest import PUBLISHED, render_killed_then_resumed
from dopplertof.render import CheckpointError


def test_resume_after_interruption_is_bitwise_identical(tmp_path, monkeypatch):
    scene = dopplertof.load_file(PUBLISHED, {"resx": 12, "resy": 10})
    reference = dopplertof.render(scene, spp=64, seed=4)
    # killed after two passes were saved
    resumed = render_killed_then_resumed(monkeypatch, scene, tmp_path / "r.ckpt", 2,
                                         spp=64, seed=4)
    assert np.array_equal(resumed, reference)


def test_checkpoint_of_another_render_is_refused(tmp_path):
    scene = dopplertof.load_file(PUBLISHED, {"resx": 8, "resy": 8})
    ckpt = tmp_path / "r.ckpt"
    dopplertof.render(scene, spp=16, seed=1, checkpoint=ckpt)
    with pytest.raises(CheckpointError, match="belongs to a different render"):
        dopplertof.render(scene, spp=16, seed=2, checkpoint=ckpt)
    with pytest.raises(CheckpointError, match="belongs to a different render"):
        dopplertof.render(scene, spp=16, seed=1, checkpoint=ckpt,
                          params={"hetero_offset": 0.25})
    other = dopplertof.load_file(PUBLISHED, {"resx": 8, "resy": 8, "max_depth": 3})
    with pytest.raises(CheckpointError, match="belongs to a different render"):
        dopplertof.render(other, spp=16, seed=1, checkpoint=ckpt)


@pytest.mark.slow
def test_cli_killed_render_resumes(tmp_path):
    """The CLI killed (SIGKILL) right after its first checkpoint is saved (no race: the
    process kills itself there); the same command then finishes with the image of an
    uninterrupted run."""
    out, ckpt = tmp_path / "img.npy", tmp_path / "img.ckpt"
    args = ["render", PUBLISHED, "-D", "resx=96", "-D", "resy=96", "--spp", "512", "--seed",
            "2", "--quiet", "-o", str(out), "--checkpoint", str(ckpt)]
    die_after_first_save = (
        "import os, signal, sys\n"
        "import dopplertof.cli\n"
        "R = sys.modules['dopplertof.render']\n"
        "save = R.Checkpoint.save\n"
        "def save_then_die(self, *a):\n"
        "    save(self, *a)\n"
        "    os.kill(os.getpid(), signal.SIGKILL)\n"
        "R.Checkpoint.save = save_then_die\n"
        "sys.exit(dopplertof.cli.main(sys.argv[1:]))\n")
    proc = subprocess.run([sys.executable, "-c", die_after_first_save, *args],
                          capture_output=True, timeout=300)
    killed = proc.returncode == -signal.SIGKILL
    assert killed and ckpt.exists() and not out.exists()
    assert [p.name for p in tmp_path.iterdir()] == [ckpt.name]  # no partial files
    done = subprocess.run([sys.executable, "-m", "dopplertof.cli", *args], capture_output=True,
                          text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    assert not ckpt.exists()
    scene = dopplertof.load_file(PUBLISHED, {"resx": 96, "resy": 96})
    assert np.array_equal(np.load(out), dopplertof.render(scene, spp=512, seed=2))



def test_cli_render_says_it_resumed_and_from_how_many_samples(tmp_path, monkeypatch,
                                                               capsys):
    """A render interrupted after 2 of its passes (one chunk of 8 groups each) were
    saved: the render command resumes it and says so on stderr, with the samples per
    pixel the checkpoint held (the library's metadata has the number); a fresh render
    says nothing of the kind."""
    import shutil

    import dopplertof.cli

    scene = dopplertof.load_file(PUBLISHED, {"resx": 6, "resy": 5})
    ckpt, copy, out = tmp_path / "r.ckpt", tmp_path / "copy.ckpt", tmp_path / "r.npy"
    fresh = dopplertof.render_result(scene, spp=64, seed=3, checkpoint=ckpt)
    assert "resumed_from_samples" not in fresh.metadata
    ckpt.unlink()
    R = sys.modules["dopplertof.render"]
    original = R.Checkpoint.save

    def save_then_stop(self, accumulator, next_chunk, counts):
        original(self, accumulator, next_chunk, counts)
        if next_chunk == 2:
            raise KeyboardInterrupt

    monkeypatch.setattr(R.Checkpoint, "save", save_then_stop)
    with pytest.raises(KeyboardInterrupt):
        dopplertof.render(scene, spp=64, seed=3, pass_chunks=1, checkpoint=ckpt)
    monkeypatch.setattr(R.Checkpoint, "save", original)
    shutil.copy(ckpt, copy)
    saved = 2 * 8 * scene.params.time_correlate_number  # two chunks of 8 groups
    assert 0 < saved < 64
    resumed = dopplertof.render_result(scene, spp=64, seed=3, checkpoint=copy)
    assert resumed.metadata["resumed_from_samples"] == saved
    assert np.array_equal(resumed.image, fresh.image)
    capsys.readouterr()
    args = ["render", PUBLISHED, "-D", "resx=6", "-D", "resy=5", "--spp", "64", "--seed",
            "3", "--quiet", "-o", str(out), "--checkpoint", str(ckpt)]
    assert dopplertof.cli.main(args) == 0
    err = capsys.readouterr().err
    assert (f"dopplertof: resumed from checkpoint {ckpt}: {saved} of 64 samples per pixel "
            "were saved there") in err, err
    assert np.array_equal(np.load(out), fresh.image) and not ckpt.exists()
