"""Hostile input through the CLI: one line naming the problem, exit code 2, no traceback,
and an existing output file left untouched. Each case is a distinct fault."""

import numpy as np
import pytest

import dopplertof
from dopplertof.cli import main

GOOD = """<scene version="3.0.0">
  <default name="res" value="6"/>
  <integrator type="dopplertof">
    <integer name="max_depth" value="3"/>
    <float name="hetero_frequency" value="1"/>
  </integrator>
  <sensor type="perspective">
    <transform name="to_world"><lookat origin="0,0,5" target="0,0,0" up="0,1,0"/></transform>
    <float name="shutter_close" value="0.0015"/>
    <film type="hdrfilm"><integer name="width" value="$res"/><integer name="height" value="$res"/>
      <rfilter type="box"/></film>
    <sampler type="correlated"><integer name="sample_count" value="4"/></sampler>
  </sensor>
  <emitter type="point"><point name="position" x="0" y="0" z="5"/>
    <rgb name="intensity" value="10"/></emitter>
  <bsdf type="diffuse" id="white"/>
  <shape type="cube" id="box"><ref id="white"/>
    <animation name="to_world">
      <transform time="0"><translate z="0"/></transform>
      <transform time="0.0015"><translate z="0.01"/></transform>
    </animation>
  </shape>
</scene>"""

KEYFRAMES = """<transform time="0"><translate z="0"/></transform>
      <transform time="0.0015"><translate z="0.01"/></transform>"""

# (case id, replacement old -> new in GOOD, expected text in the message)
SCENE_CASES = [
    ("broken-xml", ("</scene>", "</scen>"), "malformed XML"),
    ("not-a-scene", (None, '<shape type="cube"/>'), "root element must be <scene>"),
    ("unknown-tag", ('<bsdf type="diffuse" id="white"/>', '<bsdf type="diffuse" id="white"/><gizmo/>'),
     "gizmo"),
    ("unknown-plugin", ('type="diffuse"', 'type="velvetish"'), "velvetish"),
    ("unknown-integrator-param", ('<integer name="max_depth" value="3"/>',
                                  '<integer name="max_dept" value="3"/>'), "max_dept"),
    ("wrong-type", ('<integer name="max_depth" value="3"/>',
                    '<integer name="max_depth" value="deep"/>'), "must be an integer"),
    ("nan-frequency", ('<float name="hetero_frequency" value="1"/>',
                       '<float name="hetero_frequency" value="nan"/>'), "non-finite"),
    ("negative-exposure", ('<float name="hetero_frequency" value="1"/>',
                           '<float name="time" value="-1"/>'), "must be > 0"),
    ("zero-exposure", ('<float name="hetero_frequency" value="1"/>',
                       '<float name="time" value="0"/>'), "must be > 0"),
    ("unknown-waveform", ('<float name="hetero_frequency" value="1"/>',
                          '<string name="wave_function_type" value="sawtooth"/>'),
     "unknown wave_function_type"),
    ("unknown-method", ('<float name="hetero_frequency" value="1"/>',
                        '<string name="time_sampling_method" value="lucky"/>'),
     "unknown time_sampling_method"),
    ("both-frequencies", ('<float name="hetero_frequency" value="1"/>',
                          '<float name="hetero_frequency" value="1"/><float name="w_s" value="30"/>'),
     "not both"),
    ("one-keyframe", (KEYFRAMES, '<transform time="0"/>'), "at least 2 keyframes"),
    ("unsorted-keyframes", (KEYFRAMES, '<transform time="1"/><transform time="0"/>'),
     "unsorted keyframe"),
    ("duplicate-keyframes", (KEYFRAMES, '<transform time="0"/><transform time="0"/>'),
     "duplicate keyframe"),
    ("nan-keyframe", (KEYFRAMES, '<transform time="0"><translate z="nan"/></transform>'
                                 '<transform time="1"/>'), "non-finite"),
    ("singular-keyframe", (KEYFRAMES, '<transform time="0"><scale x="0"/></transform>'
                                      '<transform time="1"/>'), "non-invertible"),
    ("keyframe-without-time", (KEYFRAMES, '<transform/><transform time="1"/>'), "needs a 'time'"),
    ("unknown-transform-op", (KEYFRAMES, '<transform time="0"><shear x="1"/></transform>'
                                         '<transform time="1"/>'), "<shear>"),
    ("animated-emitter", ('<rgb name="intensity" value="10"/></emitter>',
                          '<rgb name="intensity" value="10"/><animation name="to_world">'
                          '<transform time="0"/><transform time="1"/></animation></emitter>'),
     "remove its 'position'"),
    ("animated-directional-light", ('<bsdf type="diffuse" id="white"/>',
                                    '<bsdf type="diffuse" id="white"/><emitter type="directional">'
                                    '<animation name="to_world"><transform time="0"/>'
                                    '<transform time="1"/></animation></emitter>'),
     "only point and spot lights can move"),
    ("sensor-follows", ('<float name="shutter_close" value="0.0015"/>',
                        '<animation name="to_world" follow="sensor"/>'), "'follow' is for lights"),
    ("sensor-animation-and-transform", ('<float name="shutter_close" value="0.0015"/>',
                                        '<animation name="to_world"><transform time="0"/>'
                                        '<transform time="1"/></animation>'),
     "must not also have"),
    ("missing-mesh", ('<bsdf type="diffuse" id="white"/>',
                      '<bsdf type="diffuse" id="white"/><shape type="obj">'
                      '<string name="filename" value="nowhere.obj"/></shape>'), "nowhere.obj"),
    ("undefined-default", ('value="$res"/><integer name="height"', 'value="$rez"/><integer name="height"'),
     "undefined parameter $rez"),
    ("unknown-sampler-param", ('<integer name="sample_count" value="4"/>',
                               '<integer name="sample_count" value="4"/>'
                               '<integer name="time_corelate_number" value="2"/>'),
     "time_corelate_number"),
    ("no-emitter", ('<emitter type="point"><point name="position" x="0" y="0" z="5"/>\n'
                    '    <rgb name="intensity" value="10"/></emitter>', ""), "no emitter"),
    ("sampler-method", ('<sampler type="correlated">', '<sampler type="correlated">'
                        '<string name="time_sampling_method" value="antithetic"/>'),
     "unknown parameter 'time_sampling_method' of the correlated sampler"),
    ("analytic-square-waves", ('<float name="hetero_frequency" value="1"/>',
                               '<float name="hetero_frequency" value="1"/>'
                               '<string name="time_sampling_method" value="analytic"/>'
                               '<string name="wave_function_type" value="rectangular"/>'),
     "needs wave_function_type 'sinusoidal'"),
    ("kp-not-dividing-spp", ('<integer name="sample_count" value="4"/>',
                             '<integer name="sample_count" value="4"/>'
                             '<integer name="path_correlate_number" value="3"/>'),
     "spp 4 is not a multiple of path_correlate_number=3"),
    ("mirror-with-four", ('<sampler type="correlated">', '<sampler type="correlated">'
                          '<integer name="time_correlate_number" value="4"/>'), None),
]


