"""How many of the published scene's paths never meet a moving body: the share of
antithetic partners that a renderer could skip (a static path's value at any time is its
value at one time times the modulation's), the bound of that lever at h = 1.

Paths as the published scene's integrator traces them at its max_depth 4: the camera ray
and three bounces (cosine-weighted: every surface is diffuse), a shadow segment from each
vertex to the point light, no Russian roulette before depth 5 (Mitsuba's rr_depth). A
path is static when none of its segments meets a moving box's volume swept over the
exposure, taken as the axis-aligned box of its corners at both ends of the exposure (the
boxes only translate): looser than the swept volume itself, so the share is a lower
bound. Stock Mitsuba traces the rays (the boxes at their first keyframe), NumPy tests the
segments.

    .venv/bin/python benchmarks/static_paths.py [--paths 1048576] [--seed 1]
"""

from __future__ import annotations

import argparse
import os
import re

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SCENE = os.path.join(ROOT, "..", "shared", "fixtures", "published", "cornell_box_moving.xml")
DEFAULTS = {"spp": "1", "resx": "256", "resy": "256", "max_depth": "4"}


def stock_scene(text: str):
    """(stock Mitsuba's XML of the scene, the boxes at their first keyframe with a plain
    path tracer; the moving boxes' swept boxes as (lower, upper) corners)."""
    swept = []

    def first_keyframe(match):
        matrices = re.findall(r'<matrix value="([^"]+)"', match.group(0))
        offsets = re.findall(r'<translate x="([^"]+)" y="([^"]+)" z="([^"]+)"', match.group(0))
        M = np.array([float(v) for v in matrices[0].split()]).reshape(4, 4)
        corners = np.array([[x, y, z, 1.0] for x in (-1, 1) for y in (-1, 1)
                            for z in (-1, 1)]) @ M.T
        ends = [corners[:, :3]] + [corners[:, :3] + np.array(o, float) for o in offsets]
        points = np.concatenate(ends)
        swept.append((points.min(axis=0) - 1e-4, points.max(axis=0) + 1e-4))
        return f'<transform name="to_world"><matrix value="{matrices[0]}"/></transform>'

    text = re.sub(r"<integrator.*?</integrator>", '<integrator type="path"/>', text, flags=re.S)
    text = text.replace('type="correlated"', 'type="independent"')
    text = re.sub(r'<animation name="to_world">.*?</animation>', first_keyframe, text, flags=re.S)
    text = re.sub(r"\$(\w+)", lambda m: DEFAULTS[m.group(1)], text)
    return text, swept


def meets(swept, origin, direction, t_max):
    """Per segment (origin + t direction, 0 <= t <= t_max), whether it meets a swept box."""
    hit = np.zeros(len(origin), bool)
    with np.errstate(divide="ignore", invalid="ignore"):
        for lo, hi in swept:
            t1, t2 = (lo - origin) / direction, (hi - origin) / direction
            near = np.max(np.where(np.isnan(t1), -np.inf, np.minimum(t1, t2)), axis=1)
            far = np.min(np.where(np.isnan(t1), np.inf, np.maximum(t1, t2)), axis=1)
            hit |= (near <= far) & (far >= 0) & (near <= t_max)
    return hit


def cosine_directions(rng, normal):
    """Cosine-weighted directions about each unit ``normal``."""
    u1, u2 = rng.random(len(normal)), rng.random(len(normal))
    r, phi = np.sqrt(u1), 2 * np.pi * u2
    helper = np.where(np.abs(normal[:, :1]) > 0.9, [[0.0, 1.0, 0.0]], [[1.0, 0.0, 0.0]])
    tangent = np.cross(normal, helper)
    tangent /= np.linalg.norm(tangent, axis=1, keepdims=True)
    bitangent = np.cross(normal, tangent)
    return (r * np.cos(phi))[:, None] * tangent + (r * np.sin(phi))[:, None] * bitangent \
        + np.sqrt(1 - u1)[:, None] * normal


def static_share(paths: int, seed: int) -> tuple:
    """(share of static paths, share whose camera ray alone meets a swept box)."""
    import mitsuba as mi

    mi.set_variant("llvm_ad_rgb")
    with open(SCENE) as f:
        text, swept = stock_scene(f.read())
    scene = mi.load_string(text)
    light = np.array(scene.emitters()[0].world_transform().translation()).ravel()  # (point light)
    rng = np.random.default_rng(seed)
    ray, _ = scene.sensors()[0].sample_ray(mi.Float(0.0), mi.Float(0.5), mi.Point2f(
        rng.random(paths), rng.random(paths)), mi.Point2f(0.5, 0.5))
    origin, direction = np.array(ray.o).T, np.array(ray.d).T
    alive, dynamic = np.ones(paths, bool), np.zeros(paths, bool)
    for bounce in range(3):
        si = scene.ray_intersect(mi.Ray3f(mi.Point3f(*origin.T), mi.Vector3f(*direction.T)))
        valid = np.array(si.is_valid()) & alive
        dynamic |= alive & meets(swept, origin, direction,
                                 np.where(valid, np.array(si.t), np.inf))
        if bounce == 0:
            camera_only = dynamic.copy()
        alive = valid
        point = np.where(alive[:, None], np.array(si.p).T, 0.0)
        normal = np.where(alive[:, None], np.array(si.sh_frame.n).T, [[0.0, 0.0, 1.0]])
        to_light = light - point
        distance = np.linalg.norm(to_light, axis=1)
        dynamic |= alive & meets(swept, point, to_light / distance[:, None], distance)
        normal = np.where((np.sum(normal * direction, axis=1) > 0)[:, None], -normal, normal)
        origin, direction = point + 1e-4 * normal, cosine_directions(rng, normal)
    return 1.0 - dynamic.mean(), camera_only.mean()


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--paths", type=int, default=1 << 20)
    ap.add_argument("--seed", type=int, default=1)
    args = ap.parse_args(argv)
    if not os.path.isfile(SCENE):
        raise SystemExit(f"static_paths.py: {SCENE} is missing (../shared/fixtures)")
    share, camera = static_share(args.paths, args.seed)
    print(f"{args.paths} paths of the published scene (max_depth 4): static {share:.3f}; "
          f"camera ray alone meets a swept box {camera:.3f}")
    print(f"skipping a static path's antithetic partner: {2 - share:.3f} paths a pair, "
          f"equal-time RMSE at most {np.sqrt(2 / (2 - share)):.3f}x lower at h = 1")


if __name__ == "__main__":
    main()
