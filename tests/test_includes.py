"""Files a scene ``<include>``s are read into its description by the loader
(scene/includes.py), as Mitsuba reads them: a scene written in another unit than metres
(-D unit=mm) places what it includes in metres with the rest (it stayed in millimetres: an
included light 700 m away, a dark capture); a nested include is read from the including
file's folder and takes the scene's ``$name`` values; a missing file is one line naming
it and the ``<include>``; a scene in metres renders as with the included content inline."""

import os
import re

import numpy as np
import pytest

import dopplertof

HERE = os.path.dirname(os.path.abspath(__file__))
CORNELL = os.path.join(HERE, "data", "stock", "cornell", "scene.xml")
SPHERE = os.path.join(os.path.dirname(HERE), "examples", "translating_sphere.xml")
AREA = '<emitter type="area"><rgb name="radiance" value="18.4, 15.6, 8.0"/></emitter>'
#: a point light under the Cornell box's ceiling, in millimetres (intensity per mm^2)
LAMP = ('<emitter type="point"><point name="position" value="278, 500, 0"/>'
        '<rgb name="intensity" value="$power"/></emitter>')


def _write(folder, name, text):
    path = folder / name
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text)
    return str(path)


def _cornell(lamp: str) -> str:
    """The millimetre Cornell box, its area light replaced by ``lamp``."""
    with open(CORNELL, encoding="utf-8") as f:
        text = f.read()
    assert text.count(AREA) == 1
    return text.replace(AREA, "").replace(
        '<scene version="3.0.0">', '<scene version="3.0.0"><default name="power" '
        'value="3e5"/>', 1).replace("</scene>", lamp + "</scene>")


def _capture(capsys, scene, out):
    """``capture SCENE -D unit=mm --camera azure-kinect`` at 12x10, 2 spp, seed 3:
    (depth, raw)."""
    from dopplertof.cli import main

    code = main(["capture", scene, "-D", "unit=mm", "--camera", "azure-kinect", "--res",
                 "12x10", "--spp", "2", "--seed", "3", "--keep-mixed-pixels", "-o", str(out),
                 "--quiet"])
    err = capsys.readouterr().err
    assert code == 0, err
    return np.load(out / "depth.npy"), np.load(out / "raw.npy")


def test_a_light_included_into_a_millimetre_scene_is_placed_in_metres(tmp_path, capsys):
    """The millimetre Cornell box with its point light in a file it includes captures
    bitwise what it captures with the light inline (the included light stayed at
    (278, 500, 0) m, unscaled: the capture came out dark, no valid depth)."""
    _write(tmp_path, "lamp.xml", f'<scene version="3.0.0">{LAMP}</scene>')
    inline = _write(tmp_path, "inline.xml", _cornell(LAMP))
    included = _write(tmp_path, "included.xml", _cornell('<include filename="lamp.xml"/>'))
    depth, raw = _capture(capsys, inline, tmp_path / "inline")
    assert np.isfinite(depth).any()  # (lit: some pixel has a depth)
    depth_i, raw_i = _capture(capsys, included, tmp_path / "included")
    assert np.array_equal(raw_i, raw)
    assert np.array_equal(depth_i, depth, equal_nan=True)


def _emitters(scene):
    import mitsuba as mi

    return [{key: np.asarray(value).tolist() for key, value in mi.traverse(e).items()}
            for e in scene.static.emitters()]


def test_a_nested_include_is_read_from_its_folder_with_the_scenes_values(tmp_path):
    """lights/all.xml includes lamp.xml (beside it) and is included by a name given by a
    parameter; the lamp's intensity is the scene's ``$power``, given by -D: the light
    loads as the inline one does, placed in metres and its intensity scaled."""
    from dopplertof.cameras.preset import load_preset
    from dopplertof.cameras.scene_view import load_scene_for_camera

    _write(tmp_path, "lights/lamp.xml", f'<scene version="3.0.0">{LAMP}</scene>')
    _write(tmp_path, "lights/all.xml",
           '<scene version="3.0.0"><include filename="lamp.xml"/></scene>')
    inline = _write(tmp_path, "inline.xml", _cornell(LAMP))
    nested = _write(tmp_path, "nested.xml", _cornell('<include filename="lights/$set.xml"/>'))
    dopplertof.set_variant("llvm_ad_rgb")
    preset = load_preset("azure-kinect")
    want = load_scene_for_camera(inline, preset, (4, 4), {"unit": "mm", "power": "2e5"})
    got = load_scene_for_camera(nested, preset, (4, 4),
                                {"unit": "mm", "power": "2e5", "set": "all"})
    assert _emitters(got) == _emitters(want)
    assert len(_emitters(got)) == 1 and "camera_illuminator" not in [
        e.id() for e in got.static.emitters()]


