"""Per-pixel variance of the film at equal spp: dopplertof against stock Mitsuba `path`.

Static Cornell box (``mi.cornell_box()``), 48x48, the same filter for both, 24 seeds x
16 spp. dopplertof renders homodyne at a vanishing frequency, where its image is the
constant g1 C(0) = 0.25 times the radiance, so that both estimate one quantity. The
variance of every pixel over the seeds is compared on the smooth pixels of the walls
(3x3 neighbourhoods whose high-spp mean varies by less than 30%: no edge of a surface
or a shadow inside; the light excluded).

    .venv/bin/python benchmarks/film.py [--res 48] [--spp 16] [--seeds 24]
    .venv/bin/python benchmarks/film.py --timing 7     (throughput of the pixel sets)
    .venv/bin/python benchmarks/film.py --timing 7 --against 842c696
                                                       (the default film's throughput
                                                        against an older commit's)
    .venv/bin/python benchmarks/film.py --depths 2 3 6 (the default film's ratio by max_depth:
                                                        where the variance is)
    .venv/bin/python benchmarks/film.py --stock-samplers (stock `path` with each of Mitsuba's
                                                        own samplers: what stratifying every
                                                        dimension of stock's paths reaches)
    .venv/bin/python benchmarks/film.py --weights       (the default film's samples weighed
                                                        again: what the filter's weights cost)

Prints, per filter and film (``splat`` with each normalization and ``pixel_sets``,
``importance``), the ratio of our variance to stock's (< 1: less noisy than stock); the
last line reads `worst film variance ratio (splat, default normalization, joint pixel
sets, over box/tent/gaussian): X`.
"""

from __future__ import annotations

import argparse

import numpy as np

WEIGHT = 0.25  #: g1 C(0): the D-ToF image over the radiance at a vanishing frequency
#: (film_sampling, film_normalization, pixel_sets), side by side; the first is the joint
#: sets (the last line's worst ratio), the second the default
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


#: one process's warm render time of the published scene (128x128, 64 spp, ``auto``,
#: the default film), median of argv[1] after a warm-up: run with another tree's src
TIMED_RENDER = """
import os, statistics, sys, time
import dopplertof
dopplertof.set_variant("llvm_ad_rgb")
scene = dopplertof.load_file(sys.argv[2], {"resx": 128, "resy": 128})
times = []
for _ in range(int(sys.argv[1]) + 1):
    started = time.perf_counter()
    dopplertof.render(scene, spp=64, seed=1, params={"time_sampling_method": "auto"})
    times.append(time.perf_counter() - started)
print(statistics.median(times[1:]))
"""


def throughput_against(commit: str, repeats: int) -> None:
    """Warm seconds per render of the published scene, default film, in this tree and
    in ``commit``'s sources (same venv), in alternating processes: ``repeats`` rounds of
    one process each, 3 renders a process (after a warm-up), medians."""
    import os
    import statistics
    import subprocess
    import sys
    import tempfile

    from startup import ROOT, baseline_sources

    xml = os.path.join(ROOT, "tests", "fixtures", "cornell_box_moving.xml")
    with tempfile.TemporaryDirectory() as tmp:
        trees = {"this tree": os.path.join(ROOT, "src"), commit: baseline_sources(commit, tmp)}
        seconds = {name: [] for name in trees}
        for _ in range(repeats):
            for name, src in trees.items():
                out = subprocess.run([sys.executable, "-c", TIMED_RENDER, "3", xml],
                                     env={**os.environ, "PYTHONPATH": src}, check=True,
                                     capture_output=True, text=True)
                seconds[name].append(float(out.stdout.split()[-1]))
    median = {name: statistics.median(v) for name, v in seconds.items()}
    for name, value in median.items():
        print(f"  {name:12s} {value:.3f} s (median of {repeats} processes)")
    print(f"throughput ratio (this tree / {commit}): {median['this tree'] / median[commit]:.3f}")


def stock_images(stock_scene, spp: int, seeds: int) -> np.ndarray:
    """(seeds, H, W): stock renders of ``stock_scene``, channels averaged."""
    import mitsuba as mi

    return np.array([np.array(mi.render(stock_scene, spp=spp, seed=s))[..., :3].mean(-1)
                     for s in range(seeds)])


def our_images(ours_scene, seeds: int) -> np.ndarray:
    """(seeds, H, W): our renders of ``ours_scene``, as radiance (divided by WEIGHT)."""
    import dopplertof

    return np.array([dopplertof.render(ours_scene, seed=s).mean(-1) / WEIGHT
                     for s in range(seeds)])


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
            stock, ours = stock_images(stock_scene, spp, seeds), our_images(ours_scene, seeds)
            v_stock, v_ours = (a.var(0, ddof=1)[mask].mean() for a in (stock, ours))
            print(f"  {rfilter:5s} max_depth {depth}: stock {v_stock:.3e}, ours {v_ours:.3e}, "
                  f"ratio {v_ours / v_stock:.2f}", flush=True)


