"""The command line: outputs, exit codes, one-line errors, untouched files on failure."""

import os
import subprocess
import sys

import numpy as np
import pytest

from conftest import PUBLISHED, ROOT

SMALL = ["-D", "resx=12", "-D", "resy=10", "--spp", "4", "--quiet"]


def run(*args, timeout=300):
    return subprocess.run([sys.executable, "-m", "dopplertof.cli", *args],
                          capture_output=True, text=True, timeout=timeout)


@pytest.mark.parametrize("ext", [".npy", ".exr", ".png"])
def test_render_writes_each_format(tmp_path, ext):
    out = tmp_path / f"img{ext}"
    proc = run("render", PUBLISHED, *SMALL, "-o", str(out))
    assert proc.returncode == 0, proc.stderr
    assert out.is_file() and out.stat().st_size > 0
    assert [p.name for p in tmp_path.iterdir()] == [out.name]  # no temporary left behind
    if ext == ".npy":
        img = np.load(out)
        assert img.shape == (10, 12, 3) and img.dtype == np.float32
    if ext == ".exr":
        import mitsuba as mi

        bmp = np.array(mi.Bitmap(str(out)))
        assert bmp.shape == (10, 12, 3)


def test_npy_equals_library_render(tmp_path):
    import dopplertof

    out = tmp_path / "a.npy"
    assert run("render", PUBLISHED, *SMALL, "--seed", "3", "-o", str(out)).returncode == 0
    scene = dopplertof.load_file(PUBLISHED, {"resx": 12, "resy": 10})
    assert np.array_equal(np.load(out), dopplertof.render(scene, spp=4, seed=3))


@pytest.mark.parametrize("args,message", [
    (["render", "missing.xml", "-o", "{out}"], "scene file not found"),
    (["render", PUBLISHED, *SMALL, "-o", "{dir}/x.tiff"], "unknown output extension"),
    (["render", PUBLISHED, *SMALL, "-o", "{out}/x.npy"], "is not a folder"),
    (["render", PUBLISHED, "-D", "bogus=1", "-o", "{out}"], "unknown scene parameter 'bogus'"),
    (["render", PUBLISHED, "-D", "resx=8", "--spp", "3", "-o", "{out}"],
     "not a multiple of the group size"),
    (["render", PUBLISHED, "-P", "wave_function_type=saw", "-o", "{out}"],
     "unknown wave_function_type"),
    (["render", PUBLISHED, "-D", "oops", "-o", "{out}"], "-D expects name=value"),
])
def test_bad_input_one_line_exit_2_output_untouched(tmp_path, args, message):
    out = tmp_path / "keep.npy"
    np.save(out, np.arange(3))
    before = out.read_bytes()
    args = [a.format(out=out, dir=tmp_path) for a in args]
    proc = run(*args)
    assert proc.returncode == 2, proc.stderr
    assert message in proc.stderr
    assert proc.stderr.count("\n") == 1 and "Traceback" not in proc.stderr
    assert out.read_bytes() == before


@pytest.mark.parametrize("args", [("--debug", "render", "missing.xml", "-o", "x.npy"),
                                  ("render", "missing.xml", "-o", "x.npy", "--debug"),
                                  ("fmcw", "missing.xml", "--debug", "-o", "x")],
                         ids=["before", "after", "after-fmcw"])
def test_debug_shows_traceback(args):
    proc = run(*args)
    assert proc.returncode != 0 and "Traceback" in proc.stderr, proc.stderr


def test_mitsuba_plugin_renders_static_scene():
    """<integrator type="dopplertof"> through plain mitsuba.load_string + mitsuba.render."""
    import mitsuba as mi

    import dopplertof

    text = open(PUBLISHED).read()
    start, end = text.index('<shape type="cube" id="ShortBox">'), text.index("<emitter")
    text = text[:start] + text[end:]  # drop the moving boxes
    text = text.replace('type="correlated"', 'type="independent"')
    scene = mi.load_string(text, resx=8, resy=8)
    img = np.array(mi.render(scene, spp=8, seed=1))
    ours = dopplertof.render(dopplertof.scene.load_string(text, {"resx": 8, "resy": 8}),
                             spp=8, seed=1)
    assert np.array_equal(img, ours)


def test_an_fmcw_scene_loads_after_mitsuba_renders_with_the_plugin():
    """mitsuba.render traverses the integrator (its modality settings, dataclasses) and
    Dr.Jit resolves their fields' type names to classes in place: the FMCW settings of
    every scene loaded after it were refused ('dopplertof: error: <class 'float'>')."""
    import mitsuba as mi

    import dopplertof

    text = open(PUBLISHED).read()
    start, end = text.index('<shape type="cube" id="ShortBox">'), text.index("<emitter")
    text = (text[:start] + text[end:]).replace('type="correlated"', 'type="independent"')
    mi.render(mi.load_string(text, resx=4, resy=4), spp=2, seed=1)
    street = dopplertof.load_file(os.path.join(ROOT, "examples", "fmcw_street.xml"),
                                  {"res": "4"})
    assert street.modality_settings["fmcw"].bandwidth == 4.0  # (the file's fmcw_bandwidth)


def test_the_mitsuba_plugin_is_the_integrator_class():
    """<integrator type="dopplertof"> (and the published "dopplertofpath") is the class
    the pipeline renders with, a mi.SamplingIntegrator; its properties are checked."""
    import mitsuba as mi

    from dopplertof.integrators.dtof_path import integrator_class

    for name in ("dopplertof", "dopplertofpath"):
        integrator = mi.load_dict({"type": name, "max_depth": 3, "w_g": 20.0})
        assert type(integrator) is integrator_class(mi)
        assert isinstance(integrator, mi.SamplingIntegrator)
        assert integrator.params.max_depth == 3 and integrator.params.w_g == 20.0
    with pytest.raises(Exception, match="unknown parameter 'max_dept'"):
        mi.load_dict({"type": "dopplertof", "max_dept": 3})


def test_version_and_every_variant_option_has_help():
    """issue 42: no --version; cameras' (and demo's) --variant had no help."""
    from dopplertof import __version__

    done = subprocess.run([sys.executable, "-m", "dopplertof.cli", "--version"],
                          capture_output=True, text=True)
    assert done.returncode == 0 and done.stdout.strip() == f"dopplertof {__version__}"
    for command in ("cameras", "demo", "render", "capture"):
        helped = subprocess.run([sys.executable, "-m", "dopplertof.cli", command, "--help"],
                                capture_output=True, text=True)
        assert "--variant VARIANT     Mitsuba variant" in helped.stdout, command
