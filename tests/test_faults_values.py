"""Values that were silently wrong (issue 22, items 4-7, the unit mistakes, 14 and 17):
each is now a correct result or a one-line refusal naming the argument."""

import numpy as np
import pytest

import dopplertof
from dopplertof.demo import demo_scene_path
from dopplertof.experiments import ConfigError, config_from_mapping, plan_sweep


def sweep_config(run_seeds, reference_seed):
    """A 6x6 Cornell box sweep over ``run_seeds`` against a reference at ``reference_seed``
    that samples like the runs (the same spp): only the seed tells them apart."""
    return config_from_mapping({
        "name": "seeds", "scene": demo_scene_path(), "defines": {"res": 6, "max_depth": 2},
        "fixed": {"spp": 4, "hetero_frequency": 1.0},
        "grid": {"seed": list(run_seeds)},
        "reference": {"spp": 4, "seed": reference_seed}}, source="seeds.toml")


# ---- Item 5: the reference must not share a stream key with the runs -----------------

def test_a_reference_at_seed_2_to_the_32_is_not_the_runs_seed_0(tmp_path):
    """Seed 2^32 wrapped onto seed 0: the reference passed the 'must not share a seed'
    check and every run's MSE was 0.0. Now its stream key differs and so does its image."""
    tasks = plan_sweep(sweep_config([0], 1 << 32), str(tmp_path / "out"))
    run, = [t for t in tasks if t.kind == "run"]
    reference, = [t for t in tasks if t.kind == "reference"]
    assert (run.seed, reference.seed) == (0, 1 << 32)
    scene = dopplertof.load_file(run.scene, run.defines)
    images = [dopplertof.render(scene, spp=t.spp, seed=t.seed, params=t.params,
                                progress=False) for t in (run, reference)]
    assert np.mean((images[0] - images[1]) ** 2) > 0


def test_a_reference_sharing_the_runs_stream_key_is_refused():
    with pytest.raises(ConfigError, match=r"reference.seed 4294967296 is also a seed of the "
                                          "runs"):
        sweep_config([1, 1 << 32], 1 << 32)
    with pytest.raises(ConfigError, match=r"seed must be an integer in \[0, 2\^64\)"):
        sweep_config([1 << 64], 5)


# ---- Item 6 (see also test_bad_input.py): the limit is the documented one ----------------

def test_the_nonfinite_limit_is_one_percent():
    from dopplertof.integrators.pipeline import MAX_NONFINITE_FRACTION

    assert MAX_NONFINITE_FRACTION == 0.01


# ---- Item 7: a zero-length shutter is refused like time=0 ------------------------------

ROOT = __import__("os").path.dirname(__import__("os").path.dirname(__file__))
SPHERE = f"{ROOT}/examples/translating_sphere.xml"


def sphere_with(old, new, tmp_path):
    text = open(SPHERE).read()
    assert old in text
    path = tmp_path / "scene.xml"
    path.write_text(text.replace(old, new))
    return path


def fails(capsys, *argv):
    from dopplertof.cli import main

    code = main(list(argv))
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and "Traceback" not in err, err
    return err


@pytest.mark.parametrize("opens", ["0", "0.5"])
def test_a_zero_length_shutter_is_refused_naming_the_sensor(tmp_path, capsys, opens):
    """shutter_open = shutter_close was silently replaced by 1.5 ms (time=0 is refused)."""
    scene = sphere_with('<float name="shutter_open" value="0"/>     <!-- the exposure: 1.5 ms -->\n'
                        '        <float name="shutter_close" value="0.0015"/>',
                        f'<float name="shutter_open" value="{opens}"/>'
                        f'<float name="shutter_close" value="{opens}"/>', tmp_path)
    sensor_line = next(i for i, line in enumerate(open(scene), 1) if "<sensor" in line)
    err = fails(capsys, "render", str(scene), "-o", str(tmp_path / "x.npy"), "-D", "res=4",
                "--spp", "2", "--quiet")
    assert f"{scene}:{sensor_line}: the sensor's shutter (the exposure) must be open for > 0 " \
           f"seconds, got shutter_open = shutter_close = {opens}" in err
    assert not (tmp_path / "x.npy").exists()
    with pytest.raises(dopplertof.SceneError, match="must be open for > 0 seconds"):
        dopplertof.load_file(scene)