@pytest.fixture
def output(tmp_path):
    out = tmp_path / "keep.npy"
    np.save(out, np.arange(5.0))
    return out


def run_cli(capsys, *args):
    code = main(list(args))
    err = capsys.readouterr().err
    return code, err


def assert_clean_failure(code, err, expected, output, before):
    assert code == 2
    assert expected in err, err
    assert err.count("\n") == 1 and err.startswith("dopplertof: error: ")
    assert "Traceback" not in err
    assert output.read_bytes() == before


@pytest.mark.parametrize("change,expected", [c[1:] for c in SCENE_CASES],
                         ids=[c[0] for c in SCENE_CASES])
def test_bad_scene(tmp_path, capsys, output, change, expected):
    old, new = change
    text = new if old is None else GOOD.replace(old, new)
    assert old is None or old in GOOD
    if expected is None:  # a group of 4 with mirrored pairs
        text = text.replace('<float name="hetero_frequency" value="1"/>',
                            '<string name="time_sampling_method" value="antithetic_mirror"/>')
        expected = "needs time_correlate_number=2"
    scene = tmp_path / "scene.xml"
    scene.write_text(text)
    before = output.read_bytes()
    code, err = run_cli(capsys, "render", str(scene), "-o", str(output), "--quiet")
    assert_clean_failure(code, err, expected, output, before)


def test_a_stock_integrator_renders_with_the_defaults_and_a_note(tmp_path, capsys, output):
    """<integrator type="path"> (a stock scene's): the D-ToF defaults, as the Python API
    renders an mi.Scene under another integrator, and a one-line note naming it."""
    start, end = GOOD.index('<integrator type="dopplertof">'), GOOD.index("</integrator>")
    scene = tmp_path / "scene.xml"
    scene.write_text(GOOD[:start] + '<integrator type="path"/>'
                     + GOOD[end + len("</integrator>"):])
    code, err = run_cli(capsys, "render", str(scene), "-o", str(output), "--quiet")
    assert code == 0, err
    note, = [line for line in err.splitlines() if "note" in line]
    assert f'{scene}:3: <integrator type="path"> is not a D-ToF integrator: using the D-ToF ' \
           'defaults' in note
    loaded = dopplertof.load_file(str(scene))
    assert loaded.params == dopplertof.RenderParams()