#: Mitsuba's samplers that take any sample count (``orthogonal`` needs a prime's square)
STOCK_SAMPLERS = ("independent", "stratified", "multijitter", "ldsampler")


def stock_samplers(res: int, spp: int, seeds: int) -> None:
    """Per filter: stock `path` with each of Mitsuba's samplers (every 2-D decision of
    the path stratified per pixel by ``stratified``, ``multijitter`` and ``ldsampler``)
    and our default film, each over stock `path` with the independent sampler."""
    import mitsuba as mi

    import dopplertof

    for rfilter in ("box", "tent", "gaussian"):
        variances = {}
        for name in STOCK_SAMPLERS:
            d = scene({"type": "path", "max_depth": 6}, rfilter, res, spp)
            d["sensor"]["sampler"] = {"type": name, "sample_count": spp}
            stock_scene = mi.load_dict(d)
            if name == "independent":
                mask = smooth_pixels(np.array(mi.render(stock_scene, spp=256 * spp,
                                                        seed=10_000))[..., :3].mean(-1))
            variances[name] = stock_images(stock_scene, spp, seeds).var(0, ddof=1)[mask].mean()
        ours = our_images(dopplertof.load_dict(scene(
            {"type": "dopplertof", "max_depth": 6, "w_g": 1e-6}, rfilter, res, spp)), seeds)
        variances["dopplertof (default film)"] = ours.var(0, ddof=1)[mask].mean()
        print(f"{rfilter:9s} " + "  ".join(f"{name} {v / variances['independent']:.3f}"
                                           for name, v in variances.items()), flush=True)


def axis_weights(splat, d) -> dict:
    """e(d - k) for every neighbour k of the film's filter (SplatFilter.axis_weights, the
    weights the render splats with), ``d`` offsets on one axis (NumPy), as NumPy."""
    import mitsuba as mi

    return {k: np.asarray(w, np.float64) for k, w in splat.axis_weights(mi.Float(d)).items()}


