"""A Dask worker plugin that keeps a worker's stderr out of the terminal (imported only
where a cluster runs: it imports distributed)."""

from __future__ import annotations

import os
import sys

from distributed import WorkerPlugin

#: the name the plugin is registered under: one per scheduler, replaced by each run's
PLUGIN_NAME = "dopplertof-worker-log"

#: a worker's states once it is closing (its plugins' teardown is its first step)
_CLOSING = {"closing", "closing_gracefully", "closed", "failed"}


class WorkerStderrToFile(WorkerPlugin):
    """The worker process's stderr (file descriptor 2, where Dask logs and a failing
    task's traceback go) appends to ``path``; a worker that restarts runs it again.

    Not idempotent: each run's registration replaces the one before (the first run's
    path stuck on an external scheduler, every later run's log stayed empty)."""

    idempotent = False

    def __init__(self, path: str):
        self.path = path
        self.saved = None  # (the worker's own stderr, while this plugin holds fd 2)

    def setup(self, worker) -> None:
        """A folder removed since the run registered the plugin (a worker restarted
        later) leaves the worker's stderr where it is, without a traceback (P1-18)."""
        if not os.path.isdir(os.path.dirname(self.path) or "."):
            return
        saved = os.dup(2)
        try:
            _stderr_to(self.path)
        except OSError:
            os.close(saved)
            return
        self.saved = saved

    def teardown(self, worker) -> None:
        """The worker is closing (its first step, before its connections close): what it
        says from here on is its shutdown's noise (a CommClosedError traceback
        in workers.log after a successful run, from a heartbeat racing the scheduler's
        close), so its stderr goes to /dev/null. The plugin removed from a running
        worker (the run is over): its own stderr again."""
        status = getattr(getattr(worker, "status", None), "name", None)
        if worker is None or status in _CLOSING:
            _stderr_to(os.devnull)
        elif self.saved is not None:
            sys.stderr.flush()
            os.dup2(self.saved, 2)
        if self.saved is not None:
            os.close(self.saved)
            self.saved = None


def _stderr_to(path: str) -> None:
    """This process's file descriptor 2 appends to ``path``."""
    log = os.open(path, os.O_WRONLY | os.O_APPEND | os.O_CREAT, 0o666)
    sys.stderr.flush()
    os.dup2(log, 2)
    os.close(log)
