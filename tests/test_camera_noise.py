"""Sensor noise model: shot noise statistics, read noise, clipping, ADC, ambient, seeding.

Statistics (90000 draws each): the 6 mean comparisons hold |z| under Z_BOUND, the normal
quantile that gives them a family-wise false-failure rate of 1e-4 (Bonferroni; 4
standard errors before: 3.8e-4). The variance comparisons were measured over 20-30
other seeds: the sample variance's relative standard deviation is 0.43-0.55% (the 3%
tolerance is 5.4-7 of them, below 1e-7 for all 5) and the ambient light's extra
variance's 0.9% (the 10% tolerance: 11 of them).
"""

import numpy as np
import pytest

from bounds import normal_bound
from dopplertof.tof import NoiseError, NoiseModel, apply_noise

T = 0.0015
SHAPE = (300, 300)  # 90000 pixels: the sample variance is within ~1% (4 sigma ~ 2%)
Z_BOUND = normal_bound(1e-4, 6)  # about 4.3


def fine_adc(**kw):
    """A sensor whose ADC and well do not limit: 32 bits at 0.01 e-/DN, huge well."""
    base = dict(photons_per_unit=1e6, quantum_efficiency=0.5, read_noise=0.0,
                full_well=1e12, gain=0.01, bits=32)
    return NoiseModel(**{**base, **kw})


def test_tap_is_poisson_mean_equals_variance():
    model = NoiseModel(read_noise=0.0, gain=1.0, bits=20, full_well=1e9)
    rng = np.random.default_rng(3)
    for mean in (4.0, 50.0, 2500.0):
        dn, saturated = model.read_tap(np.full(SHAPE, mean), rng)
        assert not saturated.any()
        assert dn.mean() == pytest.approx(mean, abs=Z_BOUND * np.sqrt(mean / dn.size))
        assert dn.var() == pytest.approx(mean, rel=0.03)


def test_signed_measurement_mean_and_variance_match_the_model():
    """A - B of two taps with their own shot noise: mean V, variance
    (e_A + e_B + 2 read^2 + 2 gain^2 / 12) / (QE K T)^2."""
    model = fine_adc(read_noise=3.0)
    value, unmodulated = 0.12, 0.5
    rng = np.random.default_rng(7)
    noisy, saturated = model.measure(np.full(SHAPE, value), np.full(SHAPE, unmodulated), T, rng)
    noisy = noisy.astype(np.float64)
    assert not saturated.any()
    e_a, e_b = model.tap_means(value, unmodulated, T)
    k = model.electrons_per_unit(T)
    assert k == pytest.approx(0.5 * 1e6 * T)
    assert e_a == pytest.approx(k * (unmodulated + value) / 2)
    assert e_b == pytest.approx(k * (unmodulated - value) / 2)
    predicted_var = (e_a + e_b + 2 * 9.0 + 2 * 0.01**2 / 12) / k**2
    assert model.variance(value, unmodulated, T) == pytest.approx(predicted_var)
    n = noisy.size
    assert noisy.mean() == pytest.approx(value, abs=Z_BOUND * np.sqrt(predicted_var / n))
    assert noisy.var() == pytest.approx(predicted_var, rel=0.03)
    # the variance follows the unmodulated light (A + B), not the signed value
    noisy2, _ = model.measure(np.full(SHAPE, -value), np.full(SHAPE, unmodulated), T, rng)
    noisy2 = noisy2.astype(np.float64)
    assert noisy2.mean() == pytest.approx(-value, abs=Z_BOUND * np.sqrt(predicted_var / n))
    assert noisy2.var() == pytest.approx(predicted_var, rel=0.03)


