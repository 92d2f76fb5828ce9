"""Bias of the interior-only derivatives at silhouettes, against central differences.

Per case (a scene, a body's motion parameter, a path depth), the pixel sums of the
forward-mode derivative (``render_derivatives``) and of central differences of renders
with common random numbers (the derivative's seed) at two steps, over each pixel class
of ``dopplertof.diff.silhouette.pixel_classes`` (the body's interior, its silhouette,
its rim, the other pixels) and over the whole image. The differences' noise is
their standard error over the seeds (each seed a different set of random numbers);
``bias`` is derivative / difference at the larger step - 1, +- that noise.

Then, for the fit's residuals (sums over 8x8 blocks of one body's pixels): the
Gauss-Newton step ratio (J . F) / (J . J) of the derivative's block sums J against the
difference's F, for the fit's blocks (interior pixels) and for blocks of every pixel
whose footprint sees the body (silhouettes included).

    .venv/bin/python benchmarks/silhouettes.py [--res 32] [--spp 256] [--seeds 6]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

SPHERE = "examples/translating_sphere.xml"
BOX = "tests/fixtures/cornell_box_moving.xml"
#: (label, scene, its resolution's defines, parameter, max_depth, the two steps)
CASES = (
    ("sphere", SPHERE, ("res",), "body0.vz", 2, (10.0, 20.0)),
    ("sphere", SPHERE, ("res",), "body0.vz", 4, (10.0, 20.0)),
    ("box", BOX, ("resx", "resy"), "body0.vz", 2, (10.0, 20.0)),
    ("box", BOX, ("resx", "resy"), "body0.vz", 3, (10.0, 20.0)),
    ("box", BOX, ("resx", "resy"), "body1.wy", 3, (5.0, 10.0)),
)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--res", type=int, default=32)
    ap.add_argument("--spp", type=int, default=256)
    ap.add_argument("--seeds", type=int, default=6)
    args = ap.parse_args(argv)

    import dopplertof

    dopplertof.set_variant("llvm_ad_rgb")
    seeds = list(range(args.seeds))
    print(f"{args.res}x{args.res}, {args.spp} spp, {args.seeds} seeds; sums over pixels "
          "(channel 0), difference +- its standard error over the seeds")
    print(f"{'case':<22} {'pixels':<10} {'n':>4} {'derivative':>11} "
          f"{'difference h1':>22} {'difference h2':>22} {'bias':>16}")
    for label, path, res_names, name, depth, steps in CASES:
        started = time.perf_counter()
        defines = {**{r: args.res for r in res_names}, "max_depth": depth}
        rows, ratios = case_rows(dopplertof.load_file(path, defines), name, steps,
                                 args.spp, seeds)
        case = f"{label} {name} d{depth}"
        for row in rows:
            print(f"{case:<22} {row}")
        print(f"{case:<22} step ratio (J.F)/(J.J) over 8x8 blocks: interior "
              f"{ratios[0]:.3f}, with silhouettes {ratios[1]:.3f}; "
              f"h = {steps[0]:g}, {steps[1]:g}; {time.perf_counter() - started:.0f} s")


def case_rows(scene, name: str, steps, spp: int, seeds) -> tuple:
    """The table's rows for one case (formatted) and its two step ratios."""
    from dopplertof.diff import DifferentiableScene
    from dopplertof.diff.silhouette import (PIXEL_CLASSES, body_parameter, measure,
                                            pixel_classes, relative_bias, step_ratio)

    k = body_parameter(name)[0]
    classes = pixel_classes(scene, k)
    m = measure(DifferentiableScene(scene), name, steps, spp, seeds)
    rows = []
    for cls in PIXEL_CLASSES + ("all",):
        mask = classes[cls] if cls != "all" else np.ones_like(classes["interior"])
        derivative, differences = m.sums(mask)
        cells = [f"{np.mean(f):+.3e} +- {_se(f):.1e}" for f in differences.values()]
        bias, noise = relative_bias(derivative, differences[steps[-1]])
        rows.append(f"{cls:<10} {int(mask.sum()):>4} {np.mean(derivative):+11.3e} "
                    f"{cells[0]:>22} {cells[1]:>22} {100 * bias:+7.1f}% +- {100 * noise:.1f}%")
    derivative = np.mean(m.derivative, 0)
    difference = np.mean(m.difference[steps[-1]], 0)
    ratios = (step_ratio(derivative, difference, classes["interior"]),
              step_ratio(derivative, difference, classes["footprint"]))
    return rows, ratios


def _se(values) -> float:
    return float(np.std(values, ddof=1) / np.sqrt(len(values)))


if __name__ == "__main__":
    main()
