"""Derivatives of renders (dopplertof.diff): one test per parameter kind against the
derivative of the quadrature reference (tests/analytic.py) on the moving plane, and
against central finite differences with common random numbers (the same seed: the
same random numbers at both steps) on the moving plane and on interior pixels of the
published scene.

Tolerances and false-failure rates: the derivative estimates' relative standard
deviations over seeds were measured (10 seeds, at the sample counts used here) at
0.07% (plane velocity, 1024 spp: 0.04%), 0.15% (camera velocity), < 1e-6 (homodyne
modulation parameters, reflectance); the 2% tolerance is more than 10 standard
deviations for every test against a reference: false-failure rate below 1e-20. The
finite-difference comparisons share all random numbers with the derivative: they
differ by the step's second-order term and by paths that cross a discontinuity
between the two steps, not by Monte Carlo noise (deterministic per seed).
"""

import numpy as np
import pytest

from analytic import RHO, plane_scene, reference
from conftest import PUBLISHED

Z0, V = 2.0, 10.0
TOL = 0.02


def _central(f, x, h):
    return (f(x + h) - f(x - h)) / (2 * h)


def _plane(hetero_frequency=1.0, spp=256, **integrator):
    import dopplertof
    from dopplertof.diff import DifferentiableScene

    scene = dopplertof.load_dict(plane_scene(
        Z0, V, spp=spp, integrator={"hetero_frequency": hetero_frequency, **integrator}))
    return DifferentiableScene(scene)


def _derivative(ds, name, spp=256, seed=0):
    from dopplertof.diff import render_derivatives

    return render_derivatives(ds, [name], spp=spp, seed=seed).tangents[name][0, 0, 0]


def test_body_linear_velocity_matches_the_quadrature_derivative_and_crn_differences():
    from dopplertof.diff import render_derivatives

    ds = _plane()
    got = _derivative(ds, "body0.vz", spp=1024)
    expected = _central(lambda v: reference(Z0, v, hetero_frequency=1.0), V, 0.1)
    assert abs(got / expected - 1) < TOL, (got, expected)
    # central differences of renders with common random numbers (same seed)
    h = 0.05

    def image(v):
        ds.set_body_velocity(0, [0.0, 0.0, v])
        return render_derivatives(ds, [], spp=1024).image[0, 0, 0]

    fd = _central(image, V, h)
    ds.set_body_velocity(0, [0.0, 0.0, V])
    assert abs(fd / got - 1) < TOL, (fd, got)


def test_camera_velocity_matches_the_quadrature_derivative():
    ds = _plane()
    got = _derivative(ds, "camera.vz")
    expected = _central(lambda c: reference(Z0, V, hetero_frequency=1.0, camera_velocity=c,
                                            light_velocity=0.0), 0.0, 0.1)
    assert abs(got / expected - 1) < TOL, (got, expected)


@pytest.mark.parametrize("name, h", [("w_g", 0.01), ("hetero_offset", 1e-3), ("g_1", 1e-3)])
def test_modulation_parameters_match_the_quadrature_derivative(name, h):
    ds = _plane(hetero_frequency=0.0, hetero_offset=0.0)
    got = _derivative(ds, name)
    keyword = {"g_1": "g1"}.get(name, name)
    start = {"w_g": 30.0, "hetero_offset": 0.0, "g_1": 0.5}[name]
    expected = _central(lambda x: reference(Z0, V, hetero_frequency=0.0, **{keyword: x}),
                        start, h)
    assert abs(expected) > 1e-3 * abs(reference(Z0, V, hetero_frequency=0.0))  # not small
    assert abs(got / expected - 1) < TOL, (got, expected)


def test_mitsuba_parameter_reflectance_channel_by_channel():
    """The render is linear in the plane's albedo: d/drho_c = value / rho in channel c
    and 0 in the others."""
    from dopplertof.diff import render_derivatives

    ds = _plane()
    d = render_derivatives(ds, ["white.reflectance.value[1]", "white.reflectance.value"],
                           spp=256)
    expected = reference(Z0, V, hetero_frequency=1.0) / RHO
    one = d.tangents["white.reflectance.value[1]"][0, 0]
    assert one[0] == 0.0 and one[2] == 0.0
    assert abs(one[1] / expected - 1) < TOL, (one, expected)
    assert abs(d.tangents["white.reflectance.value"][0, 0, 0] / expected - 1) < TOL


# ---- The published scene: interior pixels against CRN differences ------------------

@pytest.fixture(scope="module")
def published():
    import dopplertof
    from dopplertof.tof.ground_truth import ground_truth

    dopplertof.set_variant("llvm_ad_rgb")
    scene = dopplertof.load_file(PUBLISHED, {"resx": 24, "resy": 24, "max_depth": 3})
    truth = ground_truth(scene)
    return scene, truth


def _interior(truth, k):
    from dopplertof.diff.fit import interior

    return interior(truth, k)


