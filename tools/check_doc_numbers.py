"""Re-measure the numbers the docs quote and flag a drift over 10% (issue 42, 2026-12-03).

Each entry of REGISTRY is one quoted figure: the doc that quotes it, the text around it
(checked to be still in the doc: a doc that changed its figure changes the registry),
the quoted value, the command beside it in the doc, and how the measured value is read
from the command's result. A command is either a `dopplertof` command line (run in-process
in a scratch folder; its result the summary.json it wrote in ``{out}``, or ``{out}.json``
beside a figure ``{out}.png``) or a :class:`Call`, a Python function that the script the
doc names runs (its result the function's return value). Entries sharing a command run it
once. Prints quoted, measured and drift per figure and exits 1 when any drift is over the
tolerance (or a quote is gone from its doc).

    PYTHONPATH=src .venv/bin/python tools/check_doc_numbers.py              # the cheap ones
    PYTHONPATH=src .venv/bin/python tools/check_doc_numbers.py --all        # the demo too
    PYTHONPATH=src .venv/bin/python tools/check_doc_numbers.py --only sphere-ball-median

NOT_REMEASURED lists the quoted figures this script does not re-measure, and why.
"""

from __future__ import annotations

import argparse
import contextlib
import importlib
import io
import json
import os
import sys
import tempfile
from typing import NamedTuple

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
TOLERANCE = 0.10

SPHERE = "capture examples/translating_sphere.xml -o {out}"
SPHERE_MIXED = "capture examples/translating_sphere.xml -o {out} --keep-mixed-pixels"
TUMBLE = ("capture examples/user_meshes.xml -D res=64 -D max_depth=2 -D spin_x=1 "
          "-D spin_y=0 -o {out}")
DEMO = "demo -o {out}"
DEMO_MIXED = "capture src/dopplertof/data/cornell_demo.xml --spp 512 --keep-mixed-pixels -o {out}"
STREET = "fmcw examples/fmcw_street.xml -o {out} -D res=96"
DIRECT = "capture src/dopplertof/data/cornell_demo.xml -D max_depth=2 -o {out}"
SPHERE_DIRECT = SPHERE + " -P max_depth=2"
SPHERE_CAMERA = ("capture examples/translating_sphere.xml --camera paper-dtof --res 24x24 "
                 "--spp 16 -D max_depth=2 --noiseless -o {out}")
SPHERE_CAMERA_MIXED = SPHERE_CAMERA + " --keep-mixed-pixels"
COMPARE = ("cameras --compare examples/cameras_moving.xml --with kinect-v2,azure-kinect,"
           "opt8241,mlx75027,pmd-argos3d-p320,paper-dtof --res 64x48 --spp 16 -o {out}.png")
COMPARE_NOISELESS = COMPARE + " --noiseless"


class Call(NamedTuple):
    """A Python function the command ``named`` in the doc beside the figure runs:
    ``function`` ("module:name") called with ``args`` and ``kwargs`` ((key, value) pairs)."""
    function: str
    args: tuple = ()
    kwargs: tuple = ()
    named: str = ""

    def __str__(self):
        arguments = [repr(a) for a in self.args] + [f"{k}={v!r}" for k, v in self.kwargs]
        return f"{self.function}({', '.join(arguments)}) ({self.named})"


def wall(preset: str, distance: float, albedo: float, angle_deg: float = 0.0) -> Call:
    """benchmarks/camera_accuracy.py's measure of one wall (turned by ``angle_deg``)."""
    turned = (("angle_deg", angle_deg),) if angle_deg else ()
    return Call("dopplertof.cameras.accuracy:wall_accuracy", (preset, distance, albedo),
                (("seeds", 32),) + turned, "benchmarks/camera_accuracy.py")


def at(*keys, scale: float = 1.0):
    """Reads the result's value at ``keys``: a str a mapping's key or an attribute, a
    (field, value) pair the element of a list whose field has that value; times ``scale``."""
    def read(result):
        for key in keys:
            if isinstance(key, tuple):
                result = next(e for e in result if e[key[0]] == key[1])
            elif isinstance(result, dict):
                result = result[key]
            else:
                result = getattr(result, key)
        return result * scale
    return read


def body(name: str, key: str):
    """Reads summary.json's bodies[name].velocity_error_m_s[key] (or a body field)."""
    def read(summary):
        entry = next(b for b in summary["bodies"] if b["name"] == name)
        return entry["velocity_error_m_s"].get(key, entry.get(key))
    return read


