"""Cost of a camera's raw frame sequence against today's capture, at equal spp per frame.

The moving example scene (examples/cameras_moving.xml) at one resolution, through:

* ``today``: ``dopplertof.capture`` (four homodyne captures, two heterodyne, radiance:
  seven renders of one exposure window);
* one row per preset: ``cameras.capture_camera`` (N raw frames, each in its own time
  window, and one radiance render over the sequence), the same spp per frame.

Runs are interleaved after a warm-up that compiles every kernel (Dr.Jit caches them;
since issue 40 the windows are opaque values, so the presets share most); the median
time of each is compared with the issue's target, N/4 times today's frame. The cold time
(the first run, compiles included) is printed too.

    .venv/bin/python benchmarks/cameras.py [--res 96] [--spp 32] [--repeats 3]

``--cold`` (issue 40) runs ``dopplertof capture --camera`` as a user does, one process
per capture, from an empty Dr.Jit kernel cache (a temporary folder): the first scene
(every kernel compiled), the second scene right after it (the cache holds the first
one's kernels: what a new scene costs), and the second scene again (warm). Printed side
by side, with the ratios: the new scene over its rerun (target: at most 1.3) and the
empty cache over the rerun.

    .venv/bin/python benchmarks/cameras.py --cold [--camera kinect-v2] [--size 48x40] \
        [--spp 16] [--scenes translating_sphere.xml,rotating_cube.xml]
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time

from timing import (cache_size, empty_kernel_cache,  # (benchmarks/timing.py, beside this script)
                    interleaved_medians)

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SCENE = os.path.join(ROOT, "examples", "cameras_moving.xml")


def timed_capture(scene: str, camera: str, size: str, spp: int) -> float:
    """Wall seconds of ``dopplertof capture`` of an example scene through a preset, in a
    process of its own (start-up, scene load, kernels, renders, output)."""
    with tempfile.TemporaryDirectory(prefix="dopplertof-capture-bench-") as folder:
        command = [sys.executable, "-c", "from dopplertof.cli import main; main()", "capture",
                   os.path.join(ROOT, "examples", scene), "--camera", camera, "--res", size,
                   "--spp", str(spp), "--quiet", "-o", folder]
        started = time.perf_counter()
        subprocess.run(command, check=True, stdout=subprocess.DEVNULL)
        return time.perf_counter() - started


def cold_and_warm(args) -> None:
    """--cold: the first scene from an empty kernel cache, the second right after, and
    the second again; printed side by side with their ratios."""
    first, second = args.scenes.split(",")
    runs = [(f"{first}, empty kernel cache", first), (f"{second}, right after", second),
            (f"{second} again (warm)", second)]
    with empty_kernel_cache() as cache:
        seconds = [timed_capture(scene, args.camera, args.size, args.spp) for _, scene in runs]
        kernels, megabytes = cache_size(cache)
    print(f"dopplertof capture --camera {args.camera} --res {args.size} --spp {args.spp}, "
          f"one process each; the kernel cache ends with {kernels} kernels "
          f"({megabytes:.1f} MB)")
    print(f"{'run':<44} {'wall s':>7} {'/ warm':>7}")
    for (name, _), wall in zip(runs, seconds):
        print(f"{name:<44} {wall:>7.2f} {wall / seconds[-1]:>6.2f}x")
    print(f"new scene / its rerun: {seconds[1] / seconds[2]:.2f}x (target <= 1.3x); "
          f"empty cache / rerun: {seconds[0] / seconds[2]:.2f}x")


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--res", type=int, default=96)
    ap.add_argument("--spp", type=int, default=None, help="default 32 (--cold: 16)")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--cameras", default="kinect-v2,opt8241,pmd-argos3d-p320,paper-dtof")
    ap.add_argument("--cold", action="store_true",
                    help="empty kernel cache, a second scene, its rerun (one process each)")
    ap.add_argument("--camera", default="kinect-v2", help="--cold: the preset")
    ap.add_argument("--size", default="48x40", help="--cold: WIDTHxHEIGHT")
    ap.add_argument("--scenes", default="translating_sphere.xml,rotating_cube.xml",
                    help="--cold: two example scenes, comma-separated")
    args = ap.parse_args(argv)
    if args.cold:
        args.spp = args.spp or 16
        return cold_and_warm(args)
    args.spp = args.spp or 32

    import dopplertof
    from dopplertof.cameras import load_preset
    from dopplertof.cameras.capture import capture_camera
    from dopplertof.cameras.scene_view import load_scene_for_camera

    dopplertof.set_variant("llvm_ad_rgb")
    presets = [load_preset(n) for n in args.cameras.split(",")]
    # one field of view for every run: today's capture sees the scene through the first preset
    scenes = {p.name: load_scene_for_camera(SCENE, p, (args.res, args.res)) for p in presets}
    today_scene = scenes[presets[0].name]
    runs = {"today": lambda: dopplertof.capture(today_scene, spp=args.spp, progress=False)}
    for p in presets:
        runs[p.name] = (lambda p=p: capture_camera(scenes[p.name], p, spp=args.spp,
                                                   progress=False))
    cold, warm = interleaved_medians(runs, args.repeats)
    today = warm["today"]
    print(f"{args.res}x{args.res}, {args.spp} spp per frame, median of {args.repeats}")
    print(f"{'run':<20} {'frames':>6} {'cold s':>8} {'warm s':>8} {'/ today':>8} "
          f"{'target N/4':>10}")
    print(f"{'today (7 renders)':<20} {7:>6} {cold['today']:8.2f} {today:8.2f} {1.0:8.3f}")
    for p in presets:
        n = len(p.frames)
        ratio = warm[p.name] / today
        print(f"{p.name:<20} {n:>6} {cold[p.name]:8.2f} {warm[p.name]:8.2f} {ratio:8.3f} "
              f"{n / 4:10.2f}  {'within' if ratio <= n / 4 else 'OVER'}")


if __name__ == "__main__":
    main()
