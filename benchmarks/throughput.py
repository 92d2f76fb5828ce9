"""Throughput: dopplertof against stock Mitsuba `path` on the same scene, side by side.

Both render the same Cornell box at the same variant, resolution, spp and max depth;
stock Mitsuba sees the moving bodies baked static at their first keyframe (it cannot
move them). Runs are interleaved (stock, ours, stock, ours, ...) after a warm-up that
compiles every kernel, and the median time of each is compared.

    .venv/bin/python benchmarks/throughput.py [--res 256] [--spp 64] [--repeats 5]
        [--variant llvm_ad_rgb] [--quick]

Each comparison also prints `time per sample (LABEL): dopplertof X ns, stock path Y ns`
(median time over resolution^2 x spp; tools/gpu_report.py divides CUDA's by LLVM's, issue 44).
The last lines read `throughput ratio (2 moving bodies): X` (ours / stock time), the
static ratio with a tent and a gaussian filter (stock Mitsuba's film splats too), and
`splat film cost (gaussian): Y`: the time of the splat film (every sample weighted into
each pixel its filter reaches) over the importance film, both dopplertof, interleaved,
on the static scene with that filter (tent and gaussian; a box is the same kernel).
``--variant cuda_ad_rgb`` runs both on the GPU; ``--quick`` runs only the two moving
bodies (the dry run of tools/gpu_check.sh); ``--one-scene-per-kernel`` renders ours with
the OptiX fallback (docs/design.md section 3; stock Mitsuba as always).
"""

from __future__ import annotations

import argparse
import contextlib
import statistics
import time

import numpy as np

WALLS = """
  <bsdf type="diffuse" id="white"><rgb name="reflectance" value="0.725, 0.71, 0.68"/></bsdf>
  <bsdf type="diffuse" id="red"><rgb name="reflectance" value="0.63, 0.065, 0.05"/></bsdf>
  <bsdf type="diffuse" id="green"><rgb name="reflectance" value="0.14, 0.45, 0.091"/></bsdf>
  <shape type="rectangle"><transform name="to_world"><rotate x="1" angle="-90"/></transform>
    <ref id="white"/></shape>
  <shape type="rectangle"><transform name="to_world"><rotate x="1" angle="90"/>
    <translate y="2"/></transform><ref id="white"/></shape>
  <shape type="rectangle"><transform name="to_world"><translate y="1" z="-1"/></transform>
    <ref id="white"/></shape>
  <shape type="rectangle"><transform name="to_world"><rotate y="1" angle="90"/>
    <translate x="-1" y="1"/></transform><ref id="red"/></shape>
  <shape type="rectangle"><transform name="to_world"><rotate y="1" angle="-90"/>
    <translate x="1" y="1"/></transform><ref id="green"/></shape>
  <emitter type="point"><point name="position" x="0" y="1" z="6.8"/>
    <rgb name="intensity" value="100"/></emitter>
"""


def scene_xml(n_bodies: int, moving: bool, integrator: str, res: int, spp: int,
              depth: int, rfilter: str = "box") -> str:
    """Cornell box with n boxes on a grid; ``moving`` adds keyframes (10 m/s along z)."""
    boxes = []
    side = int(np.ceil(np.sqrt(max(n_bodies, 1))))
    size = 0.6 / side
    for k in range(n_bodies):
        i, j = divmod(k, side)
        x = -0.7 + 1.4 * (j + 0.5) / side
        z = -0.7 + 1.4 * (i + 0.5) / side
        base = (f'<scale x="{size * 0.45}" y="{0.3 + 0.1 * (k % 3)}" z="{size * 0.45}"/>'
                f'<rotate y="1" angle="{17 * k}"/><translate x="{x}" y="0.3" z="{z}"/>')
        if moving:
            v = 0.015 if k % 2 == 0 else -0.015
            body = (f'<animation name="to_world"><transform time="0">{base}</transform>'
                    f'<transform time="0.0015">{base}<translate z="{v}"/></transform>'
                    f"</animation>")
        else:
            body = f'<transform name="to_world">{base}</transform>'
        # each box has its own BSDF so that Mitsuba does not merge the static ones
        boxes.append(f'<bsdf type="diffuse" id="b{k}"/><shape type="cube">{body}'
                     f'<ref id="b{k}"/></shape>')
    return f"""<scene version="3.0.0">
  <integrator type="{integrator}"><integer name="max_depth" value="{depth}"/></integrator>
  <sensor type="perspective"><float name="fov" value="19.5"/>
    <transform name="to_world"><lookat origin="0,1,6.8" target="0,1,0" up="0,1,0"/></transform>
    <float name="shutter_close" value="0.0015"/>
    <sampler type="independent"><integer name="sample_count" value="{spp}"/></sampler>
    <film type="hdrfilm"><integer name="width" value="{res}"/>
      <integer name="height" value="{res}"/><rfilter type="{rfilter}"/></film>
  </sensor>
  {WALLS}
  {''.join(boxes)}
</scene>"""


