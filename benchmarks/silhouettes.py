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

``fixed``: the bias of ``with_visibility`` (the derivative of a seed the differences did
not use, its silhouette and rim pixels replaced by central differences at 4x the spp),
and its step ratio with silhouettes.

``--fit``: Gauss-Newton on the sphere starter's ``body0.vz`` alone (depth 2), from half
its velocity, on 8x8 block sums of every pixel whose footprint sees the sphere
(silhouettes included), with the Jacobian held from the start: with the plain derivative
and with ``with_visibility``; the velocity after each step. The capture is rendered
with the fit's seed, so that the residuals hold no Monte Carlo noise (at these sizes an
independent capture's noise would outweigh the velocity's signal): what is left is the
Jacobian's effect on the steps.

    .venv/bin/python benchmarks/silhouettes.py [--res 32] [--spp 256] [--seeds 6]
    .venv/bin/python benchmarks/silhouettes.py --fit [--res 32] [--spp 256]
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
    ap.add_argument("--fit", action="store_true", help="the sphere's velocity fitted")
    args = ap.parse_args(argv)
    if args.fit:
        return fit_sphere(args.res, args.spp)

    import dopplertof

    dopplertof.set_variant("llvm_ad_rgb")
    seeds = list(range(args.seeds))
    print(f"{args.res}x{args.res}, {args.spp} spp, {args.seeds} seeds; sums over pixels "
          "(channel 0), difference +- its standard error over the seeds")
    print(f"{'case':<22} {'pixels':<10} {'n':>4} {'derivative':>11} "
          f"{'difference h1':>22} {'difference h2':>22} {'bias':>16} {'fixed':>8}")
    for label, path, res_names, name, depth, steps in CASES:
        started = time.perf_counter()
        defines = {**{r: args.res for r in res_names}, "max_depth": depth}
        rows, ratios = case_rows(dopplertof.load_file(path, defines), name, steps,
                                 args.spp, seeds)
        case = f"{label} {name} d{depth}"
        for row in rows:
            print(f"{case:<22} {row}")
        print(f"{case:<22} step ratio (J.F)/(J.J) over 8x8 blocks: interior "
              f"{ratios[0]:.3f}, with silhouettes {ratios[1]:.3f} (with_visibility "
              f"{ratios[2]:.3f}); "
              f"h = {steps[0]:g}, {steps[1]:g}; {time.perf_counter() - started:.0f} s")


def case_rows(scene, name: str, steps, spp: int, seeds) -> tuple:
    """The table's rows for one case (formatted) and its step ratios: interior, with
    silhouettes, with silhouettes after ``with_visibility``."""
    from dopplertof.diff import DifferentiableScene
    from dopplertof.diff.silhouette import (PIXEL_CLASSES, body_parameter, measure,
                                            pixel_classes, relative_bias, step_ratio)

    k = body_parameter(name)[0]
    classes = pixel_classes(scene, k)
    ds = DifferentiableScene(scene)
    m = measure(ds, name, steps, spp, seeds)
    corrected = _corrected(ds, name, steps[-1], spp, max(seeds) + 1)
    rows = []
    for cls in PIXEL_CLASSES + ("all",):
        mask = classes[cls] if cls != "all" else np.ones_like(classes["interior"])
        derivative, differences = m.sums(mask)
        cells = [f"{np.mean(f):+.3e} +- {_se(f):.1e}" for f in differences.values()]
        bias, noise = relative_bias(derivative, differences[steps[-1]])
        fixed, _ = relative_bias([corrected[mask].sum()], differences[steps[-1]])
        rows.append(f"{cls:<10} {int(mask.sum()):>4} {np.mean(derivative):+11.3e} "
                    f"{cells[0]:>22} {cells[1]:>22} {100 * bias:+7.1f}% +- {100 * noise:.1f}%"
                    f" {100 * fixed:+7.1f}%")
    derivative = np.mean(m.derivative, 0)
    difference = np.mean(m.difference[steps[-1]], 0)
    ratios = (step_ratio(derivative, difference, classes["interior"]),
              step_ratio(derivative, difference, classes["footprint"]),
              step_ratio(corrected, difference, classes["footprint"]))
    return rows, ratios


def _corrected(ds, name: str, step: float, spp: int, seed: int) -> np.ndarray:
    """The derivative of a seed the differences did not use, through ``with_visibility``
    (channel 0)."""
    from dopplertof.diff import render_derivatives
    from dopplertof.diff.silhouette import with_visibility

    plain = render_derivatives(ds, [name], spp=spp, seed=seed)
    return with_visibility(ds, plain, steps={name: step}).tangents[name][..., 0]


def fit_sphere(res: int, spp: int, seeds=(1, 2, 3), iterations: int = 3) -> None:
    """Gauss-Newton steps on the sphere's v_z from half of it, both Jacobians, for each
    of ``seeds`` (the capture's, the Jacobian's and the renders' seed)."""
    import dopplertof
    from dopplertof.diff import DifferentiableScene
    from dopplertof.diff.silhouette import pixel_classes

    dopplertof.set_variant("llvm_ad_rgb")
    scene = dopplertof.load_file(SPHERE, {"res": res, "max_depth": 2})
    footprint = pixel_classes(scene, 0)["footprint"]
    ds = DifferentiableScene(scene)
    truth = ds.body_velocity(0)[0][2]
    print(f"sphere {res}x{res}, {spp} spp, v_z from {0.5 * truth:g} m/s (truth {truth:g}), "
          "8x8 blocks of every pixel whose footprint sees the sphere")
    for seed in seeds:
        for label, history in _fit_steps(ds, footprint, truth, spp, seed, iterations):
            steps = ", ".join(f"{x:.3f} ({100 * (x / truth - 1):+.1f}%)" for x in history)
            print(f"  seed {seed} {label:<16} v_z after each step: {steps}")
    ds.set_body_velocity(0, [0.0, 0.0, truth])


def _fit_steps(ds, footprint, truth: float, spp: int, seed: int, iterations: int):
    """(label, v_z after each step) for the plain and the with_visibility Jacobian."""
    from dopplertof.diff import render_derivatives
    from dopplertof.diff.silhouette import block_sums, with_visibility

    def blocks(image):
        return block_sums(image[..., 0], footprint)

    ds.set_body_velocity(0, [0.0, 0.0, truth])
    capture = blocks(render_derivatives(ds, [], spp=spp, seed=seed).image)  # noise-free
    ds.set_body_velocity(0, [0.0, 0.0, 0.5 * truth])
    plain = render_derivatives(ds, ["body0.vz"], spp=spp, seed=seed)
    for label, d in (("plain", plain), ("with_visibility", with_visibility(ds, plain))):
        jacobian = blocks(d.tangents["body0.vz"])
        v, history = 0.5 * truth, []
        for _ in range(iterations):
            ds.set_body_velocity(0, [0.0, 0.0, v])
            residual = capture - blocks(render_derivatives(ds, [], spp=spp, seed=seed).image)
            v += float(jacobian @ residual / (jacobian @ jacobian))
            history.append(v)
        yield label, history


def _se(values) -> float:
    return float(np.std(values, ddof=1) / np.sqrt(len(values)))


if __name__ == "__main__":
    main()
