"""Side-by-side timing for the benchmark scripts: one warm-up run of each (timed: the
cold time, kernels compiled), then ``repeats`` rounds in which every run goes once, in
turn, so that a machine's drift falls on all of them alike."""

from __future__ import annotations

import contextlib
import os
import shutil
import statistics
import sys
import tempfile
import time


def interleaved_medians(runs: dict, repeats: int) -> tuple[dict, dict]:
    """(cold seconds, median warm seconds) of each of ``runs`` (name -> callable)."""
    cold, warm = {}, {name: [] for name in runs}
    for name, run in runs.items():  # warm-up: compile every kernel
        started = time.perf_counter()
        run()
        cold[name] = time.perf_counter() - started
    for _ in range(repeats):
        for name, run in runs.items():
            started = time.perf_counter()
            run()
            warm[name].append(time.perf_counter() - started)
    return cold, {name: statistics.median(times) for name, times in warm.items()}


def peak_memory(run) -> float:
    """Peak Dr.Jit memory (MB, the LLVM backend) while ``run`` runs (the arrays the
    kernels read and write, the scene's included)."""
    import drjit as dr

    dr.flush_malloc_cache()
    dr.detail.malloc_clear_statistics()
    run()
    return dr.detail.malloc_watermark(dr.JitBackend.LLVM) / 2**20


#: the environment variable that moves Dr.Jit's kernel cache (default ~/.drjit); Dr.Jit
#: reads it once, when it starts
KERNEL_CACHE_VARIABLE = "DRJIT_CACHE_DIR"


@contextlib.contextmanager
def empty_kernel_cache():
    """An empty Dr.Jit kernel cache folder (a temporary one, removed after the block) for
    this process, if it has not started Dr.Jit yet, and for every process started in the
    block (Dask workers, subprocesses): the cold-cache mode of the benchmarks (issue 40).
    Yields the folder."""
    if "drjit" in sys.modules:
        raise RuntimeError("Dr.Jit is loaded already: its kernel cache cannot move now")
    saved = os.environ.get(KERNEL_CACHE_VARIABLE)
    folder = tempfile.mkdtemp(prefix="dopplertof-kernel-cache-")
    os.environ[KERNEL_CACHE_VARIABLE] = folder
    try:
        yield folder
    finally:
        if saved is None:
            os.environ.pop(KERNEL_CACHE_VARIABLE, None)
        else:
            os.environ[KERNEL_CACHE_VARIABLE] = saved
        shutil.rmtree(folder, ignore_errors=True)


def cache_size(folder: str) -> tuple[int, float]:
    """(kernels, MB) in a Dr.Jit kernel cache folder."""
    files = [os.path.join(folder, name) for name in os.listdir(folder)]
    return len(files), sum(os.path.getsize(f) for f in files) / 2**20
