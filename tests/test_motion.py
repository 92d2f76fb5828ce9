"""Keyframe interpolation: rigid (translation lerp, rotation slerp, scale lerp) and matrix."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from dopplertof.scene.motion import Keyframes, Motion, MotionError


def trs(t=(0, 0, 0), angle_deg=0.0, axis=(0, 1, 0), scale=(1, 1, 1)):
    M = np.eye(4)
    M[:3, :3] = Rotation.from_rotvec(np.radians(angle_deg) * np.asarray(axis)).as_matrix() \
        @ np.diag(scale)
    M[:3, 3] = t
    return M


def test_rigid_interpolation_slerps_rotation_and_lerps_the_rest():
    m = Motion(Keyframes.create([0.0, 2.0], [trs((0, 0, 0), 0, scale=(1, 1, 1)),
                                             trs((2, 4, 0), 90, scale=(3, 3, 3))]))
    M = m.world_matrix(1.0)
    np.testing.assert_allclose(M, trs((1, 2, 0), 45, scale=(2, 2, 2)), atol=1e-12)
    # clamped outside the keyframes
    np.testing.assert_allclose(m.world_matrix(-1.0), trs(), atol=1e-12)
    np.testing.assert_allclose(m.world_matrix(5.0), trs((2, 4, 0), 90, scale=(3, 3, 3)),
                               atol=1e-12)


def test_matrix_interpolation_is_elementwise():
    A, B = trs((0, 0, 0), 0), trs((2, 0, 0), 90)
    m = Motion(Keyframes.create([0.0, 1.0], [A, B], interpolation="matrix"))
    np.testing.assert_allclose(m.world_matrix(0.25), 0.75 * A + 0.25 * B, atol=1e-12)


def test_three_keyframes_and_relative_transform():
    mats = [trs((0, 0, 0), 0), trs((1, 0, 0), 30), trs((1, 1, 0), 60)]
    m = Motion(Keyframes.create([0.0, 1.0, 3.0], mats))
    np.testing.assert_allclose(m.world_matrix(2.0), trs((1, 0.5, 0), 45), atol=1e-12)
    rel = m.relative_matrix(2.0)
    np.testing.assert_allclose(rel @ mats[0], m.world_matrix(2.0), atol=1e-12)
    (A, b), (IA, Ib) = m.relative(np.float64(2.0))
    R = np.eye(4)
    R[:3, :3], R[:3, 3] = A, b
    Inv = np.eye(4)
    Inv[:3, :3], Inv[:3, 3] = IA, Ib
    np.testing.assert_allclose(R @ Inv, np.eye(4), atol=1e-12)


def test_translation_only_motion_is_exact():
    m = Motion(Keyframes.create([0, 1], [trs((0, 0, 0), 20), trs((0, 0, 3), 20)]))
    assert m.translation_only
    (A, b), _ = m.relative(np.float64(0.5))
    assert A is None and np.allclose(b, [0, 0, 1.5])


def test_swept_box_contains_the_moving_box():
    m = Motion(Keyframes.create([0, 1], [trs((0, 0, 0), 0), trs((0, 0, 0), 90)]))
    lo, hi = m.swept_bbox([-1, -1, -2], [1, 1, 2], 0.0, 1.0)
    # rotating a 2x2x4 box by 90 degrees about y sweeps its corners over radius sqrt(5)
    assert np.all(lo <= [-np.sqrt(5), -1, -np.sqrt(5)]) and np.all(hi >= [np.sqrt(5), 1,
                                                                           np.sqrt(5)])


@pytest.mark.parametrize("times,mats,message", [
    ([0.0], [np.eye(4)], "at least 2 keyframes"),
    ([1.0, 0.0], [np.eye(4)] * 2, "unsorted"),
    ([1.0, 1.0], [np.eye(4)] * 2, "duplicate"),
    ([0.0, np.inf], [np.eye(4)] * 2, "finite"),
    ([0.0, 1.0], [np.eye(4), np.diag([1, 1, 0, 1.0])], "non-invertible"),
    ([0.0, 1.0], [np.eye(4), np.full((4, 4), np.nan)], "non-finite"),
])
def test_bad_keyframes(times, mats, message):
    with pytest.raises(MotionError, match=message):
        Keyframes.create(times, mats)


def test_unknown_interpolation():
    with pytest.raises(MotionError, match="unknown interpolation 'cubic'"):
        Keyframes.create([0, 1], [np.eye(4)] * 2, interpolation="cubic")


def test_rotating_body_renders_like_its_pose_at_fixed_time():
    """A body rotating during the exposure, rendered with a zero-length... we instead check
    that the renderer's per-lane transform equals the NumPy one."""
    import mitsuba as mi

    m = Motion(Keyframes.create([0, 1], [trs((0, 0, 0), 0, scale=(1, 2, 1)),
                                         trs((1, 0, 0), 120, axis=(0, 0, 1), scale=(1, 2, 1))]))
    ts = np.linspace(0, 1, 7)
    (A, b), _ = m.relative(mi.Float(ts))
    for k, t in enumerate(ts):
        ref = m.relative_matrix(t)
        got = np.array([[np.asarray(A[r][c])[k] for c in range(3)] for r in range(3)])
        np.testing.assert_allclose(got, ref[:3, :3], atol=1e-5)
        np.testing.assert_allclose([np.asarray(x)[k] for x in b], ref[:3, 3], atol=1e-5)


