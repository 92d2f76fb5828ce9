"""Room light through an absolute camera preset: a stock scene's area lights, environments
and directional lights are left out of the modulated render (the sensor's demodulation
rejects them but for their shot noise, --ambient-irradiance's), with one note naming them
and summary.json's ``room_lights_left_out``; the capture equals the one of the same scene
with them removed by hand (bitwise, same seed). Without --camera and through an
auto-exposed preset the scene loads as written."""

import json
import os

import numpy as np
import pytest

from dopplertof.scene import SceneError

STOCK = os.path.join(os.path.dirname(os.path.abspath(__file__)), "data", "stock")
CORNELL = os.path.join(STOCK, "cornell", "scene.xml")
CHECKER = os.path.join(STOCK, "textured", "checker.png")
AREA = '<emitter type="area"><rgb name="radiance" value="18.4, 15.6, 8.0"/></emitter>'
ROOM = (f'<emitter type="envmap" id="sky"><string name="filename" value="{CHECKER}"/>'
        '</emitter><emitter type="directional"><vector name="direction" value="0, -1, 1"/>'
        '</emitter>')
NOTE = "room light left out of the render through azure-kinect"


def _cornell():
    with open(CORNELL, encoding="utf-8") as f:
        text = f.read()
    assert text.count(AREA) == 1  # (the light removed by hand below is the scene's)
    return text


def _write(folder, name, text):
    path = folder / name
    path.write_text(text)
    return str(path)


def _capture(capsys, scene, out, *args):
    """``capture SCENE -D unit=mm --camera azure-kinect`` at 12x10, 2 spp, mixed pixels
    kept (at 12x10 most pixels' footprints straddle two walls); (summary,
    depth, raw, the note lines on stderr)."""
    from dopplertof.cli import main

    code = main(["capture", scene, "-D", "unit=mm", "--camera", "azure-kinect", "--res",
                 "12x10", "--spp", "2", "--seed", "3", "--keep-mixed-pixels", "-o", str(out),
                 "--quiet", *args])
    err = capsys.readouterr().err
    assert code == 0, err
    summary = json.loads((out / "summary.json").read_text())
    return (summary, np.load(out / "depth.npy"), np.load(out / "raw.npy"),
            [line for line in err.splitlines() if NOTE in line])


@pytest.fixture
def by_hand(tmp_path, capsys):
    """The Cornell box with its area light removed by hand: (depth, raw) of its capture,
    which notes no room light."""
    plain = _write(tmp_path, "by_hand.xml", _cornell().replace(AREA, ""))
    summary, depth, raw, notes = _capture(capsys, plain, tmp_path / "by_hand")
    assert notes == [] and "room_lights_left_out" not in summary
    assert np.isfinite(depth).any() and raw.max() > raw.min()  # (the illuminator lights it)
    return depth, raw


def test_the_cornell_boxs_area_light_is_left_out(tmp_path, capsys, by_hand):
    summary, depth, raw, notes = _capture(capsys, CORNELL, tmp_path / "out")
    assert len(notes) == 1, notes
    assert "the area light of shape 'light'" in notes[0]
    assert CORNELL in notes[0] and "--ambient-irradiance" in notes[0]
    assert summary["room_lights_left_out"] == ["the area light of shape 'light'"]
    assert np.array_equal(depth, by_hand[0], equal_nan=True)
    assert np.array_equal(raw, by_hand[1])


def test_an_environment_and_a_directional_light_are_left_out(tmp_path, capsys, by_hand):
    scene = _write(tmp_path, "sky.xml", _cornell().replace(AREA, "").replace(
        "</scene>", ROOM + "</scene>"))
    summary, depth, raw, notes = _capture(capsys, scene, tmp_path / "out")
    assert len(notes) == 1, notes
    assert "the envmap 'sky'" in notes[0] and "a directional emitter" in notes[0]
    assert summary["room_lights_left_out"] == ["the envmap 'sky'", "a directional emitter"]
    assert np.array_equal(depth, by_hand[0], equal_nan=True)
    assert np.array_equal(raw, by_hand[1])


def _kinds(scene):
    return sorted(e.class_name() for e in scene.static.emitters())