def test_good_scene_renders(tmp_path, capsys, output):
    scene = tmp_path / "scene.xml"
    scene.write_text(GOOD)
    code, err = run_cli(capsys, "render", str(scene), "-o", str(output), "--quiet")
    assert code == 0, err
    assert np.load(output).shape == (6, 6, 3)


@pytest.mark.parametrize("args,expected", [
    (["--spp", "3"], "not a multiple of the group size"),
    (["--spp", "0"], "spp must be >= 1"),
    (["--seed", "-1"], "seed must be an integer in [0, 2^64)"),
    (["--seed", str(1 << 64)], "seed must be an integer in [0, 2^64), got 18446744073709551616"),
    (["-D", "resolution=4"], "unknown scene parameter 'resolution'"),
    (["-D", "res"], "-D expects name=value"),
    (["-P", "hetero_frequncy=1"], "unknown parameter 'hetero_frequncy'"),
    (["-P", "max_depth=0"], "max_depth must be >= 1"),
    (["-P", "rr_depth=x"], "must be an integer"),
    (["--variant", "scalar_rgb"], "not supported"),
    (["-P", "samples_per_pass=3"], "spp 4 is not a multiple of samples_per_pass=3"),
    (["-P", "timeout=inf"], "must be finite"),
], ids=lambda v: " ".join(v) if isinstance(v, list) else None)
def test_bad_arguments(tmp_path, capsys, output, args, expected):
    scene = tmp_path / "scene.xml"
    scene.write_text(GOOD)
    before = output.read_bytes()
    code, err = run_cli(capsys, "render", str(scene), "-o", str(output), "--quiet", *args)
    assert_clean_failure(code, err, expected, output, before)


@pytest.mark.parametrize("target,expected", [
    ("{dir}/out.jpg", "unknown output extension"),
    ("{dir}/out", "unknown output extension"),
    ("{dir}/keep.npy/sub/out.npy", "keep.npy is a file"),
    ("{dir}", "unknown output extension"),
])
def test_bad_output_paths(tmp_path, capsys, output, target, expected):
    scene = tmp_path / "scene.xml"
    scene.write_text(GOOD)
    before = output.read_bytes()
    code, err = run_cli(capsys, "render", str(scene), "-o", target.format(dir=tmp_path))
    assert_clean_failure(code, err, expected, output, before)


def test_unwritable_output_folder(tmp_path, capsys, output):
    import os

    locked = tmp_path / "locked"
    locked.mkdir()
    locked.chmod(0o500)
    scene = tmp_path / "scene.xml"
    scene.write_text(GOOD)
    before = output.read_bytes()
    try:
        code, err = run_cli(capsys, "render", str(scene), "-o", str(locked / "x.npy"))
    finally:
        locked.chmod(0o700)
    if os.geteuid() == 0:  # root writes anywhere: the check must still not crash
        assert code == 0, err
    else:
        assert_clean_failure(code, err, "not writable", output, before)


def test_scene_that_is_not_xml(tmp_path, capsys, output):
    scene = tmp_path / "scene.xml"
    scene.write_bytes(b"\x89PNG\r\n\x1a\n\x00\x00")
    before = output.read_bytes()
    code, err = run_cli(capsys, "render", str(scene), "-o", str(output))
    assert_clean_failure(code, err, "scene", output, before)


@pytest.mark.parametrize("rfilter", ["box", "tent"])  # (tent: the splat film's own kernel)
def test_a_few_nonfinite_samples_are_dropped_counted_and_said(rfilter, capfd):
    """A NaN that reaches the renderer (dict scenes are not checked) on a speck seen by
    a few samples: dropped per sample, counted in the metadata and on stderr (also
    without progress output, as --quiet renders), the image finite."""
    import dopplertof
    from analytic import plane_scene

    d = plane_scene(3.0, 0.0, spp=16, res=16)
    d["sensor"]["film"]["rfilter"] = {"type": rfilter}
    d["nan"] = {"type": "diffuse",
                "reflectance": {"type": "rgb", "value": [float("nan"), 0.5, 0.5]}}
    d["speck"] = {"type": "sphere", "center": [0.0, 0.0, 2.9], "radius": 0.004,
                  "bsdf": {"type": "ref", "id": "nan"}}
    result = dopplertof.render_result(dopplertof.load_dict(d), seed=0, progress=False)
    dropped = result.metadata["nonfinite_samples_dropped"]
    assert 0 < dropped <= 0.01 * 16 * 16 * 16  # (5 of 4096 at seed 0)
    assert np.all(np.isfinite(result.image))
    err = capfd.readouterr().err
    assert f"dopplertof: {dropped} of 4096 samples" in err and "dropped" in err


