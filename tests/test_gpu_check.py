"""tools/gpu_check.sh, dry-run on the CPU so that it cannot rot before a GPU is lent:
the quick check on llvm_ad_rgb passes and reports into the folder given (--out, issue 44),
a check whose variant's tests were skipped or whose step ran out of time fails, and bad
arguments write nothing. The install from a wheelhouse: tests/test_offline_wheels.py."""

import os
import subprocess
import sys

import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SCRIPT = os.path.join(ROOT, "tools", "gpu_check.sh")
sys.path.insert(0, os.path.join(ROOT, "tools"))

import gpu_report  # noqa: E402


def check(tmp_path, *args, env=None):
    """The script run from ``tmp_path`` (relative paths are the caller's)."""
    return subprocess.run(["bash", SCRIPT, "--python", sys.executable, *args],
                          capture_output=True, text=True, timeout=180, cwd=tmp_path,
                          env={**os.environ, **(env or {})})


@pytest.mark.slow  # (5 s: make quick stays under its budget, issue 42)
def test_quick_check_on_llvm_passes_and_writes_its_report(tmp_path):
    report = tmp_path / "out" / "report.txt"
    done = check(tmp_path, "--variant", "llvm_ad_rgb", "--quick", "--out", "out")
    assert done.returncode == 0, done.stdout + done.stderr
    text = report.read_text()
    assert text in done.stdout and text.rstrip().endswith("result: PASS")
    assert (tmp_path / "out" / "junit.xml").exists()
    assert not (tmp_path / "out" / "throughput_llvm.txt").exists()  # LLVM is the variant
    assert "(the variant checked is LLVM's)" in text and "libLLVM: /" in text
    assert "gpu tests (llvm_ad_rgb): 2 passed, 0 failed, 0 skipped, 0 without" in text
    agreement = next(line for line in text.splitlines() if "moving_plane: image mean t" in line)
    assert "?" not in agreement and "16 seeds a side; passed" in agreement
    ratio = next(line for line in text.splitlines() if "throughput ratio (2 moving" in line)
    assert float(ratio.rsplit(":", 1)[1]) > 0
    assert "GPU: " in text and "mitsuba 3.9" in text


def test_a_step_out_of_time_fails_the_check(tmp_path):
    """(also with an earlier run's passing JUnit file left in the logs folder)"""
    logs = tmp_path / "out"
    report = logs / "report.txt"
    logs.mkdir()
    (logs / "junit.xml").write_text('<testsuite><testcase name="test_x[llvm_ad_rgb]"/>'
                                    '</testsuite>')
    done = check(tmp_path, "--variant", "llvm_ad_rgb", "--quick", "--out", str(logs),
                 env={"GPU_CHECK_BUDGET_S": "1"})
    assert done.returncode == 1, done.stdout + done.stderr
    text = report.read_text()
    assert "tests timed-out-after-1s" in text and "throughput no-time-left" in text
    assert "result: FAIL" in text and "no llvm_ad_rgb test passed" in text


def _junit(path, outcomes):
    cases = "".join(
        f'<testcase classname="tests.test_gpu" name="{name}">'
        + ("" if outcome == "passed" else f'<{outcome} message="{outcome} here"/>')
        + "</testcase>" for name, outcome in outcomes)
    path.write_text(f'<testsuites><testsuite name="pytest">{cases}</testsuite></testsuites>')


@pytest.mark.parametrize("outcome, problem", [("skipped", "1 cuda_ad_rgb test(s) skipped"),
                                              ("failure", "1 cuda_ad_rgb test(s) failed")])
