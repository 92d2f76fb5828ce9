"""Dask distributed: a LocalCluster of process workers by default, or an existing
scheduler; one Dask task per render task, retried, with a progress bar over tasks.
"""

from __future__ import annotations

import contextlib
import logging
import os
import sys
import time
from dataclasses import dataclass, field, replace

#: fewest Dr.Jit threads a worker is given (its EXR writes need two, and image_files.write_exr
#: raises the count for the write in any case: image_files.MIN_EXR_THREADS)
MIN_DRJIT_THREADS = 2

#: retries of a task that raised, before it is reported as failed
DEFAULT_RETRIES = 2

#: longest one-line error kept of a failed task
MAX_ERROR_CHARS = 800

#: the workers' log in a sweep's or an animation's output folder
WORKER_LOG = os.path.join("logs", "workers.log")

#: seconds without any worker after which the tasks not done are reported failed
NO_WORKER_TIMEOUT = 60.0
#: how often a run looks for completed tasks, and for workers
POLL_SECONDS = 0.1
WORKER_CHECK_SECONDS = 1.0


class ClusterError(RuntimeError):
    """A scheduler that cannot be reached or a cluster that cannot start."""


@dataclass
class RunOutcome:
    """What happened to the submitted tasks."""

    done: list = field(default_factory=list)  #: results returned by the task function
    failed: list = field(default_factory=list)  #: (task name, one-line error)
    seconds: float = 0.0


def default_workers() -> int:
    return max(1, min(os.cpu_count() or 1, 8))


@contextlib.contextmanager
def dask_client(scheduler: str | None = None, workers: int | None = None,
                client=None, log_file: str | None = None):
    """Yield ``(client, threads_per_render)``.

    ``client``: use this one as is. ``scheduler``: connect to that address.
    Otherwise start a LocalCluster of ``workers`` single-threaded process workers and
    give each render ``cpu_count / workers`` Dr.Jit threads (at least 2).
    ``log_file``: where the workers' stderr (Dask's logs and tracebacks of failing
    tasks) and this process's Dask messages go, instead of the terminal.
    """
    if client is not None:
        yield client, None
        return
    from distributed import Client, LocalCluster

    if scheduler:
        try:
            c = Client(scheduler, timeout="20s")
        except (OSError, TimeoutError) as e:
            raise ClusterError(f"cannot reach the Dask scheduler at {scheduler}: "
                               f"{' '.join(str(e).split())}") from None
        try:
            _check_workers(c, scheduler)
            with _dask_logs_to(c, log_file, release=True):
                yield c, None
        finally:
            _close_quietly(c)
        return
    n = workers or default_workers()
    if n < 1:
        raise ClusterError(f"--workers must be >= 1, got {n}")
    threads = max(MIN_DRJIT_THREADS, (os.cpu_count() or 1) // n)
    _start_resource_tracker_quietly()
    with _workers_ignore_ctrl_c() as held, _spawned_stderr_to(log_file):
        cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True,
                               dashboard_address=":0", silence_logs=logging.ERROR)
    if held:  # Ctrl-C while the cluster started: stop it, then act on the Ctrl-C
        cluster.close()
        _deliver_ctrl_c()
    try:
        with Client(cluster) as c, _dask_logs_to(c, log_file):
            yield c, threads
    finally:
        cluster.close()


def _check_workers(client, scheduler: str) -> None:
    """:func:`cluster_checks.check_workers` with its error a ClusterError (a worker
    without dopplertof read as a broken local install, or hung the run)."""
    from .cluster_checks import WorkerCheckError, check_workers

    try:
        check_workers(client, scheduler)
    except WorkerCheckError as e:
        raise ClusterError(str(e)) from None


def _close_quietly(client) -> None:
    """Close ``client`` without Dask's log records: a client that lost its scheduler
    logs its reconnection's CancelledError traceback as it closes."""
    names = ["distributed"] + [n for n in logging.root.manager.loggerDict
                               if n.startswith("distributed.")]
    loggers = [(logging.getLogger(n), logging.getLogger(n).disabled) for n in names]
    for logger, _ in loggers:
        logger.disabled = True
    try:
        client.close()
    finally:
        for logger, disabled in loggers:
            logger.disabled = disabled


