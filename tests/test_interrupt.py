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


# ---- Ctrl-C during a render (issue 22, item 13) --------------------------------------

def test_interrupt_wrapped_by_drjit_is_the_interrupt_line(tmp_path, monkeypatch, capsys):
    """Dr.Jit turns a KeyboardInterrupt raised inside a loop it traces into
    ``RuntimeError: dr.while_loop(): encountered an exception (see above)``."""
    import drjit as dr
    import mitsuba as mi

    import dopplertof
    from dopplertof.cli import main

    def render_interrupted_in_a_loop(*args, **kwargs):
        def body(i):
            raise KeyboardInterrupt

        dr.while_loop((mi.UInt32(0, 1),), lambda i: i < 10, body)

    monkeypatch.setattr(dopplertof, "render_result", render_interrupted_in_a_loop)
    code = main(["render", SPHERE, "-D", "res=8", "-o", str(tmp_path / "x.npy"), "--quiet"])
    assert (code, capsys.readouterr().err) == (130, "dopplertof: interrupted\n")


@pytest.mark.slow
def test_sigint_at_any_moment_of_a_render_is_one_line(tmp_path):
    """SIGINT at several moments after the CLI's main starts: while it builds its parser,
    sets the variant, loads the scene, renders. Always the one line and exit 130. (The
    render is long, 16384 spp, so that the last moment falls inside it. A clean-clone run
    once found x.npy written: a SIGINT whose KeyboardInterrupt was lost let the render go
    on to its end; io.atomic_path no longer commits a file after one, see the test
    below.)"""
    out = tmp_path / "x.npy"
    code = ("import sys, dopplertof.cli as cli; print('ready', flush=True); "
            "sys.exit(cli.main(sys.argv[1:]))")
    argv = [sys.executable, "-c", code, "render", SPHERE, "-D", "res=128", "--spp", "16384",
            "-o", str(out), "--quiet"]
    outcomes = []
    for delay in (0.05, 0.2, 0.4, 0.7, 1.0, 1.5, 2.5):
        proc = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                text=True,
                                preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
        try:
            assert proc.stdout.readline() == "ready\n"
            time.sleep(delay)
            proc.send_signal(signal.SIGINT)
            _, err = proc.communicate(timeout=60)
        finally:
            if proc.poll() is None:
                proc.kill()
                proc.communicate()
        outcomes.append((delay, proc.returncode, err))
    bad = [o for o in outcomes if o[1:] != (130, "dopplertof: interrupted\n")]
    assert not bad, bad
    assert not out.exists() and not list(tmp_path.glob(".*.tmp*"))


def test_a_ctrl_c_python_drops_in_a_weakref_callback_still_stops_the_command(tmp_path, capsys,
                                                                            monkeypatch):
    """A SIGINT whose KeyboardInterrupt is raised inside a weakref callback (matplotlib's
    transforms have them; Python prints such an exception and goes on) still stops the
    command: exit 130, one line, no output committed, no 'Exception ignored' traceback.
    Found by the capture --checkpoint test: a SIGINT 6 s into a capture (while its
    previews were drawn) let the capture finish and exit 0."""
    import weakref

    import dopplertof.cli
    from dopplertof import io

    class Target:
        pass

    kept = []
    path = io.StagedFolder.path

    def path_then_lost_interrupt(self, name):  # the first file: a callback meets Ctrl-C
        if not kept:
            target = Target()
            kept.append(weakref.ref(target, lambda ref: signal.raise_signal(signal.SIGINT)))
            del target  # the callback runs now; its KeyboardInterrupt is dropped
        return path(self, name)

    monkeypatch.setattr(io.StagedFolder, "path", path_then_lost_interrupt)
    out = tmp_path / "out"
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)  # (a terminal's)
    try:
        code = dopplertof.cli.main(["capture", SPHERE, "-D", "res=4", "--spp", "8",
                                    "--quiet", "-o", str(out)])
    finally:
        signal.signal(signal.SIGINT, previous)
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # (as under nohup: no handler of ours)
    try:  # the next command in this process is not taken for interrupted
        again = dopplertof.cli.main(["capture", SPHERE, "-D", "res=4", "--spp", "8",
                                     "--quiet", "-o", str(tmp_path / "again")])
    finally:
        signal.signal(signal.SIGINT, previous)
    assert again == 0
    err = capsys.readouterr().err
    assert kept and code == 130, err
    assert "dopplertof: interrupted" in err.strip().splitlines()
    assert "Exception ignored" not in err and "Traceback" not in err, err
    assert not out.exists() or not any(out.iterdir())


