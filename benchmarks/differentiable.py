"""Cost of forward-mode derivatives: a derivative render against a plain render.

The demo scene (two moving boxes) at the same resolution, spp and seed:

* ``plain (splat)``: ``dopplertof.render``, the default film;
* ``plain (importance)``: ``render_derivatives`` with no parameter (the film the
  derivatives accumulate on);
* one row per parameter kind: ``render_derivatives`` with that one parameter (the
  render and its derivative: one derivative pass);
* ``gradient (all N)``: ``dopplertof.diff.gradient`` of a linear loss with respect to every
  differentiable name (reverse mode, ``auto``: path replay), with its peak Dr.Jit memory
  against the plain render's (benchmarks/gradient.py compares the adjoint methods).

Runs are interleaved after a warm-up that compiles every kernel; the median time of
each is compared. The last line reads `worst derivative / plain (splat): X`.

``--fit``: the demo's capture and its fit side by side, on the same machine, in one
process (each starting cold: the fit's time includes compiling its kernels, as the
capture's does): the capture's time, the fit's (`dopplertof fit` from its default
start, the closed form), their ratio and each body's fitted radial velocity against
the truth. The demo itself is 128x128 at 512 spp (`--res 128 --spp 512`).

    .venv/bin/python benchmarks/differentiable.py [--res 64] [--spp 64] [--repeats 3]
    .venv/bin/python benchmarks/differentiable.py --fit [--res 48] [--spp 256] [--fit-spp 256]
        [--keep DIR]
"""

from __future__ import annotations

import argparse
import time

from timing import interleaved_medians, peak_memory  # (benchmarks/timing.py, beside this script)

PARAMETERS = ("body0.vz", "body0.wy", "camera.vz", "w_g", "hetero_offset", "g_1",
              "white.reflectance.value")


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--res", type=int, default=64)
    ap.add_argument("--spp", type=int, default=64)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--fit", action="store_true", help="the capture and its fit side by side")
    ap.add_argument("--fit-spp", type=int, default=None, help="the fit's spp (default its own)")
    ap.add_argument("--keep", metavar="DIR", default=None,
                    help="with --fit: write the capture into DIR (kept) instead of a "
                    "temporary folder")
    args = ap.parse_args(argv)
    if args.fit:
        return fit_against_capture(args.res, args.spp, args.fit_spp, args.keep)

    import dopplertof
    from dopplertof.demo import demo_scene_path
    from dopplertof.diff import DifferentiableScene, render_derivatives
    from dopplertof.diff.render import differentiable_names

    dopplertof.set_variant("llvm_ad_rgb")
    scene = dopplertof.load_file(demo_scene_path(), {"res": args.res, "spp": args.spp})
    ds = DifferentiableScene(scene)
    runs = {"plain (splat)": lambda: dopplertof.render(scene, spp=args.spp, progress=False),
            "plain (importance)": lambda: render_derivatives(ds, [], spp=args.spp)}
    for name in PARAMETERS:
        runs[name] = lambda name=name: render_derivatives(ds, [name], spp=args.spp)
    everything = f"gradient (all {len(differentiable_names(ds))})"
    runs[everything] = _gradient_run(ds, args.res, args.spp)
    _, times = interleaved_medians(runs, args.repeats)
    plain = times["plain (splat)"]
    print(f"demo scene {args.res}x{args.res}, {args.spp} spp, median of {args.repeats}")
    for name, m in times.items():
        print(f"  {name:<26} {m:8.3f} s   {m / plain:5.2f} x plain (splat)")
    worst = max(times[n] for n in PARAMETERS)
    print(f"worst derivative / plain (splat): {worst / plain:.2f}")
    memory = peak_memory(runs[everything]) / peak_memory(runs["plain (splat)"])
    print(f"gradient of every parameter / plain (splat): time {times[everything] / plain:.2f}, "
          f"memory {memory:.2f}")


def _gradient_run(ds, res: int, spp: int):
    """A gradient of benchmarks/gradient.py's linear loss with respect to every
    differentiable name."""
    from gradient import linear_loss  # (benchmarks/gradient.py, beside this script)

    from dopplertof.diff import gradient

    loss = linear_loss(res)
    return lambda: gradient(ds, loss, spp=spp)


def fit_against_capture(res: int, spp: int, fit_spp: int | None, keep=None) -> None:
    """The demo captured at ``res`` and ``spp`` and fitted from the closed form: times
    side by side and the fit's errors; the capture kept in ``keep`` when given. The fit
    prints one line per iteration on stderr."""
    import contextlib
    import tempfile

    import dopplertof
    from dopplertof.demo import demo_scene_path
    from dopplertof.diff.fit import FIT_SPP, fit, format_fit

    dopplertof.set_variant("llvm_ad_rgb")
    kept = contextlib.nullcontext(keep) if keep else tempfile.TemporaryDirectory()
    with kept as folder:
        started = time.perf_counter()
        scene = dopplertof.load_file(demo_scene_path(), {"res": res, "spp": spp})
        dopplertof.capture(scene, spp=spp, seed=0, progress=False).write(folder)
        captured = time.perf_counter() - started
        started = time.perf_counter()
        print(f"capture {captured:.1f} s", flush=True)
        result = fit(folder, spp=fit_spp or FIT_SPP, progress=None)
        fitted = time.perf_counter() - started
    print(format_fit(result))
    print(f"demo scene {res}x{res}: capture {spp} spp {captured:.1f} s, fit "
          f"{fit_spp or FIT_SPP} spp {fitted:.1f} s ({result.iterations} iterations)")
    for body in result.bodies:
        truth = body["capture_velocity_gt_median_m_s"]
        print(f"  {body['name']}: error {100 * (body['radial_velocity_m_s'] / truth - 1):+.2f}% "
              f"(+- {100 * body['radial_velocity_uncertainty_m_s'] / abs(truth):.2f}%)")
    print(f"fit / capture: {fitted / captured:.2f}")


if __name__ == "__main__":
    main()