def test_a_shutter_given_by_time_or_not_given_keeps_working(tmp_path):
    from analytic import plane_scene

    # no shutter at all (Mitsuba's default, 0 to 0): the default exposure, 1.5 ms
    d = plane_scene(3.0, 0.0, spp=4, res=2)
    del d["sensor"]["shutter_open"], d["sensor"]["shutter_close"]
    assert dopplertof.load_dict(d).params.exposure(0.0) == 0.0015
    # a zero-length shutter beside an explicit exposure time: the time is the exposure
    d = plane_scene(3.0, 0.0, spp=4, res=2, integrator={"time": 0.002})
    d["sensor"]["shutter_close"] = 0.0
    assert dopplertof.load_dict(d).params.time == 0.002
    d = plane_scene(3.0, 0.0, spp=4, res=2)
    d["sensor"]["shutter_close"] = 0.0
    with pytest.raises(dopplertof.SceneError, match=r"<dict>\['sensor'\]: the sensor's shutter"):
        dopplertof.load_dict(d)


# ---- Unit mistakes: frequencies in MHz, times in seconds -----------------------------

@pytest.mark.parametrize("given, expected", [
    ("w_g=30e6", "w_g is in MHz: did you mean w_g=30? w_g must be a modulation frequency in "
                 "[1e-06, 100000] MHz (1 Hz to 100 GHz), got 3e+07"),
    ("w_g=1e30", "w_g must be a modulation frequency in [1e-06, 100000] MHz"),
    ("w_s=2.5e7", "w_s is in MHz: did you mean w_s=25?"),
    ("w_g=1e-9", "got 1e-09"),
])
def test_frequencies_outside_the_physical_range_are_refused(tmp_path, capsys, given, expected):
    err = fails(capsys, "render", SPHERE, "-o", str(tmp_path / "x.npy"), "-D", "res=4",
                "--spp", "2", "--quiet", "-P", given)
    assert expected in err
    assert not (tmp_path / "x.npy").exists()


def test_an_unwrap_frequency_in_hz_is_refused():
    from analytic import plane_scene

    scene = dopplertof.load_dict(plane_scene(3.0, 0.0, spp=4, res=2))
    with pytest.raises(ValueError, match="unwrap frequency is in MHz: did you mean "
                                         "unwrap frequency=25?"):
        dopplertof.capture(scene, spp=4, unwrap_frequency=25e6, progress=False)


def test_an_exposure_the_keyframes_barely_cover_is_warned(tmp_path, capfd):
    """-P time=1.5 (meant as ms) with keyframes to 1.5 ms ran a 1.5 s exposure whose
    motion stopped after 0.1% of it, without a word."""
    from dopplertof.cli import main

    assert main(["render", SPHERE, "-o", str(tmp_path / "x.npy"), "-D", "res=4", "--spp",
                 "2", "--quiet", "-P", "time=1.5"]) == 0
    warning = ("dopplertof: warning: the keyframes (0 to 0.0015 s) cover 0.1% of the exposure "
               "(0 to 1.5 s)")
    assert warning in capfd.readouterr().err
    assert main(["capture", SPHERE, "-o", str(tmp_path / "cap"), "-D", "res=4", "--spp", "2",
                 "--quiet", "-P", "time=1.5"]) == 0
    assert warning in capfd.readouterr().err
    import json

    summary = json.loads((tmp_path / "cap" / "summary.json").read_text())
    assert summary["warnings"][0].startswith(warning.removeprefix("dopplertof: warning: "))
    # the scene's own exposure, covered by its keyframes: no warning
    assert main(["render", SPHERE, "-o", str(tmp_path / "x.npy"), "-D", "res=4", "--spp",
                 "2", "--quiet"]) == 0
    assert "warning" not in capfd.readouterr().err


def test_keyframe_times_written_in_ms_are_warned():
    """Keyframes at time 0 and 1.5 (meant as 1.5 ms) under a 1.5 ms exposure cover it
    whole, so the coverage rule is silent, yet the body travels 1/1000 of its path (a
    truth of -0.007 m/s for 7 m/s, issue 22): the span of 1000 exposures is warned; the
    same keyframes in seconds are not."""
    import mitsuba as mi
    from analytic import plane_scene

    T = mi.ScalarTransform4f
    plane = lambda z: T().translate([0, 0, z]).rotate([0, 1, 0], 180).scale(50)  # noqa: E731
    warnings = []
    for last in (1.5, 0.0015):
        d = plane_scene(3.0, 0.0, spp=2, res=2)
        d["plane"]["to_world"] = dopplertof.Animation([(0.0, plane(3.0)), (last, plane(2.99))])
        result = dopplertof.render_result(dopplertof.load_dict(d), seed=0, progress=False)
        warnings.append(result.metadata.get("warnings", []))
    assert warnings[1] == []
    assert len(warnings[0]) == 1 and warnings[0][0].startswith(
        "the keyframes span 1.5 s, 1000 times the exposure (0.0015 s)")
    assert "were they written in ms?" in warnings[0][0]


