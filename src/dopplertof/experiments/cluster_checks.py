"""Checks of an external Dask scheduler's workers before a run submits anything to them,
and the words for a scheduler lost in the middle of a run."""

from __future__ import annotations

import threading
import time

#: seconds a run waits for a scheduler without any worker to get one
WORKER_WAIT_SECONDS = 60.0
#: seconds a worker has to answer the environment probe
PROBE_SECONDS = 15.0

#: what a worker evaluates to show it can import dopplertof (``eval`` is pickled by
#: reference to the builtins, which every Python has: a function of this package would
#: itself need dopplertof on the worker to be unpickled)
_PROBE = "__import__('dopplertof').__version__"


class WorkerCheckError(RuntimeError):
    """A worker that cannot run dopplertof's tasks, or a scheduler without any worker."""


def check_workers(client, address: str, *, wait: float | None = None,
                  probe_seconds: float | None = None) -> None:
    """Raise WorkerCheckError unless the scheduler at ``address`` has a worker within
    ``wait`` seconds and every worker it lists imports this version of dopplertof,
    each answering within ``probe_seconds``."""
    from .. import __version__

    wait = WORKER_WAIT_SECONDS if wait is None else wait
    probe_seconds = PROBE_SECONDS if probe_seconds is None else probe_seconds
    workers = _wait_for_workers(client, wait)
    if not workers:
        raise WorkerCheckError(
            f"the Dask scheduler at {address} has no worker (none joined in {wait:g} s): "
            f"start one with `dask worker {address}` in an environment with dopplertof")
    answers = _probe(client, workers, probe_seconds)
    for worker in workers:
        if worker not in answers:
            raise WorkerCheckError(
                f"the Dask worker at {worker} does not answer in {probe_seconds:g} s (a "
                "worker that failed to start stays listed, e.g. one whose Python cannot "
                "import dopplertof): stop it, and start workers in an environment with "
                "dopplertof")
        answer = answers[worker]
        if isinstance(answer, BaseException):
            cause = " ".join(str(answer).split()) or type(answer).__name__
            raise WorkerCheckError(
                f"the Dask worker at {worker} cannot import dopplertof ({cause}): install "
                f"dopplertof {__version__} in the Python that runs `dask worker`")
        if answer != __version__:
            raise WorkerCheckError(
                f"the Dask worker at {worker} runs dopplertof {answer}, this is "
                f"{__version__}: install the same version in the worker's environment")


def _wait_for_workers(client, wait: float) -> list:
    deadline = time.monotonic() + wait
    while True:
        workers = sorted(client.scheduler_info().get("workers", {}))
        if workers or time.monotonic() >= deadline:
            return workers
        time.sleep(0.2)


def _probe(client, workers: list, seconds: float) -> dict:
    """Each worker's dopplertof version, or the exception it raised; a worker that has
    not answered in ``seconds`` is left out (one thread per worker, never joined: a
    worker that failed to start may never answer)."""
    answers: dict = {}

    def ask(worker):
        try:
            answers.update(client.run(eval, _PROBE, workers=[worker], on_error="return"))
        except Exception as e:  # (the scheduler's own failure to reach it)
            answers[worker] = e

    threads = [threading.Thread(target=ask, args=(w,), daemon=True) for w in workers]
    for thread in threads:
        thread.start()
    deadline = time.monotonic() + seconds
    for thread in threads:
        thread.join(timeout=max(0.0, deadline - time.monotonic()))
    return dict(answers)


def scheduler_lost(client) -> bool:
    """Whether ``client`` has lost its scheduler (it reconnects, or gave up)."""
    return getattr(client, "status", "running") not in ("running", "newly-created")


def lost_scheduler_message(client) -> str:
    address = getattr(getattr(client, "scheduler", None), "address", None) or "?"
    return (f"lost the Dask scheduler at {address} in the middle of the run: the tasks "
            "not finished were not run; start the scheduler and its workers again and "
            "rerun the command, which renders only what is missing")