def error(quantity: str, key: str, scale: float = 1.0):
    """Reads summary.json's errors[quantity][key] (over the whole image) times ``scale``."""
    return at("errors", quantity, key, scale=scale)


def static(key: str):
    return lambda summary: summary["static_surfaces"]["velocity_error_m_s"][key]


#: (name, doc, text around the figure in the doc, quoted value, command, reader, cheap)
REGISTRY = [
    ("sphere-ball-median", "docs/camera.md", "median of 0.228 m/s", 0.228, SPHERE,
     body("ball", "median_abs"), True),
    ("sphere-ball-p95", "docs/camera.md", "95th percentile of 5.81 m/s", 5.81, SPHERE,
     body("ball", "p95_abs"), True),
    ("sphere-ball-mean", "docs/camera.md", "mean of\n-0.893 m/s", -0.893, SPHERE,
     body("ball", "mean_signed"), True),
    ("sphere-ball-pixels", "docs/camera.md", "ball's 656 of", 656, SPHERE,
     body("ball", "pixels"), True),
    ("sphere-ball-p95-mixed", "docs/camera.md", "0.294, 21.2 and -2.41", 21.2, SPHERE_MIXED,
     body("ball", "p95_abs"), True),
    ("sphere-ball-mean-mixed", "docs/camera.md", "0.294, 21.2 and -2.41", -2.41, SPHERE_MIXED,
     body("ball", "mean_signed"), True),
    ("tumble-torus-median", "docs/camera.md", "reads a median error of 3.42 m/s", 3.42,
     TUMBLE, body("torus", "median_abs"), True),
    ("tumble-torus-median-30mhz", "docs/camera.md", "(`-P w_g=30`) 2.24 m/s", 2.24,
     TUMBLE + " -P w_g=30", body("torus", "median_abs"), True),
    ("tumble-torus-median-mixed", "docs/camera.md", "`--keep-mixed-pixels` 6.04 over 381",
     6.04, TUMBLE + " --keep-mixed-pixels", body("torus", "median_abs"), True),
    ("tumble-torus-pixels", "docs/camera.md", "over the torus's 231 pixels kept", 231, TUMBLE,
     body("torus", "pixels"), True),
    ("tumble-torus-mean", "docs/camera.md", "(mean -3.6, 95th percentile\n10.8;", -3.6, TUMBLE,
     body("torus", "mean_signed"), True),
    ("tumble-torus-p95", "docs/camera.md", "(mean -3.6, 95th percentile\n10.8;", 10.8, TUMBLE,
     body("torus", "p95_abs"), True),
    ("tumble-torus-pixels-mixed", "docs/camera.md", "`--keep-mixed-pixels` 6.04 over 381", 381,
     TUMBLE + " --keep-mixed-pixels", body("torus", "pixels"), True),
    # docs/reliability.md's row on mixed footprints quotes the starter sphere's ball
    ("reliability-ball-p95", "docs/reliability.md", "the ball's 95th-percentile error 5.81 m/s",
     5.81, SPHERE, body("ball", "p95_abs"), True),
    ("reliability-ball-mean", "docs/reliability.md", "and mean -0.893 m/s, not 21.2 and -2.41",
     -0.893, SPHERE, body("ball", "mean_signed"), True),
    ("reliability-ball-p95-mixed", "docs/reliability.md", "not 21.2 and -2.41", 21.2,
     SPHERE_MIXED, body("ball", "p95_abs"), True),
    ("reliability-ball-mean-mixed", "docs/reliability.md", "not 21.2 and -2.41", -2.41,
     SPHERE_MIXED, body("ball", "mean_signed"), True),
    ("demo-short-box-median", "README.md", "median errors 0.689 m/s", 0.689, DEMO,
     body("short_box", "median_abs"), False),
    ("demo-tall-box-median", "README.md", "1.22 m/s on the tall one", 1.22, DEMO,
     body("tall_box", "median_abs"), False),
    ("demo-short-box-p95", "README.md", "95th percentiles 6.08 and 5.35", 6.08, DEMO,
     body("short_box", "p95_abs"), False),
    ("demo-tall-box-p95", "README.md", "95th percentiles 6.08 and 5.35", 5.35, DEMO,
     body("tall_box", "p95_abs"), False),
    ("demo-static-p95", "README.md", "95th-percentile error of 18.7 m/s", 18.7, DEMO,
     static("p95_abs"), False),
    ("demo-pixels-mixed", "README.md", "are NaN (355 pixels", 355, DEMO,
     at("velocity", "mixed_footprints"), False),
    # docs/camera.md's copy of the demo's printout, and the demo's frame with its silhouettes
    ("demo-image-median", "docs/camera.md", "velocity error: median 1.14 m/s, 95th percentile "
     "17.1 m/s over 16029 pixels", 1.14, DEMO, error("velocity_m_s", "median_abs"), False),
    ("demo-image-p95", "docs/camera.md", "velocity error: median 1.14 m/s, 95th percentile "
     "17.1 m/s over 16029 pixels", 17.1, DEMO, error("velocity_m_s", "p95_abs"), False),
    ("demo-image-pixels", "docs/camera.md", "17.1 m/s over 16029 pixels", 16029, DEMO,
     error("velocity_m_s", "pixels"), False),
    ("demo-depth-median", "docs/camera.md", "depth error: median 0.0563 m, 95th percentile "
     "0.476 m", 0.0563, DEMO, error("depth_m", "median_abs"), False),
    ("demo-depth-p95", "docs/camera.md", "depth error: median 0.0563 m, 95th percentile "
     "0.476 m", 0.476, DEMO, error("depth_m", "p95_abs"), False),
    ("demo-short-box-mean", "docs/camera.md", "mean -0.278 m/s over 1509 of 1639", -0.278, DEMO,
     body("short_box", "mean_signed"), False),
    ("demo-tall-box-mean", "docs/camera.md", "mean +0.305 m/s over 2282 of 2391", 0.305, DEMO,
     body("tall_box", "mean_signed"), False),
    ("demo-static-median", "docs/camera.md", "static surfaces: velocity error median 1.26 m/s",
     1.26, DEMO, static("median_abs"), False),
    ("demo-short-box-p95-mixed", "docs/camera.md", "short box's 95th percentile is\n15.9 m/s",
     15.9, DEMO_MIXED, body("short_box", "p95_abs"), False),
    ("demo-short-box-p95-camera", "docs/camera.md", "15.9 m/s (its silhouettes), 6.08 without",
     6.08, DEMO, body("short_box", "p95_abs"), False),
    # docs/fmcw.md section 5: the street example at 96x96 (issue 43)
    ("street-car-velocity", "docs/fmcw.md", "the car reads -9.79 m/s", -9.79, STREET,
     at("regions", ("name", "car"), "velocity_gt_median_m_s"), True),
    ("street-car-median", "docs/fmcw.md", "median error of 0.00017 m/s", 0.00017, STREET,
     at("regions", ("name", "car"), "velocity_m_s", "median_abs"), True),
    ("street-car-p95", "docs/fmcw.md", "percentile 1.2 m/s: its silhouette", 1.2, STREET,
     at("regions", ("name", "car"), "velocity_m_s", "p95_abs"), True),
    ("street-pedestrian-velocity", "docs/fmcw.md", "(-0.26 m/s median)", -0.26, STREET,
     at("regions", ("name", "pedestrian"), "velocity_gt_median_m_s"), True),
    ("street-pedestrian-median", "docs/fmcw.md", "median) within 0.0002 m/s", 0.0002,
     STREET, at("regions", ("name", "pedestrian"), "velocity_m_s", "median_abs"), True),
    ("street-range-median", "docs/fmcw.md", "range within 5.7 cm", 5.7, STREET,
     at("errors", "range_m", "median_abs", scale=100), True),
    ("street-range-p95", "docs/fmcw.md", "but 4.2 m at the 95th percentile", 4.2, STREET,
     at("errors", "range_m", "p95_abs"), True),
]