def test_animation_frames_past_the_last_keyframe_are_warned(tmp_path):
    from dopplertof.experiments.animate import frames_past_keyframes, plan_animation

    tasks = plan_animation(SPHERE, tmp_path / "frames", 3, defines={"res": "4"}, spp=2)
    span = dopplertof.load_file(SPHERE, {"res": "4"}).keyframe_span
    assert span == (0.0, 0.0015)
    assert frames_past_keyframes(tasks, span) == (
        "frames 1 to 2 of 3 end after the last keyframe (0.0015 s): there everything holds "
        "its last pose and the motion stops (velocity 0)")
    assert frames_past_keyframes(tasks[:1], span) is None


# ---- Item 14 (part): a film of 0 pixels ------------------------------------------------

def test_a_film_of_zero_pixels_is_refused_naming_the_define(tmp_path, capsys):
    """-D res=0 gave 'integer division or modulo by zero'."""
    err = fails(capsys, "render", SPHERE, "-o", str(tmp_path / "x.npy"), "-D", "res=0",
                "--quiet")
    width_line = next(i for i, line in enumerate(open(SPHERE), 1) if '"width"' in line)
    assert (f"{SPHERE}:{width_line}: the film's width must be >= 1 pixel, got 0; from "
            "-D res=0") in err
    from analytic import plane_scene

    with pytest.raises(dopplertof.SceneError, match="the film is 0x0 pixels: its width and "
                                                    "height must be >= 1"):
        dopplertof.load_dict(plane_scene(3.0, 0.0, spp=4, res=0))


# ---- Item 17: the Python API names a bad argument and the type it expects ---------------

def _plane():
    from analytic import plane_scene

    return dopplertof.load_dict(plane_scene(3.0, 0.0, spp=4, res=2))


@pytest.mark.parametrize("call, error, message", [
    (lambda s: dopplertof.render(SPHERE), TypeError,
     "scene must be a DopplerScene (from dopplertof.load_file) or an mi.Scene: load it first with "
     "dopplertof.load_file(path), got str"),
    (lambda s: dopplertof.render_result(None), TypeError, "scene must be a DopplerScene"),
    (lambda s: dopplertof.render(s, params="w_g=30"), TypeError,
     "params must be a dict {name: value} of render parameters or a RenderParams"),
    (lambda s: dopplertof.render(s, spp=16.7), TypeError,
     "spp must be a positive integer (None: the scene's sample count), got float 16.7"),
    (lambda s: dopplertof.render(s, spp="16"), TypeError, "spp must be a positive integer"),
    (lambda s: dopplertof.render_result(s, seed=True), TypeError,
     "seed must be an integer in [0, 2^64), got bool True"),
    (lambda s: dopplertof.capture(s, spp=16.7), TypeError, "spp must be a positive integer"),
    (lambda s: dopplertof.capture(s, spp="16"), TypeError, "spp must be a positive integer"),
    (lambda s: dopplertof.capture(s, seed=True), TypeError, "seed must be an integer"),
    (lambda s: dopplertof.capture(s, params="w_g=30"), TypeError, "params must be a dict"),
    (lambda s: dopplertof.capture(42), TypeError, "scene must be a DopplerScene"),
    (lambda s: dopplertof.load_file(None), TypeError,
     "path must be a file path (str or os.PathLike), got NoneType None"),
    (lambda s: dopplertof.load_file(SPHERE, overrides="res=4"), TypeError,
     "overrides must be a dict or None"),
    (lambda s: dopplertof.load_string(None), TypeError, "text must be a str"),
    (lambda s: dopplertof.load_dict("scene.xml"), TypeError, "scene_dict must be a dict"),
    (lambda s: dopplertof.set_variant(3), TypeError, "variant must be a str"),
])
def test_public_entry_points_name_the_bad_argument(call, error, message):
    with pytest.raises(error) as info:
        call(_plane())
    assert message in str(info.value) and "\n" not in str(info.value)


def test_integer_like_arguments_of_numpy_still_work():
    scene = _plane()
    image = dopplertof.render(scene, spp=np.int64(4), seed=np.uint32(3))
    assert np.array_equal(image, dopplertof.render(scene, spp=4, seed=3))
