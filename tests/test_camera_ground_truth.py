"""Ground truth from the analytic motion: depth, radial velocity (u.n)/(d.n), u.d.

The checks are independent of the formula: they intersect each pixel's ray with the
known moving plane at two nearby times (plane equation, NumPy) and difference the
distances, so a surface sliding along itself, or turning, must come out right.
"""

import math

import numpy as np
import pytest

import dopplertof
from dopplertof.tof import capture, ground_truth

T = 0.0015


def _transform():
    import mitsuba as mi

    return mi.ScalarTransform4f


def plane_dict(animation, fov=20.0, res=8, spp=16, backdrop=False, integrator=None):
    T4 = _transform()
    scene = {
        "type": "scene",
        "integrator": {"type": "dopplertof", "max_depth": 2, **(integrator or {})},
        "sensor": {
            "type": "perspective", "fov": fov, "near_clip": 0.01,
            "to_world": T4().look_at(origin=[0, 0, 0], target=[0, 0, 1], up=[0, 1, 0]),
            "shutter_open": 0.0, "shutter_close": T,
            "film": {"type": "hdrfilm", "width": res, "height": res, "rfilter": {"type": "box"}},
            "sampler": {"type": "independent", "sample_count": spp},
        },
        "light": {"type": "point", "position": [0, 0, 0],
                  "intensity": {"type": "rgb", "value": 10}},
        "plane": {"type": "rectangle", "bsdf": {"type": "diffuse"},
                  "to_world": dopplertof.Animation(animation)},
    }
    if backdrop:
        scene["backdrop"] = {
            "type": "rectangle", "bsdf": {"type": "diffuse"},
            "to_world": T4().translate([0, 0, 6]).rotate([0, 1, 0], 180).scale(1.5)}
    return scene


# ---- A plane tilted by 45 degrees about y, sliding sideways along x ----
TILT_Z0 = 4.0
TILT_NORMAL = np.array([-math.sqrt(0.5), 0.0, -math.sqrt(0.5)])  # faces the camera


def tilted_sliding_plane(speed, **kw):
    T4 = _transform()

    def pose(x):  # rectangle normal +z -> rotated 225 degrees about y: TILT_NORMAL
        return T4().translate([x, 0, TILT_Z0]).rotate([0, 1, 0], 225).scale(50)

    return plane_dict([(0.0, pose(0.0)), (T, pose(speed * T))], **kw)


def tilted_plane_distance(directions, t, speed):
    """Distance along each ray to the tilted plane at time t (plane equation)."""
    point = np.array([speed * t, 0.0, TILT_Z0])
    return (TILT_NORMAL @ point) / (directions @ TILT_NORMAL)


@pytest.mark.parametrize("speed", [12.0, -30.0])
def test_tilted_plane_sliding_sideways(speed):
    scene = dopplertof.load_dict(tilted_sliding_plane(speed))
    gt = ground_truth(scene)
    d = gt.direction
    mid, dt = T / 2, 1e-7
    expected = (tilted_plane_distance(d, mid + dt, speed)
                - tilted_plane_distance(d, mid - dt, speed)) / (2 * dt)
    assert np.allclose(gt.velocity, expected, rtol=1e-4, atol=1e-6)
    assert np.allclose(gt.depth, tilted_plane_distance(d, mid, speed), rtol=1e-5)
    # the material velocity along the ray, u.d = speed * d_x, is not what the phase follows
    assert np.allclose(gt.velocity_point, speed * d[..., 0], atol=1e-6)
    assert np.min(np.abs(gt.velocity - gt.velocity_point)) > 0.5 * abs(speed)
    # near the optical axis the distance changes at about the sliding speed, while u.d ~ 0
    centre = np.abs(gt.velocity_point) < 0.05 * abs(speed)
    assert centre.any() and np.allclose(gt.velocity[centre], speed, rtol=0.05)


