"""Why a spinning torus's velocity error is large (issue 42 item 12, 2026-12-03;
docs/camera.md, "Limit: spinning bodies").

Captures examples/user_meshes.xml with direct light only (max_depth 2) at the given
exposures, spin rates and spin axes (y: the torus's axis of symmetry, its facets slide
past each pixel; x: a diameter, the torus tumbles and its faces turn to the light), and
compares the reconstructed velocity over the torus's pixels (mixed footprints NaN, as
the capture leaves them) with five references (dopplertof.tof.exposure_truth):

* mid: velocity_gt.npy, the radial velocity at mid-exposure at the pixel centre;
* weighted: the exposure's weighted mean (1 - cos 2 pi t / T) of the radial velocity
  along the pixel's rays (F x F over its footprint), what the sinusoid measures to first
  order in the Doppler phase;
* model, constant brightness: the velocity reconstructed from captures computed from the
  rays' path lengths over the exposure (exact phase: tests the small-angle assumption);
* model: the same with each ray's brightness |n . d| / s^2 over the exposure; at the
  centre ray and over the footprint (the latter leaves only the render's noise).

Prints one row per setting: median |error| and mean error against each, and the
brightness-curvature prediction -c omega^2 T / (8 pi^2 h f_g) of a turning face.

    cd benchmarks && PYTHONPATH=../src ../.venv/bin/python spinning_torus.py \\
        --exposure-ms 20 5 1 --omega 30 10 --axis x y
"""

from __future__ import annotations

import argparse
import json
import math
import os
import time

import numpy as np

SCENE = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))),
                     "examples", "user_meshes.xml")

#: spp at 20 ms; shorter exposures take more (the velocity's noise grows as 1 / T)
BASE_SPP = 64


def scene_values(exposure: float, omega: float, axis: str, res: int, spp: int) -> dict:
    """The -D values of examples/user_meshes.xml for a torus turning at ``omega`` rad/s
    about ``axis`` (its frame's x or y) and the scene's speeds, direct light only."""
    return {"res": str(res), "spp": str(spp), "max_depth": "2", "exposure": repr(exposure),
            "spin": repr(float(math.degrees(omega * exposure))), "travel": repr(3.0 * exposure),
            "blob_dx": repr(0.5 * exposure), "blob_dz": repr(-2.0 * exposure),
            "spin_x": "1" if axis == "x" else "0", "spin_y": "1" if axis == "y" else "0"}


def measure(exposure: float, omega: float, axis: str, res=64, spp=None, samples=48,
            footprint=3, seed=0) -> dict:
    """One row: the torus's errors against each reference (m/s)."""
    import dopplertof
    from dopplertof.tof import capture
    from dopplertof.tof import exposure_truth as et
    from dopplertof.tof.reconstruct import CaptureModel, brightness_curvature_bias

    spp = spp or int(BASE_SPP * max(1.0, (0.02 / exposure) ** 2 / 16) // 1)
    scene = dopplertof.load_file(SCENE, scene_values(exposure, omega, axis, res, spp))
    result = capture(scene, spp=spp, seed=seed, progress=False)
    v, truth = result.reconstruction.velocity, result.truth
    model = CaptureModel.of(scene.params.modulation(scene.shutter_interval), 1.0)
    centre = et.ray_histories(scene, samples=samples)
    wide = et.ray_histories(scene, samples=samples, footprint=footprint)
    refs = {"mid": truth.velocity, "weighted": et.weighted_velocity(wide),
            "model_constant_brightness": et.history_velocity(centre, model, brightness=False),
            "model_centre": et.history_velocity(centre, model),
            "model_footprint": et.history_velocity(wide, model)}
    on = (truth.body == 0) & np.isfinite(v)
    row = {"exposure_ms": exposure * 1e3, "omega_rad_s": omega, "axis": axis, "spp": spp,
           "pixels": int(on.sum()),
           "curvature_prediction_m_s": float(brightness_curvature_bias(model, -omega**2 / 2))}
    for name, ref in refs.items():
        error = (v - ref)[on]
        row[name] = {"median_abs": float(np.nanmedian(np.abs(error))),
                     "mean": float(np.nanmean(error)),
                     "standard_error": float(np.nanstd(error) / math.sqrt(on.sum()))}
    return row


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--exposure-ms", type=float, nargs="+", default=[20.0])
    parser.add_argument("--omega", type=float, nargs="+", default=[30.0])
    parser.add_argument("--axis", nargs="+", choices=("x", "y"), default=["x", "y"])
    parser.add_argument("--res", type=int, default=64)
    parser.add_argument("--spp", type=int, default=None,
                        help=f"default {BASE_SPP} at 20 ms, x (20 ms / T)^2 / 16 below 5 ms")
    parser.add_argument("--json", help="also write the rows here")
    args = parser.parse_args(argv)
    import dopplertof

    dopplertof.set_variant()
    rows = []
    for axis in args.axis:
        for omega in args.omega:
            for ms in args.exposure_ms:
                started = time.perf_counter()
                rows.append(measure(ms * 1e-3, omega, axis, args.res, args.spp))
                print(format_row(rows[-1]), f"({time.perf_counter() - started:.0f} s)",
                      flush=True)
    if args.json:
        with open(args.json, "w") as f:
            json.dump(rows, f, indent=1)
    return 0


def format_row(row: dict) -> str:
    cells = [f"axis {row['axis']} {row['omega_rad_s']:g} rad/s {row['exposure_ms']:g} ms "
             f"{row['spp']} spp {row['pixels']} px, curvature prediction "
             f"{row['curvature_prediction_m_s']:+.3f}"]
    for name in ("mid", "weighted", "model_constant_brightness", "model_centre",
                 "model_footprint"):
        e = row[name]
        cells.append(f"{name} {e['median_abs']:.3f} ({e['mean']:+.3f} +- "
                     f"{e['standard_error']:.3f})")
    return " | ".join(cells)


if __name__ == "__main__":
    raise SystemExit(main())
