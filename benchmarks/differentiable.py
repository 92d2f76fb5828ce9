"""Cost of forward-mode derivatives: a derivative render against a plain render.

The demo scene (two moving boxes) at the same resolution, spp and seed:

* ``plain (splat)``: ``dopplertof.render``, the default film;
* ``plain (importance)``: ``render_derivatives`` with no parameter (the film the
  derivatives accumulate on);
* one row per parameter kind: ``render_derivatives`` with that one parameter (the
  render and its derivative: one derivative pass).

Runs are interleaved after a warm-up that compiles every kernel; the median time of
each is compared. The last line reads `worst derivative / plain (splat): X`.

    .venv/bin/python benchmarks/differentiable.py [--res 64] [--spp 64] [--repeats 3]
"""

from __future__ import annotations

import argparse
import statistics
import time

PARAMETERS = ("body0.vz", "body0.wy", "camera.vz", "w_g", "hetero_offset", "g_1",
              "white.reflectance.value")


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--res", type=int, default=64)
    ap.add_argument("--spp", type=int, default=64)
    ap.add_argument("--repeats", type=int, default=3)
    args = ap.parse_args(argv)

    import dopplertof
    from dopplertof.demo import demo_scene_path
    from dopplertof.diff import DifferentiableScene, render_derivatives

    dopplertof.set_variant("llvm_ad_rgb")
    scene = dopplertof.load_file(demo_scene_path(), {"res": args.res, "spp": args.spp})
    ds = DifferentiableScene(scene)
    runs = {"plain (splat)": lambda: dopplertof.render(scene, spp=args.spp, progress=False),
            "plain (importance)": lambda: render_derivatives(ds, [], spp=args.spp)}
    for name in PARAMETERS:
        runs[name] = lambda name=name: render_derivatives(ds, [name], spp=args.spp)
    times = {name: [] for name in runs}
    for name, run in runs.items():  # warm-up: compile every kernel
        run()
    for _ in range(args.repeats):
        for name, run in runs.items():
            t = time.perf_counter()
            run()
            times[name].append(time.perf_counter() - t)
    plain = statistics.median(times["plain (splat)"])
    print(f"demo scene {args.res}x{args.res}, {args.spp} spp, median of {args.repeats}")
    for name, ts in times.items():
        m = statistics.median(ts)
        print(f"  {name:<26} {m:8.3f} s   {m / plain:5.2f} x plain (splat)")
    worst = max(statistics.median(times[n]) for n in PARAMETERS)
    print(f"worst derivative / plain (splat): {worst / plain:.2f}")


if __name__ == "__main__":
    main()