#: the demo scene with direct light only (README.md, docs/camera.md), the starter sphere with
#: direct light and through paper-dtof (docs/camera.md; issue 42, 2026-12-04)
REGISTRY += [
    ("direct-static-median", "README.md", "static pixels' median error is 9e-5 m/s", 9e-5,
     DIRECT, static("median_abs"), True),
    ("direct-short-box-median", "README.md", "the boxes' 0.08 m/s", 0.08, DIRECT,
     body("short_box", "median_abs"), True),
    ("direct-tall-box-median", "README.md", "the boxes' 0.08 m/s", 0.08, DIRECT,
     body("tall_box", "median_abs"), True),
    ("direct-short-box-p95", "README.md", "(95th percentiles 0.29 and\n0.24 m/s", 0.29,
     DIRECT, body("short_box", "p95_abs"), True),
    ("direct-tall-box-p95", "README.md", "(95th percentiles 0.29 and\n0.24 m/s", 0.24, DIRECT,
     body("tall_box", "p95_abs"), True),
    ("direct-image-median", "docs/camera.md", "median velocity error of 1.3e-4 m/s over the "
     "image", 1.3e-4, DIRECT, error("velocity_m_s", "median_abs"), True),
    ("direct-static-median-camera", "docs/camera.md", "(static pixels, most of it: 9e-5)", 9e-5,
     DIRECT, static("median_abs"), True),
    ("direct-short-box-median-camera", "docs/camera.md", "(0.079 short, 0.077 tall", 0.079,
     DIRECT, body("short_box", "median_abs"), True),
    ("direct-tall-box-median-camera", "docs/camera.md", "(0.079 short, 0.077 tall", 0.077,
     DIRECT, body("tall_box", "median_abs"), True),
    ("direct-short-box-p95-camera", "docs/camera.md", "95th percentiles 0.29 and 0.24 m/s), and",
     0.29, DIRECT, body("short_box", "p95_abs"), True),
    ("direct-tall-box-p95-camera", "docs/camera.md", "95th percentiles 0.29 and 0.24 m/s), and",
     0.24, DIRECT, body("tall_box", "p95_abs"), True),
    ("direct-depth-median", "docs/camera.md", "depth error of 0.03 mm", 0.03, DIRECT,
     error("depth_m", "median_abs", 1e3), True),
    ("sphere-direct-ball-mean", "docs/camera.md", "kept pixels' mean is +0.0356 m/s", 0.0356,
     SPHERE_DIRECT, body("ball", "mean_signed"), True),
    ("sphere-direct-ball-p95", "docs/camera.md", "95th percentile 0.3)", 0.3, SPHERE_DIRECT,
     body("ball", "p95_abs"), True),
    ("sphere-paper-dtof-mixed", "docs/camera.md", "24x24: 36 pixels", 36, SPHERE_CAMERA,
     at("mixed_footprints"), True),
    ("sphere-paper-dtof-mean-mixed", "docs/camera.md", "the mean velocity error -0.55 m/s with "
     "them", -0.55, SPHERE_CAMERA_MIXED, error("velocity_m_s", "mean_signed"), True),
    ("sphere-paper-dtof-mean", "docs/camera.md", "-0.55 m/s with them, -0.025", -0.025,
     SPHERE_CAMERA, error("velocity_m_s", "mean_signed"), True),
    # README.md's Azure Kinect summary: the far ends of benchmarks/camera_accuracy.py's table
    ("readme-azure-kinect-random", "README.md", "(17.8 mm at the NFOV far end", 17.8,
     wall("azure-kinect", 3.86, 0.15), at("random_m", scale=1e3), True),
    ("readme-azure-kinect-nfov-binned-random", "README.md", "12.4 mm binned at 5.46 m", 12.4,
     wall("azure-kinect-nfov-binned", 5.46, 0.15), at("random_m", scale=1e3), True),
    ("readme-azure-kinect-wfov-unbinned-random", "README.md", "20.0 mm WFOV unbinned at 2.21 m",
     20.0, wall("azure-kinect-wfov-unbinned", 2.21, 0.15), at("random_m", scale=1e3), True),
]


