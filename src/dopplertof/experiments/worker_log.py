"""A Dask worker plugin that keeps a worker's stderr out of the terminal (imported only
where a cluster runs: it imports distributed)."""

from __future__ import annotations

import os
import sys

from distributed import WorkerPlugin


class WorkerStderrToFile(WorkerPlugin):
    """The worker process's stderr (file descriptor 2, where Dask logs and a failing
    task's traceback go) appends to ``path``; a worker that restarts runs it again."""

    idempotent = True

    def __init__(self, path: str):
        self.path = path

    def setup(self, worker) -> None:
        _stderr_to(self.path)

    def teardown(self, worker) -> None:
        """The worker is closing (its first step, before its connections close): what it
        says from here on is its shutdown's noise (issue 42: a CommClosedError traceback
        in workers.log after a successful run, from a heartbeat racing the scheduler's
        close), so its stderr goes to /dev/null."""
        _stderr_to(os.devnull)


def _stderr_to(path: str) -> None:
    """This process's file descriptor 2 appends to ``path``."""
    log = os.open(path, os.O_WRONLY | os.O_APPEND | os.O_CREAT, 0o666)
    sys.stderr.flush()
    os.dup2(log, 2)
    os.close(log)
