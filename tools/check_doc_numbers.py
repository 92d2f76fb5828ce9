"""Re-measure the numbers the docs quote and flag a drift over 10% (issue 42, 2026-12-03).

Each entry of REGISTRY is one quoted figure: the doc that quotes it, the text around it
(checked to be still in the doc: a doc that changed its figure changes the registry),
the quoted value, the command beside it in the doc (a `dopplertof` command line, run
in-process in a scratch folder), and how the measured value is read from the command's
summary.json. Entries sharing a command run it once. Prints quoted, measured and drift per
figure and exits 1 when any drift is over the tolerance (or a quote is gone from its doc).

    PYTHONPATH=src .venv/bin/python tools/check_doc_numbers.py              # the cheap ones
    PYTHONPATH=src .venv/bin/python tools/check_doc_numbers.py --all        # the demo too
    PYTHONPATH=src .venv/bin/python tools/check_doc_numbers.py --only sphere-ball-median

NOT_REMEASURED lists the quoted figures this script does not re-measure, and why.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import os
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
TOLERANCE = 0.10

SPHERE = "capture examples/translating_sphere.xml -o {out}"
SPHERE_MIXED = "capture examples/translating_sphere.xml -o {out} --keep-mixed-pixels"
TUMBLE = ("capture examples/user_meshes.xml -D res=64 -D max_depth=2 -D spin_x=1 "
          "-D spin_y=0 -o {out}")
DEMO = "demo -o {out}"


def body(name: str, key: str):
    """Reads summary.json's bodies[name].velocity_error_m_s[key] (or a body field)."""
    def read(summary):
        entry = next(b for b in summary["bodies"] if b["name"] == name)
        return entry["velocity_error_m_s"].get(key, entry.get(key))
    return read


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
]

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
    ("docs/cameras.md, docs/dataset.md, docs/fmcw.md, docs/reliability.md",
     "their figures", "not yet in the registry (issue 42's target is every number)"),
]


def run_command(command: str, scratch: str) -> dict:
    """Runs ``dopplertof COMMAND`` (``{out}`` a folder in ``scratch``) from the repository
    root, its output swallowed: the summary.json it wrote."""
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
    with open(os.path.join(out, "summary.json"), encoding="utf-8") as f:
        return json.load(f)


def check(entries, tolerance: float = TOLERANCE) -> list:
    """Rows (name, doc, quoted, measured, drift, flag) for ``entries`` of REGISTRY."""
    summaries, rows = {}, []
    with tempfile.TemporaryDirectory(prefix="doc_numbers_") as scratch:
        for name, doc, text, quoted, command, read, _ in entries:
            with open(os.path.join(ROOT, doc), encoding="utf-8") as f:
                in_doc = " ".join(text.split()) in " ".join(f.read().split())
            if command not in summaries:
                summaries[command] = run_command(command, scratch)
            measured = float(read(summaries[command]))
            drift = abs(measured - quoted) / abs(quoted)
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
    print(f"{'figure':<28} {'doc':<16} {'quoted':>9} {'measured':>10} {'drift':>7}")
    for name, doc, quoted, measured, drift, flag in rows:
        print(f"{name:<28} {doc:<16} {quoted:>9.4g} {measured:>10.4g} {drift:>7.1%}  {flag}")
    print("\nnot re-measured:")
    for doc, what, why in NOT_REMEASURED:
        print(f"  {doc}: {what}: {why}")
    return 1 if any(row[5] != "ok" for row in rows) else 0


if __name__ == "__main__":
    sys.path.insert(0, os.path.join(ROOT, "src"))
    raise SystemExit(main())