def wiggling_entries() -> list:
    """docs/cameras.md's noise-free wiggling errors (``cameras NAME --wiggling FIG.png``)."""
    quoted = (("kinect-v2", "kinect-v2 4.6 mm / 6e-5 mm", 4.6),
              ("azure-kinect", "azure-kinect\n2.6 mm", 2.6),
              ("opt8241", "opt8241 31 mm", 31), ("mlx75027", "mlx75027 18 mm", 18),
              ("pmd-argos3d-p320", "pmd-argos3d-p320 85 mm", 85))
    entries = [(f"wiggling-{name}", "docs/cameras.md", text, value,
                f"cameras {name} --wiggling {{out}}.png",
                at("max_abs_error_uncalibrated_m", scale=1e3), True)
               for name, text, value in quoted]
    return entries + [("wiggling-kinect-v2-calibrated", "docs/cameras.md", quoted[0][1], 6e-5,
                       "cameras kinect-v2 --wiggling {out}.png",
                       at("max_abs_error_reported_m", scale=1e3), True)]


#: docs/cameras.md's compare table (noiseless) and the noisy medians after it: (camera, its
#: row, median mm, 95th percentile mm, pixels failing to unwrap)
COMPARED = (
    ("kinect-v2", "| kinect-v2 | 13 ms | 0.67 mm | 2.66 mm | 525 px |", 0.67, 2.66, 525),
    ("azure-kinect", "| azure-kinect | 12.8 ms | 0.56 mm | 1.88 mm | 461 px |", 0.56, 1.88, 461),
    ("opt8241", "| opt8241 | 8.7 ms | 0.75 mm | 5.1 mm | 17 px |", 0.75, 5.1, 17),
    ("mlx75027", "| mlx75027 | 1.95 ms | 0.57 mm | 1.6 mm | 59 px |", 0.57, 1.6, 59),
    ("pmd-argos3d-p320", "| pmd-argos3d-p320 | 4.3 ms | 1.98 mm | 5.5 mm | 0 |", 1.98, 5.5, 0),
    ("paper-dtof", "| paper-dtof | 1.5 ms (parallel) | 0.45 mm | 1.49 mm | 0;", 0.45, 1.49, 0))
