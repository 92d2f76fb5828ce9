"""Start-up costs of the command line, side by side with an older commit (issue 24,
section 7).

Each row runs a command in fresh interpreters, this tree's sources against the
baseline commit's (``git archive BASELINE src``, with the same venv), ``--repeat``
times, and prints the median wall time and the median CPU time (user + system of
the child; on a loaded machine the wall time stretches, the CPU time much less):

- ``dopplertof --help`` and a usage error (``render SCENE -P max_dept=3``, a
  misspelt parameter): the time before the first line of output;
- a small capture (16x16, 16 spp, the translating sphere, written to a temporary
  folder) with a warm kernel cache and with a cold one (a fresh ``HOME``: Dr.Jit
  keeps its compiled kernels in ``~/.drjit``): its time outside the renders is the
  total minus the ``seconds.render`` of its summary.json;
- the CPU time of writing that capture's folder (arrays, the 14 PNG previews,
  summary.json) in one process: the first write, Matplotlib's import included, and
  the next ones;
- the kernels a second capture with other offsets and frequencies compiles (Dr.Jit's
  kernel history; in this tree only).

    .venv/bin/python benchmarks/startup.py [--baseline 084448f] [--repeat 5]
"""

from __future__ import annotations

import argparse
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SCENE = os.path.join(ROOT, "examples", "translating_sphere.xml")


def run_once(src: str, argv: list, env_extra=None) -> tuple:
    """(wall seconds, CPU seconds, exit code) of ``python -m dopplertof.cli ARGV`` with
    ``src`` first on the path."""
    env = dict(os.environ, PYTHONPATH=src, **(env_extra or {}))
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    code = subprocess.run([sys.executable, "-m", "dopplertof.cli", *argv], env=env,
                          cwd=ROOT, stdout=subprocess.DEVNULL,
                          stderr=subprocess.DEVNULL).returncode
    wall = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return wall, cpu, code


def median_run(src: str, argv: list, repeat: int, env_extra=None) -> tuple:
    """Median wall and CPU seconds over ``repeat`` runs."""
    runs = [run_once(src, argv, env_extra) for _ in range(repeat)]
    return (statistics.median(r[0] for r in runs), statistics.median(r[1] for r in runs),
            runs[0][2])


def capture_outside_renders(src: str, repeat: int, cold: bool) -> tuple:
    """Median (wall, CPU, wall outside the renders) of a 16x16, 16-spp capture."""
    from dopplertof.capture_summary import read_capture

    rows = []
    for _ in range(repeat):
        with tempfile.TemporaryDirectory() as tmp:
            env = {"HOME": os.path.join(tmp, "home")} if cold else None
            out = os.path.join(tmp, "out")
            wall, cpu, code = run_once(src, ["capture", SCENE, "-o", out, "-D", "res=16",
                                             "--spp", "16", "--quiet"], env)
            if code != 0:
                raise SystemExit(f"capture failed with exit code {code} ({src})")
            render = read_capture(out)["seconds"]["render"]
            rows.append((wall, cpu, wall - render))
    return tuple(statistics.median(r[i] for r in rows) for i in range(3))


def kernels_compiled_by_second_capture(src: str) -> str:
    """How many kernels the first capture launched and how many the second one, with
    other offsets and frequencies, compiled anew (run in a fresh interpreter)."""
    code = f"""
import dopplertof, drjit as dr
dopplertof.set_variant()
scene = dopplertof.load_file({SCENE!r}, res=16)
dr.set_flag(dr.JitFlag.KernelHistory, True)
def kernels(**settings):
    dopplertof.capture(scene, spp=16, progress=False, **settings)
    return {{k["hash"] for k in dr.kernel_history() if k["type"] == dr.KernelType.JIT}}
first = kernels()
second = kernels(hetero_frequency=2, params={{"w_g": 20, "hetero_offset": 0.3}})
print(len(first), len(second - first))
"""
    out = subprocess.run([sys.executable, "-c", code], env=dict(os.environ, PYTHONPATH=src),
                         cwd=ROOT, capture_output=True, text=True)
    if out.returncode != 0:
        return "failed: " + out.stderr.strip().splitlines()[-1]
    first, new = out.stdout.split()[-2:]
    return f"{first} kernels for the first capture, {new} new for the second"


def folder_writing_seconds(src: str) -> str:
    """CPU seconds of writing a small capture's folder (its arrays, 14 PNG previews and
    summary.json: CaptureResult.write), in a fresh interpreter: the first write (with
    Matplotlib's import) and the median of three more."""
    code = f"""
import os, statistics, tempfile, time, dopplertof
dopplertof.set_variant()
scene = dopplertof.load_file({SCENE!r}, res=16)
result = dopplertof.capture(scene, spp=16, progress=False)
seconds = []
with tempfile.TemporaryDirectory() as tmp:
    for k in range(4):
        start = time.process_time()
        result.write(os.path.join(tmp, str(k)))
        seconds.append(time.process_time() - start)
print(seconds[0], statistics.median(seconds[1:]))
"""
    out = subprocess.run([sys.executable, "-c", code], env=dict(os.environ, PYTHONPATH=src),
                         cwd=ROOT, capture_output=True, text=True)
    if out.returncode != 0:
        return "failed: " + out.stderr.strip().splitlines()[-1]
    first, then = (float(v) for v in out.stdout.split()[-2:])
    return f"first {first:.2f}, then {then:.2f}"


def baseline_sources(commit: str, folder: str) -> str:
    """The ``src`` folder of ``commit``, extracted into ``folder``."""
    archive = subprocess.run(["git", "-C", ROOT, "archive", commit, "src"],
                             capture_output=True, check=True).stdout
    subprocess.run(["tar", "-x", "-C", folder], input=archive, check=True)
    return os.path.join(folder, "src")


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--baseline", default="afb2c4e", help="commit to compare with")
    p.add_argument("--repeat", type=int, default=5, help="runs per row (median)")
    args = p.parse_args()
    here = os.path.join(ROOT, "src")
    with tempfile.TemporaryDirectory() as tmp:
        old = baseline_sources(args.baseline, tmp)
        rows = [("dopplertof --help", ["--help"]),
                ("usage error (-P max_dept=3)",
                 ["render", SCENE, "-o", os.path.join(tmp, "x.png"), "-P", "max_dept=3"])]
        print(f"{'':34} {'this tree':>22} {args.baseline:>22}")
        print(f"{'':34} {'wall s':>11}{'CPU s':>11} {'wall s':>11}{'CPU s':>11}")
        for name, argv in rows:
            new_t, old_t = (median_run(s, argv, args.repeat)[:2] for s in (here, old))
            print(f"{name:34} {new_t[0]:11.2f}{new_t[1]:11.2f} {old_t[0]:11.2f}{old_t[1]:11.2f}")
        for cold in (False, True):
            new_t, old_t = (capture_outside_renders(s, max(1, args.repeat // 2), cold)
                            for s in (here, old))
            kind = "cold" if cold else "warm"
            print(f"{'capture 16x16 16spp, ' + kind + ' kernels':34} "
                  f"{new_t[0]:11.2f}{new_t[1]:11.2f} {old_t[0]:11.2f}{old_t[1]:11.2f}")
            print(f"{'  of which outside the renders':34} {new_t[2]:11.2f}{'':11} "
                  f"{old_t[2]:11.2f}")
        print(f"{'writing the folder, CPU s':34} {folder_writing_seconds(here):>22} "
              f"{folder_writing_seconds(old):>22}")
        print("second capture, other offsets and frequencies: "
              + kernels_compiled_by_second_capture(here))


if __name__ == "__main__":
    main()
