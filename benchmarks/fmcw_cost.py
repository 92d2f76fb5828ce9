"""FMCW cost (issue 43): a spectrum render against one D-ToF render at equal spp.

The same scene (examples/translating_sphere.xml by default), resolution and spp; runs
interleaved (D-ToF, FMCW, D-ToF, ...) after a warm-up that compiles both kernels, the
median of each compared. The FMCW time is the spectra only (fmcw.trace.render_spectra:
tracing, the atomic splats and their copy to the host), not the peaks or the truth.

    .venv/bin/python benchmarks/fmcw_cost.py [--scene FILE] [--res 64] [--spp 64]
        [--bins 256] [--repeats 3] [--beam flood|collimated] [--speckle] [--threads N]

Each render is timed by the clock on the wall and by the CPU time of the process (all
its threads): on a machine shared with other work the CPU time is the steadier
measure (with --threads 1, Dr.Jit's one worker thread, it is the render's work), and
the fastest of the repeats the least disturbed. Medians, then the fastest runs' CPU
times; the last line reads `fmcw / dtof cpu time: Y` (medians).
"""

from __future__ import annotations

import argparse
import os
import statistics
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--scene", default=os.path.join(ROOT, "examples", "translating_sphere.xml"))
    p.add_argument("--res", type=int, default=64)
    p.add_argument("--spp", type=int, default=64)
    p.add_argument("--bins", type=int, default=256)
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--beam", default="flood", choices=("flood", "collimated"))
    p.add_argument("--speckle", action="store_true", help="with the coherent sums")
    p.add_argument("--threads", type=int, default=None,
                   help="Dr.Jit's worker threads (default: its own choice)")
    args = p.parse_args(argv)

    import dopplertof
    from dopplertof.fmcw import Chirp
    from dopplertof.fmcw.trace import render_spectra

    dopplertof.set_variant("llvm_ad_rgb")
    if args.threads:
        import drjit as dr

        dr.set_thread_count(args.threads)
    scene = dopplertof.load_file(args.scene, {"res": args.res})
    chirp = Chirp(bandwidth=10e9, chirp_time=1e-6, bins=args.bins)
    runs = {"dtof": lambda: dopplertof.render(scene, spp=args.spp, progress=False),
            "fmcw": lambda: render_spectra(scene, chirp, args.spp, beam=args.beam,
                                           speckle=args.speckle)}
    times = {name: [] for name in runs}
    cpu = {name: [] for name in runs}
    for name, run in runs.items():  # warm-up: compile the kernels
        run()
    for _ in range(args.repeats):
        for name, run in runs.items():
            start, start_cpu = time.perf_counter(), time.process_time()
            run()
            times[name].append(time.perf_counter() - start)
            cpu[name].append(time.process_time() - start_cpu)
    median = {name: statistics.median(t) for name, t in times.items()}
    median_cpu = {name: statistics.median(t) for name, t in cpu.items()}
    print(f"{os.path.basename(args.scene)} {args.res}x{args.res}, {args.spp} spp, "
          f"{args.bins} bins, {args.beam} beam{', speckle' if args.speckle else ''}"
          f"{f', {args.threads} thread(s)' if args.threads else ''}: dtof "
          f"{median['dtof']:.3f} s (cpu {median_cpu['dtof']:.3f} s), fmcw "
          f"{median['fmcw']:.3f} s (cpu {median_cpu['fmcw']:.3f} s)")
    print(f"fmcw / dtof time: {median['fmcw'] / median['dtof']:.2f}")
    print(f"fmcw / dtof cpu time, fastest runs: {min(cpu['fmcw']) / min(cpu['dtof']):.2f}")
    print(f"fmcw / dtof cpu time: {median_cpu['fmcw'] / median_cpu['dtof']:.2f}")


if __name__ == "__main__":
    main()
