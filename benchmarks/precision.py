"""Predicted against measured precision, by repetition, on three scenes.

For each scene and source of error (Monte Carlo over 32 seeds, sensor noise over 32
noise draws of one render, both together), the median over pixels of the predicted /
measured per-pixel standard deviation of velocity and depth
(dopplertof.tof.validation.repetition_check), with the medians of both, and
"v 1-cap": the median over pixels and repetitions of one capture's own predicted /
measured velocity std (below 1 where the errors are heavy-tailed):

* the moving plane (tests/analytic.py plane_scene, 4 m, 10 m/s, box filter);
* the demo Cornell box (global illumination, 4 bounces, box filter);
* the plane with the light 0.6 m beside the camera and a tent filter (splatting:
  neighbouring pixels share samples).

    .venv/bin/python benchmarks/precision.py            # 24x24 and 32x32, 64 spp, 8 batches
    .venv/bin/python benchmarks/precision.py --quick    # 8x8 and 16x16, 32 spp, 4 batches
"""

from __future__ import annotations

import argparse
import os
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "tests"))  # analytic.plane_scene


def scenes(res_plane: int, res_demo: int):
    import dopplertof
    from analytic import plane_scene
    from dopplertof.demo import demo_scene_path

    plane = plane_scene(4.0, 10.0, spp=64, res=res_plane)
    off = plane_scene(4.0, 10.0, spp=64, res=res_plane)
    off["light"]["position"] = [0.6, 0.0, 0.0]
    off["sensor"]["film"]["rfilter"] = {"type": "tent"}
    return [("moving plane", dopplertof.load_dict(plane)),
            ("demo Cornell box", dopplertof.load_file(demo_scene_path(), {"res": res_demo})),
            ("plane, light off camera, tent", dopplertof.load_dict(off))]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true")
    args = ap.parse_args(argv)
    import dopplertof
    from dopplertof.tof import NoiseModel
    from dopplertof.tof.validation import repetition_check

    dopplertof.set_variant(None)
    spp, batches = (32, 4) if args.quick else (64, 8)
    res_plane, res_demo = (8, 16) if args.quick else (24, 32)
    noise = NoiseModel(full_well=2e6, gain=500)  # so that MC and sensor both matter
    print(f"{spp} spp, {batches} batches, 32 repetitions; noise: 2e6 e- well, 500 e-/DN; "
          "ratio = median over pixels of predicted / measured std")
    print(f"{'scene':<32}{'source':<8}{'px':>6}{'v ratio':>9}{'v pred':>10}{'v meas':>10}"
          f"{'d ratio':>9}{'d pred':>10}{'d meas':>10}{'v 1-cap':>9}{'s':>7}")
    for name, scene in scenes(res_plane, res_demo):
        for source in ("mc", "sensor", "total"):
            started = time.perf_counter()
            c = repetition_check(scene, spp, batches, source,
                                 noise=None if source == "mc" else noise, progress=False)
            v, d = c["velocity"], c["depth"]
            print(f"{name:<32}{source:<8}{v['pixels']:>6}"
                  f"{v['predicted_over_measured_median']:>9.3f}"
                  f"{v['predicted_std_median']:>10.3g}{v['measured_std_median']:>10.3g}"
                  f"{d['predicted_over_measured_median']:>9.3f}"
                  f"{d['predicted_std_median']:>10.3g}{d['measured_std_median']:>10.3g}"
                  f"{v['single_capture_median']:>9.3f}{time.perf_counter() - started:>7.1f}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
