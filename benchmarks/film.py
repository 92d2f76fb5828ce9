"""Per-pixel variance of the film at equal spp: dopplertof against stock Mitsuba `path`.

Static Cornell box (``mi.cornell_box()``), 48x48, the same filter for both, 24 seeds x
16 spp. dopplertof renders homodyne at a vanishing frequency, where its image is the
constant g1 C(0) = 0.25 times the radiance, so that both estimate one quantity. The
variance of every pixel over the seeds is compared on the smooth pixels of the walls
(3x3 neighbourhoods whose high-spp mean varies by less than 30%: no edge of a surface
or a shadow inside; the light excluded).

    .venv/bin/python benchmarks/film.py [--res 48] [--spp 16] [--seeds 24]
    .venv/bin/python benchmarks/film.py --timing 7     (throughput of the pixel sets)
    .venv/bin/python benchmarks/film.py --depths 2 3 6 (the default film's ratio by max_depth:
                                                        where the variance is)

Prints, per filter and film (``splat`` with each normalization and ``pixel_sets``,
``importance``), the ratio of our variance to stock's (< 1: less noisy than stock); the
last line reads `worst film variance ratio (splat, default normalization, joint pixel
sets, over box/tent/gaussian): X`.
"""

from __future__ import annotations

import argparse

import numpy as np

WEIGHT = 0.25  #: g1 C(0): the D-ToF image over the radiance at a vanishing frequency
#: (film_sampling, film_normalization, pixel_sets), side by side; the first is the default
PIXEL_SETS = ("independent", "joint")
FILMS = (("splat", "weights", "joint"), ("splat", "weights", "independent"),
         ("splat", "expected", "joint"), ("importance", "weights", "independent"))


def scene(integrator, rfilter, res, spp):
    import mitsuba as mi

    d = mi.cornell_box()
    d["integrator"] = integrator
    d["sensor"]["film"]["width"] = d["sensor"]["film"]["height"] = res
    d["sensor"]["film"]["rfilter"] = {"type": rfilter}
    d["sensor"]["sampler"] = {"type": "independent", "sample_count": spp}
    return d


def smooth_pixels(mean):
    """Pixels whose 3x3 neighbourhood of ``mean`` (H, W) varies by under 30% and that
    are not the light (the brightest pixels)."""
    h, w = mean.shape
    pad = np.pad(mean, 1, mode="edge")
    stack = np.stack([pad[dy:dy + h, dx:dx + w] for dy in range(3) for dx in range(3)])
    spread = (stack.max(0) - stack.min(0)) / np.maximum(mean, 1e-12)
    return (spread < 0.3) & (mean < np.quantile(mean, 0.98)) & (mean > 0)


def throughput(repeats: int) -> None:
    """Seconds per render of the published scene (128x128, 64 spp, its tent filter,
    ``auto``) with each pixel_sets, interleaved (benchmarks/timing.py), and the ratio."""
    import os

    import dopplertof
    from timing import interleaved_medians

    xml = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "tests", "fixtures",
                       "cornell_box_moving.xml")
    scene = dopplertof.load_file(xml, {"resx": 128, "resy": 128})
    runs = {sets: (lambda sets=sets: dopplertof.render(scene, spp=64, seed=1, params={
        "time_sampling_method": "auto", "pixel_sets": sets})) for sets in PIXEL_SETS}
    _, warm = interleaved_medians(runs, repeats)
    for sets in PIXEL_SETS:
        print(f"  {sets:12s} {warm[sets]:.3f} s (median of {repeats})")
    print(f"throughput ratio (joint / independent pixel sets): "
          f"{warm['joint'] / warm['independent']:.3f}")


def by_depth(res: int, spp: int, seeds: int, depths) -> None:
    """Per filter (box, tent) and max_depth, stock's per-pixel variance, ours (the default
    film) and their ratio, on the smooth pixels of the depth-6 reference: how much of the
    variance is direct light (max_depth 2) and how much each depth adds."""
    import mitsuba as mi

    import dopplertof

    for rfilter in ("box", "tent"):
        stock_full = mi.load_dict(scene({"type": "path", "max_depth": 6}, rfilter, res, spp))
        mask = smooth_pixels(np.array(mi.render(stock_full, spp=64 * spp, seed=10_000))
                             [..., :3].mean(-1))
        for depth in depths:
            stock_scene = mi.load_dict(scene({"type": "path", "max_depth": depth}, rfilter,
                                             res, spp))
            ours_scene = dopplertof.load_dict(scene(
                {"type": "dopplertof", "max_depth": depth, "w_g": 1e-6}, rfilter, res, spp))
            stock = np.array([np.array(mi.render(stock_scene, spp=spp, seed=s))[..., :3]
                              .mean(-1) for s in range(seeds)])
            ours = np.array([dopplertof.render(ours_scene, seed=s).mean(-1) / WEIGHT
                             for s in range(seeds)])
            v_stock, v_ours = (a.var(0, ddof=1)[mask].mean() for a in (stock, ours))
            print(f"  {rfilter:5s} max_depth {depth}: stock {v_stock:.3e}, ours {v_ours:.3e}, "
                  f"ratio {v_ours / v_stock:.2f}", flush=True)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--res", type=int, default=48)
    p.add_argument("--spp", type=int, default=16)
    p.add_argument("--seeds", type=int, default=24)
    p.add_argument("--timing", type=int, metavar="REPEATS",
                   help="only time the pixel sets against each other (interleaved)")
    p.add_argument("--depths", type=int, nargs="+", metavar="MAX_DEPTH",
                   help="only the default film against stock at each max_depth (box, tent): "
                   "2 is direct light, the rest adds bounces")
    args = p.parse_args(argv)

    import mitsuba as mi

    import dopplertof

    dopplertof.set_variant("llvm_ad_rgb")
    if args.timing:
        throughput(args.timing)
        return 0
    if args.depths:
        by_depth(args.res, args.spp, args.seeds, args.depths)
        return 0
    worst = 0.0
    for rfilter in ("box", "tent", "gaussian"):
        stock_scene = mi.load_dict(scene({"type": "path", "max_depth": 6}, rfilter, args.res,
                                         args.spp))
        stock = np.array([np.array(mi.render(stock_scene, spp=args.spp, seed=s))[..., :3]
                          .mean(-1) for s in range(args.seeds)])
        reference = np.array(mi.render(stock_scene, spp=256 * args.spp, seed=10_000))
        mask = smooth_pixels(reference[..., :3].mean(-1))
        stock_var = stock.var(0, ddof=1)[mask].mean()
        row = [f"{rfilter:9s} ({mask.sum()} smooth pixels)"]
        for film, normalization, sets in FILMS:
            ours_scene = dopplertof.load_dict(scene(
                {"type": "dopplertof", "max_depth": 6, "w_g": 1e-6, "film_sampling": film,
                 "film_normalization": normalization, "pixel_sets": sets}, rfilter,
                args.res, args.spp))
            ours = np.array([dopplertof.render(ours_scene, seed=s).mean(-1) / WEIGHT
                             for s in range(args.seeds)])
            ratio = ours.var(0, ddof=1)[mask].mean() / stock_var
            row.append(f"{film}/{normalization}/{sets} {ratio:.2f}")
            if (film, normalization, sets) == FILMS[0]:
                worst = max(worst, ratio)
        print("  ".join(row), flush=True)
    print("worst film variance ratio (splat, default normalization, joint pixel sets, over "
          f"box/tent/gaussian): {worst:.2f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
