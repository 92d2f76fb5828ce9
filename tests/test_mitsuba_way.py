"""The Mitsuba way in Python (issue 24, section 5): Mitsuba's own calls work beside
dopplertof's, and its errors about names say which name was meant."""

import os
import re
import subprocess
import sys

import numpy as np
import pytest

import dopplertof

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SPHERE = os.path.join(ROOT, "examples", "translating_sphere.xml")
SRC = os.path.join(ROOT, "src")


def static_copy(tmp_path):
    """The translating sphere without its <animation>: a scene Mitsuba loads itself."""
    text = re.sub(r"<animation.*?</animation>", "", open(SPHERE).read(), flags=re.S)
    path = tmp_path / "static.xml"
    path.write_text(text)
    return str(path)


def run_python(code: str) -> subprocess.CompletedProcess:
    """``code`` in a fresh interpreter (this tree's sources first on the path)."""
    env = dict(os.environ, PYTHONPATH=SRC + os.pathsep + os.environ.get("PYTHONPATH", ""))
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          env=env, cwd=ROOT, timeout=300)


# ---- mi.set_variant registers the plugin, whichever is imported first ----

@pytest.mark.parametrize("imports", [
    "import dopplertof\nimport mitsuba as mi",
    "import mitsuba as mi\nimport dopplertof",
    "import mitsuba as mi\nmi.set_variant('llvm_ad_mono')\nimport dopplertof",
], ids=["dopplertof first", "mitsuba first", "mitsuba's variant set first"])
def test_mitsuba_set_variant_then_load_file_finds_the_plugin(tmp_path, imports):
    scene = static_copy(tmp_path)
    result = run_python(f"""{imports}
if mi.variant() is None:
    mi.set_variant("llvm_ad_mono")
scene = mi.load_file({scene!r}, res=4)
print("found", type(scene.integrator()).__name__, scene.integrator().params.w_g)
with mi.variant_context("llvm_ad_rgb"):
    print("found", type(mi.load_file({scene!r}, res=4).integrator()).__name__)
""")
    assert result.returncode == 0, result.stderr
    found = [line.split("found ")[1].split() for line in result.stdout.splitlines()
             if "found " in line]  # (Mitsuba logs to stdout too)
    assert found == [["DopplerToFPath", "30.0"], ["DopplerToFPath"]]


def test_a_variant_dopplertof_cannot_run_in_says_why(tmp_path):
    import mitsuba as mi

    scene = static_copy(tmp_path)
    mi.set_variant("scalar_rgb")  # (the fixture sets llvm_ad_rgb again)
    with pytest.raises(Exception, match="scalar_rgb' runs Python per sample"):
        mi.load_file(scene, res=4)


def test_import_dopplertof_does_not_import_mitsuba():
    """The hook waits for mitsuba's own import (the command line stays fast)."""
    result = run_python("import sys, dopplertof\nprint('mitsuba' in sys.modules, "
                        "'drjit' in sys.modules)")
    assert result.returncode == 0, result.stderr
    assert result.stdout.split() == ["False", "False"]


# ---- A plain mi.Scene in dopplertof, a DopplerScene in Mitsuba ----

def test_render_accepts_a_plain_mitsuba_scene(tmp_path):
    import mitsuba as mi

    plain = mi.load_file(static_copy(tmp_path), res=4)
    image = dopplertof.render(plain, spp=4, seed=1, progress=False)
    assert image.shape == (4, 4, 3)
    # the same as Mitsuba's own call of the plugin, and as the loaded static scene
    assert np.array_equal(image, np.asarray(mi.render(plain, spp=4, seed=1)))
    loaded = dopplertof.load_file(static_copy(tmp_path), res=4)
    assert np.array_equal(image, dopplertof.render(loaded, spp=4, seed=1, progress=False))


def test_capture_accepts_a_plain_mitsuba_scene(tmp_path):
    import mitsuba as mi

    result = dopplertof.capture(mi.load_file(static_copy(tmp_path), res=4), spp=4,
                                progress=False)
    assert np.allclose(result.velocity_gt, 0.0)