def test_mostly_nonfinite_samples_fail_the_render_naming_the_count():
    """Every sample meets a NaN (issue 22, item 6: an all-zero image and exit 0 before):
    a SceneError naming the count, the limit and the likely cause."""
    import dopplertof
    from analytic import plane_scene

    d = plane_scene(5.0, 0.0, spp=16, res=4)
    d["white"] = {"type": "diffuse",
                  "reflectance": {"type": "rgb", "value": [float("nan"), 0.5, 0.5]}}
    with pytest.raises(dopplertof.SceneError, match=r"256 of 256 samples \(100.00%\) were "
                       r"non-finite.*more than the 1%.*NaN or infinite values in the scene"):
        dopplertof.render_result(dopplertof.load_dict(d), seed=0, progress=False)


def test_a_phase_float32_cannot_evaluate_fails_the_render(tmp_path, capsys, output):
    """-P hetero_frequency=1e12 made every sample NaN and wrote an all-zero image with
    exit 0 (with --quiet, not a word): one line naming the count and the cause, exit 2."""
    scene = tmp_path / "scene.xml"
    scene.write_text(GOOD)
    before = output.read_bytes()
    code, err = run_cli(capsys, "render", str(scene), "-o", str(output), "--quiet",
                        "-P", "hetero_frequency=1e12")
    assert_clean_failure(code, err, "of 144 samples", output, before)  # (6x6, 4 spp)
    assert "were non-finite" in err and "likely cause: hetero_frequency 1e+12" in err


# ---- Bad mesh files (issue 22, item 15): the file named and what is wrong with it ------

QUAD_OBJ = "v -1 -1 0\nv 1 -1 0\nv 1 1 0\nv -1 1 0\nf 1 2 3\nf 1 3 4\n"


def binary_ply(vertices, faces, vertex_count=None) -> bytes:
    """A binary little-endian PLY of float xyz vertices and triangles (uchar, int)."""
    import struct

    header = (f"ply\nformat binary_little_endian 1.0\n"
              f"element vertex {len(vertices) if vertex_count is None else vertex_count}\n"
              "property float x\nproperty float y\nproperty float z\n"
              f"element face {len(faces)}\nproperty list uchar int vertex_indices\n"
              "end_header\n")
    return (header.encode() + np.asarray(vertices, "<f4").tobytes()
            + b"".join(struct.pack("<B3i", 3, *face) for face in faces))


QUAD = [[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]]
ASCII_PLY = ("ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\n"
             "property float z\nelement face 2\nproperty list uchar int vertex_indices\n"
             "end_header\n-1 -1 0\n1 -1 0\n1 1 0\n-1 1 0\n3 0 1 2\n3 0 2 3\n")

# (case id, file name, contents, expected text in the message besides the file name)
MESH_CASES = [
    ("obj-empty", "wall.obj", b"", "the file is empty"),
    ("obj-binary-junk", "wall.obj", bytes(range(256)) * 2, "not an OBJ text file"),
    ("obj-cut-in-a-face", "wall.obj", QUAD_OBJ[:41].encode(), "line 5: a face with only 2"),
    ("obj-cut-in-a-vertex", "wall.obj", QUAD_OBJ[:14].encode(), "line 2: a vertex with 1"),
    ("obj-no-faces", "wall.obj", QUAD_OBJ[:36].encode(), "no faces"),
    ("obj-index-out-of-range", "wall.obj", QUAD_OBJ.replace("f 1 3 4", "f 1 3 9").encode(),
     "line 6: a face uses vertex 9, but 4 vertices"),
    ("obj-nan-vertex", "wall.obj", QUAD_OBJ.replace("v 1 1 0", "v 1 nan 0").encode(),
     "line 3: non-finite vertex"),
    ("ply-empty", "wall.ply", b"", "the file is empty"),
    ("ply-not-ply", "wall.ply", b"\x89PNG" + bytes(100), "not a PLY file"),
    ("ply-cut-off", "wall.ply", binary_ply(QUAD, [[0, 1, 2], [0, 2, 3]])[:-10],
     "cut off: 64 bytes of data, the header's counts need at least 74"),
    ("ply-counts-disagree", "wall.ply", binary_ply(QUAD, [[0, 1, 2]], vertex_count=6),
     "the header's counts need at least"),
    ("ply-no-faces", "wall.ply", binary_ply(QUAD, []), "no faces"),
    ("ply-index-out-of-range", "wall.ply", binary_ply(QUAD, [[0, 1, 2], [0, 2, 9]]),
     "face 1 uses vertex 9 (counting from 0), but the mesh has 4 vertices"),
    ("ply-ascii-cut-off", "wall.ply", ASCII_PLY[:-5].encode(),
     "data line 6 (face 1): '3 0' is not a whole face"),
]


