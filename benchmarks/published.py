"""dopplertof against the published implementation on its own scene and renders.

Renders the published XML (``../shared/fixtures/published/cornell_box_moving.xml``,
256x256, 1024 spp, max_depth 4, 30 MHz, one beat per exposure) with our naive
sampling, the scene's own settings, ``auto`` and ``auto`` + ``adaptive_sampling``, and
prints the RMSE of each time average against the published 16384-spp reference, beside
the RMSE of the published renders computed from the fixture files (see the fixtures'
README: a Mitsuba 0.6 ``.npy`` holds 1 + T * value, T = 0.0015 s), and the ratios.

    .venv/bin/python benchmarks/published.py [--seeds 1 2 3] [--importance]
        [--pixel-sets independent joint] [--reference NPY] [--fixtures DIR]

``--importance`` adds the same rows with ``film_sampling="importance"`` (each sample in
one pixel); every row is rendered with each ``--pixel-sets`` (default both, side by
side); ``--reference`` adds the RMSE against a deeper reference
(benchmarks/reference.py); ``--equal-time 256 1024 ...`` renders only `auto` + adaptive
at those spp (the first ``--pixel-sets``) and prints RMSE, wall and CPU seconds. The last line reads
`RMSE against the published reference (auto + adaptive / published best): X`
(X < 1: ours is closer to the reference at the same spp).
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time

import numpy as np

PIXEL_SETS = ("independent", "joint")  #: (pixel_sets.PIXEL_SETS, in the order rendered)
HERE = os.path.dirname(os.path.abspath(__file__))
FIXTURES = os.path.normpath(os.path.join(HERE, "..", "..", "shared", "fixtures", "published"))
EXPOSURE = 0.0015

#: our rows: name, render parameters, the published render it is set beside
CONFIGURATIONS = (
    ("naive (uniform time, independent paths, no stratification)",
     {"time_sampling_method": "uniform", "path_correlation_depth": 0,
      "use_stratified_sampling_for_each_interval": False}, "m06 uniform"),
    ("the scene's own settings (antithetic, correlation depth 4)", {}, "Mitsuba 3 EXR"),
    ("auto", {"time_sampling_method": "auto"}, "best"),
    ("auto + adaptive_sampling", {"time_sampling_method": "auto", "adaptive_sampling": True},
     "best"),
)


def published_renders(fixtures: str) -> dict:
    """The published renders' time averages (256, 256, 3), by name."""
    import mitsuba as mi

    def m06(name):
        return (np.load(os.path.join(fixtures, "m06", name)) - 1.0) / EXPOSURE

    exr = np.array(mi.Bitmap(os.path.join(fixtures, "cornell_box_moving_1024spp.exr")),
                   dtype=np.float64)[..., :3]
    return {"reference": m06("reference_spp_16384.npy"), "m06 uniform": m06("uniform.npy"),
            "m06 antithetic + path correlation": m06("antithetic_path_corr_direction.npy"),
            "Mitsuba 3 EXR": exr}


def rmse(image, reference) -> float:
    return float(np.sqrt(np.mean((np.asarray(image, np.float64) - reference) ** 2)))


def our_row(dopplertof, scene, args, label, reference, own, theirs, beside, params):
    """Render one row at every seed, print it; returns its mean RMSE."""
    started = time.perf_counter()
    images = [dopplertof.render(scene, spp=args.spp, seed=seed, params=params)
              for seed in args.seeds]
    values = [rmse(image, reference) for image in images]
    value = statistics.mean(values)
    spread = f" (seeds {min(values):.3e}-{max(values):.3e})" if len(values) > 1 else ""
    against_own = ("" if own is None else "   against ours "
                   f"{statistics.mean(rmse(i, own) for i in images):.3e}")
    print(f"  {label:72s} {value:.3e}{spread}   / {beside} {value / theirs:.3f}   "
          f"{(time.perf_counter() - started) / len(values):.1f} s{against_own}", flush=True)
    return value