def test_a_skipped_or_failed_test_of_the_variant_fails_the_report(tmp_path, outcome, problem):
    """(a skip for a missing shared fixture is listed, and does not fail it)"""
    (tmp_path / "steps.txt").write_text("tests ok 3\nthroughput ok 2\nthroughput-llvm ok 1\n")
    (tmp_path / "throughput.txt").write_text(
        "time per sample (2 moving bodies): dopplertof 5.000 ns, stock path 4.000 ns\n"
        "throughput ratio (2 moving bodies): 1.3\n")
    (tmp_path / "throughput_llvm.txt").write_text(
        "time per sample (2 moving bodies): dopplertof 200.0 ns, stock path 150.0 ns\n")
    _junit(tmp_path / "junit.xml", [("test_same_seed_same_image_bitwise[llvm_ad_rgb]", "passed"),
                                    ("test_capture_velocity[cuda_ad_rgb]", "passed"),
                                    ("test_same_seed_same_image_bitwise[cuda_ad_rgb]", outcome)])
    (tmp_path / "throughput_fallback.txt").write_text("throughput ratio (static): 2.5\n")
    text, passed = gpu_report.report("cuda_ad_rgb", str(tmp_path))
    assert not passed and problem in text and "result: FAIL" in text
    assert "one scene per kernel: throughput ratio (static): 2.5" in text
    assert "gpu tests (cuda_ad_rgb): 1 passed" in text
    assert "cuda_ad_rgb 5 ns, llvm_ad_rgb 200 ns: ratio 0.025 (40 times as fast as LLVM)" in text
    _junit(tmp_path / "junit.xml", [("test_capture_velocity[cuda_ad_rgb]", "passed")])
    assert gpu_report.report("cuda_ad_rgb", str(tmp_path))[1]  # and all passed: PASS
    (tmp_path / "junit.xml").write_text(
        '<testsuite><testcase name="test_capture_velocity[cuda_ad_rgb]"/><testcase name="'
        'test_variant_agrees_with_llvm_within_noise[cuda_ad_rgb-published]"><skipped message='
        '"Skipped: the published scene is absent (../shared)"/></testcase></testsuite>')
    text, passed = gpu_report.report("cuda_ad_rgb", str(tmp_path))
    assert passed and "0 skipped, 1 without their fixture" in text and "is absent" in text
    (tmp_path / "throughput_llvm.txt").unlink()  # no ratio to LLVM: a failure
    text, passed = gpu_report.report("cuda_ad_rgb", str(tmp_path))
    assert not passed and "no time per sample against llvm_ad_rgb measured" in text


@pytest.mark.parametrize("args, message", [
    (("--variant", "scalar_rgb"), "--variant scalar_rgb: expected a cuda_* or llvm_* variant"),
    (("--out", "/nonexistent/folder/out"), "folder /nonexistent/folder does not exist"),
    (("--out", ROOT), "is the repository root: give the report a folder of its own"),
    (("--wheelhouse", "/nonexistent/wheels"), "--wheelhouse /nonexistent/wheels: no such folder"),
    (("--wheelhouse", "."), "no mitsuba wheel in it (make it with tools/offline_wheels.sh)"),
    (("--quick", "--fast"), "unknown argument '--fast'"),
    (("--variant",), "--variant needs a value"),
])
def test_bad_arguments_are_one_line_and_write_nothing(tmp_path, args, message):
    logs = tmp_path / "out"
    done = check(tmp_path, "--out", str(logs), *args)
    assert done.returncode == 2 and message in done.stderr, done.stderr
    assert len(done.stderr.strip().splitlines()) == 1 and not logs.exists()


def test_without_out_it_says_so_in_one_line(tmp_path):
    done = check(tmp_path, "--quick")
    assert done.returncode == 2 and "--out DIR is needed" in done.stderr
    assert len(done.stderr.strip().splitlines()) == 1 and not os.listdir(tmp_path)


def test_without_python_it_runs_the_makefiles_setup_and_stops_when_it_fails(tmp_path):
    """(a stand-in `make` on the PATH: the suite must not reinstall the venv)"""
    bin_dir, called = tmp_path / "bin", tmp_path / "make_called"
    bin_dir.mkdir()
    fake_make = bin_dir / "make"
    fake_make.write_text(f'#!/bin/sh\necho "$PWD $*" > {called}\necho "pip: no network"\nexit 3\n')
    fake_make.chmod(0o755)
    done = subprocess.run(["bash", SCRIPT, "--out", str(tmp_path / "out")],
                          capture_output=True, text=True, timeout=60,
                          env={**os.environ, "PATH": f"{bin_dir}:{os.environ['PATH']}"})
    assert done.returncode == 1 and "make setup failed: no report" in done.stderr
    assert called.read_text().split() == [ROOT, "setup"]
    assert "pip: no network" in done.stdout and not (tmp_path / "out" / "report.txt").exists()
    assert (tmp_path / "out" / "steps.txt").read_text().startswith("setup exit-3 ")
