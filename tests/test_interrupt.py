"""Ctrl-C during `animate` (Dask LocalCluster): one line, the workers shut down, nothing
half-written (issue 15, item 14)."""

import glob
import os
import signal
import subprocess
import sys
import time

import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SPHERE = os.path.join(ROOT, "examples", "translating_sphere.xml")


def _group_alive(pgid) -> bool:
    try:
        os.killpg(pgid, 0)
        return True
    except ProcessLookupError:
        return False


@pytest.mark.slow
def test_ctrl_c_during_animate_is_one_line_and_stops_the_workers(tmp_path):
    out = tmp_path / "frames"
    # renders long enough (tens of seconds a frame) to be interrupted in the middle
    argv = [sys.executable, "-m", "dopplertof.cli", "animate", SPHERE, "--frames", "8",
            "-D", "res=96", "--spp", "4096", "--workers", "2", "-o", str(out), "--quiet"]
    proc = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            start_new_session=True,  # its own group, as a terminal's job
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    try:
        deadline = time.monotonic() + 120
        while not glob.glob(str(out / "frame_*")) and time.monotonic() < deadline \
                and proc.poll() is None:
            time.sleep(0.1)
        assert glob.glob(str(out / "frame_*")), "no frame started"
        os.killpg(proc.pid, signal.SIGINT)  # Ctrl-C reaches the whole group
        _, err = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.communicate()
    assert proc.returncode == 130
    assert err == "dopplertof: interrupted\n", err
    deadline = time.monotonic() + 30
    while _group_alive(proc.pid) and time.monotonic() < deadline:
        time.sleep(0.2)
    assert not _group_alive(proc.pid), "worker processes left running"
    assert not glob.glob(str(out / "**" / ".*.tmp*"), recursive=True)
    assert not glob.glob(str(out / "frame_*" / "*.npy"))  # no frame was complete
