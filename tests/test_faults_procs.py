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


# ---- Sweeps: failing tasks, a full disk, no worker left (items 8 and 12) -------------------

TWO_POINT_SWEEP = """name = "faults"
scene = "{scene}"
[defines]
res = 8
max_depth = 3
[fixed]
spp = 8
hetero_frequency = 1.0
[grid]
hetero_offset = [0.0, 0.25]
seed = {seeds}
"""


def write_sweep(tmp_path, seeds=(0,)) -> str:
    from dopplertof.demo import demo_scene_path

    config = tmp_path / "sweep.toml"
    config.write_text(TWO_POINT_SWEEP.format(scene=demo_scene_path(), seeds=list(seeds)))
    return str(config)


def assert_failures_listed(proc, out, failed: set):
    """Exit 1; stderr is one line per failed run and nothing else; summary.json lists
    them; the workers' log is in the output folder."""
    import json

    assert proc.returncode == 1, proc.stderr[-3000:]
    lines = proc.stderr.splitlines()
    assert all(line.startswith("dopplertof: task failed: ") for line in lines), \
        proc.stderr[-3000:]
    assert {line.split(": ")[2] for line in lines} == failed
    summary = json.loads((out / "summary.json").read_text())
    assert {f["task"] for f in summary["failed"]} == failed
    assert summary["done"] + len(failed) == summary["total"]
    assert summary["worker_log"] == str(out / "logs" / "workers.log")
    assert (out / "logs" / "workers.log").is_file()


@pytest.mark.slow
def test_a_failing_sweep_task_is_one_line_and_listed(tmp_path):
    """A file where a run's folder should be: the task raises on every attempt. Its Dask
    traceback (22 lines on afb2c4e) goes to OUT/logs/workers.log."""
    out = tmp_path / "out"
    (out / "runs").mkdir(parents=True)
    (out / "runs" / "hetero_offset=0.25__seed=0").write_text("in the way")
    proc = run_cli(["sweep", write_sweep(tmp_path), "-o", str(out), "--workers", "1",
                    "--retries", "1", "--quiet"], timeout=240)
    assert_failures_listed(proc, out, {"hetero_offset=0.25__seed=0"})
    assert "FileExistsError" in (out / "logs" / "workers.log").read_text()


def _mount_small_tmpfs(folder, size: str) -> str | None:
    """Mount a tmpfs of ``size`` on ``folder``; the reason it cannot be, or None."""
    if shutil.which("mount") is None or os.geteuid() != 0:
        return "mounting a tmpfs needs root and mount(8)"
    folder.mkdir()
    proc = subprocess.run(["mount", "-t", "tmpfs", "-o", f"size={size}", "tmpfs",
                           str(folder)], capture_output=True, text=True)
    return None if proc.returncode == 0 else f"cannot mount a tmpfs: {proc.stderr.strip()}"


@pytest.mark.slow
def test_a_full_disk_during_a_sweep_lists_its_failures(tmp_path):
    """A 48 KiB tmpfs holds sweep.json, summary.json and a run or two of six: the others
    fail with ENOSPC, one line each (about 330 lines of tracebacks and exit 2 without a
    summary.json on afb2c4e)."""
    disk = tmp_path / "disk"
    reason = _mount_small_tmpfs(disk, "48k")
    if reason:
        pytest.skip(reason)
    try:
        out = disk / "out"
        proc = run_cli(["sweep", write_sweep(tmp_path, seeds=(0, 1, 2)), "-o", str(out),
                        "--workers", "1", "--retries", "1", "--quiet"], timeout=300)
        import json

        failed = {f["task"] for f in json.loads((out / "summary.json").read_text())["failed"]}
        assert failed and all("No space left on device" in line
                              for line in proc.stderr.splitlines())
        assert_failures_listed(proc, out, failed)
    finally:
        subprocess.run(["umount", str(disk)], capture_output=True)


@pytest.mark.slow  # (5.5 s: make quick stays under its budget, issue 42)
def test_a_sweep_with_no_worker_left_ends(monkeypatch):
    """Every worker gone (here: the cluster scaled to 0; in the campaign: workers killed
    faster than they restart). On afb2c4e the run waited forever."""
    import logging
    import threading
    import time
    import types

    from distributed import Client, LocalCluster

    from dopplertof.experiments import cluster as cluster_module

    monkeypatch.setattr(cluster_module, "NO_WORKER_TIMEOUT", 3.0, raising=False)

    def slow(task):
        import time

        time.sleep(30)
        return task.name

    tasks = [types.SimpleNamespace(name=f"t{i}", hash=f"{i}" * 16) for i in range(3)]
    local = LocalCluster(n_workers=1, threads_per_worker=1, processes=True,
                         dashboard_address=":0", silence_logs=logging.CRITICAL)
    result = {}
    try:
        with Client(local) as client:
            client.wait_for_workers(1)
            run = threading.Thread(target=lambda: result.update(
                outcome=cluster_module.run_tasks(client, slow, tasks, progress=False)),
                daemon=True)
            run.start()
            time.sleep(1.0)
            started = time.monotonic()
            local.scale(0)
            run.join(timeout=40)
            hung = run.is_alive()
            seconds = time.monotonic() - started
            for future in list(client.futures.values()):
                future.cancel()
    finally:
        local.close()
    assert not hung, "run_tasks still waiting 40 s after the last worker left"
    outcome = result["outcome"]
    assert outcome.done == [] and [name for name, _ in outcome.failed] == ["t0", "t1", "t2"]
    assert all("no Dask worker left for 3 s" in error for _, error in outcome.failed)
    assert seconds < 3.0 + 10.0


def test_a_closing_worker_writes_nothing_more_to_the_workers_log(tmp_path):
    """issue 42: logs/workers.log held a CommClosedError traceback after a successful run
    (a worker's heartbeat racing the scheduler's close). The plugin's teardown, a
    closing worker's first step, sends its stderr to /dev/null."""
    log = tmp_path / "workers.log"
    code = ("import os, sys\n"
            "from dopplertof.experiments.worker_log import WorkerStderrToFile\n"
            f"plugin = WorkerStderrToFile({str(log)!r})\n"
            "plugin.setup(None)\n"
            "os.write(2, b'a task failed\\n')\n"
            "plugin.teardown(None)\n"
            "os.write(2, b'CommClosedError at shutdown\\n')\n")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=60)
    assert done.returncode == 0, done.stderr
    assert log.read_text() == "a task failed\n" and done.stderr == ""


def test_a_worker_restarted_after_the_run_folder_was_removed_starts_quietly(tmp_path):
    """issue 39, 2026-12-03 campaign P1-18: the plugin's setup raised FileNotFoundError for the removed folder's log
    (a traceback in the restarted worker's log); now the worker's stderr stays where
    it is."""
    code = ("import os\n"
            "from dopplertof.experiments.worker_log import WorkerStderrToFile\n"
            f"plugin = WorkerStderrToFile({str(tmp_path / 'gone' / 'logs' / 'w.log')!r})\n"
            "plugin.setup(object())\n"
            "os.write(2, b'still the terminal\\n')\n"
            "plugin.teardown(object())\n")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=60)
    assert done.returncode == 0 and done.stderr == "still the terminal\n", done.stderr
    assert not (tmp_path / "gone").exists()