def weighed(splat, res: int, pixel, offset, value, cells: int) -> np.ndarray:
    """The (res, res) image from samples (source pixel, film offset from its centre,
    value), with the film's filter ``splat`` (integrators/film.SplatFilter). ``cells``
    0: Mitsuba's ratio, sum w f / sum w over every sample a pixel's filter reaches (the
    film's own estimate); c >= 1: the ratio within each c x c cell of each source
    pixel, the cells weighted by their exact filter integrals (c = 1: one weight per
    source pixel, w's variation within the pixel kept inside the ratio); -1: each
    source pixel's plain mean, weighted by its pixel's filter integral (a coarser
    filter, not Mitsuba's: what the image would cost if a sample's weight did not vary
    within its pixel)."""
    split = max(cells, 1)
    if cells < 0:  # one sample per source pixel: its mean, at the centre
        value = np.bincount(pixel, value, res * res) / np.bincount(pixel, None, res * res)
        pixel, offset = np.arange(res * res), np.zeros((res * res, 2))
    wx, wy = axis_weights(splat, offset[:, 0]), axis_weights(splat, offset[:, 1])
    cell = (np.minimum(((offset + 0.5) * split).astype(int), split - 1) * [1, split]).sum(1)
    num, den = np.zeros(res * res), np.zeros(res * res)
    for ox, oy in splat.offsets:
        px, py = pixel % res - ox, pixel // res - oy  # the pixel reached: its centre o away
        inside = (px >= 0) & (px < res) & (py >= 0) & (py < res)
        target, w = py * res + px, wx[-ox] * wy[-oy]  # e(offset + o): axis_weights' k = -o
        if cells == 0:
            np.add.at(num, target[inside], (w * value)[inside])
            np.add.at(den, target[inside], w[inside])
            continue
        for k in range(split * split):
            lo_x, lo_y = (k % split) / split - 0.5, (k // split) / split - 0.5
            W = (splat.integral(lo_x + ox, lo_x + 1 / split + ox)
                 * splat.integral(lo_y + oy, lo_y + 1 / split + oy))
            mine = inside & (cell == k)
            if W <= 0.0 or not mine.any():
                continue
            if cells < 0:  # the plain mean, weighted by the pixel's integral
                np.add.at(num, target[mine], W * value[mine])
                np.add.at(den, target[mine], W)
                continue
            sums = np.bincount(target[mine], (w * value)[mine], res * res)
            weights = np.bincount(target[mine], w[mine], res * res)
            seen = weights > 0
            num[seen] += W * sums[seen] / weights[seen]
            den[seen] += W
    return (num / np.maximum(den, 1e-300)).reshape(res, res)


def filter_weights(res: int, spp: int, seeds: int) -> None:
    """Per filter: the default film's own samples (captured as the render adds them),
    weighed again in NumPy by ``weighed``'s estimators, each image's per-pixel variance
    over stock `path`'s (independent sampler). The first column must equal the render's."""
    import mitsuba as mi

    import dopplertof
    from dopplertof.integrators import pipeline
    from dopplertof.integrators.film import SplatFilter

    captured = []
    add = pipeline.Accumulator.add

    def capture(self, value, film_offset, chunk_size, threads, pilot):
        pixels, _, lanes = threads  # lanes are pixel-major (path_steps.PassLayout)
        captured.append((np.repeat(pixels, lanes), np.asarray(film_offset).reshape(2, -1).T,
                         np.asarray(value).reshape(3, -1).mean(0) / WEIGHT))
        return add(self, value, film_offset, chunk_size, threads, pilot)

    pipeline.Accumulator.add = capture  # (measurement only: the sums are the render's)
    estimators = {"Mitsuba's ratio": 0, "ratio per source pixel": 1,
                  "ratio per quadrant": 2, "ratio per 1/16 cell": 4,
                  "one weight per source pixel (another filter)": -1}
    for rfilter in ("box", "tent", "gaussian"):
        stock_scene = mi.load_dict(scene({"type": "path", "max_depth": 6}, rfilter, res, spp))
        mask = smooth_pixels(np.array(mi.render(stock_scene, spp=256 * spp, seed=10_000))
                             [..., :3].mean(-1))
        stock_var = stock_images(stock_scene, spp, seeds).var(0, ddof=1)[mask].mean()
        ours_scene = dopplertof.load_dict(scene(
            {"type": "dopplertof", "max_depth": 6, "w_g": 1e-6}, rfilter, res, spp))
        splat = SplatFilter(ours_scene.sensor.film())
        images, rendered = {name: [] for name in estimators}, []
        for seed in range(seeds):
            captured.clear()
            rendered.append(dopplertof.render(ours_scene, seed=seed).mean(-1) / WEIGHT)
            pixel, offset, value = (np.concatenate(part) for part in zip(*captured))
            for name, cells in estimators.items():
                images[name].append(weighed(splat, res, pixel, offset, value, cells))
        agree = np.abs(np.array(images["Mitsuba's ratio"]) - np.array(rendered)).max()
        print(f"{rfilter:9s} render {np.var(rendered, 0, ddof=1)[mask].mean() / stock_var:.3f} "
              f"(NumPy's ratio within {agree:.1e} of it)  " + "  ".join(
                  f"{name} {np.var(images[name], 0, ddof=1)[mask].mean() / stock_var:.3f}"
                  for name in estimators), flush=True)
    pipeline.Accumulator.add = add


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
    p.add_argument("--against", metavar="COMMIT",
                   help="with --timing: this tree's default film against COMMIT's sources")
    p.add_argument("--stock-samplers", action="store_true",
                   help="only stock `path` with each of Mitsuba's samplers, and our film")
    p.add_argument("--weights", action="store_true",
                   help="only the default film's samples weighed again by other estimators")
    args = p.parse_args(argv)

    import mitsuba as mi

    import dopplertof

    dopplertof.set_variant("llvm_ad_rgb")
    if args.timing and args.against:
        throughput_against(args.against, args.timing)
        return 0
    if args.timing:
        throughput(args.timing)
        return 0
    if args.depths:
        by_depth(args.res, args.spp, args.seeds, args.depths)
        return 0
    if args.stock_samplers:
        stock_samplers(args.res, args.spp, args.seeds)
        return 0
    if args.weights:
        filter_weights(args.res, args.spp, args.seeds)
        return 0
    worst = 0.0
    for rfilter in ("box", "tent", "gaussian"):
        stock_scene = mi.load_dict(scene({"type": "path", "max_depth": 6}, rfilter, args.res,
                                         args.spp))
        stock = stock_images(stock_scene, args.spp, args.seeds)
        reference = np.array(mi.render(stock_scene, spp=256 * args.spp, seed=10_000))
        mask = smooth_pixels(reference[..., :3].mean(-1))
        stock_var = stock.var(0, ddof=1)[mask].mean()
        row = [f"{rfilter:9s} ({mask.sum()} smooth pixels)"]
        for film, normalization, sets in FILMS:
            ours_scene = dopplertof.load_dict(scene(
                {"type": "dopplertof", "max_depth": 6, "w_g": 1e-6, "film_sampling": film,
                 "film_normalization": normalization, "pixel_sets": sets}, rfilter,
                args.res, args.spp))
            ours = our_images(ours_scene, args.seeds)
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
