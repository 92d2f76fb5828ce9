"""Every time-sampling method and correlation depth converges to the same image.

On the published moving Cornell box (global illumination, two moving bodies), each
configuration is rendered with independent seeds; its mean over regions of the image
must agree with the naive configuration (uniform time, independent paths) within
4 combined standard errors estimated from the seeds.
"""

import numpy as np
import pytest

import dopplertof
from conftest import PUBLISHED

SEEDS = range(1, 7)
SPP = 32
CONFIGS = [
    ("uniform", 0, True), ("uniform", 2, True), ("stratified", 1, True),
    ("stratified", 1 << 16, False), ("antithetic", 0, True), ("antithetic", 1, True),
    ("antithetic", 2, True), ("antithetic", 1 << 16, True), ("antithetic", 1 << 16, False),
    ("antithetic_mirror", 2, True), ("antithetic_mirror", 1 << 16, True),
    ("stratified", 0, True), ("auto", 1 << 16, True),
]


@pytest.fixture(scope="module")
def scene():
    dopplertof.set_variant("llvm_ad_rgb")
    return dopplertof.load_file(PUBLISHED, {"resx": 24, "resy": 24}).with_params(
        hetero_frequency=0.5, hetero_offset=0.3)


def region_means(img):
    """Whole image, left half (tall box side) and bottom-right quarter (short box)."""
    lum = img.mean(axis=-1)
    h, w = lum.shape
    return np.array([lum.mean(), lum[:, : w // 2].mean(), lum[h // 2:, w // 2:].mean()])


def estimate(scene, method, depth, stratify):
    params = dict(time_sampling_method=method, path_correlation_depth=depth,
                  use_stratified_sampling_for_each_interval=stratify)
    samples = np.array([region_means(dopplertof.render(scene, spp=SPP, seed=s, params=params))
                        for s in SEEDS])
    return samples.mean(axis=0), samples.std(axis=0, ddof=1) / np.sqrt(len(SEEDS))


@pytest.fixture(scope="module")
def naive(scene):
    return estimate(scene, "uniform", 0, False)


@pytest.mark.parametrize("method,depth,stratify", CONFIGS)
def test_methods_agree(scene, naive, method, depth, stratify):
    mean, se = estimate(scene, method, depth, stratify)
    ref_mean, ref_se = naive
    combined = np.sqrt(se**2 + ref_se**2)
    assert np.all(combined > 0)
    z = np.abs(mean - ref_mean) / combined
    assert np.all(z < 4.0), (mean, ref_mean, combined)


def test_antithetic_full_correlation_reduces_variance(scene):
    """At one beat period per exposure the paper's sampler beats naive sampling."""
    s = scene.with_params(hetero_frequency=1.0, hetero_offset=0.0)
    _, se_naive = estimate(s, "uniform", 0, False)
    _, se_anti = estimate(s, "antithetic", 1 << 16, True)
    assert se_anti[0] < se_naive[0] / 3
