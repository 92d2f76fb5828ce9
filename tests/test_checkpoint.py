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