@contextlib.contextmanager
def _dask_logs_to(client, log_file: str | None, release: bool = False):
    """Send the workers' stderr (present and restarted ones) and this process's Dask
    log records to ``log_file`` (appended) while the block runs. ``release``: the
    workers outlive the run (an external scheduler's): their stderr is their own again
    once it ends."""
    if log_file is None:
        yield
        return
    from .worker_log import PLUGIN_NAME, WorkerStderrToFile

    os.makedirs(os.path.dirname(log_file), exist_ok=True)
    client.register_plugin(WorkerStderrToFile(log_file), name=PLUGIN_NAME)
    if release:
        with _released(client, PLUGIN_NAME), _dask_records_to(log_file):
            yield
        return
    with _dask_records_to(log_file):
        yield


@contextlib.contextmanager
def _released(client, plugin: str):
    """Unregister the worker plugin ``plugin`` once the block ends (not from a client
    that lost its scheduler: it would wait for it)."""
    try:
        yield
    finally:
        if not _lost(client):
            with contextlib.suppress(Exception):
                client.unregister_worker_plugin(plugin)


@contextlib.contextmanager
def _dask_records_to(log_file: str):
    """This process's Dask log records to ``log_file`` instead of the terminal."""
    handler = logging.FileHandler(log_file, encoding="utf-8")
    handler.setFormatter(logging.Formatter("%(asctime)s %(name)s %(levelname)s %(message)s"))
    dask_logger = logging.getLogger("distributed")
    consoles = [(h, h.level) for h in dask_logger.handlers
                if isinstance(h, logging.StreamHandler)
                and not isinstance(h, logging.FileHandler)]
    for console, _ in consoles:
        console.setLevel(logging.CRITICAL + 1)  # (silenced, not removed: Dask owns them)
    dask_logger.addHandler(handler)
    try:
        yield
    finally:
        dask_logger.removeHandler(handler)
        handler.close()
        for console, level in consoles:
            console.setLevel(level)


def _start_resource_tracker_quietly() -> None:
    """Start multiprocessing's resource tracker (the workers share it) with its stderr on
    /dev/null. After Ctrl-C the workers busy rendering are killed at shutdown, and the
    tracker, which then removes the semaphores they held, would print a two-line
    UserWarning about them after our one-line "interrupted"."""
    from multiprocessing import resource_tracker

    devnull = os.open(os.devnull, os.O_WRONLY)
    saved = os.dup(2)
    try:
        sys.stderr.flush()
        os.dup2(devnull, 2)
        resource_tracker.ensure_running()
    finally:
        os.dup2(saved, 2)
        os.close(saved)
        os.close(devnull)


@contextlib.contextmanager
def _spawned_stderr_to(log_file: str | None):
    """The processes started while the block runs (the local cluster's workers) have
    ``log_file`` (appended) as their stderr, and so has this process meanwhile. A worker
    whose driver was killed before it wrote the worker's start-up data into its pipe
    printed multiprocessing's `EOFError: Ran out of input` traceback on the user's
    terminal after the driver died; it goes to the
    run's log now. The worker plugin sends a worker's stderr there once it runs."""
    if log_file is None:
        yield
        return
    os.makedirs(os.path.dirname(log_file) or ".", exist_ok=True)
    log = os.open(log_file, os.O_WRONLY | os.O_APPEND | os.O_CREAT, 0o666)
    saved = os.dup(2)
    try:
        sys.stderr.flush()
        os.dup2(log, 2)
        yield
    finally:
        sys.stderr.flush()
        os.dup2(saved, 2)
        os.close(saved)
        os.close(log)


