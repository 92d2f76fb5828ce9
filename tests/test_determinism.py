"""Same seed, same image bitwise, whatever the pass size; zero motion equals static."""

import numpy as np
from scipy import stats

import dopplertof
from conftest import PUBLISHED


def small_scene():
    return dopplertof.load_file(PUBLISHED, {"resx": 16, "resy": 12})


def test_same_seed_same_image_whatever_the_pass_size():
    scene = small_scene()
    a = dopplertof.render(scene, spp=64, seed=5)
    b = dopplertof.render(scene, spp=64, seed=5)
    c = dopplertof.render(scene, spp=64, seed=5, pass_chunks=1)  # 4 passes of 16 spp
    d = dopplertof.render(scene, spp=64, seed=5, max_lanes=16 * 12 * 48)  # uneven passes
    assert a.shape == (12, 16, 3) and a.dtype == np.float32
    assert np.array_equal(a, b) and np.array_equal(a, c) and np.array_equal(a, d)


def test_different_seeds_give_independent_noise():
    scene = dopplertof.load_file(PUBLISHED, {"resx": 32, "resy": 24}).with_params(
        hetero_frequency=0.0, time_sampling_method="uniform", path_correlation_depth=0)
    ref = dopplertof.render(scene, spp=1024, seed=100).mean(axis=-1)

    def error(seed):  # per pixel (the channels of one path are correlated)
        return (dopplertof.render(scene, spp=8, seed=seed).mean(axis=-1) - ref).ravel()

    a, b = error(1), error(2)
    # rank correlation: the errors are heavy tailed, and Pearson's correlation of them
    # scatters by 0.053 over seeds (measured, 40 pairs: 0.15 is only 2.8 of those, a
    # false-failure rate of 5e-3); Spearman's scatters by 0.037 = 1 / sqrt(767) (measured
    # too), so 0.15 is 4.1 of its standard deviations: a false-failure rate of 4e-5. A
    # stream shared between seeds gives a correlation near 1.
    corr = stats.spearmanr(a, b)[0]
    assert abs(corr) < 0.15, corr  # independent noise
    assert np.array_equal(a, error(1))  # and the same seed replays bitwise


def test_zero_motion_bodies_equal_the_static_scene():
    moving = small_scene()
    text = open(PUBLISHED).read()
    # identical keyframes: the boxes stay in place, but still go through the body path
    still = text.replace('<translate x="0.0" y="0.0" z="0.015" />', "").replace(
        '<translate x="0.0" y="0.0" z="-0.015" />', "")
    static_text = still
    for _ in range(2):  # replace each animation by its first keyframe, as a plain transform
        start = static_text.index("<animation")
        end = static_text.index("</animation>") + len("</animation>")
        block = static_text[start:end]
        first = block[block.index("<matrix"):block.index("/>", block.index("<matrix")) + 2]
        static_text = static_text[:start] + f'<transform name="to_world">{first}</transform>' \
            + static_text[end:]
    over = {"resx": 16, "resy": 12}
    still_scene = dopplertof.scene.load_string(still, over)
    static_scene = dopplertof.scene.load_string(static_text, over)
    assert len(still_scene.bodies) == 2 and len(static_scene.bodies) == 0
    a = dopplertof.render(still_scene, spp=32, seed=9, params={"hetero_frequency": 0})
    b = dopplertof.render(static_scene, spp=32, seed=9, params={"hetero_frequency": 0})
    assert np.abs(b).max() > 0.01
    # the same samples, each through a body's local frame or pre-transformed vertices:
    # float32 rounding of those transforms (a few u of each sample's value) and the same
    # summation order in both (one kernel, on any CPU); rtol 1e-4 is 1700 u (measured at
    # most 9e-6 relative, 0.2% of the tolerance)
    np.testing.assert_allclose(a, b, rtol=1e-4, atol=1e-6)
    assert len(moving.bodies) == 2


def test_sample_count_not_a_multiple_of_the_chunk():
    """20 spp = one chunk of 16 and a short chunk of 4, rendered in one or two passes."""
    scene = small_scene()
    a = dopplertof.render(scene, spp=20, seed=8)
    b = dopplertof.render(scene, spp=20, seed=8, pass_chunks=1)
    assert np.array_equal(a, b) and np.all(np.isfinite(a))
    # and the short chunk really is rendered: 20 spp differs from its first 16 samples
    assert not np.array_equal(a, dopplertof.render(scene, spp=16, seed=8))