def scene_with_mesh(tmp_path, name: str) -> str:
    scene = tmp_path / "scene.xml"
    scene.write_text(GOOD.replace(
        '<bsdf type="diffuse" id="white"/>',
        f'<bsdf type="diffuse" id="white"/><shape type="{name[-3:]}" id="wall">'
        f'<string name="filename" value="{name}"/><ref id="white"/></shape>'))
    return str(scene)


@pytest.mark.parametrize("name,contents,expected", [c[1:] for c in MESH_CASES],
                         ids=[c[0] for c in MESH_CASES])
def test_bad_mesh_file(tmp_path, capsys, output, name, contents, expected):
    (tmp_path / name).write_bytes(contents)
    scene = scene_with_mesh(tmp_path, name)
    before = output.read_bytes()
    code, err = run_cli(capsys, "render", scene, "-o", str(output), "--quiet")
    assert_clean_failure(code, err, expected, output, before)
    assert "wall" in err  # the mesh named: its file, or its id for what Mitsuba loaded


@pytest.mark.parametrize("name,contents", [
    ("wall.obj", QUAD_OBJ.encode()), ("wall.ply", binary_ply(QUAD, [[0, 1, 2], [0, 2, 3]])),
    ("wall.ply", ASCII_PLY.encode())], ids=["obj", "binary-ply", "ascii-ply"])
def test_good_mesh_files_render(tmp_path, capsys, output, name, contents):
    (tmp_path / name).write_bytes(contents)
    code, err = run_cli(capsys, "render", scene_with_mesh(tmp_path, name), "-o", str(output),
                        "--quiet")
    assert code == 0, err


def test_bad_mesh_in_a_dict_scene(tmp_path, monkeypatch):
    import dopplertof
    from analytic import plane_scene

    monkeypatch.chdir(tmp_path)
    (tmp_path / "empty.obj").write_bytes(b"")
    d = plane_scene(5.0, 0.0, spp=4, res=4)
    d["wall"] = {"type": "obj", "filename": "empty.obj"}
    with pytest.raises(dopplertof.SceneError, match="'wall': mesh file empty.obj: the file is "
                       "empty"):
        dopplertof.load_dict(d)


@pytest.mark.parametrize("command", [["dataset", "{file}", "-o", "{out}"],
                                     ["sweep", "{file}", "-o", "{out}"],
                                     ["cameras", "{file}"]])
@pytest.mark.parametrize("content", [bytes(range(0xC1, 0xFF)) * 2,  # D02, P37: junk
                                     'name = "café"\n'.encode("latin-1")])  # D58: Latin-1
def test_a_config_or_preset_that_is_not_utf8_names_the_file(tmp_path, capsys, command,
                                                            content):
    """issue 39, 2026-12-03 campaign D02, D58, P37: 'utf-8' codec can't decode byte 0xc1
    in position 0, naming no file."""
    from dopplertof.cli import main

    path = tmp_path / "config.toml"
    path.write_bytes(content)
    out = tmp_path / "out"
    code = main([a.format(file=path, out=out) for a in command])
    err = capsys.readouterr().err.strip()
    assert code == 2 and len(err.splitlines()) == 1, err
    assert f"{path}: not a UTF-8 text file" in err and not out.exists()


def test_a_toml_file_with_a_utf8_byte_order_mark_is_read(tmp_path):
    """issue 39, 2026-12-03 campaign D57: a configuration saved with a byte-order mark (as
    Windows editors write) failed as 'malformed TOML: Invalid statement (at line 1,
    column 1)'."""
    from dopplertof.file_formats import read_toml

    text = 'samples = 3\n[render]\nspp = 4\nname = "wall"\n'
    (tmp_path / "plain.toml").write_text(text, encoding="utf-8")
    (tmp_path / "bom.toml").write_bytes(b"\xef\xbb\xbf" + text.encode("utf-8"))
    assert read_toml(tmp_path / "bom.toml") == read_toml(tmp_path / "plain.toml") == {
        "samples": 3, "render": {"spp": 4, "name": "wall"}}