@contextlib.contextmanager
def _workers_ignore_ctrl_c():
    """Start processes that never see Ctrl-C: it reaches every process of the terminal's
    group, and only this one should act on it, by shutting the workers down, rather than
    each worker printing its traceback. SIGINT is blocked in this thread while the block
    runs: the threads started meanwhile (the cluster's) and the processes they spawn
    inherit the blocked signal, across exec too. A Ctrl-C meanwhile is held, not lost:
    yields a list that holds it once the block ends (it was ignored, SIG_IGN, and the run
    went on to exit 0); the caller stops
    what it started, then :func:`_deliver_ctrl_c`."""
    import signal
    import threading

    held: list = []
    if threading.current_thread() is not threading.main_thread():
        yield held
        return
    previous = signal.getsignal(signal.SIGINT)
    if previous not in (signal.SIG_IGN, None):
        # (Python runs a handler in the main thread, even for a signal another thread
        # took: recorded, not raised in the middle of the cluster's start)
        signal.signal(signal.SIGINT, lambda signum, frame: held.append(signum))
    mask = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    try:
        yield held
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, mask)  # a held Ctrl-C arrives now
        if previous not in (signal.SIG_IGN, None):
            signal.signal(signal.SIGINT, previous)


def _deliver_ctrl_c() -> None:
    """The Ctrl-C :func:`_workers_ignore_ctrl_c` held, to this process's own handler (the
    CLI's: the interrupt line and exit 130); KeyboardInterrupt where it does not raise."""
    import signal

    signal.raise_signal(signal.SIGINT)
    raise KeyboardInterrupt


def show_progress(progress) -> bool:
    return bool(progress) if progress is not None else sys.stderr.isatty()


def run_in_folder(function, pending: list, output: str, *, scheduler=None, workers=None,
                  client=None, retries: int = DEFAULT_RETRIES, progress=None,
                  description: str = "tasks", already_done: int = 0) -> RunOutcome:
    """:func:`run_tasks` on the cluster :func:`dask_client` opens (its workers' log in
    ``output``'s WORKER_LOG unless a ``client`` is given), each task given the threads
    per worker the cluster chose (its ``threads`` field)."""
    log_file = os.path.join(output, WORKER_LOG) if client is None else None
    with dask_client(scheduler, workers, client, log_file) as (dask, threads):
        if threads:
            pending = [replace(t, threads=threads) for t in pending]
        return run_tasks(dask, function, pending, retries=retries, progress=progress,
                         description=description, already_done=already_done,
                         run=run_token(output))


def run_token(output: str) -> str:
    """What tells this run's tasks from every other run's on a shared scheduler: its
    output folder (absolute) and a random part drawn once per run."""
    import uuid

    return f"{os.path.abspath(output)}\n{uuid.uuid4().hex}"


def task_key(task, run: str) -> str:
    """The Dask key of ``task`` in the run ``run`` (:func:`run_token`): the task's name
    and a digest of its spec hash and the run, so that two runs of the same
    configuration on one scheduler (into two folders, or one after the other) never
    share a task (a shared key attaches the second run's futures to the first run's
    results, rendered into the first run's folder)."""
    from .tasks import spec_hash

    return f"dopplertof-{task.name}-{spec_hash([task.hash, run])[:16]}"


