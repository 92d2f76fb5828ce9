"""Memory and time estimated before a render (issue 15, item 10): what cannot fit is
refused at once with the estimate and what to lower; a long render says what it takes."""

import os

import numpy as np
import pytest

import dopplertof
from dopplertof import budget
from dopplertof.cli import main

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SPHERE = os.path.join(ROOT, "examples", "translating_sphere.xml")


@pytest.fixture
def output(tmp_path):
    out = tmp_path / "keep.npy"
    np.save(out, np.arange(3.0))
    return out


@pytest.mark.parametrize("res,expected", [
    (100000, "of memory"),          # the host sums alone: numpy's "Unable to allocate"
    (20000, "per array"),           # a pass beyond Dr.Jit's 2^32 entries
])
def test_huge_requests_are_refused_with_the_estimate(capsys, output, res, expected):
    before = output.read_bytes()
    code = main(["render", SPHERE, "-D", f"res={res}", "-o", str(output)])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and "Traceback" not in err
    assert "GiB" in err and expected in err and "-D res" in err
    assert output.read_bytes() == before


def test_a_pass_too_big_for_memory_names_spp(monkeypatch):
    scene = dopplertof.load_file(SPHERE, {"res": 64})
    monkeypatch.setattr(budget, "memory_limits", lambda: [budget.MemoryLimit(4 << 20, "x")])
    with pytest.raises(budget.ResourceError, match=r"--spp below 16.*-D res"):
        dopplertof.render(scene, spp=64)
    monkeypatch.setattr(budget, "memory_limits", lambda: [budget.MemoryLimit(1 << 40, "x")])
    assert dopplertof.render(scene, spp=2).shape == (64, 64, 3)


def test_a_long_render_says_what_it_will_take(monkeypatch, capsys):
    scene = dopplertof.load_file(SPHERE, {"res": 8})
    monkeypatch.setattr(budget, "SAMPLES_PER_CORE_SECOND", 1.0)  # as if it were slow
    dopplertof.render(scene, spp=4)
    err = capsys.readouterr().err
    assert err.startswith("dopplertof: rendering 8x8 pixels at 4 spp: about ")
    assert "MiB of memory" in err and "roughly" in err
    dopplertof.render(scene, spp=4, progress=False)
    assert capsys.readouterr().err == ""


def test_the_estimate_grows_with_the_pass():
    small = budget.estimate(100, 100, 3, 64, 16, 1)
    big = budget.estimate(100, 100, 3, 64, 16, 4)
    assert small.lanes_per_pass == 100 * 100 * 16 and small.passes == 4
    assert big.pass_bytes == 4 * small.pass_bytes and big.passes == 1


# ---- Limits besides MemAvailable (issue 22, item 10) -------------------------------------

def _render_under_address_space_limit(tmp_path, limit_mib: int, res: int):
    """``dopplertof render`` with RLIMIT_AS (``ulimit -v``) set to ``limit_mib``; a hang
    fails the test."""
    import resource
    import subprocess
    import sys

    def limit_address_space():
        resource.setrlimit(resource.RLIMIT_AS, (limit_mib << 20, limit_mib << 20))

    argv = [sys.executable, "-m", "dopplertof.cli", "render", SPHERE, "-D", f"res={res}",
            "--spp", "16", "-o", str(tmp_path / "x.npy"), "--quiet"]
    try:
        return subprocess.run(argv, capture_output=True, text=True, timeout=120,
                              preexec_fn=limit_address_space)
    except subprocess.TimeoutExpired:
        pytest.fail(f"hung under an address-space limit of {limit_mib} MiB")


@pytest.mark.parametrize("limit_mib", [300, 600])  # "libLLVM.so could not be found"; a hang
def test_an_address_space_too_small_to_start_is_one_line(tmp_path, limit_mib):
    proc = _render_under_address_space_limit(tmp_path, limit_mib, 16)
    assert proc.returncode == 2, proc.stderr[-2000:]
    assert proc.stderr.count("\n") == 1, proc.stderr[-2000:]
    assert (f"address-space limit (ulimit -v) of {limit_mib} MiB is below the ~"
            in proc.stderr and "memory is the cause" in proc.stderr), proc.stderr
    assert not (tmp_path / "x.npy").exists()


@pytest.mark.slow
def test_a_render_beyond_the_address_space_limit_is_refused(tmp_path):
    """1400x1400 under 1.5 GB: about 1.6 GiB, accepted by MemAvailable on afb2c4e, which
    then crashed without a word; a 64x64 render under the same limit runs."""
    proc = _render_under_address_space_limit(tmp_path, 1500, 1400)
    assert proc.returncode == 2 and proc.stderr.count("\n") == 1, proc.stderr[-2000:]
    assert "of memory available (the address-space limit (ulimit -v) of 1500 MiB" \
        in proc.stderr and "-D res" in proc.stderr, proc.stderr
    proc = _render_under_address_space_limit(tmp_path, 1500, 64)
    assert proc.returncode == 0, proc.stderr[-2000:]


@pytest.mark.parametrize("files,expected", [
    ({"memory.max": "1073741824\n", "memory.current": "536870912\n",
      "memory.stat": "anon 1\ninactive_file 134217728\n"}, (1 << 30) - (384 << 20)),
    ({"memory.max": "max\n", "memory.current": "5\n"}, None),
    ({"memory/memory.limit_in_bytes": "2147483648\n",
      "memory/memory.usage_in_bytes": "1073741824\n"}, 1 << 30),
    ({"memory/memory.limit_in_bytes": "9223372036854771712\n",
      "memory/memory.usage_in_bytes": "1\n"}, None),
], ids=["v2", "v2-no-limit", "v1", "v1-no-limit"])
def test_the_cgroup_limit_less_its_usage(tmp_path, files, expected):
    for name, text in files.items():
        (tmp_path / name).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / name).write_text(text)
    limit = budget.cgroup_memory(str(tmp_path))
    assert (None if limit is None else limit.available) == expected
    if limit is not None:
        assert "cgroup memory limit" in limit.source


def test_the_smallest_limit_refuses_and_is_named(monkeypatch):
    monkeypatch.setattr(budget, "_system_memory", lambda: budget.MemoryLimit(1 << 40, "M"))
    monkeypatch.setattr(budget, "cgroup_memory",
                        lambda: budget.MemoryLimit(1 << 20, "the cgroup memory limit of 9"))
    monkeypatch.setattr(budget, "_address_space_left", lambda: None)
    assert budget.available_memory() == 1 << 20
    with pytest.raises(budget.ResourceError, match=r"more than the 1 MiB of memory available "
                       r"\(the cgroup memory limit of 9\)"):
        budget.check(budget.estimate(64, 64, 3, 16, 16, 1))