def test_a_missing_included_file_is_one_line_naming_it(tmp_path, capsys):
    """A file that a nested include names is missing: one line naming the including file
    and line and the name (it was Mitsuba's message, naming the scene file's line and
    repeating itself), exit 2, nothing written."""
    from dopplertof.cli import main

    _write(tmp_path, "lights/all.xml",
           '<scene version="3.0.0">\n<include filename="nope.xml"/></scene>')
    scene = _write(tmp_path, "nested.xml", _cornell('<include filename="lights/all.xml"/>'))
    code = main(["capture", scene, "-D", "unit=mm", "--camera", "azure-kinect", "--res",
                 "4x4", "--spp", "2", "-o", str(tmp_path / "out"), "--quiet"])
    errors = [line for line in capsys.readouterr().err.splitlines() if "error" in line]
    assert code == 2 and len(errors) == 1, errors
    where = re.escape(os.path.join(str(tmp_path), "lights", "all.xml"))
    assert re.search(rf"{where}:2: included file 'nope.xml' not found", errors[0]), errors
    assert not (tmp_path / "out").exists()


def test_a_scene_in_metres_renders_as_with_its_include_inline(tmp_path):
    """examples/translating_sphere.xml (in metres) with its point light in a file it
    includes, and its moving ball's BSDF in a file whose root is that <bsdf>: the render
    is bitwise the one of the same scene with both written inline, same seed."""
    with open(SPHERE, encoding="utf-8") as f:
        text = f.read()
    lamp = re.search(r'<emitter type="point">.*?</emitter>', text, flags=re.S).group(0)
    ref = '<ref id="grey"/>\n    </shape>\n</scene>'
    bsdf = '<bsdf type="diffuse"><rgb name="reflectance" value="0.6"/></bsdf>'
    assert text.count(ref) == 1  # (the ball's, the last shape)
    _write(tmp_path, "parts/lamp.xml", f'<scene version="3.0.0">{lamp}</scene>')
    _write(tmp_path, "parts/grey.xml", bsdf.replace("<bsdf ", '<bsdf version="3.0.0" '))
    inline = _write(tmp_path, "inline.xml", text.replace(ref, ref.replace(
        '<ref id="grey"/>', bsdf)))
    scene = _write(tmp_path, "included.xml", text.replace(
        lamp, '<include filename="parts/lamp.xml"/>').replace(ref, ref.replace(
            '<ref id="grey"/>', '<include filename="parts/grey.xml"/>')))
    dopplertof.set_variant("llvm_ad_rgb")
    a, b = (dopplertof.capture(dopplertof.load_file(path, {"res": "8", "spp": "2"}), spp=2,
                               seed=1, progress=False) for path in (inline, scene))
    assert a.radiance.max() > 0
    assert np.array_equal(a.radiance, b.radiance)


@pytest.mark.parametrize("part, message", [
    ('<scene version="3.0.0"><include filename="part.xml"/></scene>',
     r"part\.xml:1: <include> of 'part\.xml' nested more than 15 files deep \(Mitsuba's "
     r"limit\): does a file include itself\?"),
    ('<scene version="3.0.0"><emitter type="point"', r"part\.xml:1: malformed XML"),
    ('<scene><emitter type="point"/></scene>',
     r"part\.xml: the root element <scene> of a file .*scene\.xml:\d+ includes has no "
     r"'version'"),
], ids=["includes-itself", "malformed", "no-version"])
def test_a_bad_included_file_is_one_line_naming_it(tmp_path, part, message):
    from dopplertof.scene import SceneError

    _write(tmp_path, "part.xml", part)
    scene = _write(tmp_path, "scene.xml", _cornell('<include filename="part.xml"/>'))
    dopplertof.set_variant("llvm_ad_rgb")
    with pytest.raises(SceneError, match=message) as caught:
        dopplertof.load_file(scene, {"unit": "mm"})
    assert len(str(caught.value).splitlines()) == 1