NOISY = (("mlx75027", "3.8 mm (mlx75027)", 3.8), ("azure-kinect", "azure-kinect 8.0 mm", 8.0),
         ("pmd-argos3d-p320", "to 29 mm (pmd-argos3d-p320", 29))


def compare_entries() -> list:
    """docs/cameras.md's one moving scene through every camera (``cameras --compare``)."""
    entries = []
    for camera, row, median, p95, failed in COMPARED:
        depth = ("cameras", ("camera", camera), "errors", "depth_m")
        entries += [
            (f"compare-{camera}-median", "docs/cameras.md", row, median, COMPARE_NOISELESS,
             at(*depth, "median_abs", scale=1e3), True),
            (f"compare-{camera}-p95", "docs/cameras.md", row, p95, COMPARE_NOISELESS,
             at(*depth, "p95_abs", scale=1e3), True),
            (f"compare-{camera}-unwrap", "docs/cameras.md", row, failed, COMPARE_NOISELESS,
             at("cameras", ("camera", camera), "masked_by", "unwrapping failed"), True)]
    velocity = ("cameras", ("camera", "paper-dtof"), "errors", "velocity_m_s")
    entries.append(("compare-paper-dtof-velocity-p95", "docs/cameras.md",
                    "velocity median 0, 95th percentile 2.4 m/s", 2.4, COMPARE_NOISELESS,
                    at(*velocity, "p95_abs"), True))
    entries += [(f"compare-noisy-{camera}-median", "docs/cameras.md", text, value, COMPARE,
                 at("cameras", ("camera", camera), "errors", "depth_m", "median_abs",
                    scale=1e3), True) for camera, text, value in NOISY]
    return entries + [("compare-noisy-paper-dtof-velocity", "docs/cameras.md",
                       "(70 m/s median", 70, COMPARE, at(*velocity, "median_abs"), True)]


#: the far end of each Azure mode in the calibration table (issue 38): (preset, far end m,
#: docs/cameras.md's row, its random error mm and reported %, docs/benchmarks.md's row, its
#: random error at albedo 0.15, 0.5, 0.95 mm, systematic at 0.15 mm and reported at 0.15 %)
CALIBRATION = (
    ("azure-kinect", 3.86, "| azure-kinect | 3.86 m | 17.8 mm (fitted) | 17 mm | 3.9 mm | 99.2% |",
     17.8, 99.2, "**3.86 m** (far end) | **17.82** (fitted) | 8.22 | 5.69 | 17 | 3.86 | 0.50 | "
     "< 14.9 | 99.2% |", (17.82, 8.22, 5.69), 0.50, 99.2),
    ("azure-kinect-nfov-binned", 5.46, "| azure-kinect-nfov-binned | 5.46 m | 12.4 mm "
     "(predicted) | 17 mm | 5.5 mm | 100% |", 12.4, 100, "**5.46 m** (far end) | **12.38** "
     "(predicted: -27%) | 6.42 | 4.57 | 17 | 5.46 | 0.43 | < 16.5 | 100% |",
     (12.38, 6.42, 4.57), 0.43, 100),
    ("azure-kinect-wfov-binned", 2.88, "| azure-kinect-wfov-binned | 2.88 m | 17.6 mm (fitted) "
     "| 17 mm | 2.9 mm | 99.5% |", 17.6, 99.5, "**2.88 m** (far end) | **17.63** (fitted) | "
     "8.59 | 6.21 | 17 | 2.88 | 0.23 | < 13.9 | 99.5% |", (17.63, 8.59, 6.21), 0.23, 99.5),
    ("azure-kinect-wfov-unbinned", 2.21, "| azure-kinect-wfov-unbinned | 2.21 m | 20.0 mm "
     "(predicted: +18%) | 17 mm | 2.2 mm | 98.4% |", 20.0, 98.4, "**2.21 m** (far end) | "
     "**19.99** (predicted: +18%) | 10.06 | 7.00 | 17 | 2.21 | 0.58 | < 13.2 | 98.4% |",
     (19.99, 10.06, 7.00), 0.58, 98.4))


