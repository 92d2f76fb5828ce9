"""time_sampling_method="analytic" (integrators/analytic.py): against a direct quadrature
of its own approximation on the moving plane, its small and computable bias there, a
large bias where the contribution is far from linear in time, and its refusals.

Statistics: only film positions are random here, and they are low-discrepancy sets:
measured over 40 other seeds, one render's relative standard deviation is 2e-8 to
6e-7, so the relative tolerances (2e-4 to 2e-3, 10 comparisons) are 400 or more of
them, and the 4 standard errors of 4 seeds (a Student tail of 3e-2 alone) add nothing
to the 2e-4 allowance. No false failures to speak of; a relative bias of the tolerance
fails them.
"""

import math

import numpy as np
import pytest

import dopplertof
from analytic import analytic_approximation, plane_scene, reference


def render_analytic(z0, v, spp=256, seeds=range(4), **integrator):
    scene = dopplertof.load_dict(plane_scene(z0, v, spp=spp, integrator=dict(
        integrator, time_sampling_method="analytic")))
    return np.array([dopplertof.render(scene, seed=s)[0, 0, 0] for s in seeds])


def test_cosine_moments_against_quadrature():
    """The closed forms of the integrals over [0, 1] of cos(x s + b) and s cos(x s + b),
    their series near x = 0 included."""
    import mitsuba as mi

    from dopplertof.integrators.analytic import cosine_moments

    xs = [0.0, 3e-5, -9e-5, 2e-4, 1e-3, -9.9e-3, 1.01e-2, 0.3, 2 * math.pi, -40.0]
    bs = [0.0, 1.1, -2.5, 6.0, 0.7, 4.4, -1.3, 3.0, 0.2, 1.9]
    m0, m1 = cosine_moments(mi.Float64(xs), mi.Float64(bs))
    nodes, weights = np.polynomial.legendre.leggauss(200)
    s, w = (nodes + 1) / 2, weights / 2
    for i, (x, b) in enumerate(zip(xs, bs)):
        assert abs(m0[i] - np.sum(w * np.cos(x * s + b))) < 1e-12, (x, b)
        assert abs(m1[i] - np.sum(w * s * np.cos(x * s + b))) < 1e-12, (x, b)


@pytest.mark.parametrize("v,h,offset", [(30.0, 1.0, 0.0), (-60.0, 1.0, 0.3), (40.0, 0.0, 0.1),
                                        (15.0, 0.5, 0.6)])
def test_matches_the_quadrature_of_its_approximation(v, h, offset):
    """The renderer evaluates the approximation it claims: 4 standard errors over seeds
    (film positions are the only randomness: time is integrated)."""
    expected = analytic_approximation(4.0, v, hetero_frequency=h, hetero_offset=offset)
    values = render_analytic(4.0, v, hetero_frequency=h, hetero_offset=offset)
    se = values.std(ddof=1) / np.sqrt(len(values))
    assert abs(values.mean() - expected) < 4 * se + 2e-4 * abs(expected) + 1e-9, (
        values, expected)


def test_bias_on_the_moving_plane_is_small_and_computable():
    """On the plane the path length is linear in time and the value (1/z^2) nearly so:
    the approximation is within 1e-3 of the exact value at 30 m/s (relative bias from
    the curvature of 1/z^2, about (v T / z)^2 = 1.3e-4), and so is the render."""
    exact = reference(4.0, 30.0, hetero_frequency=1.0)
    approx = analytic_approximation(4.0, 30.0, hetero_frequency=1.0)
    assert abs(approx - exact) < 1e-3 * abs(exact), (approx, exact)
    assert abs(approx - exact) > 0.0  # biased, if slightly
    values = render_analytic(4.0, 30.0, hetero_frequency=1.0)
    assert abs(values.mean() - exact) < 2e-3 * abs(exact)


def test_biased_where_the_value_is_far_from_linear_in_time():
    """A plane receding from 1 m to 2.5 m during the exposure: 1/z^2 falls 6x, not
    linearly, and the homodyne value of the approximation misses the exact one by far
    more than its noise; the render still follows its approximation."""
    v = 1.5 / 0.0015
    exact = reference(1.0, v, hetero_frequency=0.0)
    approx = analytic_approximation(1.0, v, hetero_frequency=0.0)
    assert abs(approx - exact) > 0.1 * abs(exact), (approx, exact)
    values = render_analytic(1.0, v, hetero_frequency=0.0)
    assert abs(values.mean() - approx) < 1e-3 * abs(approx)


def test_the_sensor_offset_enters_the_phase():
    """b = k L1 + psi (the published code drops psi): offset 1/2 negates the image,
    1/4 gives the other quadrature, each as its approximation says."""
    values = {o: render_analytic(4.0, 30.0, seeds=[0], hetero_frequency=1.0,
                                 hetero_offset=o)[0] for o in (0.0, 0.25, 0.5)}
    expected = {o: analytic_approximation(4.0, 30.0, hetero_frequency=1.0, hetero_offset=o)
                for o in values}
    scale = math.hypot(expected[0.0], expected[0.25])
    assert abs(expected[0.5] + expected[0.0]) < 1e-9 * scale
    for o in values:
        assert abs(values[o] - expected[o]) < 1e-3 * scale, (o, values[o], expected[o])


@pytest.mark.parametrize("method", ["analytic", "control_variate"])
@pytest.mark.parametrize("integrator,message", [
    ({"wave_function_type": "rectangular"}, "needs wave_function_type 'sinusoidal'"),
    ({"low_frequency_component_only": False}, "needs low_frequency_component_only=true"),
])
def test_other_waveforms_are_refused(integrator, message, method):
    """Both methods built on the closed form (the analytic integral and its control
    variate) refuse the waveforms it does not cover, in one line naming the method."""
    with pytest.raises(dopplertof.SceneError, match=message) as info:
        dopplertof.load_dict(plane_scene(4.0, 30.0, spp=4, integrator=dict(
            integrator, time_sampling_method=method)))
    assert f"'{method}'" in str(info.value) and "\n" not in str(info.value)
