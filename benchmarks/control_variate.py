"""The analytic integral as a control variate against sampled time, and the floor of any time integration.

    .venv/bin/python benchmarks/control_variate.py [--hetero-frequency 1 2.5] [--spp 32]
        [--seeds 4] [--res 256] [--figure FIG.png] [--fixtures DIR]
    .venv/bin/python benchmarks/control_variate.py --beats 0.5 1 1.05 ... [--res 128]

On the published moving Cornell box (max depth 4), at each beat count h, renders each
method with ``--seeds`` seeds, one seed of every method after the other (the machine's
load falls on all alike), and prints per method the image's mean per-pixel variance
over the seeds, the seconds per render and the efficiency against sampled time
(variance x time, inverted: above 1 is better at equal time). The methods:

- sampled: what ``auto`` picks without the control variate (antithetic pairs half a beat
  apart sharing their whole path near a whole number of beats, else stratified time);
- ``control_variate``: the analytic integral as a control variate for one sampled time
  per path (three paths traced per sample: the exposure's ends and the sampled time);
- ``analytic``: biased (its image mean is far from the reference's): its variance only;
- at a whole number of beats, antithetic groups of K = 8, 16 and 32 periodic times
  sharing one path: each path's time average is then nearly exact, and the variance is
  a K / spp, a the variance of one path's exact time average over paths.

From the last rows the floor a / spp: the variance at one path per sample with its time
average exact, the best any time integration can do at equal paths. The pairs' variance
over the floor bounds what a time integrator (a control variate included) can gain at
equal cost; the printout turns it into the most an equal-time race against the
published code could reach from the 4.67x measured side by side
(benchmarks/race_published.py). ``--figure`` draws, per h,
the block variance ratio of the control variate against sampled time, where it loses
(silhouettes, occlusion changes) and each method's efficiency and seconds. ``--beats``
instead prints, per h, the candidates of ``auto`` against the control variate: the
table its rule comes from.
"""

from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
FIXTURES = os.path.normpath(os.path.join(HERE, "..", "..", "shared", "fixtures", "published"))

#: the equal-time ratio against the published CPU code measured side by side on an idle
#: machine on 2026-12-07 (benchmarks/race_published.py: auto + adaptive, 4096 spp in
#: 48.7 s, against its 1024 spp in 108.6 s; 4.07 in a loaded sitting the same day)
PUBLISHED_RATIO = 4.67
#: periodic group sizes whose variance gives the path-space floor
FLOOR_GROUPS = (8, 16, 32)

def methods(h: float) -> dict:
    """The rows at h beats per exposure: name -> render parameters (the floor's groups
    only at a whole number of beats, which K periodic times then cancel)."""
    from dopplertof.sampling import FULL_CORRELATION, auto_sampling

    rows = {"sampled (auto's choice without the control variate)": auto_sampling(h),
            "control_variate": {"time_sampling_method": "control_variate"},
            "analytic (biased)": {"time_sampling_method": "analytic"}}
    if h == round(h) and h >= 1:
        rows.update({f"antithetic K={k}": {
            "time_sampling_method": "antithetic", "time_correlate_number": k,
            "antithetic_shift": 1.0 / k, "path_correlation_depth": FULL_CORRELATION}
            for k in FLOOR_GROUPS})
    return rows


#: the row the others are measured against
BASE = "sampled (auto's choice without the control variate)"


def measure(dopplertof, scene, rows: dict, spp: int, seeds: int):
    """Per row: the per-pixel variance over seeds (H, W) and the seconds per render."""
    images = {name: [] for name in rows}
    seconds = {name: 0.0 for name in rows}
    for name, params in rows.items():  # compile every kernel before timing
        dopplertof.render(scene, spp=spp, seed=0, params=params)
    for seed in range(1, seeds + 1):
        for name, params in rows.items():
            started = time.perf_counter()
            image = dopplertof.render(scene, spp=spp, seed=seed, params=params)
            seconds[name] += time.perf_counter() - started
            images[name].append(np.asarray(image, np.float64))
    variance = {name: np.var(np.array(v), axis=0, ddof=1).mean(axis=-1)
                for name, v in images.items()}
    return variance, {name: s / seeds for name, s in seconds.items()}


