"""Loading: the published fixture, animations, the dict API, and bad scenes."""

import numpy as np
import pytest

import dopplertof
from conftest import PUBLISHED
from dopplertof.scene import SceneError

BASE = """<scene version="3.0.0">
  <integrator type="dopplertof">{integrator}</integrator>
  <sensor type="perspective">
    <transform name="to_world"><lookat origin="0,0,5" target="0,0,0" up="0,1,0"/></transform>
    <film type="hdrfilm"><integer name="width" value="8"/><integer name="height" value="8"/>
      <rfilter type="box"/></film>
    <sampler type="independent"><integer name="sample_count" value="4"/></sampler>
  </sensor>
  <emitter type="point"><point name="position" x="0" y="0" z="5"/>
    <rgb name="intensity" value="10"/></emitter>
  <bsdf type="diffuse" id="white"/>
  {shapes}
</scene>"""

ANIM = """<shape type="cube" id="{id}"><ref id="white"/>
  <animation name="to_world">{keyframes}</animation></shape>"""


def load(integrator="", shapes="", **overrides):
    return dopplertof.scene.load_string(BASE.format(integrator=integrator, shapes=shapes),
                                        overrides)


def keyframes(*times):
    return "".join(f'<transform time="{t}"><translate z="{i * 0.01}"/></transform>'
                   for i, t in enumerate(times))


def test_published_fixture_renders_with_signal_on_moving_boxes():
    scene = dopplertof.load_file(PUBLISHED, {"resx": 48, "resy": 48})
    assert scene.params.time_sampling_method == "antithetic"
    assert scene.params.hetero_frequency == 1.0
    assert scene.params.path_correlation_depth == 4 and scene.params.max_depth == 4
    assert scene.shutter_interval == pytest.approx(0.0015)
    assert len(scene.bodies) == 2 and scene.spp == 1024
    H = dopplertof.render(scene, spp=128, seed=0, params={"hetero_frequency": 0}).mean(-1)
    E = dopplertof.render(scene, spp=128, seed=0).mean(-1)
    assert np.all(np.isfinite(E)) and np.all(np.isfinite(H))
    # Tall box (left of centre): receding at 10 m/s, so E / H ~ omega_g 2 v T / (c 2 pi)
    expected = 2 * 10 * 30e6 * 0.0015 / 299792458
    tall = (slice(21, 42), slice(12, 22))
    ratio = np.median((E[tall] / H[tall])[np.abs(H[tall]) > 0.02])
    assert 0.6 * expected < ratio < 1.6 * expected
    # A static wall (top rows): no Doppler signal beyond noise
    wall = (slice(8, 16), slice(12, 36))
    assert abs(np.median(E[wall] / H[wall])) < 0.2 * expected


def test_defaults_and_overrides():
    s = load(integrator='<float name="w_g" value="$f"/>', f=20)
    assert s.params.w_g == 20.0
    with pytest.raises(SceneError, match="unknown scene parameter 'nope'"):
        load(nope=3)
    with pytest.raises(SceneError, match=r"undefined parameter \$f"):
        load(integrator='<float name="w_g" value="$f"/>')


def test_shapes_with_equal_animation_form_one_body():
    shapes = (ANIM.format(id="a", keyframes=keyframes(0, 1))
              + ANIM.format(id="b", keyframes=keyframes(0, 1))
              + ANIM.format(id="c", keyframes=keyframes(0, 2)))
    s = load(shapes=shapes)
    assert sorted(b.names for b in s.bodies) == [("a", "b"), ("c",)]


@pytest.mark.parametrize("shapes,message", [
    (ANIM.format(id="a", keyframes=keyframes(0)), "at least 2 keyframes"),
    (ANIM.format(id="a", keyframes=keyframes(1, 0)), "unsorted keyframe times"),
    (ANIM.format(id="a", keyframes=keyframes(0, 0)), "duplicate keyframe times"),
    (ANIM.format(id="a", keyframes='<transform time="0"><scale value="0"/></transform>'
                 '<transform time="1"/>'), "non-invertible"),
    (ANIM.format(id="a", keyframes='<transform time="0"><translate x="nan"/></transform>'
                 '<transform time="1"/>'), "non-finite"),
    (ANIM.format(id="a", keyframes='<transform time="x"/><transform time="1"/>'),
     "not a number"),
    ('<shape type="cube"><animation name="bsdf"><transform time="0"/><transform time="1"/>'
     '</animation></shape>', 'only <animation name="to_world">'),
])
def test_bad_animations(shapes, message):
    with pytest.raises(SceneError, match=message):
        load(shapes=shapes)