def run_tasks(client, function, tasks, *, retries: int = DEFAULT_RETRIES, progress=None,
              description: str = "tasks", already_done: int = 0,
              no_worker_timeout: float | None = None, run: str | None = None) -> RunOutcome:
    """Submit ``function(task)`` for every task (``task.name`` names it, under the key
    :func:`task_key` of the run ``run``, default a fresh :func:`run_token` of the
    working folder); collect results and failures as they complete. A failing task
    does not stop the others.
    When the cluster has had no worker for ``no_worker_timeout`` seconds (default
    NO_WORKER_TIMEOUT), the tasks not finished are failures ("no Dask worker ...") and
    the run ends."""
    from distributed import as_completed
    from tqdm import tqdm

    started = time.perf_counter()
    outcome = RunOutcome()
    futures = {}
    run = run or run_token(os.getcwd())
    for task in tasks:
        future = client.submit(function, task, key=task_key(task, run), retries=retries,
                               pure=False)
        futures[future] = task
    bar = tqdm(total=len(tasks) + already_done, initial=already_done, unit="task",
               desc=description, disable=not show_progress(progress), file=sys.stderr,
               dynamic_ncols=True)
    watch = _WorkerWatch(client, NO_WORKER_TIMEOUT if no_worker_timeout is None
                         else no_worker_timeout)
    try:
        completed = as_completed(list(futures))
        while futures:
            batch = completed.next_batch(block=False)
            if not batch:
                if watch.gone_for_good():
                    outcome.failed += [(task.name, watch.error()) for task in futures.values()]
                    break
                time.sleep(POLL_SECONDS)
            _check_scheduler(client, batch)
            for future in batch:
                if future.status not in DONE:
                    # (lost: its worker died holding the result after it completed, and
                    # the scheduler computes it again; a failure "task ended as finished"
                    # before, its shard rendered and intact)
                    completed.add(future)
                    continue
                _collect(future, futures.pop(future), outcome)
                bar.update(1)
            if outcome.failed:
                bar.set_postfix(failed=len(outcome.failed))
    finally:
        bar.close()
        if not _lost(client):  # (a cancel would wait for the lost scheduler)
            for future in futures:
                future.cancel()
    outcome.seconds = time.perf_counter() - started
    return outcome


def _lost(client) -> bool:
    from .cluster_checks import scheduler_lost

    return scheduler_lost(client)


def _check_scheduler(client, batch) -> None:
    """Raise ClusterError when ``client`` lost its scheduler: its futures end as
    cancelled, each without a word of the cause ("task ended as cancelled" lines and a
    Dask traceback). A future of this run
    ends as cancelled only so (no one else knows its key), the client reconnected to a
    scheduler restarted at once or not."""
    from .cluster_checks import lost_scheduler_message, scheduler_lost

    if any(f.status == "cancelled" for f in batch) or (not batch and scheduler_lost(client)):
        raise ClusterError(lost_scheduler_message(client))


#: the statuses of a future that will not change (any other: computed, or again)
DONE = ("finished", "error", "cancelled")


def _collect(future, task, outcome: RunOutcome) -> None:
    """A completed future's result, or its task's one-line failure, into ``outcome``."""
    if future.status == "finished":
        outcome.done.append(future.result())
    else:
        outcome.failed.append((task.name, one_line_error(future)))
    future.release()


class _WorkerWatch:
    """Whether the cluster has had no worker for ``timeout`` seconds (asked at most
    every WORKER_CHECK_SECONDS: a killed worker's nanny restarts it in a few seconds)."""

    def __init__(self, client, timeout: float):
        self.client, self.timeout = client, timeout
        self.checked = self.alone_since = None
        self.seen = False  # (whether it ever had a worker)

    def gone_for_good(self) -> bool:
        now = time.monotonic()
        if self.checked is not None and now - self.checked < WORKER_CHECK_SECONDS:
            return self.alone_since is not None and now - self.alone_since >= self.timeout
        self.checked = now
        try:
            workers = len(self.client.scheduler_info().get("workers", {}))
        except Exception:  # the scheduler itself is gone: no worker will come back
            workers = 0
        if workers:
            self.alone_since, self.seen = None, True
        elif self.alone_since is None:
            self.alone_since = now
        return self.alone_since is not None and now - self.alone_since >= self.timeout

    def error(self) -> str:
        if not self.seen:  # (not "killed": there never was one)
            return (f"the Dask scheduler has had no worker for {self.timeout:g} s; not "
                    "run")
        return (f"no Dask worker left for {self.timeout:g} s (workers killed or out of "
                "memory, faster than they restart); not run")


def one_line_error(future) -> str:
    try:
        exc = future.exception()
    except Exception as e:  # the exception itself could not be fetched
        exc = e
    if exc is None:
        return f"task ended as {future.status}"
    text = " ".join(str(exc).split())
    if len(text) > MAX_ERROR_CHARS:  # (summary.json keeps room for this much per task)
        text = text[:MAX_ERROR_CHARS - 3] + "..."
    name = type(exc).__name__
    return f"{name}: {text}" if text else name
