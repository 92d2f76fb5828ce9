"""Conformance with the published implementations: the published scene rendered by us
against their renders (../shared/fixtures/published, README there), compared on
16x16-pixel block means of the time average, with bounds set from our own measured
noise (two seeds) plus the measured floor of the fixtures.

Skipped, saying why, where the fixtures are absent (a user's clone); CI has them.

False failures: the block errors are RMS over 256 blocks, so they and the noise estimate
have a relative standard deviation of about 1 / sqrt(2 x 256) = 4.4%; the bounds
(1.25 x the expected error) are about 5 of those above the measured errors (measured
5.2-5.3% against 6.8%; 6.2-6.4% against 8.7%; 3.3-3.4% against 5%), a rate of about 1e-6
each (normal tails). The scales are within 1.3% and 2.7-4.5% of 1 (5% and 8% bounds).
"""

import os

import numpy as np
import pytest

import dopplertof

PUBLISHED_DIR = os.path.normpath(os.path.join(os.path.dirname(__file__), "..", "..", "shared",
                                              "fixtures", "published"))
EXPOSURE = 0.0015  # the m06 files hold 1 + T * value

pytestmark = [pytest.mark.slow, pytest.mark.skipif(  # slow: renders of the published scene
    not os.path.isdir(PUBLISHED_DIR),
    reason=f"the published renders are not here ({PUBLISHED_DIR} is absent: it sits beside "
           "the repository in CI)")]


def published_path(name):
    return os.path.join(PUBLISHED_DIR, name)


def m06(name):
    """A Mitsuba 0.6 render as the time average."""
    return (np.load(published_path(os.path.join("m06", name))) - 1.0) / EXPOSURE


def blocks(image, size=16):
    h, w, c = image.shape
    return image.reshape(h // size, size, w // size, size, c).mean(axis=(1, 3))


def block_rmse(image, target):
    """Relative RMSE of the 16x16 block means (RMSE over the target's RMS)."""
    a, b = blocks(image), blocks(target)
    return float(np.sqrt(np.mean((a - b) ** 2) / np.mean(b ** 2)))


def ls_scale(image, target):
    """The least-squares scale s of image = s * target."""
    return float(np.sum(image * target) / np.sum(target * target))


@pytest.fixture(scope="module")
def ours():
    """Our render of the published XML as it is (256x256, its defaults) at 2 x 128 spp
    (seeds 0 and 1), and the block noise of their mean, relative to the reference's
    RMS: half the blocks' seed difference (measured 5.1-5.3%, splat film)."""
    scene = dopplertof.load_file(published_path("cornell_box_moving.xml"))
    a, b = (dopplertof.render(scene, spp=128, seed=s) for s in (0, 1))
    reference = m06("reference_spp_16384.npy")
    noise = float(0.5 * np.sqrt(np.mean(blocks(a - b) ** 2) / np.mean(blocks(reference) ** 2)))
    return 0.5 * (a + b), noise


def test_against_the_published_reference(ours):
    """The Mitsuba 0.6 reference (16384 spp, antithetic, correlated paths): our block
    error is our noise (measured 5.2-5.3% against 5.1-5.3% noise; 2.6% at 1024 spp, the
    floor), within 1.25 sqrt(noise^2 + 2%^2); the scale is 1 within 5% (measured 0.995,
    1.013)."""
    image, noise = ours
    reference = m06("reference_spp_16384.npy")
    error = block_rmse(image, reference)
    assert 0.01 < noise < 0.1, noise  # the noise estimate itself is sane
    assert error < 1.25 * np.hypot(noise, 0.02), (error, noise)
    assert abs(ls_scale(image, reference) - 1.0) < 0.05


def test_against_the_published_mitsuba3_render(ours):
    """The Mitsuba 3 implementation's own EXR of this XML (1024 spp): its own block error
    against the reference is 3.2% (scale 1.0045), ours against it 6.2-6.4% at our
    noise; bound 1.25 sqrt(noise^2 + 3.2%^2 + 2%^2); scale within 8% (measured 0.955,
    0.973: its noise and ours)."""
    import mitsuba as mi

    image, noise = ours
    bitmap = mi.Bitmap(published_path("cornell_box_moving_1024spp.exr"))
    exr = np.array(bitmap.convert(mi.Bitmap.PixelFormat.RGB, mi.Struct.Type.Float32, False))
    assert exr.shape == image.shape
    reference = m06("reference_spp_16384.npy")
    floor = block_rmse(exr, reference)
    assert floor < 0.04  # the fixture is what the README says
    error = block_rmse(image, exr)
    assert error < 1.25 * np.sqrt(noise**2 + floor**2 + 0.02**2), (error, noise, floor)
    assert abs(ls_scale(image, exr) - 1.0) < 0.08


def test_analytic_mode_reproduces_the_published_analytic_render():
    """time_sampling_method="analytic" against the Mitsuba 0.6 analytic render (512
    samples of two paths): block error under 5% (measured 3.3-3.4% over 3 seeds at
    128 spp: the published render's own noise and the length conventions), while both
    are biased alike against the reference (ours 7.9-8.0%, theirs 9.5%, far above our
    noise there)."""
    scene = dopplertof.load_file(published_path("cornell_box_moving.xml"))
    image = dopplertof.render(scene, spp=128, seed=0,
                              params={"time_sampling_method": "analytic"})
    published = m06("analytic_path_corr_direction.npy")
    reference = m06("reference_spp_16384.npy")
    assert block_rmse(image, published) < 0.05
    assert block_rmse(published, reference) > 0.08  # the published bias
    assert block_rmse(image, reference) > 0.06  # ours: the same bias, not the truth
