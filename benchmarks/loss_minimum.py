"""Where the plain and the cross-seed loss have their minimum over a body's velocity (issue 42,
2026-12-04).

docs/differentiable.md's gradient section fits a render to a target. The plain squared loss
of one render R against the target C, sum((R - C)^2), adds the render's variance, which
depends on the velocity (a faster body spreads its samples' Doppler phases wider), so its
minimum is away from the truth; the cross-seed loss (R_A - C) . (R_B - C) of two renders of
independent seeds (``dopplertof.diff.cross_loss``, ``cross_seed_gradient``) has the
expectation |E R - C|^2, lowest at the truth. This script renders the translating sphere
(examples/translating_sphere.xml, direct light, its own 30 MHz and 1.5 ms; the target a
high-spp render at its true velocity) at a grid of velocities along the axis for many seed
pairs, and prints both losses side by side: their means over the pairs with standard errors,
the grid velocity where each mean is lowest, and where each mean is lowest between the grid's
points (a parabola through its lowest grid point and the two beside it) with a bootstrap
standard deviation over the pairs. (Each pair's own minimum is no estimate of the truth: the
renders' noise grows with the velocity, so noisy curves' minima scatter to one side.)

    PYTHONPATH=src .venv/bin/python benchmarks/loss_minimum.py [--res 16] [--spp 256] [--pairs 128]
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np

SPHERE = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))),
                      "examples", "translating_sphere.xml")


def sphere(res: int):
    """The starter sphere at ``res`` x ``res``, direct light, as a DifferentiableScene, and its
    velocity (m/s along the axis, toward the camera > 0)."""
    import dopplertof
    from dopplertof.diff import DifferentiableScene

    dopplertof.set_variant("llvm_ad_rgb")
    scene = dopplertof.load_file(SPHERE, {"res": str(res), "max_depth": "2"})
    ds = DifferentiableScene(scene)
    return ds, float(ds.body_velocity(0)[0][2])


def render(ds, vz: float, spp: int, seed: int) -> np.ndarray:
    """The image (H, W, 3) of ``ds`` with the body's velocity (0, 0, vz)."""
    import drjit as dr

    from dopplertof.diff import gradient

    ds.set_body_velocity(0, v=[0.0, 0.0, vz])
    return gradient(ds, lambda image: dr.sum(image - image, axis=None), names=[], spp=spp,
                    seed=seed).image


def losses(ds, target, grid, spp: int, pairs: int) -> tuple[np.ndarray, np.ndarray]:
    """(plain, cross), each (pairs, len(grid)): per seed pair (2p + 1, 2p + 2) and velocity,
    the plain loss (the mean of the two renders' sum((R - C)^2)) and the cross loss."""
    from dopplertof.diff import cross_loss

    plain, cross = np.zeros((pairs, len(grid))), np.zeros((pairs, len(grid)))
    for p in range(pairs):
        for k, vz in enumerate(grid):
            a = render(ds, vz, spp, 2 * p + 1) - target
            b = render(ds, vz, spp, 2 * p + 2) - target
            plain[p, k] = 0.5 * (np.sum(a * a) + np.sum(b * b))
            cross[p, k] = cross_loss(a, b)
    return plain, cross


def lowest(grid, values) -> float:
    """Where ``values`` over ``grid`` (evenly spaced) is lowest: the vertex of the parabola
    through the lowest point and its two neighbours (the grid's end when it is lowest)."""
    k = int(np.argmin(values))
    if k in (0, len(grid) - 1):
        return float(grid[k])
    left, mid, right = values[k - 1], values[k], values[k + 1]
    step = grid[1] - grid[0]
    return float(grid[k] + 0.5 * step * (left - right) / (left - 2 * mid + right))


def report(grid, truth: float, plain, cross) -> None:
    """The two losses side by side, then where each is lowest."""
    pairs = len(plain)
    print(f"{'vz m/s':>7} | {'plain loss (mean +- se)':>26} | {'cross loss (mean +- se)':>26}")
    for k, vz in enumerate(grid):
        cells = [f"{v[:, k].mean():>12.4g} +- {v[:, k].std(ddof=1) / np.sqrt(pairs):<9.2g}"
                 for v in (plain, cross)]
        mark = "  (truth)" if np.isclose(vz, truth) else ""
        print(f"{vz:>7.2f} | {cells[0]:>26} | {cells[1]:>26}{mark}")
    print(f"\nlowest mean over {pairs} seed pairs on the grid: plain at "
          f"{grid[np.argmin(plain.mean(0))]:.2f} m/s, cross at {grid[np.argmin(cross.mean(0))]:.2f}"
          f" m/s (truth {truth:.2f})")
    for name, values in (("plain", plain), ("cross", cross)):
        at, spread = minimum_of_mean(grid, values)
        print(f"minimum of the mean {name} loss: {at:+.2f} m/s +- {spread:.2f} (bootstrap sd over "
              f"the pairs), {at - truth:+.2f} from the truth")


def minimum_of_mean(grid, values, draws: int = 1000) -> tuple[float, float]:
    """Where the mean of ``values`` (pairs, grid) over the pairs is lowest (:func:`lowest`),
    and the standard deviation of that over ``draws`` bootstrap resamples of the pairs."""
    rng = np.random.default_rng(0)
    pairs = len(values)
    again = [lowest(grid, values[rng.integers(0, pairs, pairs)].mean(0)) for _ in range(draws)]
    return lowest(grid, values.mean(0)), float(np.std(again, ddof=1))


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--res", type=int, default=16)
    parser.add_argument("--spp", type=int, default=256, help="samples per pixel of each render")
    parser.add_argument("--target-spp", type=int, default=16384)
    parser.add_argument("--pairs", type=int, default=128, help="seed pairs")
    parser.add_argument("--grid", type=float, nargs=3, default=(0.0, 20.0, 2.5),
                        metavar=("FROM", "TO", "STEP"), help="velocities (m/s)")
    args = parser.parse_args(argv)
    start = time.perf_counter()
    ds, truth = sphere(args.res)
    target = render(ds, truth, args.target_spp, 99)
    grid = np.arange(args.grid[0], args.grid[1] + 0.5 * args.grid[2], args.grid[2])
    print(f"{os.path.basename(SPHERE)}: {args.res}x{args.res}, direct light, {args.spp} spp a "
          f"render, {args.pairs} seed pairs, target {args.target_spp} spp at the true "
          f"{truth:.2f} m/s")
    plain, cross = losses(ds, target, grid, args.spp, args.pairs)
    report(grid, truth, plain, cross)
    print(f"{time.perf_counter() - start:.1f} s")


if __name__ == "__main__":
    main()