def calibration_entries() -> list:
    """docs/cameras.md's and docs/benchmarks.md's far-end rows of the calibration table."""
    random, reported = at("random_m", scale=1e3), at("valid", scale=100)
    entries = []
    for preset, far, row, random_mm, percent, bench, randoms, systematic, bench_percent \
            in CALIBRATION:
        entries += [(f"{preset}-random", "docs/cameras.md", row, random_mm,
                     wall(preset, far, 0.15), random, True),
                    (f"{preset}-reported", "docs/cameras.md", row, percent,
                     wall(preset, far, 0.15), reported, True)]
        entries += [(f"{preset}-random-{albedo:g}", "docs/benchmarks.md", bench, value,
                     wall(preset, far, albedo), random, True)
                    for albedo, value in zip((0.15, 0.5, 0.95), randoms)]
        entries += [(f"{preset}-systematic", "docs/benchmarks.md", bench, systematic,
                     wall(preset, far, 0.15), at("systematic_m", scale=1e3), True),
                    (f"{preset}-reported-0.15", "docs/benchmarks.md", bench, bench_percent,
                     wall(preset, far, 0.15), reported, True)]
    return entries


#: kinect-v2 on Fankhauser et al.'s walls (albedo 0.9): (distance m, angle deg, the row's
#: start in docs/cameras.md and in docs/benchmarks.md, simulated mm, reported %)
FANKHAUSER = (
    (1.0, 0.0, "| 1 m, head-on | 1.18 mm | 1.30 mm | 0.91 | 100% |",
     "| 1 m, head-on | 1.18 mm | 1.30 mm | 0.906 | 100% |", 1.18, 100),
    (2.0, 0.0, "| 2 m, head-on | 1.63 mm | 1.70 mm | 0.96 | 100% |",
     "| 2 m, head-on | 1.63 mm | 1.70 mm | 0.961 | 100% |", 1.63, 100),
    (3.0, 0.0, "| 3 m, head-on | 2.82 mm | 2.70 mm | 1.04 | 100% |",
     "| 3 m, head-on | 2.82 mm | 2.70 mm | 1.044 | 100% |", 2.82, 100),
    (4.0, 0.0, "| 4 m, head-on | 4.27 mm | 4.30 mm | 0.99 | 100% |",
     "| 4 m, head-on | 4.27 mm | 4.30 mm | 0.993 | 100% |", 4.27, 100),
    (2.0, 60.0, "| 2 m, turned 60 deg | 2.50 mm | 2.83 mm | 0.88 | 100% |",
     "| 2 m, turned 60 deg | 2.50 mm | 2.83 mm | 0.882 | 100% |", 2.50, 100))


def fankhauser_entries() -> list:
    """kinect-v2's table against Fankhauser et al. 2015, in both docs."""
    entries = []
    for distance, angle, row, bench, random_mm, percent in FANKHAUSER:
        call = wall("kinect-v2", distance, 0.9, angle)
        name = f"kinect-v2-{distance:g}m-{angle:g}deg"
        for doc, text in (("docs/cameras.md", row), ("docs/benchmarks.md", bench)):
            entries += [(f"{name}-random-{doc[5:-3]}", doc, text, random_mm, call,
                         at("random_m", scale=1e3), True),
                        (f"{name}-reported-{doc[5:-3]}", doc, text, percent, call,
                         at("valid", scale=100), True)]
    return entries


REGISTRY += (wiggling_entries() + compare_entries() + calibration_entries()
             + fankhauser_entries())

