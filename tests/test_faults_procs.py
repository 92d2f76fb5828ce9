"""Processes under stress (issue 22, items 8, 9, 10, 12, 13): one CPU, address-space and
memory caps, sweeps whose workers die or whose tasks fail. Every run is a subprocess with
a timeout: a hang fails the test instead of stalling the suite."""

import os
import shutil
import subprocess
import sys

import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SPHERE = os.path.join(ROOT, "examples", "translating_sphere.xml")


def run_cli(args, timeout, preexec_fn=None, prefix=()):
    """``dopplertof ARGS`` in a subprocess (after ``prefix``, e.g. taskset); a run past
    ``timeout`` seconds fails the test as a hang."""
    argv = [*prefix, sys.executable, "-m", "dopplertof.cli", *args]
    try:
        return subprocess.run(argv, capture_output=True, text=True, timeout=timeout,
                              preexec_fn=preexec_fn)
    except subprocess.TimeoutExpired:
        pytest.fail(f"hung: no exit within {timeout} s: {' '.join(args)}")


# ---- One CPU: the EXR writer (item 9) ----------------------------------------------------

@pytest.mark.skipif(shutil.which("taskset") is None, reason="taskset is not installed")
def test_exr_render_on_one_cpu_finishes(tmp_path):
    out = tmp_path / "x.exr"
    proc = run_cli(["render", SPHERE, "-D", "res=16", "--spp", "16", "-o", str(out),
                    "--quiet"], timeout=60, prefix=("taskset", "-c", "0"))
    assert proc.returncode == 0, proc.stderr
    assert out.stat().st_size > 0
    assert sorted(os.listdir(tmp_path)) == ["x.exr"]  # no temporary file left
