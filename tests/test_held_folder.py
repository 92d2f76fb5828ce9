"""One run at a time in an output folder: a sweep, an animation (a camera stream too), a
dataset or a capture's checkpoint folder is held for its whole run
(dopplertof.io.held_folder); a second run into a folder held by a live run is refused
before anything there changes, one that follows a killed run resumes. Every run is a
subprocess, as from a second shell."""

import json
import os
import signal
import subprocess
import sys
import time

import pytest

from dopplertof import io
from dopplertof.demo import demo_scene_path

SCENE = demo_scene_path()
TINY_SWEEP = (f"name = 'held'\nscene = {json.dumps(SCENE)}\n[defines]\nres = 8\n"
              "max_depth = 3\n[fixed]\nspp = 8\nseed = 0\nhetero_frequency = 1.0\n"
              "[grid]\ntime_sampling_method = ['uniform', 'antithetic']\n")
TINY_DATASET = ("samples = 2\nsamples_per_shard = 1\nseed = 7\n[render]\n"
                "resolution = [8, 6]\nspp = 2\nmax_depth = 3\n[objects]\ncount = [1, 1]\n"
                "shapes = ['sphere']\nmaterials = ['diffuse']\n")


def command(kind, tmp_path):
    """(the argv of a tiny run of ``kind`` into tmp_path/out, the files its two
    pieces of work complete, what its line says when they were complete before)."""
    out, workers = str(tmp_path / "out"), ["--workers", "1"]
    if kind == "sweep":
        (tmp_path / "sweep.toml").write_text(TINY_SWEEP)
        return (["sweep", str(tmp_path / "sweep.toml"), "-o", out, *workers],
                [f"runs/time_sampling_method={m}/complete.json"
                 for m in ("uniform", "antithetic")], "0 done now, 2 already complete")
    if kind == "animate":
        return (["animate", SCENE, "--frames", "2", "--spp", "4", "-D", "res=8",
                 "-D", "max_depth=3", "-o", out, *workers],
                ["frame_0000/complete.json", "frame_0001/complete.json"],
                "0 done now, 2 already complete")
    if kind == "stream":
        return (["animate", SCENE, "--camera", "azure-kinect", "--frames", "2", "--res",
                 "8x6", "--spp", "2", "-D", "max_depth=3", "-o", out, *workers],
                ["frame_0000/complete.json", "frame_0001/complete.json"],
                "0 done now, 2 already complete")
    (tmp_path / "dataset.toml").write_text(TINY_DATASET)
    return (["dataset", str(tmp_path / "dataset.toml"), "-o", out, *workers],
            ["shard_00000.h5", "shard_00001.h5"], "0 rendered now, 2 shards already complete")


def cli(args, **popen):
    argv = [sys.executable, "-m", "dopplertof.cli", *args]
    if popen:
        return subprocess.Popen(argv, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                                **popen)
    try:
        return subprocess.run(argv, capture_output=True, text=True, timeout=300)
    except subprocess.TimeoutExpired:
        pytest.fail(f"hung: no exit within 300 s: {' '.join(args)}")


def files(folder):
    """{path: (bytes, mtime in ns)} of every file under ``folder``, hidden ones too."""
    found = {}
    for root, _, names in os.walk(folder):
        for name in names:
            path = os.path.join(root, name)
            with open(path, "rb") as f:
                found[path] = (f.read(), os.stat(path).st_mtime_ns)
    return found


def holder_pid(folder):
    try:
        with open(os.path.join(folder, io.RUN_HOLDER), encoding="utf-8") as f:
            return json.load(f)["pid"]
    except (OSError, ValueError):
        return None


def stopped_holder(args, folder):
    """A run of ``args`` started in its own session and stopped (SIGSTOP) as soon as it
    holds ``folder``: a live run that holds it for as long as the test needs."""
    run = cli(args, start_new_session=True)
    deadline = time.monotonic() + 120
    while holder_pid(folder) != run.pid:
        if run.poll() is not None or time.monotonic() > deadline:
            run.kill()
            pytest.fail(f"the first run never held {folder} (exit {run.poll()})")
        time.sleep(0.002)
    os.killpg(run.pid, signal.SIGSTOP)
    return run


def refused_then_killed(args, folder):
    """Start ``args``, stop it once it holds ``folder``; the same command again is
    refused (exit 2, one line naming the folder, the holder's pid and its command) and
    changes no file there (bytes, mtime, no new file); then the first run is killed
    (SIGKILL, its workers too: its own session), its lock file left behind."""
    holder = stopped_holder(args, folder)
    try:
        before = files(folder)
        refused = cli(args)
        assert refused.returncode == 2, refused.stderr
        lines = refused.stderr.splitlines()
        assert len(lines) == 1 and f"{folder} is in use by another run" in lines[0] \
            and f"pid {holder.pid} " in lines[0] and f"dopplertof {args[0]} " in lines[0] \
            and lines[0].startswith("dopplertof: error: "), lines
        assert files(folder) == before
    finally:
        os.killpg(holder.pid, signal.SIGKILL)
        holder.wait(timeout=60)
    assert holder_pid(folder) == holder.pid  # (what a kill leaves)