def test_plain_scene_under_another_integrator_renders_with_the_defaults(tmp_path):
    import mitsuba as mi

    text = open(static_copy(tmp_path)).read()
    text = re.sub(r"<integrator.*?</integrator>", '<integrator type="path"/>', text,
                  flags=re.S)
    (tmp_path / "path.xml").write_text(text)
    scene = dopplertof.scene.scene.as_doppler_scene(
        mi.load_file(str(tmp_path / "path.xml"), res=4))
    assert scene.params == dopplertof.RenderParams()
    assert "has no <integrator>" in scene.notes[0]


def test_mi_render_renders_a_doppler_scene():
    import mitsuba as mi

    scene = dopplertof.load_file(SPHERE, res=4)
    image = mi.render(scene, spp=4, seed=2)
    assert isinstance(image, mi.TensorXf)
    assert np.array_equal(np.asarray(image),
                          dopplertof.render(scene, spp=4, seed=2, progress=False))


def test_mi_render_of_a_doppler_scene_with_mitsuba_arguments_says_what_to_pass():
    import mitsuba as mi

    scene = dopplertof.load_file(SPHERE, res=4)
    with pytest.raises(TypeError, match=r"scene\.static"):
        mi.render(scene, integrator=mi.load_dict({"type": "path"}))


def test_mi_traverse_of_a_doppler_scene_says_what_to_pass():
    import mitsuba as mi

    scene = dopplertof.load_file(SPHERE, res=4)
    with pytest.raises(TypeError, match=r"traverse scene\.static .* scene\.bodies\[i\]"):
        mi.traverse(scene)
    assert "ball.to_world" not in mi.traverse(scene.static).keys()  # what it points to
    assert len(mi.traverse(scene.bodies[0].scene).keys()) > 0


# ---- Names: a misspelt plugin, parameter or derivative key ----

def test_misspelt_plugin_in_xml_gets_a_did_you_mean(tmp_path):
    bad = tmp_path / "bad.xml"
    bad.write_text(open(SPHERE).read().replace('type="rectangle"', 'type="rectangel"', 1))
    with pytest.raises(dopplertof.SceneError, match="did you mean 'rectangle'"):
        dopplertof.load_file(str(bad))


def test_misspelt_plugin_in_a_dict_gets_a_did_you_mean():
    with pytest.raises(dopplertof.SceneError, match="did you mean 'rectangle'"):
        dopplertof.load_dict({"type": "scene", "wall": {"type": "rectangel"}})
    with pytest.raises(dopplertof.SceneError, match="did you mean 'dopplertof'"):
        dopplertof.load_dict({"type": "scene", "i": {"type": "dopplertoff"}})


def test_unknown_parameter_lists_the_three_nearest_names_not_all():
    with pytest.raises(dopplertof.ParameterError) as e:
        dopplertof.RenderParams.from_mapping({"max_dept": 3})
    message = str(e.value)
    assert "did you mean 'max_depth'?" in message
    count = len(dopplertof.RenderParams.names())  # (the table grows: 27, then pixel_sets)
    assert count > 3
    assert re.search(rf"\(nearest: max_depth, [a-z_]+, [a-z_]+; {count} in all\)", message), \
        message
    assert "wave_function_type" not in message  # not the whole list


def test_render_derivatives_unknown_key_names_the_nearest_keys():
    from dopplertof.diff import DerivativeError, DifferentiableScene, render_derivatives

    ds = DifferentiableScene(dopplertof.load_file(SPHERE, res=4))
    with pytest.raises(DerivativeError) as e:
        render_derivatives(ds, ["wall.bsdf.reflectance.valeu"], spp=4)
    message = str(e.value)
    assert "did you mean" in message and "reflectance.value" in message, message
    with pytest.raises(DerivativeError, match=r"did you mean 'body0\.vx'"):
        render_derivatives(ds, ["body0.v_x"], spp=4)