def equal_time(dopplertof, scene, reference, spps, pixel_sets: str) -> None:
    """RMSE of `auto` + adaptive at each spp with its wall and CPU seconds (one seed,
    after a warm-up render: kernels compiled), for the equal-time view."""
    params = {"time_sampling_method": "auto", "adaptive_sampling": True,
              "pixel_sets": pixel_sets}
    dopplertof.render(scene, spp=min(spps), seed=99, params=params)  # warm-up
    print(f"auto + adaptive_sampling, pixel_sets={pixel_sets}: spp, RMSE, wall s, CPU s")
    for spp in spps:
        wall, cpu = time.perf_counter(), time.process_time()
        image = dopplertof.render(scene, spp=spp, seed=1, params=params)
        wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
        print(f"  {spp:6d} {rmse(image, reference):.3e} {wall:8.1f} {cpu:8.1f}", flush=True)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--fixtures", default=FIXTURES)
    p.add_argument("--seeds", type=int, nargs="+", default=[1])
    p.add_argument("--spp", type=int, default=1024)
    p.add_argument("--importance", action="store_true",
                   help="also render every row with the importance film")
    p.add_argument("--pixel-sets", nargs="+", default=list(PIXEL_SETS),
                   choices=PIXEL_SETS, help="pixel_sets to render every row with, side by side")
    p.add_argument("--equal-time", type=int, nargs="+", metavar="SPP",
                   help="only `auto` + adaptive at these spp: RMSE, wall and CPU seconds")
    p.add_argument("--reference", metavar="NPY",
                   help="also the RMSE against this reference (benchmarks/reference.py)")
    args = p.parse_args(argv)
    if not os.path.isdir(args.fixtures):
        print(f"error: the published fixtures are not at {args.fixtures} (--fixtures DIR)",
              file=sys.stderr)
        return 2

    import dopplertof

    dopplertof.set_variant("llvm_ad_rgb")
    renders = published_renders(args.fixtures)
    reference = renders.pop("reference")
    theirs = {name: rmse(img, reference) for name, img in renders.items()}
    theirs["best"] = min(theirs.values())
    print(f"published renders against the published reference ({args.spp} spp):")
    for name, value in theirs.items():
        if name != "best":
            print(f"  {name:36s} {value:.3e}")
    scene = dopplertof.load_file(os.path.join(args.fixtures, "cornell_box_moving.xml"))
    if args.equal_time:
        equal_time(dopplertof, scene, reference, args.equal_time, args.pixel_sets[0])
        return 0
    films = ("splat", "importance") if args.importance else ("splat",)
    print(f"dopplertof, {scene.sensor.film().crop_size()[0]}x"
          f"{scene.sensor.film().crop_size()[1]}, {args.spp} spp, seeds {args.seeds} "
          "(RMSE: mean over seeds; ratio: ours over the published render beside it):")
    own = np.load(args.reference) if args.reference else None
    ours = {}
    for film in films:
        for sets in args.pixel_sets:
            for name, params, beside in CONFIGURATIONS:
                ours[film, sets, name] = our_row(
                    dopplertof, scene, args, f"[{film}, {sets}] {name}", reference, own,
                    theirs[beside], beside, {**params, "film_sampling": film,
                                             "pixel_sets": sets})
    sets = dopplertof.RenderParams().pixel_sets  # the default
    if sets not in args.pixel_sets:
        return 0
    best = ours["splat", sets, "auto + adaptive_sampling"] / theirs["best"]
    scene_settings = ours["splat", sets, CONFIGURATIONS[1][0]] / theirs["Mitsuba 3 EXR"]
    print(f"RMSE against the published reference (scene's settings / published Mitsuba 3 "
          f"render): {scene_settings:.3f}")
    print(f"RMSE against the published reference (auto + adaptive / published best): "
          f"{best:.3f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