@pytest.mark.parametrize("kind", ["sweep", *(pytest.param(k, marks=pytest.mark.slow)
                                              for k in ("animate", "stream", "dataset"))])
def test_a_second_run_on_a_held_folder_is_refused_and_a_killed_ones_resumes(kind, tmp_path):
    """Refused while the first run lives; after its kill the same command completes the
    work and leaves no lock file; run once more it skips everything (as without locks)."""
    args, complete, rerun_line = command(kind, tmp_path)
    out = str(tmp_path / "out")
    refused_then_killed(args, out)
    resumed = cli(args)
    assert resumed.returncode == 0, resumed.stderr
    assert all(os.path.isfile(os.path.join(out, f)) for f in complete)
    assert not os.path.exists(os.path.join(out, io.RUN_LOCK))
    assert not os.path.exists(os.path.join(out, io.RUN_HOLDER))
    again = cli(args)
    assert again.returncode == 0 and rerun_line in again.stdout, again.stdout + again.stderr


def test_a_capture_on_a_held_checkpoint_folder_is_refused(tmp_path):
    """`capture --checkpoint DIR` holds DIR: a second capture with it is refused; after
    the first is killed the same command captures and removes DIR, as one that served."""
    checkpoint = str(tmp_path / "checkpoint")
    args = ["capture", SCENE, "-D", "res=8", "-D", "max_depth=3", "--spp", "8", "-o",
            str(tmp_path / "frame"), "--checkpoint", checkpoint, "--quiet"]
    refused_then_killed(args, checkpoint)
    resumed = cli(args)
    assert resumed.returncode == 0, resumed.stderr
    assert (tmp_path / "frame" / "velocity.npy").is_file() and not os.path.exists(checkpoint)


def test_a_held_folder_is_refused_to_a_second_holder_and_free_after(tmp_path):
    """flock is per open file: a second hold, even from this process, is refused naming
    this process; after the first ends the folder holds none of the lock's files, and a
    folder the hold created and nothing else filled is removed again."""
    out = tmp_path / "a" / "out"
    with io.held_folder(out) as held:
        assert held == str(out) and holder_pid(held) == os.getpid()
        before = files(held)
        with pytest.raises(io.OutputError, match=rf"in use by another run \(pid "
                                                 rf"{os.getpid()} on "):
            with io.held_folder(out):
                pass
        assert files(held) == before
        (out / "kept.txt").write_text("x")
    assert os.listdir(out) == ["kept.txt"]
    with io.held_folder(tmp_path / "b" / "c"):
        pass
    assert sorted(os.listdir(tmp_path)) == ["a"]


def test_a_lock_file_of_a_killed_run_is_taken_over(tmp_path):
    """A killed run's lock file and holder file stay behind; its lock went with it: the
    next run takes the folder and says it is the holder."""
    (tmp_path / io.RUN_LOCK).write_text("")
    (tmp_path / io.RUN_HOLDER).write_text(json.dumps({"pid": 1, "host": "gone",
                                                      "command": "x", "started": "y"}))
    with io.held_folder(tmp_path):
        assert holder_pid(tmp_path) == os.getpid()
    assert os.listdir(tmp_path) == []


@pytest.mark.parametrize("garbage", ['{"pid": 1e400, "host": "h", "command": "c", '
                                     '"started": "s"}', '[1]', '\x00\xff junk'])
def test_a_garbled_holder_file_of_a_live_run_is_still_one_line(tmp_path, garbage):
    """The holder file of a live run overwritten with junk (a pid of 1e400 raised
    OverflowError): the refusal says the holder file is unreadable, on one line; a
    holder's host and time with line breaks are put on one line too."""
    with io.held_folder(tmp_path):
        holder = tmp_path / io.RUN_HOLDER
        holder.write_text(garbage, encoding="latin-1")
        with pytest.raises(io.OutputError) as refused:
            with io.held_folder(tmp_path):
                pass
        assert f"its holder file {io.RUN_HOLDER} unreadable" in str(refused.value)
        holder.write_text(json.dumps({"pid": 12, "host": "node\n7", "command": "a\nb",
                                      "started": "now\r\n"}))
        with pytest.raises(io.OutputError) as refused:
            with io.held_folder(tmp_path):
                pass
        assert "(pid 12 on node 7, started now: a b)" in str(refused.value)
        assert len(str(refused.value).splitlines()) == 1


@pytest.mark.parametrize("in_place", ["folder", "dangling link"])
def test_a_lock_file_that_cannot_be_opened_is_named(tmp_path, in_place):
    """A folder or a dangling link where the lock file goes: the error names the lock
    file (it named the output folder: "OUT: Is a directory")."""
    lock = tmp_path / io.RUN_LOCK
    if in_place == "folder":
        lock.mkdir()
    else:
        lock.symlink_to(tmp_path / "gone" / "lock")
    with pytest.raises(io.WriteError) as refused:
        with io.held_folder(tmp_path):
            pass
    assert refused.value.path == str(lock)
