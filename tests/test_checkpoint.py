"""Resumable renders: a killed render resumes to the bitwise-identical image."""

import os
import signal
import subprocess
import sys
import time

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


def test_cli_killed_render_resumes(tmp_path):
    """SIGKILL the CLI once the checkpoint exists; the same command then finishes with the
    image of an uninterrupted run."""
    out, ckpt = tmp_path / "img.npy", tmp_path / "img.ckpt"
    args = [sys.executable, "-m", "dopplertof.cli", "render", PUBLISHED, "-D", "resx=96",
            "-D", "resy=96", "--spp", "512", "--seed", "2", "--quiet", "-o", str(out),
            "--checkpoint", str(ckpt)]
    proc = subprocess.Popen(args, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    deadline = time.time() + 120
    while not ckpt.exists() and time.time() < deadline and proc.poll() is None:
        time.sleep(0.05)
    killed = proc.poll() is None
    if killed:
        os.kill(proc.pid, signal.SIGKILL)
    proc.wait()
    assert killed and ckpt.exists() and not out.exists()
    assert [p.name for p in tmp_path.iterdir()] == [ckpt.name]  # no partial files
    done = subprocess.run(args, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    assert not ckpt.exists()
    scene = dopplertof.load_file(PUBLISHED, {"resx": 96, "resy": 96})
    assert np.array_equal(np.load(out), dopplertof.render(scene, spp=512, seed=2))