def test_a_point_light_still_stands_for_the_illuminator_a_constant_is_left_out(tmp_path):
    from dopplertof.cameras.preset import load_preset
    from dopplertof.cameras.scene_view import load_scene_for_camera

    scene = _write(tmp_path, "lamp.xml", _cornell().replace(
        "</scene>", '<emitter type="point"><point name="position" value="278, 273, -700"/>'
        '<rgb name="intensity" value="1e5"/></emitter><emitter type="constant"/></scene>'))
    loaded = load_scene_for_camera(scene, load_preset("azure-kinect"), (4, 4),
                                   {"unit": "mm"})
    assert _kinds(loaded) == ["PointLight"]  # (no illuminator added: the lamp stands for it)
    assert loaded.left_out_lights == ("a constant emitter", "the area light of shape 'light'")
    assert sum(NOTE in n for n in loaded.notes) == 1


def test_without_a_camera_or_through_an_auto_exposed_preset_the_lights_stay(tmp_path):
    import dopplertof
    from dopplertof.cameras.preset import load_preset
    from dopplertof.cameras.scene_view import load_scene_for_camera

    for scene in (dopplertof.load_file(CORNELL, {"unit": "mm"}),
                  load_scene_for_camera(CORNELL, load_preset("opt8241"), (4, 4),
                                        {"unit": "mm"})):
        assert _kinds(scene) == ["AreaLight"] and scene.left_out_lights == ()
        assert not [n for n in scene.notes if "room light" in n]
    sky = _write(tmp_path, "sky.xml", _cornell().replace("</scene>", ROOM + "</scene>"))
    with pytest.raises(SceneError, match="environment emitters are not modulated"):
        dopplertof.load_file(sky, {"unit": "mm"})
    with pytest.raises(SceneError, match="environment emitters are not modulated"):
        load_scene_for_camera(sky, load_preset("opt8241"), (4, 4), {"unit": "mm"})


def test_a_stream_through_a_preset_leaves_them_out_too(tmp_path, capsys):
    from dopplertof.cli import main

    code = main(["animate", CORNELL, "-D", "unit=mm", "--camera", "azure-kinect",
                 "--frames", "2", "--res", "8x6", "--spp", "2", "--workers", "1",
                 "-o", str(tmp_path / "out"), "--quiet"])
    err = capsys.readouterr().err
    assert code == 0, err
    notes = [line for line in err.splitlines() if NOTE in line]
    assert len(notes) == 1 and "the area light of shape 'light'" in notes[0], err
    for index in ("stream.json", os.path.join("frame_0000", "summary.json")):
        summary = json.loads((tmp_path / "out" / index).read_text())
        assert summary["room_lights_left_out"] == ["the area light of shape 'light'"]


def test_an_area_light_given_by_reference_goes_with_its_ref(tmp_path):
    """``<emitter type="area" id="ceiling_light">`` at the top level, ``<ref
    id="ceiling_light"/>`` in the shape: both go (a dangling ref would not load)."""
    import dopplertof
    from dopplertof.cameras.preset import load_preset
    from dopplertof.cameras.scene_view import load_scene_for_camera

    named = AREA.replace('type="area"', 'type="area" id="ceiling_light"')
    floor = '<shape type="rectangle" id="floor">'
    scene = _write(tmp_path, "ref.xml", _cornell().replace(
        AREA, '<ref id="ceiling_light"/>').replace(floor, named + floor))
    assert _kinds(dopplertof.load_file(scene, {"unit": "mm"})) == ["AreaLight"]
    loaded = load_scene_for_camera(scene, load_preset("azure-kinect"), (4, 4), {"unit": "mm"})
    assert [e.id() for e in loaded.static.emitters()] == ["camera_illuminator"]
    assert loaded.left_out_lights == ("the area light 'ceiling_light'",)


def test_an_area_light_whose_type_is_a_parameter_is_left_out_too(tmp_path):
    """``<emitter type="$lamp">`` with ``lamp`` an area light, by its ``<default>`` or
    by -D: left out as the literal one is, and the camera's illuminator lights the scene
    (before, the illuminator was not added: "the scene has no emitter")."""
    from dopplertof.cameras.preset import load_preset
    from dopplertof.cameras.scene_view import load_scene_for_camera

    typed = _cornell().replace(AREA, AREA.replace('type="area"', 'type="$lamp"'))
    declared = typed.replace('<scene version="3.0.0">',
                             '<scene version="3.0.0"><default name="lamp" value="area"/>', 1)
    for name, text, defines in (("default.xml", declared, {}),
                                ("given.xml", typed, {"lamp": "area"})):
        loaded = load_scene_for_camera(_write(tmp_path, name, text),
                                       load_preset("azure-kinect"), (4, 4),
                                       {"unit": "mm", **defines})
        assert [e.id() for e in loaded.static.emitters()] == ["camera_illuminator"], name
        assert loaded.left_out_lights == ("the area light of shape 'light'",)


