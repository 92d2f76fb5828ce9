"""What a camera stream's frames and a new scene through a preset cost, side by side in
one run, with the kernels each compiled.

1. A stream reuses its kernels: frames 1 to N-1 of a stream (examples/stream/sphere.xml
   along examples/stream/trajectory.txt: a moving sphere, a moving and turning camera),
   each a new frame, interleaved with reruns of frame 0 (warm: every kernel of it in
   memory), all in one process as a Dask worker runs them (``run_stream_frame_task``:
   preset and scene load, the capture, its files); each new frame is also rerun itself
   (its own content warm: a later frame of a moving scene may cost more or less to
   render than frame 0 for what it shows). Target: each new frame at most 1.1x the
   warm run beside it (the median of the adjacent pairs' ratios, so that the machine's
   drift cancels).
2. A new scene through a preset: ``dopplertof capture --camera`` as a user runs it, one
   process per capture, from an empty kernel cache: a first scene (the translating
   sphere), then each later scene right after the ones before it (new: the cache holds
   their kernels) and again (warm), in ``--rounds`` rounds, each with its own empty
   cache. The later scenes: a translating cube (other shapes) and the rotating cube
   (other shapes, and a body that turns). Target: a new scene's median at most 1.3x its
   rerun's. The kernels a new scene compiled are compared with those of the scenes
   before it with their literals masked: one that matches differs by a value baked in
   as a literal; one that does not is other code.
3. ``--full``: seconds per frame of the stream at the preset's full resolution too.

``--attribute`` says what made the new scene's kernels new: the first scene (a
translating sphere) followed, in one process, by it with its body rotating as the cube
does, with its body a cube, and by the rotating cube itself.

    .venv/bin/python benchmarks/stream_cost.py [--camera azure-kinect] [--res 160x144]
        [--spp 16] [--frames 6] [--rounds 3] [--full]

A kernel is counted as compiled where Dr.Jit's kernel history says it was neither in the
process's memory nor in the kernel cache on disk (``cache_hit``, ``cache_disk``).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import re
import statistics
import subprocess
import sys
import tempfile
import time

from timing import cache_size, empty_kernel_cache  # (benchmarks/timing.py, beside this script)

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
STREAM_SCENE = os.path.join(ROOT, "examples", "stream", "sphere.xml")
TRAJECTORY = os.path.join(ROOT, "examples", "stream", "trajectory.txt")
#: what differs between two kernels of the same code: numbers (literals, and the
#: registers' and labels' numbering that follows from them)
NUMBER = re.compile(r"0x[0-9A-Fa-f]+|-?\b\d+(\.\d+)?([eE][-+]?\d+)?\b")


# ---- Kernels -------------------------------------------------------------------------------

def kernels_of(run):
    """(seconds, kernels) of ``run()``: each JIT kernel launched as a dict with its hash,
    whether it was compiled (neither in memory nor on disk), its compile milliseconds and
    the hash of its IR with every number masked."""
    import hashlib

    import drjit as dr

    with dr.scoped_set_flag(dr.JitFlag.KernelHistory, True):
        dr.kernel_history_clear()
        started = time.perf_counter()
        run()
        seconds = time.perf_counter() - started
        history = [k for k in dr.kernel_history() if k["type"] == dr.KernelType.JIT]
    kernels = []
    for k in history:
        ir = k["ir"].getvalue() if hasattr(k.get("ir"), "getvalue") else str(k.get("ir", ""))
        kernels.append({"hash": k["hash"], "compiled": not (k["cache_hit"] or k["cache_disk"]),
                        "traced": not k["cache_hit"],
                        "ms": k.get("codegen_time", 0.0) + k.get("backend_time", 0.0),
                        "shape": hashlib.sha256(NUMBER.sub("#", ir).encode()).hexdigest()})
    return seconds, kernels


def compiled(kernels) -> list:
    return [k for k in kernels if k["compiled"]]


# ---- 1. A stream's frames ------------------------------------------------------------------

def stream_frames(camera: str, res: str, spp: int, frames: int, folder: str) -> dict:
    """Frame 0 (cold), then for each new frame k = 1..frames-1: frame k, frame k again
    (warm: its own content) and frame 0 again (warm), in this process: seconds and
    compiled kernels of each."""
    from dopplertof.experiments.stream import plan_stream, run_stream_frame_task

    plan = plan_stream(STREAM_SCENE, os.path.join(folder, "stream"), frames, camera,
                       trajectory=TRAJECTORY, resolution=res, spp=spp)
    again = lambda k, n: dataclasses.replace(  # noqa: E731
        plan.tasks[k], folder=os.path.join(folder, f"again_{k}_{n}"))
    rows = {"frame 0 (cold)": kernels_of(lambda: run_stream_frame_task(plan.tasks[0]))}
    new, own, first = [], [], []
    for k in range(1, frames):
        new.append(kernels_of(lambda k=k: run_stream_frame_task(plan.tasks[k])))
        own.append(kernels_of(lambda k=k: run_stream_frame_task(again(k, k))))
        first.append(kernels_of(lambda k=k: run_stream_frame_task(again(0, k))))
    rows.update({f"frame {k}": row for k, row in enumerate(new, 1)})
    seconds = lambda runs: [s for s, _ in runs]  # noqa: E731
    return {"rows": rows, "new": seconds(new), "own": seconds(own), "warm": seconds(first),
            "new_compiled": sum(len(compiled(k)) for _, k in new),
            "warm_compiled": sum(len(compiled(k)) for _, k in own + first)}


def print_stream(result: dict, camera: str, res: str, spp: int) -> None:
    print(f"1. a stream through {camera} at {res}, {spp} spp, one process "
          f"(run_stream_frame_task: load, capture, files); per new frame k: k, k again, "
          f"0 again")
    print(f"{'frame':<18} {'s':>7} {'again s':>8} {'frame 0 again s':>16} {'kernels':>8} "
          f"{'compiled':>9}")
    rows = list(result["rows"].items())
    print(f"{rows[0][0]:<18} {rows[0][1][0]:>7.2f} {'':>8} {'':>16} {len(rows[0][1][1]):>8} "
          f"{len(compiled(rows[0][1][1])):>9}")
    for (name, (seconds, kernels)), own, warm in zip(rows[1:], result["own"], result["warm"]):
        print(f"{name:<18} {seconds:>7.2f} {own:>8.2f} {warm:>16.2f} {len(kernels):>8} "
              f"{len(compiled(kernels)):>9}")
    for label, key in (("its own rerun", "own"), ("frame 0's rerun (the issue's measure)",
                                                  "warm")):
        ratios = [n / w for n, w in zip(result["new"], result[key])]
        ratio = statistics.median(ratios)
        print(f"new frames / {label}: median of the adjacent pairs' ratios {ratio:.3f}x "
              f"(target <= 1.1x): {'met' if ratio <= 1.1 else 'NOT met'}; medians "
              f"{statistics.median(result['new']):.2f} s / "
              f"{statistics.median(result[key]):.2f} s")
    print(f"kernels compiled by the new frames {result['new_compiled']}, by the reruns "
          f"{result['warm_compiled']}")


# ---- 2. A new scene through a preset -------------------------------------------------------

def one_capture(argv) -> None:
    """--one-capture SCENE CAMERA SIZE SPP OUT.json: ``dopplertof capture --camera`` in
    this process with the kernel history on; the kernels into OUT.json."""
    scene, camera, size, spp, out = argv
    from dopplertof.cli import main

    with tempfile.TemporaryDirectory(prefix="dopplertof-capture-bench-") as folder:
        _, kernels = kernels_of(lambda: main(["capture", scene, "--camera", camera, "--res",
                                              size, "--spp", spp, "--quiet", "-o", folder]))
    with open(out, "w") as f:
        json.dump(kernels, f)


def timed_capture(scene: str, camera: str, size: str, spp: int) -> tuple:
    """(wall seconds, kernels) of one capture in a process of its own."""
    with tempfile.TemporaryDirectory(prefix="dopplertof-kernels-") as folder:
        out = os.path.join(folder, "kernels.json")
        command = [sys.executable, os.path.abspath(__file__), "--one-capture", scene, camera,
                   size, str(spp), out]
        started = time.perf_counter()
        done = subprocess.run(command, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                              text=True)
        wall = time.perf_counter() - started
        if done.returncode:
            raise RuntimeError(f"capture of {scene} failed: {done.stderr.strip()}")
        with open(out) as f:
            return wall, json.load(f)


def scene_paths(names, folder: str) -> list:
    """The scenes named (an example's file name, or a variant of :func:`swapped_scenes`)."""
    variants = swapped_scenes(folder)
    return [variants[n] if n in variants else os.path.join(ROOT, "examples", n) for n in names]


def new_scene_rounds(args) -> list:
    """Each round from an empty kernel cache: the first scene, then each later one right
    after the scenes before it (new) and again (warm)."""
    names = args.scenes.split(",")
    rounds = []
    with tempfile.TemporaryDirectory(prefix="dopplertof-variants-") as folder:
        paths = scene_paths(names, folder)
        for _ in range(args.rounds):
            with empty_kernel_cache() as cache:
                runs = [timed_capture(paths[0], args.camera_cold, args.size, args.spp)]
                for path in paths[1:]:
                    runs += [timed_capture(path, args.camera_cold, args.size, args.spp)
                             for _ in range(2)]
                rounds.append({"runs": runs, "cache": cache_size(cache)})
    return rounds


def print_new_scene(rounds, args) -> None:
    names = args.scenes.split(",")
    print(f"2. dopplertof capture --camera {args.camera_cold} --res {args.size} --spp "
          f"{args.spp}, one process each, each round from an empty kernel cache: "
          f"{names[0]}, then each later scene new and again")
    print(f"{'round':<6} {names[0] + ' (empty cache) s':>34} " + " ".join(
        f"{n + ' new / again s':>36}" for n in names[1:]))
    for n, r in enumerate(rounds):
        runs = [s for s, _ in r["runs"]]
        print(f"{n:<6} {runs[0]:>34.2f} " + " ".join(
            f"{runs[1 + 2 * i]:>20.2f} / {runs[2 + 2 * i]:.2f} = "
            f"{runs[1 + 2 * i] / runs[2 + 2 * i]:.2f}x" for i in range(len(names) - 1)))
    for i, name in enumerate(names[1:]):
        new = statistics.median(r["runs"][1 + 2 * i][0] for r in rounds)
        again = statistics.median(r["runs"][2 + 2 * i][0] for r in rounds)
        print(f"{name} new / its rerun: median {new:.2f} s / {again:.2f} s = "
              f"{new / again:.2f}x (target <= 1.3x): "
              f"{'met' if new / again <= 1.3 else 'NOT met'}")
        for n, r in enumerate(rounds):
            seen = {k["shape"] for _, ks in r["runs"][:1 + 2 * i] for k in ks}
            kb, kc = r["runs"][1 + 2 * i][1], r["runs"][2 + 2 * i][1]
            new_kernels = compiled(kb)
            literal = [k for k in new_kernels if k["shape"] in seen]
            print(f"  round {n}: launched {len(kb)} kernels, compiled {len(new_kernels)} "
                  f"({sum(k['ms'] for k in new_kernels) / 1000:.2f} s of compiling): "
                  f"{len(literal)} code seen before with other literals, "
                  f"{len(new_kernels) - len(literal)} other code; its rerun compiled "
                  f"{len(compiled(kc))}; cache at the end {r['cache'][0]} kernels")


def swapped_scenes(folder: str) -> dict:
    """The first example scene with one thing of the second's each: its body rotating as
    the cube does, its body a cube, and both (the second scene itself)."""
    def text(name):
        with open(os.path.join(ROOT, "examples", name)) as f:
            return f.read()

    sphere, cube = text("translating_sphere.xml"), text("rotating_cube.xml")
    animation = re.compile(r'<animation name="to_world">.*?</animation>', re.S)
    variants = {"rotating sphere": animation.sub(lambda _: animation.search(cube).group(0),
                                                 sphere),
                "translating cube": sphere.replace('type="sphere"', 'type="cube"')}
    paths = {}
    for name, xml in variants.items():
        paths[name] = os.path.join(folder, name.replace(" ", "_") + ".xml")
        with open(paths[name], "w") as f:
            f.write(xml)
    paths["rotating cube"] = os.path.join(ROOT, "examples", "rotating_cube.xml")
    return paths


def attribute(args) -> None:
    """--attribute: in a process of its own (an empty kernel cache), the translating
    sphere, then each variant of :func:`swapped_scenes` after it: the kernels each traces
    anew, and how many of them are the sphere's code with other literals."""
    import dopplertof
    from dopplertof.cameras import load_preset
    from dopplertof.cameras.capture import capture_camera
    from dopplertof.cameras.scene_view import load_scene_for_camera
    from dopplertof.scene.kinds import keep_common_alive

    dopplertof.set_variant("llvm_ad_rgb")
    keep_common_alive()  # (as the command line does)
    preset = load_preset(args.camera_cold)
    size = tuple(int(v) for v in args.size.split("x"))

    def capture(path):
        scene = load_scene_for_camera(path, preset, size)
        return kernels_of(lambda: capture_camera(scene, preset, spp=args.spp,
                                                 progress=False))[1]

    with tempfile.TemporaryDirectory(prefix="dopplertof-variants-") as folder:
        paths = swapped_scenes(folder)
        first = capture(os.path.join(ROOT, "examples", "translating_sphere.xml"))
        shapes = {k["shape"] for k in first}
        for name, path in paths.items():
            traced = [k for k in capture(path) if k["traced"]]
            same = sum(k["shape"] in shapes for k in traced)
            print(f"{name} after the translating sphere: {len(traced)} kernels traced anew "
                  f"(of {len(first)}), {same} of them the sphere's code with other literals")


# ---- 3. Seconds per frame --------------------------------------------------------------------

def full_resolution(camera: str, spp: int, folder: str) -> tuple:
    """(resolution, seconds of frame 0 cold, of frame 1) of a 2-frame stream at the
    preset's own resolution."""
    from dopplertof.cameras.preset import load_preset

    preset = load_preset(camera)
    res = "x".join(str(v) for v in preset.resolution)
    result = stream_frames(camera, res, spp, 2, folder)
    return res, result["rows"]["frame 0 (cold)"][0], result["new"][0], result["own"][0]


def main(argv=None) -> None:
    if argv is None and sys.argv[1:2] == ["--one-capture"]:
        return one_capture(sys.argv[2:])
    if argv is None and sys.argv[1:2] == ["--attribute-here"]:
        return attribute(build_parser().parse_args(sys.argv[2:]))
    args = build_parser().parse_args(argv)
    started = time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime())
    print(f"{started}, load average {os.getloadavg()[0]:.1f}")
    if args.attribute:  # (one process each: the variants one after the other in it)
        with empty_kernel_cache():
            subprocess.run([sys.executable, os.path.abspath(__file__), "--attribute-here",
                            *(argv if argv is not None else sys.argv[1:])], check=True,
                           stderr=subprocess.DEVNULL)
        return None
    run(args)