@pytest.mark.parametrize("angle", [0.0, 0.3, 2.0, np.pi - 1e-9, np.pi])
@pytest.mark.parametrize("axis", [(1, 0, 0), (0, 1, 0), (0, 0, 1), (1, 2, -2)])
def test_matrix_to_quaternion_is_the_rotation_about_its_axis(angle, axis):
    """The keyframes' quaternions (written out, not SciPy's: its import cost every scene
    load 0.5 s): a rotation by ``angle`` about ``axis`` is (cos a/2, sin a/2 axis), up to
    sign, also at a half turn, where the trace branch cannot be used; and SciPy agrees."""
    from dopplertof.scene.motion import rotation_quaternion

    axis = np.asarray(axis, float) / np.linalg.norm(axis)
    R = Rotation.from_rotvec(angle * axis).as_matrix()
    q = rotation_quaternion(R)
    expected = np.concatenate([[np.cos(angle / 2)], np.sin(angle / 2) * axis])
    q = q if np.dot(q, expected) >= 0 else -q
    assert np.allclose(q, expected, atol=1e-12)
    x, y, z, w = Rotation.from_matrix(R).as_quat()
    assert abs(abs(np.dot(q, [w, x, y, z])) - 1.0) < 1e-12


@pytest.mark.parametrize("omega", [(0.0, 0.0, 0.0), (0.3, -1.2, 2.0), (1e-5, 0.0, 0.0)])
def test_velocity_motion_sweeps_every_time_at_once_as_one_at_a_time(omega):
    """VelocityMotion.moved_points (all times in one NumPy pass, for the swept boxes of
    every gradient and fit step) equals Motion.moved_points (a matrix per time), with
    and without rotation and with a base pose."""
    from dopplertof.diff.motion import VelocityMotion
    from dopplertof.scene.motion import Motion

    base = np.array([[1, 0, 0, 0.2], [0, 0, -1, 0.1], [0, 1, 0, 0], [0, 0, 0, 1.0]])
    corners = np.array([[x, y, z, 1.0] for x in (-1, 1) for y in (-0.5, 0.5) for z in (0, 2)])
    times = np.linspace(0.0, 0.002, 33)
    for b in (None, base):
        vm = VelocityMotion([0.1, 0.2, 0.3], [1.0, -2.0, 0.5], list(omega), 0.001, base=b)
        np.testing.assert_allclose(vm.moved_points(corners, times),
                                   Motion.moved_points(vm, corners, times), rtol=0, atol=1e-12)