def test_a_ctrl_c_python_drops_before_a_single_file_is_written_commits_no_file(
        tmp_path, capsys, monkeypatch):
    """The same lost KeyboardInterrupt before ``render -o x.npy`` writes its one file
    (io.atomic_path, not an output folder): exit 130, one line, and no x.npy. Found by a
    clean-clone run in which a SIGINT into a render was lost, the render went on to the
    end and its file was written before the command said it was interrupted."""
    import weakref

    import dopplertof.cli
    from dopplertof import io

    class Target:
        pass

    kept = []
    atomic_path = io.atomic_path

    def write_after_lost_interrupt(path):  # the write begins: a callback meets Ctrl-C
        target = Target()
        kept.append(weakref.ref(target, lambda ref: signal.raise_signal(signal.SIGINT)))
        del target  # the callback runs now; its KeyboardInterrupt is dropped
        return atomic_path(path)

    monkeypatch.setattr(io, "atomic_path", write_after_lost_interrupt)
    out = tmp_path / "x.npy"
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)  # (a terminal's)
    try:
        code = dopplertof.cli.main(["render", SPHERE, "-D", "res=4", "--spp", "8",
                                    "--quiet", "-o", str(out)])
    finally:
        signal.signal(signal.SIGINT, previous)
    err = capsys.readouterr().err
    assert kept and code == 130, err
    assert err.strip().splitlines()[-1] == "dopplertof: interrupted", err
    assert "Exception ignored" not in err and "Traceback" not in err, err
    assert os.listdir(tmp_path) == []  # neither x.npy nor a temporary beside it


# ---- Ctrl-C while the local Dask cluster starts (issue 39) ------------------------------

def test_ctrl_c_while_the_local_cluster_starts_stops_the_run(tmp_path, monkeypatch, capsys):
    """2026-12-03 campaign G11, G18-G21: a Ctrl-C in the first second of `dataset` or
    `sweep`, while the LocalCluster starts, was ignored (SIGINT set to SIG_IGN for the
    workers' sake): the run rendered everything and exited 0. Now it is held while the
    cluster starts, the cluster is closed, and the command ends with the one line, exit
    130, no shard written."""
    import distributed

    from dopplertof.cli import main

    real, started = distributed.LocalCluster, []

    def ctrl_c_as_it_starts(*args, **kwargs):
        os.kill(os.getpid(), signal.SIGINT)
        started.append(real(*args, **kwargs))
        return started[-1]

    monkeypatch.setattr(distributed, "LocalCluster", ctrl_c_as_it_starts)
    config = tmp_path / "ds.toml"
    config.write_text('samples = 2\nsamples_per_shard = 1\nseed = 1\n[render]\n'
                      'resolution = [8, 8]\nspp = 4\nmax_depth = 3\n')
    out = tmp_path / "out"
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)  # (a terminal's)
    try:
        code = main(["dataset", str(config), "-o", str(out), "--workers", "1", "--quiet"])
    finally:
        signal.signal(signal.SIGINT, previous)
    assert (code, capsys.readouterr().err) == (130, "dopplertof: interrupted\n")
    assert started and started[0].status.name == "closed"
    assert not list(out.glob("shard_*")) and not list(out.glob(".*.tmp*"))


# ---- A kill while the local Dask cluster's workers spawn (issue 39) ---------------------

#: a driver killed right after it started a worker process, before it wrote the worker's
#: preparation data into the pipe the worker reads (the instant of the 2026-12-03 campaign
#: G16: SIGKILL at 0.6 s of `dataset`)
_KILLED_WHILE_SPAWNING = """
import os, signal, sys
from multiprocessing import util
real = util.spawnv_passfds
def spawn_then_die(path, args, passfds):
    pid = real(path, args, passfds)
    if any(b"spawn_main" in os.fsencode(a) for a in args):  # (a worker, not the tracker)
        os.kill(os.getpid(), signal.SIGKILL)
    return pid
util.spawnv_passfds = spawn_then_die
from dopplertof.cli import main
sys.exit(main(["dataset", sys.argv[1], "-o", sys.argv[2], "--workers", "1", "--quiet"]))
"""


def test_a_driver_killed_while_its_workers_spawn_leaves_nothing_on_the_terminal(tmp_path):
    """G16: the half-spawned worker read an empty pipe and printed multiprocessing's
    `EOFError: Ran out of input` traceback on the user's terminal after the driver died.
    The local cluster's processes start with their stderr on the run's logs/workers.log."""
    import subprocess
    import sys
    import time

    config = tmp_path / "ds.toml"
    config.write_text('samples = 2\nsamples_per_shard = 1\nseed = 1\n[render]\n'
                      'resolution = [8, 8]\nspp = 4\nmax_depth = 3\n')
    out, terminal = tmp_path / "out", tmp_path / "terminal.txt"
    with open(terminal, "wb") as err:
        done = subprocess.run([sys.executable, "-c", _KILLED_WHILE_SPAWNING, str(config),
                               str(out)], stderr=err, stdout=subprocess.DEVNULL, timeout=300)
    assert done.returncode == -signal.SIGKILL
    log = out / "logs" / "workers.log"
    deadline = time.monotonic() + 30  # the orphaned worker's traceback, once it is written
    while "EOFError" not in (log.read_text() if log.exists() else "") + terminal.read_text():
        assert time.monotonic() < deadline, "the orphaned worker said nothing in 30 s"
        time.sleep(0.2)
    time.sleep(0.5)
    assert terminal.read_text() == "" and "Ran out of input" in log.read_text()
