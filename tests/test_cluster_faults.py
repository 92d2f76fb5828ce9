"""External Dask clusters that fail: a worker whose Python cannot import dopplertof, a
scheduler without workers, a scheduler killed in the middle of a run (issue 39,
2026-12-03 campaign P1-07, P1-09, P1-14 to P1-16). A real `dask scheduler` and real
`dask worker` processes on 127.0.0.1, on random ports."""

import json
import os
import site
import subprocess
import sys
import threading
import time
import types

import pytest

pytestmark = pytest.mark.slow

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
CLI = os.path.join(os.path.dirname(sys.executable), "dopplertof")
DATASET_TOML = os.path.join(ROOT, "examples", "dataset.toml")


class Procs:
    """Processes started by a test, killed at its end."""

    def __init__(self, folder):
        self.folder, self.started = folder, []

    def start(self, args, name):
        log = open(os.path.join(self.folder, f"{name}.log"), "w")
        proc = subprocess.Popen(args, stdout=log, stderr=subprocess.STDOUT,
                                cwd=self.folder, start_new_session=True)
        self.started.append(proc)
        return proc

    def scheduler(self) -> tuple:
        """A `dask scheduler` on a random port: (its process, its address)."""
        path = os.path.join(self.folder, "scheduler.json")
        proc = self.start([sys.executable, "-m", "distributed.cli.dask_scheduler",
                           "--host", "127.0.0.1", "--port", "0", "--dashboard-address",
                           ":0", "--scheduler-file", path], "scheduler")
        deadline = time.monotonic() + 60
        while not os.path.exists(path) or not os.path.getsize(path):
            assert time.monotonic() < deadline and proc.poll() is None, "no scheduler"
            time.sleep(0.1)
        time.sleep(0.2)  # (the file is written whole, but give it its moment)
        return proc, json.load(open(path))["address"]

    def worker(self, address, python=sys.executable, name="worker"):
        return self.start([python, "-m", "distributed.cli.dask_worker", address,
                           "--nthreads", "1", "--dashboard-address", ":0"], name)

    def kill_all(self):
        for proc in self.started:
            if proc.poll() is None:
                try:
                    os.killpg(proc.pid, 9)
                except ProcessLookupError:
                    pass
            proc.wait(timeout=30)


@pytest.fixture
def procs(tmp_path):
    p = Procs(str(tmp_path))
    try:
        yield p
    finally:
        p.kill_all()


def python_without_dopplertof(folder) -> str:
    """A venv whose Python imports this one's packages (dask, distributed), but not
    dopplertof (installed in editable mode by a .pth file that a plain path entry
    does not run)."""
    venv = os.path.join(folder, "nodt")
    subprocess.run([getattr(sys, "_base_executable", sys.executable), "-m", "venv",
                    "--without-pip", venv], check=True, timeout=120)
    python = os.path.join(venv, "bin", "python")
    target = subprocess.run([python, "-c", "import site; print(site.getsitepackages()[0])"],
                            capture_output=True, text=True, check=True).stdout.strip()
    with open(os.path.join(target, "deps.pth"), "w") as f:
        f.write("\n".join(site.getsitepackages()) + "\n")
    done = subprocess.run([python, "-c", "import distributed, dopplertof"],
                          capture_output=True, text=True)
    assert "No module named 'dopplertof'" in done.stderr, done.stderr
    return python


def wait_for_workers(address, n, timeout=60):
    from distributed import Client

    deadline = time.monotonic() + timeout
    with Client(address, timeout="20s") as c:  # (listed, running or not)
        while len(c.scheduler_info()["workers"]) < n:
            assert time.monotonic() < deadline, f"fewer than {n} workers"
            time.sleep(0.2)
        return sorted(c.scheduler_info()["workers"])


def run_cli(args, folder, timeout=120):
    started = time.monotonic()
    done = subprocess.run([CLI, *args], capture_output=True, text=True, cwd=folder,
                          timeout=timeout)
    return done, time.monotonic() - started


def _dataset_on_a_worker_without_dopplertof(tmp_path, procs, python, address):
    """(the worker's address, the one stderr line, seconds) of a dataset run on the
    scheduler at ``address`` with one worker started by ``python`` (no dopplertof): it
    must end with exit 2, one line and no traceback."""
    procs.worker(address, python)
    (worker,) = wait_for_workers(address, 1)
    done, seconds = run_cli(["dataset", DATASET_TOML, "-o", str(tmp_path / "out"),
                             "--scheduler", address], str(tmp_path))
    assert done.returncode == 2, done.stderr
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in done.stderr, done.stderr
    return worker, lines[0], seconds