def build_parser():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--camera", default="azure-kinect", help="the stream's preset")
    ap.add_argument("--res", default="160x144", help="the stream's WIDTHxHEIGHT")
    ap.add_argument("--spp", type=int, default=16)
    ap.add_argument("--frames", type=int, default=6)
    ap.add_argument("--rounds", type=int, default=3, help="new-scene rounds")
    ap.add_argument("--camera-cold", default="kinect-v2", help="the new scene's preset")
    ap.add_argument("--size", default="48x40", help="the new scene's WIDTHxHEIGHT")
    ap.add_argument("--scenes", default="translating_sphere.xml,translating cube,"
                    "rotating_cube.xml", help="the first scene, then the new ones: files of "
                    "examples/ or variants of the first (rotating sphere, translating cube)")
    ap.add_argument("--full", action="store_true",
                    help="also a frame at the preset's full resolution")
    ap.add_argument("--skip-new-scene", action="store_true")
    ap.add_argument("--attribute", action="store_true",
                    help="only: what makes the new scene's kernels new (shape, rotation)")
    return ap


def run(args) -> None:
    rounds = [] if args.skip_new_scene else new_scene_rounds(args)  # (before Dr.Jit loads)
    import dopplertof

    dopplertof.set_variant("llvm_ad_rgb")
    with tempfile.TemporaryDirectory(prefix="dopplertof-stream-bench-") as folder:
        result = stream_frames(args.camera, args.res, args.spp, args.frames, folder)
        full = full_resolution(args.camera, args.spp, folder) if args.full else None
    print_stream(result, args.camera, args.res, args.spp)
    if rounds:
        print_new_scene(rounds, args)
    print(f"3. seconds per frame, {args.camera}, {args.spp} spp (a new frame of the stream, "
          f"one process): {args.res}: {statistics.median(result['new']):.2f} s")
    if full:
        print(f"   {full[0]}: frame 0 (cold) {full[1]:.1f} s, frame 1 {full[2]:.1f} s, "
              f"frame 1 again {full[3]:.1f} s")
    print(f"load average at the end {os.getloadavg()[0]:.1f}")


if __name__ == "__main__":
    main()
