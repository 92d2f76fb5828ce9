"""Inverse problem: a moving plane's unknown albedo texture and its velocity, recovered
together from its D-ToF captures by gradient descent (docs/differentiable.md,
"Inverse problem: texture and velocity").

A plane faces the camera 2 m away and translates at (1, 0, 5) m/s; its albedo is a
32 x 32 texel checker (written here as an EXR in a temporary folder). The captures
(`dopplertof capture`'s homodyne and heterodyne at offsets 0 and 0.25) are rendered
with the truth at seed 0; the fit starts from a uniform 0.5 texture and a velocity
25% off, and fits every texel and the velocity along the camera axis with
dopplertof.diff.inverse.fit_captures (renders of seeds 1, 2, ...). A plane's
captures see only its velocity's normal component (the ray's range does not change
when a plane slides along itself): the lateral 1 m/s is known, not fitted.

    PYTHONPATH=src .venv/bin/python examples/texture_velocity.py

prints the texture's RMSE over the texels fully in view and the velocity's error.
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import tempfile
import time

import numpy as np

#: the truth: velocity (m/s), the plane's distance (m), half-size (m), camera fov (deg)
VELOCITY = (1.0, 0.0, 5.0)
DEPTH, HALF_SIZE, FOV = 2.0, 0.6, 30.0
#: exposure (s) and modulation frequency (MHz): the heterodyne captures' Doppler phase
#: over the exposure, 4 pi w_g v T / c = 0.21 rad at 5 m/s, sets how well they see v
EXPOSURE, W_G = 0.01, 100.0
TEXTURE_KEY = "albedo.reflectance.data"


def checker(n: int, squares: int = 4, low: float = 0.2, high: float = 0.8) -> np.ndarray:
    """(n, n, 1) float32 checker of squares x squares squares."""
    i = np.arange(n) * squares // n
    return np.where((i[:, None] + i[None, :]) % 2 == 0, high, low).astype(np.float32)[..., None]


def plane_scene(texture_path: str, res: int, spp: int) -> dict:
    """The dict scene: a point light at the camera, the textured plane translating at
    :data:`VELOCITY` over the exposure."""
    import mitsuba as mi

    import dopplertof

    T = mi.ScalarTransform4f
    pose = lambda t: (T().translate([VELOCITY[0] * t, VELOCITY[1] * t, DEPTH + VELOCITY[2] * t])  # noqa: E731
                      .rotate([0, 1, 0], 180).scale(HALF_SIZE))
    return {
        "type": "scene",
        "integrator": {"type": "dopplertof", "max_depth": 2, "w_g": W_G,
                       "hetero_frequency": 1.0},
        "sensor": {"type": "perspective", "fov": FOV, "near_clip": 0.01,
                   "to_world": T().look_at(origin=[0, 0, 0], target=[0, 0, 1], up=[0, 1, 0]),
                   "shutter_open": 0.0, "shutter_close": EXPOSURE,
                   "film": {"type": "hdrfilm", "width": res, "height": res,
                            "rfilter": {"type": "box"}, "pixel_format": "rgb"},
                   "sampler": {"type": "independent", "sample_count": spp}},
        "light": {"type": "point", "position": [0, 0, 0],
                  "intensity": {"type": "rgb", "value": 10.0}},
        "albedo": {"type": "diffuse", "reflectance": {
            "type": "bitmap", "filename": texture_path, "filter_type": "nearest"}},
        "plane": {"type": "rectangle", "bsdf": {"type": "ref", "id": "albedo"},
                  "to_world": dopplertof.Animation([(0.0, pose(0.0)), (EXPOSURE, pose(EXPOSURE))])},
    }


def visible_texels(n: int) -> np.ndarray:
    """(n, n) texels whose square lies wholly in the camera's view at the plane's depth
    (the field of view is symmetric about the plane's centre)."""
    half_view = DEPTH * math.tan(math.radians(FOV) / 2)
    edges = np.linspace(-HALF_SIZE, HALF_SIZE, n + 1)
    inside = (np.abs(edges[:-1]) <= half_view) & (np.abs(edges[1:]) <= half_view)
    return inside[:, None] & inside[None, :]


def captures_of(scene, spp: int, seed: int = 0) -> dict:
    """{capture name: (its render parameters, its image)}: the homodyne and heterodyne
    captures at offsets 0 and 0.25 that `dopplertof capture` renders."""
    import dopplertof
    from dopplertof.tof.capture import plan_captures

    result = dopplertof.capture(scene, spp=spp, seed=seed, progress=False)
    wanted = ("homodyne_0", "homodyne_0.25", "heterodyne_0", "heterodyne_0.25")
    specs = {s.name: s for s in plan_captures(scene.params.w_g, 1.0)}
    return {name: ({"w_g": specs[name].frequency_mhz,
                    "hetero_frequency": specs[name].hetero_frequency,
                    "hetero_offset": specs[name].hetero_offset},
                   np.asarray(result.captures[name], np.float64)) for name in wanted}


def recover(texels: int = 32, res: int = 48, spp: int = 16, capture_spp: int = 256,
            iterations: int = 80, start_error: float = 0.25, progress=None, folder=None,
            seed: int = 1):
    """Render the captures with the truth (seed 0), fit from the start (renders of seeds
    ``seed``, ``seed`` + 1, ...), and return a summary:
    {texture_rmse, start_texture_rmse, velocity, velocity_error, seconds, result}."""
    import dopplertof
    import mitsuba as mi
    from dopplertof.diff import DifferentiableScene
    from dopplertof.diff.inverse import fit_captures, set_value

    dopplertof.set_variant("llvm_ad_rgb")
    truth = checker(texels)
    with tempfile.TemporaryDirectory(dir=folder) as tmp:
        path = os.path.join(tmp, "albedo.exr")
        mi.Bitmap(truth).write(path)
        scene = dopplertof.load_dict(plane_scene(path, res, spp))
    # ---- The captures, from the truth (seed 0) ----
    captures = captures_of(scene, capture_spp, seed=0)
    # ---- The start: a uniform 0.5 texture, the velocity start_error off ----
    ds = DifferentiableScene(scene)
    start_vz = VELOCITY[2] * (1 + start_error)
    set_value(ds, TEXTURE_KEY, np.full(truth.size, 0.5))
    set_value(ds, "body0.vz", start_vz)
    started = time.perf_counter()
    result = fit_captures(ds, captures, [TEXTURE_KEY, "body0.vz"], iterations=iterations,
                          spp=spp, seed=seed, progress=progress)
    seen = visible_texels(texels)
    fitted = result.values[TEXTURE_KEY].reshape(texels, texels)
    rmse = lambda t: float(np.sqrt(np.mean((t - truth[..., 0])[seen] ** 2)))  # noqa: E731
    vz = result.values["body0.vz"]
    return {"texture_rmse": rmse(fitted), "start_texture_rmse": rmse(np.full_like(fitted, 0.5)),
            "velocity": vz, "start_velocity": start_vz,
            "velocity_error": vz / VELOCITY[2] - 1, "visible_texels": int(seen.sum()),
            "seconds": time.perf_counter() - started, "result": result}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--texels", type=int, default=32, help="texture size (default 32)")
    parser.add_argument("--res", type=int, default=48, help="image size (default 48)")
    parser.add_argument("--spp", type=int, default=16, help="spp of the fit's renders")
    parser.add_argument("--capture-spp", type=int, default=256, help="spp of the captures")
    parser.add_argument("--iterations", type=int, default=80)
    parser.add_argument("--seed", type=int, default=1, help="first seed of the fit's renders "
                        "(the captures': 0)")
    args = parser.parse_args(argv)
    if args.seed < 1:
        parser.error("--seed must be at least 1 (seed 0 renders the captures)")
    out = recover(args.texels, args.res, args.spp, args.capture_spp, args.iterations,
                  seed=args.seed)
    print(f"texture: {out['visible_texels']} texels in view, RMSE {out['texture_rmse']:.4f} "
          f"(start {out['start_texture_rmse']:.4f}; albedos 0.2 / 0.8)")
    print(f"velocity along the axis: {out['velocity']:.4f} m/s (truth {VELOCITY[2]:g}, start "
          f"{out['start_velocity']:g}), error {100 * out['velocity_error']:+.2f}%")
    print(f"fit: {args.iterations} iterations in {out['seconds']:.1f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