#: quoted figures not re-measured here, and why
NOT_REMEASURED = [
    ("README.md, docs/camera.md", "the demo's 18.8 s wall and 24.6 s of CPU time",
     "times depend on the machine and its load; benchmarks/ measures times"),
    ("docs/camera.md", "the rotating cube's waveform table (64x64, 512 spp, 3 waveforms x 2 "
     "calibrations)", "six captures of a few minutes on 2 shared cores"),
    ("docs/camera.md", "the spinning plane's -0.075 m/s and its variants",
     "tests/test_spinning_bias.py asserts them against the closed form"),
    ("docs/camera.md", "the spinning torus's table (benchmarks/spinning_torus.py)",
     "two minutes at 1600 spp; tests/test_spinning_torus.py asserts its conclusions; its "
     "headline 3.42 / 2.24 / 6.04 m/s are re-measured above"),
    ("docs/differentiable.md", "the fits' velocities, uncertainties and times",
     "each fit takes minutes (the demo's at 128x128: about 2 on an idle machine); "
     "tests/test_fit.py asserts their accuracy statistically"),
    ("docs/benchmarks.md", "every benchmark's times and variances",
     "the benchmark scripts beside each table re-measure them; times are the machine's"),
    ("docs/benchmarks.md", "the calibration table's rows short of each mode's far end, and "
     "the fitted powers (43.7 W, 20.4 W)", "the same command (`benchmarks/camera_accuracy.py "
     "--seeds 32`, about 25 s; `--calibrate`, 14 bisection steps a power) re-measures them; "
     "the far-end rows above (the fitted 17 mm among them) stand for them"),
    ("docs/cameras.md", "the calibration summary's bounds (systematic < 0.2 / 0.3 / 1 mm over "
     "1-3 m) and ratios (3.1x between 15% and 95%)", "a bound or a ratio of two rows, not "
     "one command's value; the rows they come from are re-measured above"),
    ("docs/cameras.md", "95 and 1410 photo-electrons per raw frame (15% wall, 3.86 m and 1 m)",
     "no command beside them (summary.json's noise.radiometry of the accuracy wall); "
     "tests/test_camera_radiometry.py asserts the camera equation in closed form"),
    ("docs/cameras.md", "the unwrapping's 99.997% / 70% / 1 in 10^5 and 5.9%, and the earlier "
     "search's 49% and 50% (this search: 99%, 98.8%, 4.4 mm)", "tests/"
     "test_camera_radiometry.py asserts the first; no command beside the comparison"),
    ("docs/cameras.md", "Kinect v2's f^2 weights (0.68, 0.30), its 2.9 ms and 3 cm, the "
     "sequences' lengths (13 ms ...), pmd's calibrated wiggling below 5e-4 mm",
     "arithmetic of the presets' numbers, or a bound; no command beside them"),
    ("docs/cameras.md, docs/benchmarks.md", "kinect-v2's fitted 10.04 W and 43120 e-, and "
     "its sensitivity table (ratios to Fankhauser's curve with one inferred choice changed)",
     "`benchmarks/camera_accuracy.py --presets kinect-v2 --calibrate` and `--sensitivity` "
     "beside them print them (2 s and 9 s); the Monte Carlo rows above stand for the fit"),
    ("docs/cameras.md", "within 1 mm, within 1.5 mm, 48 noise seeds within 10%",
     "the tests named beside them assert them"),
    ("docs/fmcw.md", "the street's 1.9 s and the cost section (1.18x, 0.222 s, ...)",
     "times depend on the machine and its load; benchmarks/fmcw_cost.py measures them"),
    ("docs/fmcw.md", "the defaults' 38 m, 15 cm, 3.9 cm/s; 12.9 MHz, 2.7 MHz per metre, "
     "0.6 mm, 134 MB", "arithmetic of the chirp, no command beside them"),
    ("docs/fmcw.md", "section 8's measured values (0.01 bin, 2.74, 0.02%, 0.991, t = -1.2, "
     "1.11 and 0.96) and the spot connection's 30x", "tests/test_fmcw.py asserts them (the "
     "30x was the rejected connection's, no longer in the code)"),
    ("docs/dataset.md", "346 m/s on a cube face of sample 0, its objects' 9.4 m/s",
     "no command beside it (a reader of examples/dataset.toml's HDF5 output would be needed); "
     "not yet in the registry"),
    ("docs/dataset.md", "the preview's and check's 1.0-1.8 s, an export's 45 s a sample",
     "times depend on the machine and its load"),
    ("docs/reliability.md", "its figures but the mixed footprints' row (re-measured above)",
     "the campaign's rows quote error messages and the states of 179 reruns, which the tests "
     "each row names assert, not measured values"),
    ("README.md", "`make test`'s 16-18 minutes (and `make quick`'s)", "times of the whole "
     "suite, measured by running it (docs/testing.md's table: 18 min 5 s on 2026-12-03)"),
    ("docs/camera.md", "the sphere through paper-dtof: its silhouettes 'up to 247 m/s off'",
     "a maximum over velocity.npy, which summary.json does not hold (its 36 pixels and the "
     "means with and without them are re-measured above)"),
    ("docs/differentiable.md", "the plain and cross losses' minima over the sphere's velocity",
     "benchmarks/loss_minimum.py beside them prints them (45 s at its defaults)"),
]


