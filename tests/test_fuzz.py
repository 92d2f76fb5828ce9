"""Property-based fuzzing of the scene loader and the parameter parser: whatever the input,
the only exceptions are the clean, one-line errors (SceneError, ParameterError)."""

import math

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import dopplertof
from dopplertof.params import ParameterError, RenderParams
from dopplertof.scene import SceneError
from dopplertof.scene.motion import Keyframes, MotionError

FUZZ = settings(max_examples=60, deadline=None, derandomize=True, database=None,
                suppress_health_check=[HealthCheck.function_scoped_fixture,
                                       HealthCheck.too_slow])

numbers = st.one_of(st.floats(allow_nan=True, allow_infinity=True, width=32),
                    st.integers(-10**6, 10**6))
text_values = st.one_of(numbers.map(str), st.text(max_size=12),
                        st.sampled_from(["true", "false", "nan", "inf", "-0", "1e40", ""]))
param_names = st.one_of(st.sampled_from(RenderParams.names()), st.text(min_size=1, max_size=10))


def clean(message: str):
    assert message and "\n" not in message


@FUZZ
@given(st.dictionaries(param_names, st.one_of(text_values, numbers, st.booleans()),
                       max_size=5))
def test_parameter_parser(values):
    try:
        params = RenderParams.from_mapping(values, where="fuzz")
    except ParameterError as e:
        clean(str(e))
        return
    for name in ("w_g", "g_0", "g_1", "antithetic_shift"):
        v = getattr(params, name)
        assert v is None or math.isfinite(v)


keyframe = st.tuples(st.one_of(numbers.map(str), st.text(max_size=4)),
                     st.lists(st.sampled_from([
                         '<translate x="{v}"/>', '<scale value="{v}"/>',
                         '<rotate y="1" angle="{v}"/>', '<matrix value="{v} 0 0 0 0 1 0 0 0 0 1 0 0 0 0 1"/>',
                         '<lookat origin="0,0,{v}" target="0,0,0" up="0,1,0"/>', '<bogus/>']),
                         max_size=3),
                     numbers)

SCENE = """<scene version="3.0.0">
  <integrator type="dopplertof">{params}</integrator>
  <sensor type="perspective">
    <film type="hdrfilm"><integer name="width" value="4"/><integer name="height" value="4"/></film>
    <sampler type="independent"><integer name="sample_count" value="2"/></sampler>
  </sensor>
  <emitter type="point"><point name="position" x="0" y="0" z="5"/></emitter>
  <shape type="cube"><animation name="to_world" {interp}>{keyframes}</animation></shape>
</scene>"""


@FUZZ
@given(st.lists(keyframe, max_size=4),
       st.sampled_from(["", 'interpolation="rigid"', 'interpolation="matrix"',
                        'interpolation="spline"']),
       st.dictionaries(param_names, text_values, max_size=3))
def test_xml_animation_loader(frames, interp, params):
    kfs = "".join(f'<transform time="{t}">' + "".join(op.format(v=v) for op in ops)
                  + "</transform>" for t, ops, v in frames)
    ps = "".join(f'<string name="{n}" value="{v}"/>' for n, v in params.items())
    text = SCENE.format(params=ps.replace("&", "&amp;").replace("<", "&lt;"),
                        interp=interp, keyframes=kfs)
    try:
        scene = dopplertof.load_string(text)
    except SceneError as e:
        clean(str(e))
        return
    assert len(scene.bodies) == 1


@FUZZ
@given(st.lists(st.tuples(numbers, st.lists(numbers, min_size=16, max_size=16)), max_size=4))
def test_keyframes(frames):
    import numpy as np

    try:
        kf = Keyframes.create([t for t, _ in frames], [np.reshape(m, (4, 4)) for _, m in frames])
    except MotionError as e:
        clean(str(e))
        return
    assert len(kf.times) >= 2 and all(np.isfinite(kf.times))


@pytest.mark.parametrize("junk", ["", "<", "<scene", "\x00", "<scene version='3.0.0'><shape",
                                  "<?xml version='1.0'?><!DOCTYPE x [<!ENTITY a 'b'>]><scene/>"])
def test_junk_documents(junk):
    with pytest.raises(SceneError) as info:
        dopplertof.load_string(junk)
    clean(str(info.value))