def test_animated_emitter_is_an_error():
    text = BASE.format(integrator="", shapes="").replace(
        '<rgb name="intensity" value="10"/></emitter>',
        '<rgb name="intensity" value="10"/><animation name="to_world"><transform time="0"/>'
        '<transform time="1"/></animation></emitter>')
    with pytest.raises(SceneError, match="takes its position from the <animation>"):
        dopplertof.scene.load_string(text)


@pytest.mark.parametrize("integrator,message", [
    ('<string name="wave_function_type" value="sawtooth"/>', "unknown wave_function_type"),
    ('<string name="time_sampling_method" value="random"/>', "unknown time_sampling_method"),
    ('<float name="time" value="-0.001"/>', "must be > 0"),
    ('<float name="w_g" value="nan"/>', "non-finite value 'nan'"),
    ('<integer name="max_dpeth" value="3"/>', "unknown parameter 'max_dpeth'"),
    ('<integer name="max_depth" value="three"/>', "must be an integer"),
])
def test_bad_integrator_parameters(integrator, message):
    with pytest.raises(SceneError, match=message) as info:
        load(integrator=integrator)
    assert "\n" not in str(info.value)
    assert ":2:" in str(info.value)  # file and line of the <integrator>


def test_malformed_xml_names_the_line():
    with pytest.raises(SceneError, match=r"<string>:3: malformed XML"):
        dopplertof.scene.load_string("<scene version='3.0.0'>\n<shape type='cube'>\n</scene>")


def test_spp_not_multiple_of_group_size():
    s = load()
    with pytest.raises(ValueError, match="spp 7 is not a multiple of the group size "
                                         "time_correlate_number=2"):
        dopplertof.render(s, spp=7)


def test_unknown_render_parameter():
    with pytest.raises(dopplertof.ParameterError, match="unknown parameter 'hetero_freq'"):
        dopplertof.render(load(), spp=2, params={"hetero_freq": 1})


def test_dict_api_matches_xml():
    mi = pytest.importorskip("mitsuba")
    T = mi.ScalarTransform4f
    xml_scene = load(shapes=ANIM.format(id="box", keyframes=keyframes(0, 0.0015)))
    d = {
        "type": "scene",
        "integrator": {"type": "dopplertof"},
        "sensor": {"type": "perspective",
                   "to_world": T().look_at(origin=[0, 0, 5], target=[0, 0, 0], up=[0, 1, 0]),
                   "film": {"type": "hdrfilm", "width": 8, "height": 8,
                            "rfilter": {"type": "box"}},
                   "sampler": {"type": "correlated", "sample_count": 4}},
        "light": {"type": "point", "position": [0, 0, 5],
                  "intensity": {"type": "rgb", "value": 10}},
        "white": {"type": "diffuse"},
        "box": {"type": "cube", "bsdf": {"type": "ref", "id": "white"},
                "to_world": dopplertof.Animation([(0, T()), (0.0015, T().translate([0, 0, 0.01]))])},
    }
    dict_scene = dopplertof.load_dict(d)
    a = dopplertof.render(xml_scene, spp=8, seed=3)
    b = dopplertof.render(dict_scene, spp=8, seed=3)
    assert np.abs(a).max() > 0
    # one scene from two descriptions: the same float32 transforms up to their parsing's
    # rounding (1 u each), the same samples summed in the same order (one kernel): rtol
    # 1e-5 is 168 u of a pixel, atol 1e-7 the pixels near zero
    np.testing.assert_allclose(a, b, rtol=1e-5, atol=1e-7)


@pytest.mark.parametrize("rfilter", ["box", "tent", "gaussian"])
def test_reconstruction_filters_are_importance_sampled(rfilter):
    from analytic import plane_scene

    d = plane_scene(5.0, 0.0, spp=1 << 12, res=3)
    d["sensor"]["film"]["rfilter"] = {"type": rfilter}
    img = dopplertof.render(dopplertof.load_dict(d), seed=1)[..., 0]
    box = plane_scene(5.0, 0.0, spp=1 << 12, res=3)
    ref = dopplertof.render(dopplertof.load_dict(box), seed=2)[..., 0]
    # the plane is nearly uniform: wider filters change the centre pixel by < 0.1 % (the
    # seeds' part is negligible: such one-pixel homodyne renders scatter by ~1e-6)
    assert img[1, 1] == pytest.approx(ref[1, 1], rel=1e-3)