def test_ambient_light_adds_variance_but_no_bias():
    ambient = 4e5  # photons/s: QE * a * T / 2 = 150 electrons per tap
    model = fine_adc(ambient=ambient)
    rng = np.random.default_rng(11)
    value, unmodulated = 0.05, 0.2
    dark, _ = fine_adc().measure(np.full(SHAPE, value), np.full(SHAPE, unmodulated), T, rng)
    lit, _ = model.measure(np.full(SHAPE, value), np.full(SHAPE, unmodulated), T, rng)
    dark, lit = dark.astype(np.float64), lit.astype(np.float64)
    k = model.electrons_per_unit(T)
    extra = 2 * 0.5 * ambient * T / 2 / k**2  # both taps' ambient electrons
    assert lit.mean() == pytest.approx(value, abs=Z_BOUND * np.sqrt(lit.var() / lit.size))
    assert lit.var() - dark.var() == pytest.approx(extra, rel=0.1)


def test_adc_quantization_and_clipping():
    model = NoiseModel(photons_per_unit=1e9, quantum_efficiency=1.0, read_noise=0.0,
                       full_well=1e12, gain=10.0, bits=8)
    rng = np.random.default_rng(0)
    dn, saturated = model.read_tap(np.full((4, 4), 1e6), rng)
    assert np.all(dn == 255) and saturated.all()  # ADC at its maximum
    dn, saturated = model.read_tap(np.full((4, 4), 100.0), rng)
    assert np.all(dn == np.rint(dn)) and not saturated.any()


def test_full_well_clips_and_flags():
    model = NoiseModel(photons_per_unit=1e9, quantum_efficiency=1.0, read_noise=0.0,
                       full_well=1000.0, gain=1.0, bits=16)
    rng = np.random.default_rng(0)
    dn, saturated = model.read_tap(np.full((8, 8), 5000.0), rng)
    assert np.all(dn == 1000) and saturated.all()


def test_auto_photon_scale_fills_the_requested_fraction_of_the_well():
    unmodulated = np.linspace(0.0, 2.0, 10_000).reshape(100, 100)
    model = NoiseModel(well_fill=0.25).scaled_for(unmodulated, T)
    reference = np.percentile(unmodulated, 99.5)
    electrons = model.quantum_efficiency * model.photons_per_unit * T * reference
    assert electrons == pytest.approx(0.25 * model.full_well)  # 20000 e- < 5 e-/DN x 4095
    adc_limited = NoiseModel(well_fill=0.25, full_well=1e6, gain=2.0).scaled_for(unmodulated, T)
    electrons = adc_limited.quantum_efficiency * adc_limited.photons_per_unit * T * reference
    assert electrons == pytest.approx(0.25 * 2.0 * 4095)
    with pytest.raises(NoiseError, match="nothing in the image is lit"):
        NoiseModel().scaled_for(np.zeros((4, 4)), T)


def test_seeded_and_reproducible():
    captures = {"a": np.full((16, 16), 0.1, np.float32), "b": np.full((16, 16), -0.2, np.float32)}
    unmodulated = np.full((16, 16), 0.5)
    first, _, model = apply_noise(captures, unmodulated, T, NoiseModel(seed=5))
    again, _, _ = apply_noise(captures, unmodulated, T, NoiseModel(seed=5))
    other, _, _ = apply_noise(captures, unmodulated, T, NoiseModel(seed=6))
    assert model.photons_per_unit is not None
    assert all(np.array_equal(first[k], again[k]) for k in captures)
    assert not np.array_equal(first["a"], other["a"])
    assert not np.array_equal(first["a"], first["b"])  # each capture has its own draw


@pytest.mark.parametrize("kwargs,message", [
    (dict(quantum_efficiency=1.5), "quantum_efficiency"),
    (dict(read_noise=-1.0), "read_noise"),
    (dict(full_well=0.0), "full_well"),
    (dict(gain=0.0), "gain"),
    (dict(bits=0), "bits"),
    (dict(bits=12.5), "bits"),
    (dict(ambient=-3.0), "ambient"),
    (dict(photons_per_unit=-1.0), "photons_per_unit"),
    (dict(well_fill=2.0), "well_fill"),
    (dict(seed=-1), "seed"),
])
def test_bad_parameters_are_one_line_value_errors(kwargs, message):
    with pytest.raises(ValueError, match=message) as info:
        NoiseModel(**kwargs)
    assert isinstance(info.value, NoiseError)
    assert "\n" not in str(info.value)
