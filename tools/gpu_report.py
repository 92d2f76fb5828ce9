"""The report of tools/gpu_check.sh: GPU, driver, CUDA, the gpu tests' counts, the
CUDA-against-LLVM agreement and the throughput against stock ``path``, from the files
the check's steps wrote. Prints it, writes it (atomically) and exits 0 only when every
step passed and no test of the checked variant failed or was skipped.

    python tools/gpu_report.py --variant cuda_ad_rgb --logs LOGS --report REPORT

LOGS holds ``steps.txt`` (one ``name status seconds`` line per step), ``junit.xml``
(pytest's, with the agreement tests' properties), ``throughput.txt`` and, where the
fused renders failed, ``throughput_fallback.txt`` (one scene per kernel); for a variant
other than LLVM's, ``throughput_llvm.txt``: the two moving bodies with dopplertof on
llvm_ad_rgb, whose time per sample the variant's is divided by (issue 44).
"""

from __future__ import annotations

import argparse
import datetime
import importlib.metadata
import os
import re
import subprocess
import sys
import xml.etree.ElementTree as ET

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def gpu_description() -> str:
    """GPU name, driver and CUDA version from nvidia-smi (or why there are none)."""
    try:
        query = subprocess.run(["nvidia-smi", "--query-gpu=name,driver_version",
                                "--format=csv,noheader"], capture_output=True, text=True,
                               timeout=10)
        banner = subprocess.run(["nvidia-smi"], capture_output=True, text=True, timeout=10)
    except (OSError, subprocess.TimeoutExpired) as exc:
        return f"none (nvidia-smi: {exc.__class__.__name__}: {exc})"
    if query.returncode != 0:
        return f"none (nvidia-smi exit {query.returncode}: {query.stderr.strip()[:200]})"
    cuda = re.search(r"CUDA Version:\s*([\d.]+)", banner.stdout)
    gpus = [line.split(", ") for line in query.stdout.strip().splitlines()]
    return "; ".join(f"{g[0]}, driver {g[-1]}" for g in gpus) + \
        f", CUDA {cuda.group(1) if cuda else 'unknown'}"


def versions() -> str:
    found = []
    for name in ("mitsuba", "drjit"):
        try:
            found.append(f"{name} {importlib.metadata.version(name)}")
        except importlib.metadata.PackageNotFoundError:
            found.append(f"{name} not installed")
    return ", ".join(found)


def test_cases(junit: str) -> list:
    """(name, outcome, message, properties) per test case of a pytest JUnit file."""
    cases = []
    for case in ET.parse(junit).getroot().iter("testcase"):
        outcome, message = "passed", ""
        for kind in ("failure", "error", "skipped"):
            found = case.find(kind)
            if found is not None:
                outcome, message = kind, (found.get("message") or "").splitlines()[:1]
                message = message[0] if message else ""
                break
        properties = {p.get("name"): p.get("value") for p in case.iter("property")}
        cases.append((case.get("name"), outcome, message, properties))
    return cases


#: a skip for a missing shared fixture (tests/test_gpu.py's published()): reported, not
#: a failure of the check, where ../shared is not beside the repository
FIXTURE_ABSENT = "is absent"


def counts(cases, variant: str) -> dict:
    """Outcome counts of the test cases run in ``variant`` (its name in the test id)."""
    mine = [c for c in cases if re.search(rf"\[(.*-)?{re.escape(variant)}(-.*)?\]", c[0])]
    tally = {k: 0 for k in ("passed", "failure", "error", "skipped", "fixture_absent")}
    for name, outcome, message, _ in mine:
        absent = outcome == "skipped" and FIXTURE_ABSENT in message
        tally["fixture_absent" if absent else outcome] += 1
    return tally


def agreement_lines(cases, variant: str) -> list:
    """One line per agreement test of ``variant`` (its ``agreement_<label>_*``
    properties; a skipped one has none): the t values against LLVM."""
    lines = []
    for name, outcome, _, props in cases:
        if "agrees_with_llvm" not in name or variant not in name:
            continue
        labels = [k[len("agreement_"):-len("_mean_z")] for k in props
                  if k.startswith("agreement_") and k.endswith("_mean_z")]
        for label in labels or [name]:
            get = lambda key: props.get(f"agreement_{label}_{key}", "?")  # noqa: E731
            lines.append(f"  {label}: image mean t = {_short(get('mean_z'))}, per-pixel RMS "
                         f"t = {_short(get('rms_z'))}, max |t| = {_short(get('max_z'))} "
                         f"({get('seeds')} seeds a side; {outcome})")
    return lines or ["  (no agreement test ran)"]


def _ns(value) -> str:
    return "none" if value is None else f"{value:.4g} ns"


def _short(text: str) -> str:
    try:
        return f"{float(text):.3g}"
    except ValueError:
        return text


def throughput_lines(path: str) -> list:
    if not os.path.exists(path):
        return []
    with open(path, encoding="utf-8") as f:
        return [line.strip() for line in f if line.startswith("throughput ratio")]