def test_filters_with_negative_lobes_are_refused():
    from analytic import plane_scene

    d = plane_scene(5.0, 0.0, spp=4)
    d["sensor"]["film"]["rfilter"] = {"type": "mitchell"}
    with pytest.raises(ValueError, match="MitchellNetravaliFilter is not supported"):
        dopplertof.render(dopplertof.load_dict(d))


@pytest.mark.parametrize("light,message", [
    ({"type": "directional"}, "only point and spot lights can move, not type 'directional'"),
    ({"type": "point", "position": [0, 0, 0]}, "takes its position from the <animation>"),
    ({"type": "point", "follow": "moon"}, 'only follow="sensor"'),
])
def test_dict_scenes_follow_the_xml_rules_of_motion(light, message):
    """One rule book (scene.check_motion) for what may move, in both loaders."""
    import mitsuba as mi
    from analytic import plane_scene

    T = mi.ScalarTransform4f
    follow = light.pop("follow", None)
    animation = (dopplertof.Animation((), follow=follow) if follow else
                 dopplertof.Animation([(0.0, T()), (0.0015, T().translate([0, 0, 0.01]))]))
    d = plane_scene(4.0, 0.0, spp=4)
    d["light"] = {**light, "irradiance" if light["type"] == "directional" else "intensity":
                  {"type": "rgb", "value": 1.0}, "to_world": animation}
    with pytest.raises(SceneError, match=message):
        dopplertof.load_dict(d)


def test_both_loaders_describe_a_scene_alike():
    """The XML and the dict loader produce one SceneDescription: the same moving body,
    keyframes, motion claims and integrator, for the same scene said both ways."""
    import mitsuba as mi

    from dopplertof.scene import dicts, xml

    T = mi.ScalarTransform4f
    text = BASE.format(integrator='<integer name="max_depth" value="3"/>',
                       shapes=ANIM.format(id="box", keyframes=keyframes(0, 0.0015)))
    from_xml = xml.describe(xml._Doc(text, "<string>"))
    from_dict = dicts.describe(mi, {
        "type": "scene", "integrator": {"type": "dopplertof", "max_depth": 3},
        "sensor": {"type": "perspective", "film": {"type": "hdrfilm", "width": 8, "height": 8}},
        "light": {"type": "point", "position": [0, 0, 5]},
        "white": {"type": "diffuse"},
        "box": {"type": "cube", "bsdf": {"type": "ref", "id": "white"},
                "to_world": dopplertof.Animation([(0, T()),
                                                  (0.0015, T().translate([0, 0, 0.01]))])}})
    for d in (from_xml, from_dict):
        assert [names for _, names, _ in d.bodies] == [["box"]]
        assert [(c.what, c.plugin_type, c.follow) for c in d.motions] == [("shape", None, None)]
        (where, values), = d.parameters  # XML values are text, the dict's Python values
        assert dopplertof.RenderParams.from_mapping(values, where=where).max_depth == 3
        assert d.has_integrator and d.sensor_keyframes is None and not d.light_keyframes
    (kf_xml, _, _), (kf_dict, _, _) = from_xml.bodies[0], from_dict.bodies[0]
    np.testing.assert_array_equal(kf_xml.times, kf_dict.times)
    np.testing.assert_allclose(kf_xml.matrix_array(), kf_dict.matrix_array(), atol=1e-7)


def test_a_description_is_validated_before_anything_loads():
    """build() checks what may move and the parameters of any description, from
    whichever loader, before Mitsuba loads a part."""
    import mitsuba as mi

    from dopplertof.scene.scene import MotionClaim, SceneDescription, build

    def never(part, what):
        raise AssertionError("loaded before it was validated")

    moving_sun = SceneDescription("<test>", None, motions=[
        MotionClaim("<test>[sun]", "emitter", "directional")])
    with pytest.raises(SceneError, match=r"<test>\[sun\]: only point and spot lights can move"):
        build(mi, moving_sun, never)
    bad_depth = SceneDescription("<test>", None, parameters=[("<test> integrator",
                                                              {"max_depth": "deep"})])
    with pytest.raises(SceneError, match="max_depth"):
        build(mi, bad_depth, never)