def run_command(command: str, scratch: str):
    """Runs ``dopplertof COMMAND`` (``{out}`` a path in ``scratch``) from the repository
    root, its output swallowed: the summary.json it wrote in ``{out}``, or ``{out}.json``
    (beside a figure ``{out}.png``)."""
    from dopplertof.cli import main

    out = os.path.join(scratch, f"run{len(os.listdir(scratch))}")
    argv = command.format(out=out).split()
    here = os.getcwd()
    try:
        os.chdir(ROOT)
        with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
            code = main(argv)
    finally:
        os.chdir(here)
    if code != 0:
        raise RuntimeError(f"dopplertof {command} exited with {code}")
    from dopplertof.capture_summary import SUMMARY_JSON, read_capture

    if os.path.isfile(os.path.join(out, SUMMARY_JSON)):  # (a capture's folder)
        return read_capture(out).data
    with open(out + ".json", encoding="utf-8") as f:  # (a command writing one file)
        return json.load(f)


def run_call(call: Call):
    """Calls ``call.function`` (Mitsuba's default variant set first where none is), its
    output swallowed: its return value."""
    import mitsuba as mi

    import dopplertof

    if mi.variant() is None:
        dopplertof.set_variant()
    module, name = call.function.split(":")
    function = getattr(importlib.import_module(module), name)
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
        return function(*call.args, **dict(call.kwargs))


def run(command, scratch: str):
    """The result of an entry's command: a `dopplertof` command line's JSON, or a Call's
    return value."""
    return run_call(command) if isinstance(command, Call) else run_command(command, scratch)


def drift_of(quoted: float, measured: float) -> float:
    """|measured - quoted| / |quoted|; for a quoted 0, 0 where it is measured 0 (else inf)."""
    if quoted == 0:
        return 0.0 if measured == 0 else float("inf")
    return abs(measured - quoted) / abs(quoted)


def quoted_in(doc: str, text: str, command) -> bool:
    """The text around the figure is in ``doc``, and a Call's named command too."""
    with open(os.path.join(ROOT, doc), encoding="utf-8") as f:
        words = " ".join(f.read().split())
    named = command.named if isinstance(command, Call) else ""
    return " ".join(text.split()) in words and named in words


def check(entries, tolerance: float = TOLERANCE) -> list:
    """Rows (name, doc, quoted, measured, drift, flag) for ``entries`` of REGISTRY."""
    results, rows = {}, []
    with tempfile.TemporaryDirectory(prefix="doc_numbers_") as scratch:
        for name, doc, text, quoted, command, read, _ in entries:
            in_doc = quoted_in(doc, text, command)
            if command not in results:
                results[command] = run(command, scratch)
            measured = float(read(results[command]))
            drift = drift_of(quoted, measured)
            flag = ("QUOTE GONE" if not in_doc else "DRIFT" if drift > tolerance else "ok")
            rows.append((name, doc, quoted, measured, drift, flag))
    return rows


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--all", action="store_true", help="also the expensive entries")
    parser.add_argument("--only", nargs="+", help="these entries only")
    parser.add_argument("--tolerance", type=float, default=TOLERANCE)
    args = parser.parse_args(argv)
    entries = [e for e in REGISTRY if (e[0] in args.only if args.only else args.all or e[6])]
    rows = check(entries, args.tolerance)
    print(f"{'figure':<40} {'doc':<18} {'quoted':>9} {'measured':>10} {'drift':>7}")
    for name, doc, quoted, measured, drift, flag in rows:
        print(f"{name:<40} {doc:<18} {quoted:>9.4g} {measured:>10.4g} {drift:>7.1%}  {flag}")
    print("\nnot re-measured:")
    for doc, what, why in NOT_REMEASURED:
        print(f"  {doc}: {what}: {why}")
    return 1 if any(row[5] != "ok" for row in rows) else 0


if __name__ == "__main__":
    sys.path.insert(0, os.path.join(ROOT, "src"))
    raise SystemExit(main())
