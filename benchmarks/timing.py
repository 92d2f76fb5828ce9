"""Side-by-side timing for the benchmark scripts: one warm-up run of each (timed: the
cold time, kernels compiled), then ``repeats`` rounds in which every run goes once, in
turn, so that a machine's drift falls on all of them alike."""

from __future__ import annotations

import statistics
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