def test_an_empty_follow_on_the_sensor_keeps_its_keyframes():
    """follow="" is no follow (the rule book refuses only a non-empty one on the sensor):
    the loader reads the keyframes as before, rather than leaving the <animation> to
    Mitsuba."""
    text = """<scene version="3.0.0"><integrator type="dopplertof"/>
      <sensor type="perspective"><animation name="to_world" follow="{follow}">
        <transform time="0"><translate z="5"/></transform>
        <transform time="0.0015"><translate z="5.01"/></transform></animation>
        <film type="hdrfilm"><integer name="width" value="4"/>
          <integer name="height" value="4"/></film></sensor>
      <emitter type="point"><point name="position" x="0" y="0" z="5"/></emitter>
      <shape type="rectangle"/></scene>"""
    assert dopplertof.scene.load_string(text.format(follow="")).sensor_motion is not None
    with pytest.raises(SceneError, match="'follow' is for lights, not the sensor"):
        dopplertof.scene.load_string(text.format(follow="sensor"))


QUAD_OBJ = "v -1 -1 0\nv 1 -1 0\nv 1 1 0\nv -1 1 0\nf 1 2 3\nf 1 3 4\n"
PATH_SCENE = """<scene version="3.0.0">
  <path value="{path}"/>
  <sensor type="perspective">
    <transform name="to_world"><lookat origin="0,0,5" target="0,0,0" up="0,1,0"/></transform>
    <film type="hdrfilm"><integer name="width" value="4"/><integer name="height" value="4"/></film>
  </sensor>
  <emitter type="point"><point name="position" x="0" y="0" z="5"/></emitter>
  <shape type="obj" id="wall"><string name="filename" value="quad.obj"/></shape>
  <shape type="obj" id="panel"><string name="filename" value="{moving}"/>
    <animation name="to_world">
      <transform time="0"><translate z="1"/></transform>
      <transform time="0.0015"><translate z="1.01"/></transform>
    </animation></shape>
</scene>"""


def _path_layout(tmp_path, path="../../common", moving="quad.obj"):
    """scenes/one/scene.xml whose meshes lie in common/, named through <path>; the
    current folder elsewhere/ (neither)."""
    (tmp_path / "common").mkdir()
    (tmp_path / "common" / "quad.obj").write_text(QUAD_OBJ)
    (tmp_path / "scenes" / "one").mkdir(parents=True)
    scene = tmp_path / "scenes" / "one" / "scene.xml"
    scene.write_text(PATH_SCENE.format(path=path, moving=moving))
    (tmp_path / "elsewhere").mkdir()
    return scene


def test_path_folders_serve_static_and_moving_meshes_from_any_folder(tmp_path, monkeypatch):
    """<path> is read from the scene file's folder, as stock Mitsuba reads it, and serves
    the moving bodies' meshes as well as the static ones, whatever the current folder."""
    scene_file = _path_layout(tmp_path)
    monkeypatch.chdir(tmp_path / "elsewhere")
    scene = dopplertof.load_file(str(scene_file))
    assert [body.names for body in scene.bodies] == [("panel",)]
    assert [s.id() for s in scene.static.shapes()] == ["wall"]
    common = str(tmp_path / "common" / "quad.obj")
    assert {f.path for f in scene.inputs} == {common}
    # the resolver is left as it was: the next scene does not see these folders
    import mitsuba as mi
    resolver = mi.file_resolver()
    assert not any("common" in str(resolver[i]) for i in range(len(resolver)))


def test_a_missing_path_folder_is_one_line_naming_it(tmp_path, monkeypatch):
    scene_file = _path_layout(tmp_path, path="../nowhere")
    with pytest.raises(SceneError, match=r"scene\.xml:2: <path> folder '\.\./nowhere' not "
                                         r"found"):
        dopplertof.load_file(str(scene_file))


def test_a_bad_mesh_found_through_path_is_named(tmp_path, monkeypatch):
    scene_file = _path_layout(tmp_path, moving="cut.obj")
    (tmp_path / "common" / "cut.obj").write_text("v 0 0 0\nv 1 0 0\nf 1 2\n")
    monkeypatch.chdir(tmp_path / "elsewhere")
    with pytest.raises(SceneError, match=r"mesh file cut\.obj: line 3: a face with only 2"):
        dopplertof.load_file(str(scene_file))
