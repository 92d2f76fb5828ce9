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
    monkeypatch.setattr(budget, "available_memory", lambda: 4 << 20)  # 4 MiB
    with pytest.raises(budget.ResourceError, match=r"--spp below 16.*-D res"):
        dopplertof.render(scene, spp=64)
    monkeypatch.setattr(budget, "available_memory", lambda: 1 << 40)
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