def _crn_difference(ds, k, kind, axis, h, spp):
    from dopplertof.diff import render_derivatives

    v, w = ds.body_velocity(k)
    images = []
    for sign in (1, -1):
        vv, ww = list(v), list(w)
        (vv if kind == "v" else ww)[axis] += sign * h
        ds.set_body_velocity(k, vv, ww)
        images.append(render_derivatives(ds, [], spp=spp).image)
    ds.set_body_velocity(k, v, w)
    return (images[0] - images[1]) / (2 * h)


@pytest.mark.parametrize("name, h", [("body0.vz", 0.05), ("body1.wy", 0.1)])
def test_published_scene_interior_pixels_match_crn_differences(published, name, h):
    from dopplertof.diff import DifferentiableScene, render_derivatives

    scene, truth = published
    ds = DifferentiableScene(scene)
    spp = 32
    k = int(name[4])
    got = render_derivatives(ds, [name], spp=spp).tangents[name]
    fd = _crn_difference(ds, k, name[6], "xyz".index(name[7]), h, spp)
    inner = _interior(truth, k)
    assert inner.sum() >= 8
    a, b = got[inner].ravel(), fd[inner].ravel()
    big = np.abs(a) > 0.1 * np.abs(a).max()  # where the derivative is not small
    assert big.sum() >= 8
    assert np.linalg.norm(a[big] - b[big]) < TOL * np.linalg.norm(a[big]), (a[big], b[big])


def test_published_scene_reflectance_matches_crn_differences(published):
    from dopplertof.diff import DifferentiableScene, render_derivatives

    scene, truth = published
    ds = DifferentiableScene(scene)
    key = "ShortBoxBSDF.brdf_0.reflectance.value"
    spp = 32
    got = render_derivatives(ds, [key], spp=spp).tangents[key]
    tp = ds.scene_parameters()[key]
    base = [np.array(t[key]) for t in tp]
    h = 0.01

    def image(delta):
        import mitsuba as mi

        for t, b in zip(tp, base):
            t[key] = mi.Color3f(*[float(x) + delta for x in b.ravel()])
            t.update()
        return render_derivatives(ds, [], spp=spp).image

    fd = (image(h) - image(-h)) / (2 * h)
    image(0.0)
    inner = _interior(truth, 0)
    a, b = got[inner].ravel(), fd[inner].ravel()
    big = np.abs(a) > 0.1 * np.abs(a).max()
    assert big.sum() >= 8
    assert np.linalg.norm(a[big] - b[big]) < TOL * np.linalg.norm(a[big])


# ---- Motion parameterization and bad input ------------------------------------------

def test_velocity_motion_reproduces_two_keyframe_rigid_motion():
    """A two-keyframe rigid motion (turn and translation) is a constant-velocity motion
    about its first keyframe's translation: the same poses at every time."""
    import mitsuba as mi

    from dopplertof.diff.motion import VelocityMotion
    from dopplertof.scene.motion import Keyframes, Motion

    T = mi.ScalarTransform4f
    m0 = np.array(T().translate([0.3, -0.2, 1.0]).rotate([0, 1, 0], 10).scale(0.5).matrix)
    m1 = np.array(T().translate([0.5, -0.1, 0.9]).rotate([0.6, 0.8, 0], 40).scale(0.5).matrix)
    motion = Motion(Keyframes.create([0.0, 2.0], [m0, m1]))
    vm = VelocityMotion.from_motion(motion, 0.0, 2.0)
    for t in (0.0, 0.3, 1.0, 1.7, 2.0):
        assert np.allclose(vm.relative_matrix(t), motion.relative_matrix(t), atol=1e-9)
    kf = vm.keyframes([0.0, 1.0, 2.0])
    assert np.allclose(np.array(kf.matrices[2]), motion.world_matrix(2.0), atol=1e-9)
    # an interval inside the keyframes, referenced at its middle
    vm = VelocityMotion.from_motion(motion, 0.5, 1.5, t_ref=1.0)
    for t in (0.5, 0.8, 1.0, 1.5):
        assert np.allclose(vm.relative_matrix(t), motion.relative_matrix(t), atol=1e-9)
        assert np.allclose(vm.world_matrix(t), motion.world_matrix(t), atol=1e-9)


def test_derivative_at_zero_angular_velocity_is_finite():
    """Rodrigues' coefficients use their series near a zero angle: no NaN at omega = 0."""
    ds = _plane()
    got = _derivative(ds, "body0.wx", spp=16)
    assert np.isfinite(got)


@pytest.mark.parametrize("name", ["body7.vx", "camera.wx", "nosuch.key", "body0.vq"])
def test_unknown_parameters_are_refused_by_name(name):
    from dopplertof.diff import DerivativeError, render_derivatives

    ds = _plane()
    with pytest.raises(DerivativeError, match="body7|camera|nosuch|vq"):
        render_derivatives(ds, [name], spp=16)