#: benchmarks/throughput.py's line for the two moving bodies (dopplertof's time per sample)
PER_SAMPLE = re.compile(r"^time per sample \(2 moving bodies\): dopplertof ([0-9.eE+-]+) ns")


def time_per_sample(path: str) -> float | None:
    """dopplertof's time per sample (ns) on the two moving bodies, or None."""
    if not os.path.exists(path):
        return None
    with open(path, encoding="utf-8") as f:
        found = [PER_SAMPLE.match(line) for line in f]
    values = [float(m.group(1)) for m in found if m]
    return values[-1] if values else None


def libllvm_description() -> str:
    """The libLLVM the LLVM variants load here, or why there is none."""
    try:
        sys.path.insert(0, os.path.join(ROOT, "src"))
        from dopplertof.backend import BackendError, ensure_libllvm
    except ImportError as exc:
        return f"unknown (dopplertof: {exc})"
    try:
        return ensure_libllvm()
    except BackendError as exc:
        return f"none ({exc})"


def read_steps(path: str) -> list:
    """(name, status, seconds) per step gpu_check.sh ran, in order."""
    if not os.path.exists(path):
        return []
    with open(path, encoding="utf-8") as f:
        return [tuple(line.split()[:3]) for line in f if len(line.split()) >= 3]


def report(variant: str, logs: str) -> tuple:
    """(report text, whether the check passed)."""
    steps = read_steps(os.path.join(logs, "steps.txt"))
    junit = os.path.join(logs, "junit.xml")
    cases = test_cases(junit) if os.path.exists(junit) else []
    tally = counts(cases, variant)
    ratios = throughput_lines(os.path.join(logs, "throughput.txt"))
    fallback = throughput_lines(os.path.join(logs, "throughput_fallback.txt"))
    ours = time_per_sample(os.path.join(logs, "throughput.txt"))
    if ours is None:
        ours = time_per_sample(os.path.join(logs, "throughput_fallback.txt"))
    on_llvm = variant.startswith("llvm_")
    llvm = ours if on_llvm else time_per_sample(os.path.join(logs, "throughput_llvm.txt"))
    problems = [f"step {name}: {status}" for name, status, _ in steps if status != "ok"]
    if tally["failure"] or tally["error"]:
        problems.append(f"{tally['failure'] + tally['error']} {variant} test(s) failed")
    if tally["skipped"]:
        problems.append(f"{tally['skipped']} {variant} test(s) skipped")
    if not tally["passed"]:
        problems.append(f"no {variant} test passed")
    if not ratios:
        problems.append("no throughput ratio measured")
    if not on_llvm and (ours is None or llvm is None):
        problems.append("no time per sample against llvm_ad_rgb measured")
    stamp = datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
    lines = [f"GPU check (tools/gpu_check.sh), {stamp}, variant {variant}",
             f"GPU: {gpu_description()}", f"software: {versions()}",
             f"libLLVM: {libllvm_description()}",
             "steps: " + ", ".join(f"{n} {s} ({t} s)" for n, s, t in steps),
             f"gpu tests ({variant}): {tally['passed']} passed, "
             f"{tally['failure'] + tally['error']} failed, {tally['skipped']} skipped, "
             f"{tally['fixture_absent']} without their fixture"]
    lines += [f"  {'FAILED' if o in ('failure', 'error') else o} {n}: {m[:160]}"
              for n, o, m, _ in cases if o != "passed" and variant in n]
    lines += ["agreement with llvm_ad_rgb (independent seeds):"] + agreement_lines(cases, variant)
    lines += [f"throughput against stock path on {variant} (ours / stock time):"]
    lines += [f"  {r}" for r in ratios] or ["  (none)"]
    lines += [f"  one scene per kernel: {r}" for r in fallback]
    lines += ["against dopplertof on llvm_ad_rgb (time per sample, 2 moving bodies):"]
    if on_llvm:
        lines += ["  (the variant checked is LLVM's)"]
    elif ours is None or llvm is None:
        lines += [f"  (not measured: {variant} {_ns(ours)}, llvm_ad_rgb {_ns(llvm)})"]
    else:
        lines += [f"  {variant} {_ns(ours)}, llvm_ad_rgb {_ns(llvm)}: ratio "
                  f"{ours / llvm:.3g} ({llvm / ours:.3g} times as fast as LLVM)"]
    lines.append("result: " + ("PASS" if not problems else "FAIL: " + "; ".join(problems)))
    return "\n".join(lines) + "\n", not problems


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--variant", required=True)
    p.add_argument("--logs", required=True, help="the folder the check's steps wrote")
    p.add_argument("--report", required=True, help="the report file to write")
    args = p.parse_args()
    sys.path.insert(0, os.path.join(ROOT, "src"))
    from dopplertof.io import atomic_path

    text, passed = report(args.variant, args.logs)
    with atomic_path(args.report) as tmp, open(tmp, "w", encoding="utf-8") as f:
        f.write(text)
    sys.stdout.write(text)
    return 0 if passed else 1


if __name__ == "__main__":
    sys.exit(main())
