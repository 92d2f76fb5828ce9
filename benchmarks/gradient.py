"""Cost of a reverse-mode gradient against a plain render, and against forward mode.

The demo scene (two moving boxes) at the same resolution, spp and seed, the scene's
own film (splat):

* ``plain``: ``dopplertof.render``;
* ``trajectory`` and ``path``: ``dopplertof.diff.gradient`` of a linear loss with
  respect to every differentiable name (``differentiable_names``: 2 bodies x 6 motion
  parameters, the camera's velocity, the modulation's three, every reflectance and the
  light), with each adjoint method (``method=``; the demo's ``auto`` is path
  replay, which follows the rays as the trajectory does);
* ``forward``: ``render_derivatives`` with the same names on the importance film (one
  derivative pass per parameter), what the gradient replaces.

Times: interleaved medians after a warm-up that compiles every kernel (benchmarks/timing.py).
Memory: each run once more after the timings, the peak of Dr.Jit's device memory during it
(``dr.detail.malloc_watermark``: the arrays the kernels read and write, the scene's
included).

    .venv/bin/python benchmarks/gradient.py [--res 64] [--spp 64] [--repeats 3] [--no-forward]
"""

from __future__ import annotations

import argparse
from timing import interleaved_medians, peak_memory  # (benchmarks/timing.py, beside this script)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--res", type=int, default=64)
    ap.add_argument("--spp", type=int, default=64)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--no-forward", action="store_true", help="skip forward mode's row")
    args = ap.parse_args(argv)
    runs, names = _runs(args.res, args.spp, not args.no_forward)
    cold, times = interleaved_medians(runs, args.repeats)
    plain = times["plain"]
    print(f"demo scene {args.res}x{args.res}, {args.spp} spp, {len(names)} parameters, "
          f"median of {args.repeats} (cold: first run, kernels compiled)")
    for name, m in times.items():
        print(f"  {name:<10} {m:8.3f} s   {m / plain:6.2f} x plain   (cold {cold[name]:.1f} s)")
    peaks = {kind: peak_memory(runs[kind]) for kind in ("plain", "trajectory", "path")}
    print("  peak Dr.Jit memory (MB): " + ", ".join(f"{k} {v:.1f}" for k, v in peaks.items()))
    for method in ("trajectory", "path"):
        print(f"gradient ({method}) / plain: time {times[method] / plain:.2f}, memory "
              f"{peaks[method] / peaks['plain']:.2f}")


def _runs(res: int, spp: int, forward: bool):
    import dopplertof
    from dopplertof.demo import demo_scene_path
    from dopplertof.diff import DifferentiableScene, gradient, render_derivatives
    from dopplertof.diff.render import differentiable_names

    dopplertof.set_variant("llvm_ad_rgb")
    scene = dopplertof.load_file(demo_scene_path(), {"res": res, "spp": spp})
    ds = DifferentiableScene(scene)
    names = differentiable_names(ds)
    loss = linear_loss(res)

    runs = {"plain": lambda: dopplertof.render(scene, spp=spp, progress=False)}
    for method in ("trajectory", "path"):
        runs[method] = (lambda method=method:
                        gradient(ds, loss, names=names, spp=spp, method=method))
    if forward:
        runs["forward"] = lambda: render_derivatives(ds, names, spp=spp)
    return runs, names


def linear_loss(res: int):
    """A fixed linear loss of a res x res image: the sum of its values times weights
    drawn once (seed 1) from [0.5, 1.5]."""
    import drjit as dr
    import mitsuba as mi
    import numpy as np

    weights = mi.TensorXf(np.random.default_rng(1).uniform(0.5, 1.5, (res, res, 3))
                          .astype(np.float32))
    return lambda image: dr.sum(weights * image, axis=None)


if __name__ == "__main__":
    main()
