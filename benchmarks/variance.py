"""Variance of the time-path sampling methods on the published moving Cornell box.

For each hetero_frequency, every time-sampling method x path correlation depth
(0, 1, 2, full) x full time stratification (on/off) is rendered at the same spp and
compared with a high-spp reference (antithetic, full correlation, other seed), and so
are antithetic pairs under the motion mapping (``antithetic_mapping="motion"``),
``time_sampling_method="auto"`` and auto with ``adaptive_sampling`` (per-pixel counts
from a pilot, spp on average). Prints the RMSE table, seconds per render, the paper's
headline ratio (naive = uniform time, independent paths, no stratification)

    RMSE ratio at hetero_frequency=1 (uniform/independent over antithetic/full): X

with its equal-time value, and last the two lines of the beyond-the-paper sampling:

    RMSE ratio at hetero_frequency=1 (uniform/independent over best): X
    worst RMSE ratio over hetero_frequency 0..1 (auto over uniform): Y

    .venv/bin/python benchmarks/variance.py            # 128x128, 1024 spp, ref x64
    .venv/bin/python benchmarks/variance.py --quick    # 64x64, 256 spp, ref x64
    .venv/bin/python benchmarks/variance.py --quick --box-filter --hetero 1
    .venv/bin/python benchmarks/variance.py --hetero 1 --seed 2   # another realization
    .venv/bin/python benchmarks/variance.py --film importance       # one pixel per sample

Every render, the reference included, uses the film given by ``--film`` (default the
splat film, as the renderer's default). The naive row of this table is our own naive
sampling; benchmarks/published.py compares with the published implementation's renders.
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
SCENE = os.path.join(HERE, "..", "tests", "fixtures", "cornell_box_moving.xml")
from dopplertof.sampling import FULL_CORRELATION as FULL  # noqa: E402
from dopplertof.sampling import METHODS  # noqa: E402
DEPTHS = (0, 1, 2, FULL)
MAPPED_METHODS = ("antithetic", "antithetic_mirror")


def depth_name(d):
    return "full" if d == FULL else str(d)


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--quick", action="store_true", help="64x64, 256 spp")
    p.add_argument("--res", type=int)
    p.add_argument("--spp", type=int)
    p.add_argument("--ref-factor", type=int, default=64, help="reference spp = factor x spp")
    p.add_argument("--hetero", type=float, nargs="+", default=[0.0, 0.25, 0.5, 0.75, 1.0])
    p.add_argument("--variant", default="llvm_ad_rgb")
    p.add_argument("--seed", type=int, default=1,
                   help="seed of every measured render (the reference keeps its own)")
    p.add_argument("--film", choices=("splat", "importance"), default="splat",
                   help="film_sampling of every render (default: splat)")
    p.add_argument("--box-filter", action="store_true",
                   help="replace the scene's tent reconstruction filter by a box")
    args = p.parse_args()
    res = args.res or (64 if args.quick else 128)
    spp = args.spp or (256 if args.quick else 1024)

    import dopplertof

    dopplertof.set_variant(args.variant)
    if args.box_filter:
        text = open(SCENE).read()
        assert '<rfilter type="tent" />' in text
        scene = dopplertof.load_string(text.replace('<rfilter type="tent" />',
                                                    '<rfilter type="box" />'),
                                       {"resx": res, "resy": res})
    else:
        scene = dopplertof.load_file(SCENE, {"resx": res, "resy": res})
    print(f"published moving Cornell box, {res}x{res}, max_depth 4, {spp} spp, {args.film} film, "
          f"reference {spp * args.ref_factor} spp (antithetic, full correlation)", flush=True)

    def render(h, method, depth, strat, n, seed, mapping=None, adaptive=False):
        params = dict(hetero_frequency=h, time_sampling_method=method,
                      path_correlation_depth=depth,
                      use_stratified_sampling_for_each_interval=strat,
                      adaptive_sampling=adaptive, film_sampling=args.film)
        if mapping is not None:
            params["antithetic_mapping"] = mapping
        t = time.perf_counter()
        img = dopplertof.render(scene, spp=n, seed=seed, params=params, progress=False)
        return img.astype(np.float64), time.perf_counter() - t

    results = {}
    for h in args.hetero:
        ref, t_ref = render(h, "antithetic", FULL, True, spp * args.ref_factor, 1_000_003)
        print(f"\nhetero_frequency={h:g}: reference in {t_ref:.0f} s, "
              f"rms signal {np.sqrt(np.mean(ref ** 2)):.3e}", flush=True)
        for strat in (False, True):  # compile every kernel first: times are render times
            render(h, "uniform", 0, strat, spp, 2)
        render(h, "antithetic", FULL, True, spp, 2, mapping="motion")
        render(h, "auto", FULL, True, spp, 2, adaptive=True)
        print(f"{'method':>18} {'depth':>5} {'strat':>5} {'RMSE':>10} {'seconds':>8}")
        for strat in (False, True):
            for method in METHODS:
                for depth in DEPTHS:
                    img, sec = render(h, method, depth, strat, spp, args.seed)
                    rmse = float(np.sqrt(np.mean((img - ref) ** 2)))
                    results[(h, method, depth, strat)] = (rmse, sec)
                    print(f"{method:>18} {depth_name(depth):>5} {str(strat):>5} "
                          f"{rmse:10.3e} {sec:8.2f}", flush=True)
        for method in MAPPED_METHODS:
            img, sec = render(h, method, FULL, True, spp, args.seed, mapping="motion")
            rmse = float(np.sqrt(np.mean((img - ref) ** 2)))
            results[(h, method, "motion")] = (rmse, sec)
            print(f"{method + '+motion':>18} {'full':>5} {'True':>5} {rmse:10.3e} {sec:8.2f}",
                  flush=True)
        img, sec = render(h, "auto", FULL, True, spp, args.seed)
        rmse = float(np.sqrt(np.mean((img - ref) ** 2)))
        results[(h, "auto")] = (rmse, sec)
        print(f"{'auto':>18} {'':>5} {'':>5} {rmse:10.3e} {sec:8.2f}", flush=True)
        img, sec = render(h, "auto", FULL, True, spp, args.seed, adaptive=True)
        rmse = float(np.sqrt(np.mean((img - ref) ** 2)))
        results[(h, "auto", "adaptive")] = (rmse, sec)
        print(f"{'auto+adaptive':>18} {'':>5} {'':>5} {rmse:10.3e} {sec:8.2f}", flush=True)

    print("\nRMSE ratio naive / each (uniform, independent, no stratification = 1):")
    header = " ".join(f"h={h:<8g}" for h in args.hetero)
    print(f"{'method':>18} {'depth':>5} {'strat':>5}  {header}")
    for strat in (False, True):
        for method in METHODS:
            for depth in DEPTHS:
                row = " ".join(
                    f"{results[(h, 'uniform', 0, False)][0] / results[(h, method, depth, strat)][0]:<10.2f}"
                    for h in args.hetero)
                print(f"{method:>18} {depth_name(depth):>5} {str(strat):>5}  {row}")
    for method in MAPPED_METHODS:
        row = " ".join(
            f"{results[(h, 'uniform', 0, False)][0] / results[(h, method, 'motion')][0]:<10.2f}"
            for h in args.hetero)
        print(f"{method + '+motion':>18} {'full':>5} {'True':>5}  {row}")

    auto_ratios = {h: results[(h, "uniform", 0, False)][0] / results[(h, "auto")][0]
                   for h in args.hetero}
    print("auto (time_sampling_method='auto'): " + ", ".join(
        f"h={h:g}: {r:.2f}" for h, r in auto_ratios.items()))
    print("auto + adaptive_sampling: " + ", ".join(
        f"h={h:g}: {results[(h, 'uniform', 0, False)][0] / results[(h, 'auto', 'adaptive')][0]:.2f}"
        for h in args.hetero))
    h = 1.0 if 1.0 in args.hetero else args.hetero[-1]
    naive_rmse, naive_t = results[(h, "uniform", 0, False)]
    paper_rmse, paper_t = results[(h, "antithetic", FULL, True)]
    ratio = naive_rmse / paper_rmse
    print(f"RMSE ratio at hetero_frequency={h:g} at equal time: "
          f"{ratio * np.sqrt(naive_t / paper_t):.1f}")
    print(f"RMSE ratio at hetero_frequency={h:g} (uniform/independent over "
          f"antithetic/full): {ratio:.1f}")
    at_h = {k: v for k, v in results.items() if k[0] == h}
    best_key = min(at_h, key=lambda k: at_h[k][0])
    best_rmse, best_t = at_h[best_key]
    best = naive_rmse / best_rmse
    print(f"best at hetero_frequency={h:g}: {config_name(best_key)}, "
          f"{best_t / naive_t:.2f}x the naive time, equal-time ratio "
          f"{best * np.sqrt(naive_t / best_t):.1f}")
    print(f"RMSE ratio at hetero_frequency={h:g} (uniform/independent over best): {best:.1f}")
    print(f"worst RMSE ratio over hetero_frequency {min(args.hetero):g}.."
          f"{max(args.hetero):g} (auto over uniform): {min(auto_ratios.values()):.2f}")


def config_name(key):
    if key[1] == "auto":
        # auto at h = 1: antithetic, full correlation, stratified
        return "auto + adaptive_sampling" if key[-1] == "adaptive" else "auto"
    if key[-1] == "motion":
        return f"{key[1]}, full correlation, stratified, motion mapping"
    _, method, depth, strat = key
    return (f"{method}, correlation depth {depth_name(depth)}, "
            f"{'stratified' if strat else 'not stratified'}")


if __name__ == "__main__":
    main()
