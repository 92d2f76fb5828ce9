"""Camera and light motion: ego-motion, lights on the camera, moving lights; the
renderer against quadrature, and the camera pipeline's ground truth relative to the camera.

Statistics: the one-pixel renders against quadrature (6 comparisons, rtol 2e-3) scatter
by under 1e-5 relative over 40 other seeds (0 homodyne): over 200 standard deviations;
the ego-motion capture's median velocity is off by at most 0.48% over 5 other seeds
(rtol 2%, systematic). No false failures to speak of. Their absolute floor (a
heterodyne value can be small) is the rounding of the pixel's float32 samples
(bounds.mean_rounding_bound), not a fixed number.
"""

import numpy as np
import pytest

import dopplertof
from analytic import homodyne_amplitude, plane_scene, reference
from bounds import mean_rounding_bound


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
    assert abs(got - expected) <= 2e-3 * abs(expected) + mean_rounding_bound(
        homodyne_amplitude(4.0, 10.0, **motion), 1 << 13), (got, expected)


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


def test_a_moving_spot_light_against_quadrature():
    """A spot light moving along the axis, its beam (50 degrees) wider than the 4-degree
    view: inside the beam it is the point light of the quadrature."""
    import mitsuba as mi

    T = mi.ScalarTransform4f
    d = plane_scene(4.0, 10.0, spp=1 << 12, integrator={"hetero_frequency": 1.0})
    d["light"] = {"type": "spot", "cutoff_angle": 60.0, "beam_width": 50.0,
                  "intensity": {"type": "rgb", "value": 10.0},
                  "to_world": dopplertof.Animation([(0.0, T()),
                                                    (0.0015, T().translate([0, 0, -0.3]))])}
    got = dopplertof.render(dopplertof.load_dict(d), seed=3)[0, 0, 0]
    expected = reference(4.0, 10.0, hetero_frequency=1.0, light_velocity=-200.0)
    assert abs(got - expected) <= 2e-3 * abs(expected) + mean_rounding_bound(
        homodyne_amplitude(4.0, 10.0, light_velocity=-200.0), 1 << 12), (got, expected)


def test_matrix_interpolated_keyframes_render_the_same_motion():
    """interpolation="matrix" (the Mitsuba 3 implementation's element-wise lerp) on a
    translation, which it interpolates exactly: the render matches the quadrature."""
    d = plane_scene(4.0, 30.0, spp=1 << 12, integrator={"hetero_frequency": 1.0})
    d["plane"]["to_world"] = dopplertof.Animation(d["plane"]["to_world"].keyframes,
                                                  interpolation="matrix")
    scene = dopplertof.load_dict(d)
    assert scene.bodies[0].motion.keyframes.interpolation == "matrix"
    got = dopplertof.render(scene, seed=4)[0, 0, 0]
    expected = reference(4.0, 30.0, hetero_frequency=1.0)
    assert abs(got - expected) <= 2e-3 * abs(expected) + mean_rounding_bound(
        homodyne_amplitude(4.0, 30.0), 1 << 12), (got, expected)


def test_orthographic_camera_moving_toward_a_wall():
    """An orthographic camera (parallel rays) with its light on it closes in on a static
    wall at 25 m/s: every pixel's truth is -25 m/s, and the capture measures it."""
    import mitsuba as mi

    T = mi.ScalarTransform4f

    def pose(z):
        return (T().look_at(origin=[0, 0, z], target=[0, 0, z + 1], up=[0, 1, 0])
                @ T().scale([0.05, 0.05, 1.0]))

    d = plane_scene(3.0, 0.0, spp=256, res=6, camera_velocity=25.0)
    d["sensor"]["type"] = "orthographic"
    del d["sensor"]["fov"]
    d["sensor"]["to_world"] = dopplertof.Animation([(0.0, pose(0.0)),
                                                    (0.0015, pose(25.0 * 0.0015))])
    frame = dopplertof.capture(dopplertof.load_dict(d), spp=256, seed=0)
    assert np.allclose(frame.velocity_gt, -25.0, rtol=1e-6)
    assert np.median(np.abs(frame.velocity / -25.0 - 1)) < 0.01, frame.velocity
