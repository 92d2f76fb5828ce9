"""Camera and light motion: ego-motion, lights on the camera, moving lights; the
renderer against quadrature, and the camera pipeline's ground truth relative to the camera."""

import numpy as np
import pytest

import dopplertof
from analytic import plane_scene, reference


@pytest.mark.parametrize("motion", [
    dict(camera_velocity=40.0),                       # ego-motion, light on the camera
    dict(light_velocity=-200.0),                      # a light moving on its own
    dict(camera_velocity=30.0, light_velocity=-100.0),
])
@pytest.mark.parametrize("hetero,offset", [(0.0, 0.1), (1.0, 0.0)])
def test_moving_camera_and_lights_against_quadrature(motion, hetero, offset):
    scene = dopplertof.load_dict(plane_scene(4.0, 10.0, spp=1 << 13, integrator={
        "hetero_frequency": hetero, "hetero_offset": offset}, **motion))
    got = dopplertof.render(scene, seed=1)[0, 0, 0]
    expected = reference(4.0, 10.0, hetero_frequency=hetero, hetero_offset=offset, **motion)
    assert abs(got - expected) <= 2e-3 * abs(expected) + 2e-7, (got, expected)


def test_ego_motion_is_relative_motion():
    """A camera (and its light) moving at 40 m/s toward a plane receding at 10 m/s sees
    the plane approach at 30 m/s: the same heterodyne value as a static camera."""
    ego = reference(4.0, 10.0, hetero_frequency=1.0, camera_velocity=40.0)
    still = reference(4.0, -30.0, hetero_frequency=1.0)
    assert ego == pytest.approx(still, rel=1e-9) and ego < 0


def test_ego_motion_toward_a_static_wall_gives_negative_velocity():
    scene = dopplertof.load_dict(plane_scene(3.0, 0.0, spp=64, res=8, camera_velocity=25.0))
    frame = dopplertof.capture(scene, spp=64, seed=0)
    truth = frame.velocity_gt
    assert np.all(np.isfinite(truth))
    # the wall is static and the camera closes in: along a ray at angle a off the axis
    # the distance shrinks at 25 / cos(a) (a < 3 degrees here)
    assert np.all(truth <= -25.0 * (1 - 1e-9)) and np.all(truth > -25.0 / np.cos(np.radians(3)))
    np.testing.assert_allclose(np.nanmedian(frame.velocity), -25.0, rtol=0.02)


def test_follow_sensor_light_sits_on_the_camera():
    text = """<scene version="3.0.0"><integrator type="dopplertof"/>
      <sensor type="perspective"><animation name="to_world">
        <transform time="0"><lookat origin="0,0,-1" target="0,0,1" up="0,1,0"/></transform>
        <transform time="0.0015"><lookat origin="0,0,-0.9" target="0,0,1" up="0,1,0"/></transform>
      </animation><film type="hdrfilm"><integer name="width" value="4"/>
      <integer name="height" value="4"/></film></sensor>
      <emitter type="point"><animation name="to_world" follow="sensor"/></emitter>
      <shape type="rectangle"/></scene>"""
    scene = dopplertof.load_string(text)
    assert scene.sensor_motion is not None and len(scene.light_motions) == 1
    assert scene.light_motions[0][1] is scene.sensor_motion
    import mitsuba as mi

    light = scene.static.emitters()[scene.light_motions[0][0]]
    pos = np.array(mi.traverse(light)["position"]).reshape(-1)[:3]
    np.testing.assert_allclose(pos, [0, 0, -1], atol=1e-6)


@pytest.mark.parametrize("emitter,message", [
    ('<emitter type="directional"><animation name="to_world"><transform time="0"/>'
     '<transform time="1"/></animation></emitter>', "only point and spot lights can move"),
    ('<emitter type="point"><point name="position" x="0" y="0" z="1"/><animation '
     'name="to_world"><transform time="0"/><transform time="1"/></animation></emitter>',
     "remove its 'position'"),
    ('<emitter type="point"><animation name="to_world" follow="moon"/></emitter>',
     "only follow=\"sensor\""),
])
def test_bad_light_animations(emitter, message):
    text = f"""<scene version="3.0.0"><sensor type="perspective"><film type="hdrfilm">
      <integer name="width" value="4"/><integer name="height" value="4"/></film></sensor>
      <emitter type="point"/>{emitter}<shape type="rectangle"/></scene>"""
    with pytest.raises(dopplertof.SceneError, match=message):
        dopplertof.load_string(text)
