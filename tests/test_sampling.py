"""The correlated sampler: exact replay, shared and own streams, time sampling methods."""

import numpy as np
import pytest
from scipy import stats

import dopplertof
from dopplertof import sampling
from dopplertof.sampling import FULL_CORRELATION


def streams(pixel, group, sample, seed=7, depth=2):
    import mitsuba as mi

    return sampling.CorrelatedStreams(mi, mi.UInt32(pixel), mi.UInt32(group), mi.UInt32(sample),
                                      mi.UInt32(seed), mi.UInt32(depth))


def numbers(s, stage, dims=range(6, 30)):
    import mitsuba as mi

    return np.array([np.asarray(s.get_1d(mi.UInt32(stage), mi.UInt32(d))) for d in dims])


def test_replay_is_exact_for_same_pixel_sample_dimension():
    a = numbers(streams([3, 9, 9], [1, 4, 4], [2, 8, 9]), 1)
    b = numbers(streams([3, 9, 9], [1, 4, 4], [2, 8, 9]), 1)
    assert np.array_equal(a, b)


def test_shared_stages_equal_within_group_and_own_stages_differ():
    # samples 8 and 9 form group 4 (K = 2); correlation depth 2: stages 0 and 1 shared
    s = streams([5, 5], [4, 4], [8, 9], depth=2)
    for stage in (0, 1):
        n = numbers(s, stage)
        assert np.array_equal(n[:, 0], n[:, 1])
    n = numbers(s, 2)
    assert not np.any(n[:, 0] == n[:, 1])
    # other pixels, groups and seeds give other numbers
    assert not np.array_equal(numbers(streams(6, 4, 8), 0), numbers(streams(5, 4, 8), 0))
    assert not np.array_equal(numbers(streams(5, 5, 10), 0), numbers(streams(5, 4, 8), 0))
    assert not np.array_equal(numbers(streams(5, 4, 8, seed=8), 0),
                              numbers(streams(5, 4, 8, seed=7), 0))