def test_a_worker_without_dopplertof_is_named_with_its_address(tmp_path, procs):
    """P1-14: `ModuleNotFoundError("No module named 'dopplertof'")`, as if the local
    install were broken, and no worker named."""
    python = python_without_dopplertof(str(tmp_path))
    _, address = procs.scheduler()
    worker, line, seconds = _dataset_on_a_worker_without_dopplertof(tmp_path, procs,
                                                                    python, address)
    assert f"the Dask worker at {worker} cannot import dopplertof" in line
    assert "No module named 'dopplertof'" in line and seconds < 60


def test_a_scheduler_without_workers_says_so(tmp_path, procs, monkeypatch):
    """P1-15: it waited 60 s, then blamed kills or a lack of memory for the worker that
    never was."""
    from dopplertof.experiments import cluster_checks
    from dopplertof.experiments.cluster import ClusterError, dask_client

    _, address = procs.scheduler()
    monkeypatch.setattr(cluster_checks, "WORKER_WAIT_SECONDS", 1.0)
    with pytest.raises(ClusterError, match=f"the Dask scheduler at {address} has no "
                       r"worker \(none joined in 1 s\)"):
        with dask_client(scheduler=address):
            pass


def test_a_worker_that_failed_to_start_ends_the_run_within_seconds(tmp_path, procs):
    """P1-16: on a scheduler that ran dopplertof before (its worker plugin registered),
    a worker without dopplertof fails to start but stays listed: the run printed
    nothing and never ended."""
    from distributed import Client

    from dopplertof.experiments.worker_log import WorkerStderrToFile

    python = python_without_dopplertof(str(tmp_path))
    _, address = procs.scheduler()
    with Client(address, timeout="20s") as c:
        c.register_plugin(WorkerStderrToFile(str(tmp_path / "first.log")),
                          name="dopplertof-worker-log")
    worker, line, seconds = _dataset_on_a_worker_without_dopplertof(tmp_path, procs,
                                                                    python, address)
    assert f"the Dask worker at {worker} does not answer" in line and seconds < 60


@pytest.mark.parametrize("restart", [False, True])
def test_a_scheduler_killed_in_the_middle_of_a_run_is_one_line(tmp_path, procs, capfd,
                                                               restart):
    """P1-07, P1-09: a Dask traceback and "task ended as cancelled" lines that never
    said the scheduler died (``restart``: a new scheduler at the same address at once,
    which the client reconnects to)."""
    from dopplertof.experiments.cluster import ClusterError, run_in_folder

    def slow(task):  # (pickled by value)
        import time

        time.sleep(2.0)
        return task.name

    scheduler, address = procs.scheduler()
    procs.worker(address)
    wait_for_workers(address, 1)
    tasks = [types.SimpleNamespace(name=f"t{i}", hash="7" * 16) for i in range(6)]
    def kill():
        os.killpg(scheduler.pid, 9)
        scheduler.wait()
        if restart:
            procs.start([sys.executable, "-m", "distributed.cli.dask_scheduler", "--host",
                         "127.0.0.1", "--port", address.rsplit(":", 1)[1],
                         "--dashboard-address", ":0"], "scheduler2")

    threading.Timer(3.0, kill).start()
    started = time.monotonic()
    with pytest.raises(ClusterError) as error:
        run_in_folder(slow, tasks, str(tmp_path / "out"), scheduler=address,
                      progress=False)
    seconds = time.monotonic() - started
    assert str(error.value).startswith(f"lost the Dask scheduler at {address}")
    assert seconds < 30
    time.sleep(0.5)
    captured = capfd.readouterr()
    assert "Traceback" not in captured.err and "cancelled" not in captured.err, captured.err


def test_each_run_on_a_scheduler_has_its_workers_log_and_then_leaves_the_workers_alone(
        tmp_path, procs):
    """P1-17: the worker-log plugin was idempotent: the first run's path stuck on the
    scheduler, every later run's logs/workers.log stayed empty, and the worker's own
    stderr never came back."""
    from distributed import Client

    from dopplertof.experiments.cluster import WORKER_LOG, run_in_folder

    def say(task):  # (pickled by value)
        import os

        os.write(2, f"marker of run {task.run}\n".encode())
        return task.name

    _, address = procs.scheduler()
    procs.worker(address, name="worker")
    wait_for_workers(address, 1)
    for run in "AB":
        task = types.SimpleNamespace(name="say", hash="9" * 16, run=run)
        outcome = run_in_folder(say, [task], str(tmp_path / run), scheduler=address,
                                progress=False)
        assert outcome.done == ["say"] and not outcome.failed
    for run, other in ("AB", "BA"):
        log = (tmp_path / run / WORKER_LOG).read_text()
        assert f"marker of run {run}" in log and f"marker of run {other}" not in log
    with Client(address, timeout="20s") as c:
        c.run(os.write, 2, b"marker after the runs\n")
    time.sleep(0.5)
    assert "marker after the runs" in (tmp_path / "worker.log").read_text()
