"""Cost of a camera's raw frame sequence against today's capture, at equal spp per frame.

The moving example scene (examples/cameras_moving.xml) at one resolution, through:

* ``today``: ``dopplertof.capture`` (four homodyne captures, two heterodyne, radiance:
  seven renders of one exposure window);
* one row per preset: ``cameras.capture_camera`` (N raw frames, each in its own time
  window, and one radiance render over the sequence), the same spp per frame.

Runs are interleaved after a warm-up that compiles every kernel (Dr.Jit caches them;
each distinct window and frequency compiles its own on first use); the median time of
each is compared with the issue's target, N/4 times today's frame. The cold time (the
first run, compiles included) is printed too.

    .venv/bin/python benchmarks/cameras.py [--res 96] [--spp 32] [--repeats 3]
"""

from __future__ import annotations

import argparse
import os

from timing import interleaved_medians  # (benchmarks/timing.py, beside this script)

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SCENE = os.path.join(ROOT, "examples", "cameras_moving.xml")


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--res", type=int, default=96)
    ap.add_argument("--spp", type=int, default=32)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--cameras", default="kinect-v2,opt8241,pmd-argos3d-p320,paper-dtof")
    args = ap.parse_args(argv)

    import dopplertof
    from dopplertof.cameras import load_preset
    from dopplertof.cameras.capture import capture_camera, load_scene_for_camera

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