def test_numbers_are_uniform():
    import mitsuba as mi

    n = 1 << 16
    s = streams(np.arange(n) % 97, np.arange(n) // 2, np.arange(n), depth=0)
    u = np.asarray(s.get_1d(mi.UInt32(3), mi.UInt32(17)))
    assert u.min() >= 0 and u.max() < 1
    counts, _ = np.histogram(u, bins=16, range=(0, 1))
    chi2 = ((counts - n / 16) ** 2 / (n / 16)).sum()
    # 15 degrees of freedom: a false-failure rate of 1e-4 for another seed or stream (the
    # bound was 40 before: 4.5e-4); a 10% excess in one of the 16 bins fails it
    assert chi2 < stats.chi2.isf(1e-4, 15), chi2


def times(method, K=2, G=8, shift=0.5, stratify=True):
    import mitsuba as mi

    spp = K * G
    sample = np.arange(spp)
    s = streams(np.zeros(spp, int), sample // K, sample)
    t = sampling.time_fraction(mi, s, mi.UInt32(sample // K), mi.UInt32(sample % K),
                               group_size=K, groups_per_pixel=G,
                               method=mi.UInt32(sampling.method_index(method)),
                               antithetic_shift=mi.Float(shift), stratify=stratify,
                               double=False)
    return np.asarray(t).reshape(G, K)


def test_antithetic_pairs_are_shifted():
    t = times("antithetic", shift=0.5)
    np.testing.assert_allclose((t[:, 1] - t[:, 0]) % 1.0, 0.5, atol=1e-6)
    t = times("antithetic", shift=0.3)
    np.testing.assert_allclose((t[:, 1] - t[:, 0]) % 1.0, 0.3, atol=1e-6)


def test_periodic_groups_of_four():
    t = times("antithetic", K=4)
    np.testing.assert_allclose(np.diff(t, axis=1) % 1.0, 0.25, atol=1e-6)


def test_mirrored_pairs():
    t = times("antithetic_mirror", shift=0.0)
    np.testing.assert_allclose((t[:, 0] + t[:, 1]) % 1.0, 0.0, atol=1e-6)


def test_stratified_within_group_and_across_groups():
    t = times("stratified", K=2, G=8)
    assert np.all((t[:, 0] < 0.5) & (t[:, 1] >= 0.5))
    for i in range(2):  # each sample index covers every stratum of the group's interval
        strata = np.floor((t[:, i] * 2 - i) * 8).astype(int)
        assert sorted(strata) == list(range(8))


def test_full_time_stratification_of_primal_numbers():
    t = times("antithetic", K=2, G=16)
    assert sorted(np.floor(t[:, 0] * 16).astype(int)) == list(range(16))
    t = times("uniform", K=2, G=16, stratify=False)
    assert t.min() >= 0 and t.max() < 1


def test_mirror_needs_pairs():
    with pytest.raises(dopplertof.ParameterError, match="needs time_correlate_number=2"):
        dopplertof.RenderParams(time_sampling_method="antithetic_mirror",
                                time_correlate_number=4).validated()


def test_film_positions_are_a_scrambled_02_sequence():
    import mitsuba as mi

    idx = np.arange(64)
    pts = sampling.sobol_2d(mi, mi.UInt32(idx), mi.UInt32(0x1234567), mi.UInt32(0x89ABCDE))
    x, y = np.asarray(pts.x), np.asarray(pts.y)
    assert x.min() >= 0 and x.max() < 1 and y.min() >= 0 and y.max() < 1
    for cols, rows in ((64, 1), (8, 8), (1, 64), (16, 4)):  # every elementary interval
        cells = np.floor(x * cols).astype(int) * rows + np.floor(y * rows).astype(int)
        assert sorted(cells) == list(range(64))


def elementary_cells(x, y, n, cols, rows):
    return sorted(np.floor(x * cols).astype(int) * rows + np.floor(y * rows).astype(int))


@pytest.mark.parametrize("depth", [0, 2])
def test_first_hit_decisions_are_owen_scrambled_02_nets(depth):
    """A pixel's 64 groups (64 x 2 samples): each first-hit decision set is a (0,6,2)-net
    (its index shuffle and value scramble keep aligned blocks), shared within a group
    when stage 1 is, and paired with the other decision at random, not by index."""
    import mitsuba as mi

    G, K = 64, 2
    group = np.repeat(np.arange(G), K)
    index = np.tile(np.arange(K), G)
    s = streams(np.full(G * K, 3), group, group * K + index, depth=depth)
    pts = [s.first_hit_2d(d, mi.UInt32(group), mi.UInt32(index), G) for d in (0, 1)]
    (x0, y0), (x1, y1) = [(np.asarray(p.x), np.asarray(p.y)) for p in pts]
    for x, y in ((x0, y0), (x1, y1)):
        assert x.min() >= 0 and x.max() < 1 and y.min() >= 0 and y.max() < 1
        for i in range(K):  # the samples of one index in the group: one net
            xi, yi = x[index == i], y[index == i]
            for cols, rows in ((64, 1), (8, 8), (1, 64), (16, 4)):
                assert elementary_cells(xi, yi, 64, cols, rows) == list(range(64))
        shared = np.allclose(x[index == 0], x[index == 1])
        assert shared == (depth >= 2)
    # decisions paired at random (not the same numbers): over 128 pixels, the mean
    # correlation of the two decisions' first coordinates is 0 within 4.5 sigma (its
    # standard deviation 1 / sqrt(63 x 128) = 0.011; 0.05 is 4.5 of it: a false-failure
    # rate of 7e-6 per depth)
    P = 128
    many = streams(np.repeat(np.arange(P), G), np.tile(np.arange(G), P),
                   np.tile(np.arange(G) * K, P), depth=depth)
    g, i = mi.UInt32(np.tile(np.arange(G), P)), mi.UInt32(np.zeros(G * P, int))
    a, b = (np.asarray(many.first_hit_2d(d, g, i, G).x).reshape(P, G) for d in (0, 1))
    corr = [np.corrcoef(a[k], b[k])[0, 1] for k in range(P)]
    assert abs(np.mean(corr)) < 0.05, np.mean(corr)
    other = streams(np.full(G * K, 3), group, group * K + index, seed=8, depth=depth)
    assert not np.allclose(np.asarray(other.first_hit_2d(0, mi.UInt32(group),
                                                         mi.UInt32(index), G).x), x0)


def test_time_and_film_form_a_joint_sequence():
    """Antithetic pairs with a shared camera ray: (film x, film y, time) of a pixel's
    64 groups stratify film and time jointly (every (film x, time) cell of 8 x 8)."""
    import mitsuba as mi

    G = 64
    group = np.arange(G)
    s = streams(np.full(G, 5), group, group * 2, depth=1)
    film = s.film_2d(mi.UInt32(group), mi.UInt32(np.zeros(G, int)), G)
    t = np.asarray(sampling.time_fraction(
        mi, s, mi.UInt32(group), mi.UInt32(np.zeros(G, int)), group_size=2,
        groups_per_pixel=G, method=mi.UInt32(2), antithetic_shift=0.5, stratify=True,
        double=False))
    x = np.asarray(film.x)
    # (1,3)-sequence: the (x, t) projection holds every 8 x 8 cell at most twice, and the
    # cells of area 2/64 exactly twice
    assert elementary_cells(x, t, 64, 4, 8) == sorted(list(range(32)) * 2)
    assert sorted(np.floor(t * 64).astype(int)) == list(range(64))


def test_auto_sampling_rule():
    auto = sampling.auto_sampling
    assert auto(1.0)["time_sampling_method"] == "antithetic"
    assert auto(1.0)["antithetic_shift"] == 0.5 and auto(2.0)["antithetic_shift"] == 0.25
    for h in (0.0, 0.3, 0.5, 1.5):
        assert auto(h) == dict(time_sampling_method="stratified", path_correlation_depth=0,
                               use_stratified_sampling_for_each_interval=True,
                               antithetic_mapping="replay")
    # the group size stays the user's
    four = dopplertof.RenderParams(time_sampling_method="auto", hetero_frequency=1.0,
                                   time_correlate_number=4, time=0.001).resolved(0.0)
    assert four.time_correlate_number == 4 and four.time_sampling_method == "antithetic"
    assert auto(1.0)["antithetic_mapping"] == "replay"  # measured: motion does not pay
    p = dopplertof.RenderParams(time_sampling_method="auto", hetero_frequency=1.0,
                                time=0.001).resolved(0.0)
    assert p.time_sampling_method == "antithetic" and p.path_correlation_depth == FULL_CORRELATION


# ---- Seeds: all 64 bits key the streams (issue 22, item 4) ----------------------------

#: seeds of 2^32 and more, which wrapped modulo 2^32 onto seeds 0 and 1 (and each other)
LARGE_SEEDS = (1 << 32, (1 << 32) + 1, 1 << 40, (1 << 64) - 1)


def _seed_images(seeds):
    from analytic import plane_scene

    scene = dopplertof.load_dict(plane_scene(3.0, 10.0, spp=8, res=4,
                                             integrator={"hetero_frequency": 1.0}))
    return {s: dopplertof.render(scene, seed=s) for s in seeds}


def test_seeds_of_2_to_the_32_and_more_give_images_of_their_own():
    images = _seed_images((0, 1) + LARGE_SEEDS)
    keys = list(images)
    for i, a in enumerate(keys):
        for b in keys[i + 1:]:
            assert not np.array_equal(images[a], images[b]), (a, b)
    # NumPy's unsigned integers are the same seeds
    again = _seed_images([np.uint64((1 << 64) - 1), np.uint64(1 << 32)])
    assert np.array_equal(again[np.uint64((1 << 64) - 1)], images[(1 << 64) - 1])
    assert np.array_equal(again[np.uint64(1 << 32)], images[1 << 32])


def test_stream_keys_are_the_seeds_words():
    assert sampling.seed_words(7) == (7, None)  # below 2^32: the key it always had
    assert sampling.seed_words((1 << 32) + 7) == (7, 1)
    assert len({sampling.seed_words(s) for s in (0, 1) + LARGE_SEEDS}) == 6
    with pytest.raises(ValueError, match=r"\[0, 2\^64\)"):
        sampling.seed_words(1 << 64)


@pytest.mark.parametrize("seed, error", [(1 << 64, ValueError), (-1, ValueError),
                                         (1.5, TypeError), (True, TypeError),
                                         ("3", TypeError)])
def test_seeds_outside_the_64_bit_range_or_not_integers_are_refused(seed, error):
    from analytic import plane_scene

    scene = dopplertof.load_dict(plane_scene(3.0, 0.0, spp=8, res=2))
    with pytest.raises(error, match="seed must be an integer in") as info:
        dopplertof.render(scene, seed=seed)
    assert "\n" not in str(info.value)
