"""Errors that name the cause (issue 15, items 6-9, 11-13, 15): one line, exit 2."""

import json
import os
import subprocess
import sys

import numpy as np
import pytest

import dopplertof
from dopplertof.cli import main

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SPHERE = os.path.join(ROOT, "examples", "translating_sphere.xml")
TINY = ["-D", "res=4", "--spp", "2", "--quiet"]


def line_of(path, text):
    with open(path) as f:
        return next(i for i, line in enumerate(f, 1) if text in line)


def fails(capsys, *argv):
    code = main(list(argv))
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and "Traceback" not in err, err
    return err


@pytest.fixture
def output(tmp_path):
    out = tmp_path / "keep.npy"
    np.save(out, np.arange(3.0))
    return out


def test_unknown_plugin_names_the_users_file_and_line(tmp_path, capsys, output):
    bad = tmp_path / "bad.xml"
    bad.write_text(open(SPHERE).read().replace('type="sphere"', 'type="spheer"'))
    err = fails(capsys, "render", str(bad), "-o", str(output), *TINY)
    assert f"{bad}:{line_of(bad, 'spheer')}: " in err and "spheer" in err
    assert "line 1, col" not in err and "parser.cpp" not in err


def test_unknown_plugin_of_the_static_scene_too(tmp_path, capsys, output):
    bad = tmp_path / "bad.xml"
    bad.write_text(open(SPHERE).read().replace('type="point"', 'type="pointy"'))
    err = fails(capsys, "render", str(bad), "-o", str(output), *TINY)
    assert f"{bad}:{line_of(bad, 'pointy')}: " in err


def test_a_bad_define_value_names_the_define(capsys, output):
    err = fails(capsys, "render", SPHERE, "-o", str(output), "-D", "res=abc", "--quiet")
    assert "-D res=abc" in err and 'could not parse integer value "abc"' in err
    width = line_of(SPHERE, '<integer name="width"')
    assert f"{SPHERE}:{width}: " in err


def test_minus_p_without_value_says_minus_p(capsys, output):
    err = fails(capsys, "render", SPHERE, "-o", str(output), "-P", "hetero_offset", *TINY)
    assert "-P expects name=value" in err


def test_misspelled_parameter_gets_the_closest_name(capsys, output):
    err = fails(capsys, "render", SPHERE, "-o", str(output), "-P", "hetro_frequency=1", *TINY)
    assert "unknown parameter 'hetro_frequency', did you mean 'hetero_frequency'?" in err
    err = fails(capsys, "render", SPHERE, "-o", str(output), "-D", "ress=8", "--quiet")
    assert "did you mean 'res'?" in err


def test_capture_with_hetero_frequency_zero_says_what_it_needs(tmp_path, capsys):
    err = fails(capsys, "capture", SPHERE, "-o", str(tmp_path / "o"), "--hetero-frequency",
                "0", *TINY)
    assert "non-zero integer hetero_frequency" in err and "0 is homodyne" in err
    assert "fraction" not in err
    assert not (tmp_path / "o").exists()


def test_scene_without_integrator_says_the_defaults_on_stderr(tmp_path, capsys):
    text = open(SPHERE).read()
    start, end = text.index("<integrator"), text.index("</integrator>") + len("</integrator>")
    plain = tmp_path / "plain.xml"
    plain.write_text(text[:start] + text[end:])
    assert main(["render", str(plain), "-o", str(tmp_path / "x.npy"), *TINY]) == 0
    out, err = capsys.readouterr()
    assert "has no <integrator>" in err and "homodyne" in err and "30 MHz" in err
    assert out == ""
    assert dopplertof.load_file(SPHERE, {"res": 4}).notes == ()


def test_capture_without_integrator_says_what_it_runs(tmp_path, capsys):
    # issue 24 section 4 item 5: the note said "a homodyne capture", then heterodyne ran
    text = open(SPHERE).read()
    start, end = text.index("<integrator"), text.index("</integrator>") + len("</integrator>")
    plain = tmp_path / "plain.xml"
    plain.write_text(text[:start] + text[end:])
    out_dir = tmp_path / "c"
    assert main(["capture", str(plain), "-o", str(out_dir), *TINY]) == 0
    err = capsys.readouterr().err
    summary = json.loads((out_dir / "summary.json").read_text())
    ran = {c["kind"]: c["hetero_frequency"] for c in summary["captures"]}
    assert ran["heterodyne"] == summary["modulation"]["hetero_frequency"] == 1.0
    assert "a homodyne capture" not in err
    assert "`capture` its homodyne captures and heterodyne ones at 1 beat period" in err
    assert "`render` renders one homodyne image" in err


def test_cuda_without_a_gpu_says_so_and_what_works():
    import drjit as dr

    if dr.has_backend(dr.JitBackend.CUDA):
        pytest.skip("this machine has a CUDA device")
    proc = subprocess.run([sys.executable, "-m", "dopplertof.cli", "render", SPHERE, "-o",
                           "x.npy", "--variant", "cuda_ad_rgb", *TINY],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2 and proc.stderr.count("\n") == 1
    assert "no CUDA device or driver was found" in proc.stderr
    assert "llvm_ad_rgb" in proc.stderr and "jit_init" not in proc.stderr


def test_mitsuba_warnings_go_to_stderr_not_stdout(tmp_path):
    proc = subprocess.run([sys.executable, "-m", "dopplertof.cli", "render", SPHERE, "-o",
                           str(tmp_path / "x.npy"), "--variant", "llvm_ad_mono", *TINY],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert "WARN" not in proc.stdout and "Monochrome" in proc.stderr


def test_dict_scene_without_integrator_has_the_note():
    import mitsuba as mi

    scene = {"type": "scene",
             "sensor": {"type": "perspective", "film": {"type": "hdrfilm", "width": 4,
                                                        "height": 4}},
             "light": {"type": "point", "position": [0, 0, 0]},
             "plane": {"type": "rectangle",
                       "to_world": mi.ScalarTransform4f().translate([0, 0, 3])}}
    notes = dopplertof.load_dict(scene).notes
    assert len(notes) == 1 and "has no <integrator>" in notes[0] and "homodyne" in notes[0]
    scene["integrator"] = {"type": "dopplertof"}
    assert dopplertof.load_dict(scene).notes == ()