def test_a_room_light_in_an_included_file_is_named_with_the_include(tmp_path, capsys):
    """The loader leaves out the scene file's own room lights; one in a file it
    ``<include>``s reaches the capture, which refuses it in one line that says so and
    what to do (it said "load_scene_for_camera leaves a scene file's room lights out",
    which the user had done), exit 2, nothing written."""
    from dopplertof.cli import main

    cornell = _cornell()
    start = cornell.index('<shape type="rectangle" id="light">')
    end = cornell.index("</shape>", start) + len("</shape>")
    _write(tmp_path, "lamp.xml", '<scene version="3.0.0">' + cornell[start:end].replace(
        '<ref id="lamp"/>', "") + "</scene>")
    scene = _write(tmp_path, "included.xml", cornell[:start] + '<include filename="lamp.xml"/>'
                   + cornell[end:])
    code = main(["capture", scene, "-D", "unit=mm", "--camera", "azure-kinect", "--res",
                 "4x4", "--spp", "2", "-o", str(tmp_path / "out"), "--quiet"])
    errors = [line for line in capsys.readouterr().err.splitlines() if "error" in line]
    assert code == 2 and len(errors) == 1, errors
    assert "an AreaLight cannot stand for azure-kinect's illuminator" in errors[0]
    assert "not those of a file it <include>s: move them into the scene file" in errors[0]
    assert not (tmp_path / "out").exists()


def test_an_area_light_on_a_mesh_without_an_id_is_named_by_its_type(tmp_path):
    """An area light on an unnamed ``obj`` mesh beside the Cornell box's lamp: both left
    out, the mesh's named "the area light of an obj shape" (it read "a obj shape")."""
    from dopplertof.cameras.preset import load_preset
    from dopplertof.cameras.scene_view import load_scene_for_camera

    panel = os.path.join(STOCK, "common", "panel.obj")
    scene = _write(tmp_path, "panel.xml", _cornell().replace(
        "</scene>", f'<shape type="obj"><string name="filename" value="{panel}"/>'
        '<transform name="to_world"><scale value="30"/><translate x="278" y="540" '
        f'z="279"/></transform>{AREA}</shape></scene>'))
    loaded = load_scene_for_camera(scene, load_preset("azure-kinect"), (4, 4), {"unit": "mm"})
    assert [e.id() for e in loaded.static.emitters()] == ["camera_illuminator"]
    assert loaded.left_out_lights == ("the area light of shape 'light'",
                                      "the area light of an obj shape")


def test_a_point_light_in_an_included_file_still_stands_for_the_illuminator(tmp_path):
    """examples/translating_sphere.xml with its point light moved into a file it
    ``<include>``s: that light stands for the illuminator as the inline one does, no
    illuminator added beside it (it was: two lights, the capture silently another);
    a nested include and a name given by a parameter are followed too."""
    import re

    import dopplertof
    from dopplertof.cameras.preset import load_preset
    from dopplertof.cameras.scene_view import load_scene_for_camera

    sphere = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))),
                          "examples", "translating_sphere.xml")
    with open(sphere, encoding="utf-8") as f:
        text = f.read()
    lamp = re.search(r'<emitter type="point">.*?</emitter>', text, flags=re.S).group(0)
    (tmp_path / "lights").mkdir()
    _write(tmp_path / "lights", "lamp.xml", f'<scene version="3.0.0">{lamp}</scene>')
    _write(tmp_path / "lights", "all.xml",
           '<scene version="3.0.0"><include filename="lamp.xml"/></scene>')
    dopplertof.set_variant("llvm_ad_rgb")
    for name, include, defines in (("direct.xml", "lights/lamp.xml", {}),
                                   ("nested.xml", "lights/all.xml", {}),
                                   ("named.xml", "lights/$lights.xml", {"lights": "lamp"})):
        scene = _write(tmp_path, name, text.replace(lamp, f'<include filename="{include}"/>'))
        loaded = load_scene_for_camera(scene, load_preset("azure-kinect"), (4, 4), defines)
        assert [e.class_name() for e in loaded.static.emitters()] == ["PointLight"], name
        assert [e.id() for e in loaded.static.emitters()] != ["camera_illuminator"]