def timed(fn) -> float:
    import drjit as dr

    dr.sync_thread()
    t = time.perf_counter()
    fn()
    dr.sync_thread()
    return time.perf_counter() - t


def tracing(args):
    """How ours traces its scenes: fused (default) or one scene per kernel."""
    if not args.one_scene_per_kernel:
        return contextlib.nullcontext()
    from dopplertof.scene import bodies

    return bodies.one_scene_per_kernel()


def compare(n_bodies: int, moving: bool, args, rfilter: str = "box") -> float:
    import mitsuba as mi

    import dopplertof

    stock = mi.load_string(scene_xml(n_bodies, False, "path", args.res, args.spp, args.depth,
                                     rfilter))
    ours = dopplertof.load_string(
        scene_xml(n_bodies, moving, "dopplertof", args.res, args.spp, args.depth, rfilter))
    assert len(ours.bodies) == (n_bodies if moving else 0)

    def run_stock():
        np.asarray(mi.render(stock, spp=args.spp, seed=0))

    def run_ours():
        with tracing(args):
            dopplertof.render(ours, spp=args.spp, seed=0, progress=False)

    run_stock(), run_ours()  # warm-up: compile (or load cached) kernels
    t_stock, t_ours = [], []
    for _ in range(args.repeats):
        t_stock.append(timed(run_stock))
        t_ours.append(timed(run_ours))
    s, o = statistics.median(t_stock), statistics.median(t_ours)
    label = f"{n_bodies} moving bodies" if moving else f"static ({n_bodies} boxes)"
    label += "" if rfilter == "box" else f", {rfilter}"
    print(f"{label:>18}: stock path {s:7.3f} s   dopplertof {o:7.3f} s   ratio {o / s:5.2f}",
          flush=True)
    samples = args.res * args.res * args.spp
    print(f"time per sample ({label}): dopplertof {o / samples * 1e9:.3f} ns, stock path "
          f"{s / samples * 1e9:.3f} ns", flush=True)
    return o / s


def film_cost(rfilter: str, args) -> float:
    """Splat over importance film time, dopplertof on the static scene."""
    import dopplertof

    scene = dopplertof.load_string(
        scene_xml(2, False, "dopplertof", args.res, args.spp, args.depth, rfilter))

    def run(film):
        def render():
            with tracing(args):
                dopplertof.render(scene, spp=args.spp, seed=0, progress=False,
                                  params={"film_sampling": film})
        return render

    run("splat")(), run("importance")()  # warm-up
    t_splat, t_importance = [], []
    for _ in range(args.repeats):
        t_importance.append(timed(run("importance")))
        t_splat.append(timed(run("splat")))
    s, i = statistics.median(t_splat), statistics.median(t_importance)
    print(f"{rfilter + ' film':>18}: importance {i:7.3f} s   splat {s:7.3f} s   ratio "
          f"{s / i:5.3f}", flush=True)
    return s / i


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--res", type=int, default=256)
    p.add_argument("--spp", type=int, default=64)
    p.add_argument("--depth", type=int, default=4)
    p.add_argument("--repeats", type=int, default=5)
    p.add_argument("--variant", default="llvm_ad_rgb")
    p.add_argument("--quick", action="store_true", help="only the 2 moving bodies' ratio")
    p.add_argument("--one-scene-per-kernel", action="store_true",
                   help="ours with the OptiX fallback (bodies.one_scene_per_kernel)")
    args = p.parse_args()

    import dopplertof

    dopplertof.set_variant(args.variant)
    print(f"variant {args.variant}, {args.res}x{args.res}, {args.spp} spp, max_depth "
          f"{args.depth}, median of {args.repeats} interleaved runs"
          + (", ours one scene per kernel" if args.one_scene_per_kernel else ""))
    if args.quick:
        print(f"throughput ratio (2 moving bodies): {compare(2, True, args):.3f}")
        return
    static = compare(2, False, args)
    sixteen = compare(16, True, args)
    two = compare(2, True, args)
    costs = {f: film_cost(f, args) for f in ("tent", "gaussian")}
    # both films splat with these filters: the ratio to stock, as with the box
    filtered = {f: compare(2, False, args, f) for f in ("tent", "gaussian")}
    print(f"throughput ratio (static): {static:.3f}")
    print(f"throughput ratio (16 moving bodies): {sixteen:.3f}")
    print(f"throughput ratio (2 moving bodies): {two:.3f}")
    for f, ratio in filtered.items():
        print(f"throughput ratio (static, {f} filter): {ratio:.3f}")
    for f, cost in costs.items():
        print(f"splat film cost ({f}): {cost:.3f}")


if __name__ == "__main__":
    main()