def test_rotating_plane_and_misses():
    """A 1 m plate turning about a vertical axis off the optical axis, a static backdrop
    behind it, and rays that hit nothing."""
    T4 = _transform()
    pivot = np.array([0.3, 0.0, 3.0])
    total_angle = 10.0  # degrees over the exposure

    def pose(angle):
        return T4().translate(list(pivot)).rotate([0, 1, 0], 180 + angle).scale(0.5)

    scene = dopplertof.load_dict(plane_dict([(0.0, pose(0.0)), (T, pose(total_angle))],
                                            fov=40.0, res=12, backdrop=True))
    gt = ground_truth(scene)
    d = gt.direction

    def distance(t):
        angle = math.radians(180 + total_angle * t / T)
        normal = np.array([math.sin(angle), 0.0, math.cos(angle)])  # R_y(angle) (0, 0, 1)
        return (normal @ pivot) / (d @ normal)

    on_plate = gt.body == 0
    assert 10 < on_plate.sum() < on_plate.size
    mid, dt = T / 2, 1e-7
    expected = (distance(mid + dt) - distance(mid - dt)) / (2 * dt)
    assert np.allclose(gt.velocity[on_plate], expected[on_plate], rtol=1e-3, atol=1e-3)
    assert np.max(np.abs(gt.velocity[on_plate])) > 5.0  # it does move
    backdrop = gt.body == -1
    assert backdrop.any() and np.all(gt.velocity[backdrop] == 0.0)
    assert np.allclose(gt.depth[backdrop], 6.0 / d[backdrop][:, 2], rtol=1e-5)
    missed = gt.body == -2
    assert missed.any()
    assert np.all(np.isnan(gt.velocity[missed])) and np.all(np.isnan(gt.depth[missed]))


def test_reconstruction_follows_the_distance_not_u_dot_d():
    """Rendered and reconstructed, the tilted sliding plane measures (u.n)/(d.n)."""
    speed = 20.0
    scene = dopplertof.load_dict(tilted_sliding_plane(speed, fov=8.0, res=6))
    result = capture(scene, spp=256, seed=0, progress=False)
    v, gt = result.velocity, result.velocity_gt
    assert np.all(np.isfinite(v))
    assert np.max(np.abs(v / gt - 1)) < 0.03
    assert np.max(np.abs(result.truth.velocity_point)) < 0.1 * speed  # u.d would say ~0


def test_crop_window_is_the_same_part_of_the_frame():
    """A crop window's ground truth is that window of the whole frame's: film positions
    are normalized over the crop window, as Mitsuba's sensors take them."""
    full_dict = tilted_sliding_plane(12.0, res=16)
    crop_dict = tilted_sliding_plane(12.0, res=16)
    crop_dict["sensor"]["film"].update(
        {"crop_offset_x": 3, "crop_offset_y": 5, "crop_width": 9, "crop_height": 6})
    full = ground_truth(dopplertof.load_dict(full_dict))
    crop = ground_truth(dopplertof.load_dict(crop_dict))
    assert crop.depth.shape == (6, 9)
    window = (slice(5, 11), slice(3, 12))
    np.testing.assert_allclose(crop.direction, full.direction[window], atol=1e-6)
    np.testing.assert_allclose(crop.depth, full.depth[window], rtol=1e-5)
    np.testing.assert_allclose(crop.velocity, full.velocity[window], rtol=1e-4, atol=1e-6)


def test_a_centre_ray_through_the_crease_of_two_meshes_still_finds_the_surface():
    """issue 42: the demo's truth (128x128) had a NaN at pixel (2, 125), inside the
    closed box: the pixel-centre ray passed exactly through the edge where the ceiling
    meets a wall. Tried again a ten-thousandth of a pixel to each side, it hits."""
    import dopplertof
    from dopplertof.demo import demo_scene_path
    from dopplertof.tof.ground_truth import ground_truth

    scene = dopplertof.load_file(demo_scene_path(), {"res": 128})
    truth = ground_truth(scene, scene.params)
    assert np.all(np.isfinite(truth.depth)) and np.all(truth.body >= -1)
    # the filled pixel continues its neighbours (2.6 mm from the next one in its row)
    assert abs(truth.depth[2, 125] - truth.depth[2, 124]) < 0.01, truth.depth[1:4, 123:127]