def report(variance: dict, seconds: dict, spp: int, h: float) -> None:
    """Prints the table and, at a whole number of beats, the floor."""
    base = variance[BASE].mean() * seconds[BASE]
    print(f"\nh = {h:g} beats per exposure, {spp} spp")
    print(f"{'method':52s} {'mean variance':>14s} {'s/render':>9s} {'efficiency':>11s}")
    for name in variance:
        v = variance[name].mean()
        print(f"{name:52s} {v:14.3e} {seconds[name]:9.2f} {base / (v * seconds[name]):11.2f}")
    per_k = [variance[f"antithetic K={k}"].mean() / k for k in FLOOR_GROUPS
             if f"antithetic K={k}" in variance]
    if not per_k:
        return
    floor = min(per_k)  # (the most generous: it falls with more paths per pixel)
    gain = variance[BASE].mean() / floor
    print(f"path-space floor (variance / K at K = {FLOOR_GROUPS}): "
          + ", ".join(f"{v:.3e}" for v in per_k) + f"; taken as {floor:.3e}")
    print(f"pairs' variance over the floor: {gain:.2f} (RMSE {np.sqrt(gain):.2f}x): the most "
          "any time integration gains at equal paths")
    for paths in (1, 2, 3):
        print(f"  at {paths} path(s) per sample and equal cost per path: equal-time ratio "
              f"against the published code at most {PUBLISHED_RATIO * np.sqrt(gain / paths):.2f}"
              f" (from {PUBLISHED_RATIO})")


#: pixels per side of the figure's blocks (4 seeds' variances are too noisy per pixel)
BLOCK = 8


def _blocks(image):
    """The mean of each BLOCK x BLOCK block (the image cropped to whole blocks)."""
    h, w = (n // BLOCK * BLOCK for n in image.shape)
    return image[:h, :w].reshape(h // BLOCK, BLOCK, w // BLOCK, BLOCK).mean(axis=(1, 3))


def figure(results: dict, path: str) -> None:
    """One row per beat count: the block variance ratio map, its histogram (auto's
    noisiest blocks apart) and each method's efficiency with its seconds."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, grid = plt.subplots(len(results), 3, figsize=(17, 5 * len(results)),
                             constrained_layout=True, squeeze=False)
    for axes, (h, (variance, seconds)) in zip(grid, results.items()):
        base, cv = (_blocks(variance[n]) for n in (BASE, "control_variate"))
        ratio = np.log2(np.maximum(cv, 1e-30) / np.maximum(base, 1e-30))
        shown = axes[0].imshow(ratio, cmap="RdBu_r", vmin=-6, vmax=6)
        axes[0].set_title(f"h = {h:g}: log2 variance, control variate / sampled time,\n"
                          f"{BLOCK}x{BLOCK}-pixel blocks (red: the control variate is noisier)")
        fig.colorbar(shown, ax=axes[0])
        busy = base >= np.quantile(base, 0.9)
        bins = np.linspace(-8, 8, 49)
        axes[1].hist(ratio[~busy].ravel(), bins=bins, alpha=0.6, density=True,
                     label="other blocks")
        axes[1].hist(ratio[busy].ravel(), bins=bins, alpha=0.6, density=True,
                     label="sampled time's noisiest 10% (silhouettes)")
        axes[1].set_xlabel("log2 variance ratio per block, control variate / sampled time")
        axes[1].legend()
        names = list(variance)
        base_cost = variance[BASE].mean() * seconds[BASE]
        efficiency = [base_cost / (variance[n].mean() * seconds[n]) for n in names]
        axes[2].barh([n.split(" (")[0] for n in names], efficiency)
        axes[2].axvline(1.0, color="k", lw=0.8)
        axes[2].set_xscale("log")
        axes[2].tick_params(axis="x", which="minor", labelbottom=False)
        axes[2].set_xlabel("efficiency against sampled time (1 / variance x seconds)")
        for y, n in enumerate(names):
            axes[2].text(efficiency[y], y, f" {seconds[n]:.1f} s", va="center")
    fig.savefig(path, dpi=70)
    print(f"figure: {path}")


def beats(dopplertof, xml: str, values, spp: int, seeds: int, res: int) -> None:
    """Per beat count h: each candidate's variance x seconds against the control
    variate's (above 1: the control variate is better at equal time), and what ``auto``
    picks; the rule of sampling.auto_sampling comes from this table."""
    from dopplertof.sampling import FULL_CORRELATION, auto_sampling

    print(f"{'h':>6s} {'antithetic pairs':>17s} {'stratified':>11s}  auto picks")
    for h in values:
        scene = dopplertof.load_file(xml, {"resx": str(res), "resy": str(res)}).with_params(
            hetero_frequency=h)
        n = max(1, round(h))
        candidates = {
            "antithetic": dict(time_sampling_method="antithetic", antithetic_shift=0.5 / n,
                               path_correlation_depth=FULL_CORRELATION),
            "stratified": dict(time_sampling_method="stratified", path_correlation_depth=0),
            "control_variate": dict(time_sampling_method="control_variate")}
        cost = {}
        for name, params in candidates.items():
            dopplertof.render(scene, spp=spp, seed=0, params=params)  # (compiled)
            started = time.perf_counter()
            images = [np.asarray(dopplertof.render(scene, spp=spp, seed=s, params=params),
                                 np.float64) for s in range(1, seeds + 1)]
            seconds = (time.perf_counter() - started) / seeds
            cost[name] = np.var(np.array(images), axis=0, ddof=1).mean() * seconds
        picked = auto_sampling(h, closed_form=True)["time_sampling_method"]
        print(f"{h:6.2f} {cost['antithetic'] / cost['control_variate']:17.2f} "
              f"{cost['stratified'] / cost['control_variate']:11.2f}  {picked}", flush=True)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--fixtures", default=FIXTURES)
    p.add_argument("--spp", type=int, default=32)
    p.add_argument("--seeds", type=int, default=4)
    p.add_argument("--res", type=int, default=256)
    p.add_argument("--hetero-frequency", type=float, nargs="+", default=[1.0, 2.5],
                   metavar="H", help="beats per exposure of the rows (default 1 and 2.5)")
    p.add_argument("--figure", metavar="PNG")
    p.add_argument("--beats", type=float, nargs="+", metavar="H",
                   help="instead: compare the candidates of `auto` at these beat counts")
    args = p.parse_args(argv)
    xml = os.path.join(args.fixtures, "cornell_box_moving.xml")
    if not os.path.exists(xml):
        print(f"error: {xml} not found (--fixtures)", file=sys.stderr)
        return 2
    if args.spp % max(FLOOR_GROUPS) or args.seeds < 2:
        print(f"error: --spp must be a multiple of {max(FLOOR_GROUPS)} and --seeds >= 2",
              file=sys.stderr)
        return 2
    import dopplertof

    dopplertof.set_variant()
    if args.beats:
        beats(dopplertof, xml, args.beats, args.spp, args.seeds, args.res)
        return 0
    results = {}
    for h in args.hetero_frequency:
        scene = dopplertof.load_file(xml, {"resx": str(args.res), "resy": str(args.res)})
        scene = scene.with_params(hetero_frequency=h)
        results[h] = measure(dopplertof, scene, methods(h), args.spp, args.seeds)
        report(*results[h], args.spp, h)
    if args.figure:
        figure(results, args.figure)
    return 0


if __name__ == "__main__":
    sys.exit(main())
