"""The correlated sampler: exact replay, shared and own streams, time sampling methods."""

import numpy as np
import pytest
from scipy import stats

import dopplertof
from dopplertof import pixel_sets, sampling, sequences
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
    pts = sequences.sobol_2d(mi, mi.UInt32(idx), mi.UInt32(0x1234567), mi.UInt32(0x89ABCDE))
    x, y = np.asarray(pts.x), np.asarray(pts.y)
    assert x.min() >= 0 and x.max() < 1 and y.min() >= 0 and y.max() < 1
    for cols, rows in ((64, 1), (8, 8), (1, 64), (16, 4)):  # every elementary interval
        cells = np.floor(x * cols).astype(int) * rows + np.floor(y * rows).astype(int)
        assert sorted(cells) == list(range(64))


def elementary_cells(x, y, n, cols, rows):
    return sorted(np.floor(x * cols).astype(int) * rows + np.floor(y * rows).astype(int))


def assert_shifted_lattice(x, y, n):
    """(x, y) are the rank-1 lattice {(k, k g) / n}, shifted on the torus: every point k/n
    from the first on the x axis sits k g / n from it on the y axis (to the 24 bits kept),
    one point in every 1-D stratum of width 1/n on each axis."""
    for axis in (x, y):
        assert sorted(np.floor(axis * n).astype(int)) == list(range(n))
    dx, dy = np.mod(x - x[0], 1.0) * n, np.mod(y - y[0], 1.0) * n  # offsets from point 0
    k = np.rint(dx).astype(np.int64)
    assert np.abs(dx - k).max() < 1e-4
    expected = np.mod(k * sequences.LATTICE_GENERATOR, n)
    assert np.abs(np.mod(dy - expected + n / 2, n) - n / 2).max() < 1e-4


def _shortest_lattice_vector(g: int, m: int) -> float:
    """The torus distance between the closest two points of {(k, k g) / 2^m}: the
    shortest vector of the lattice spanned by (1, g) / 2^m and (0, 1) (Gauss reduction,
    exact in integers)."""
    n = 1 << m
    u, v = (1, g % n), (0, n)
    norm = lambda w: w[0] * w[0] + w[1] * w[1]  # noqa: E731
    if norm(u) > norm(v):
        u, v = v, u
    while True:
        mu = round((u[0] * v[0] + u[1] * v[1]) / norm(u))
        v = (v[0] - mu * u[0], v[1] - mu * u[1])
        if norm(v) >= norm(u):
            return norm(u) ** 0.5 / n
        u, v = v, u


def test_the_lattice_generator_spreads_every_power_of_two_of_points():
    """Every lattice of 2^m points (m = 3..27: 8 to 134M samples per pixel) has its
    closest points at least 0.7 of the hexagonal packing's distance sqrt(2 / (sqrt(3) n))
    apart; a poor generator (g = 1: the diagonal) is far below it."""
    for m in range(3, 28):
        n = 1 << m
        packing = (2.0 / (3.0 ** 0.5 * n)) ** 0.5
        assert _shortest_lattice_vector(sequences.LATTICE_GENERATOR, m) >= 0.7 * packing, m
    assert _shortest_lattice_vector(1, 10) < 0.1 * (2.0 / (3.0 ** 0.5 * 1024)) ** 0.5


@pytest.mark.parametrize("depth", [0, 2])
def test_first_hit_decisions_are_low_discrepancy_sets(depth):
    """A pixel's 64 groups (64 x 2 samples): its first-hit light samples are a (0,6,2)-net
    and its BSDF samples a shifted lattice of 64 (their index shuffle and scramble or
    shift keep aligned blocks), shared within a group when stage 1 is, and paired with
    each other at random, not by index."""
    import mitsuba as mi

    G, K = 64, 2
    group = np.repeat(np.arange(G), K)
    index = np.tile(np.arange(K), G)
    s = streams(np.full(G * K, 3), group, group * K + index, depth=depth)
    pts = [s.first_hit_2d(d, mi.UInt32(group), mi.UInt32(index), G) for d in (0, 1)]
    (x0, y0), (x1, y1) = [(np.asarray(p.x), np.asarray(p.y)) for p in pts]
    for d, (x, y) in enumerate(((x0, y0), (x1, y1))):
        assert x.min() >= 0 and x.max() < 1 and y.min() >= 0 and y.max() < 1
        for i in range(K):  # the samples of one index in the group: one net or lattice
            xi, yi = x[index == i], y[index == i]
            if d == 1:
                assert_shifted_lattice(xi, yi, 64)
                continue
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


# ---- Joint sets (pixel_sets="joint"): neighbouring pixels stratified together ----

def joint_streams(width, height, spp, K=2, depth=0, pilot=0, seed=7):
    """Streams of every sample of every pixel of a width x height film, joint sets."""
    import mitsuba as mi

    joint = pixel_sets.JointSets(width, spp, K, K, pilot, height)
    pixel = np.repeat(np.arange(width * height), spp)
    sample = np.tile(np.arange(spp), width * height)
    s = sampling.CorrelatedStreams(mi, mi.UInt32(pixel), mi.UInt32(sample // K),
                                   mi.UInt32(sample), mi.UInt32(seed), mi.UInt32(depth),
                                   joint=joint)
    return s, pixel, sample


def absolute_film(s, pixel, sample, width, K=2, G=8):
    import mitsuba as mi

    film = s.film_2d(mi.UInt32(sample // K), mi.UInt32(sample % K), G)
    x, y = np.asarray(film.x), np.asarray(film.y)
    assert x.min() >= 0 and x.max() < 1 and y.min() >= 0 and y.max() < 1
    return (pixel % width + x) / width, (pixel // width + y) / width


def is_net(x, y):
    n = len(x)
    levels = n.bit_length() - 1
    return all(len(set(zip(np.floor(x * 2 ** k).astype(int),
                           np.floor(y * 2 ** (levels - k)).astype(int)))) == n
               for k in range(levels + 1))


def test_joint_film_positions_are_one_net_over_the_image():
    """8x8 pixels x 16 spp: the 1024 film positions, in image coordinates, are a
    (0,10,2)-net (every elementary interval holds one), each pixel's 16 a net of its
    own; the independent sets' union is not a net."""
    import mitsuba as mi

    s, pixel, sample = joint_streams(8, 8, 16)
    x, y = absolute_film(s, pixel, sample, 8)
    assert is_net(x, y)
    for p in (0, 9, 63):
        mine = pixel == p
        assert is_net(x[mine] * 8 % 1, y[mine] * 8 % 1)
    independent = sampling.CorrelatedStreams(
        mi, mi.UInt32(pixel), mi.UInt32(sample // 2), mi.UInt32(sample), mi.UInt32(7),
        mi.UInt32(0))
    assert not is_net(*absolute_film(independent, pixel, sample, 8))


def test_joint_decisions_stratify_each_2x2_block_of_pixels():
    """The BSDF samples of a 2x2 block of pixels (4 x 16), at the first hit and the
    second, form a shifted lattice of 64, and the second hit's light samples a
    (0,6,2)-net; each pixel's first light samples are stratified in 4x4 cells at least
    twice over (Sobol's dimensions 3 and 4: t = 1)."""
    import mitsuba as mi

    s, pixel, sample = joint_streams(4, 4, 16)
    block = np.isin(pixel, [0, 1, 4, 5])
    group, index = mi.UInt32(sample // 2), mi.UInt32(sample % 2)
    light0, direction0 = (s.first_hit_2d(d, group, index, 8) for d in (0, 1))
    second = mi.UInt32(np.ones(len(pixel), int))
    light1, direction1 = (s.joint_decision(second, k) for k in (0, 1))
    for p in (direction0, direction1):
        assert_shifted_lattice(np.asarray(p.x)[block], np.asarray(p.y)[block], 64)
    assert is_net(np.asarray(light1.x)[block], np.asarray(light1.y)[block])
    x, y = np.asarray(light0.x)[pixel == 5], np.asarray(light0.y)[pixel == 5]
    assert len(set(zip(np.floor(x * 4).astype(int), np.floor(y * 4).astype(int)))) >= 8
    # decisions are paired at random: the first light is not the BSDF sample
    assert not np.allclose(np.asarray(light1.x), np.asarray(direction1.x))


def test_joint_sets_share_within_groups_and_time_with_film():
    """Path groups share film and first-hit samples when their stages are shared;
    antithetic times of a shared camera ray stratify the exposure per pixel."""
    import mitsuba as mi

    s, pixel, sample = joint_streams(4, 4, 16, depth=FULL_CORRELATION)
    group, index = sample // 2, sample % 2
    film = s.film_2d(mi.UInt32(group), mi.UInt32(index), 8)
    light, direction = (s.first_hit_2d(d, mi.UInt32(group), mi.UInt32(index), 8)
                        for d in (0, 1))
    for p in (film, light, direction):
        x = np.asarray(p.x)
        assert np.array_equal(x[index == 0], x[index == 1])
    t = np.asarray(sampling.time_fraction(
        mi, s, mi.UInt32(group), mi.UInt32(index), group_size=2, groups_per_pixel=8,
        method=mi.UInt32(2), antithetic_shift=0.5, stratify=True, double=False))
    for p in range(16):
        primal = t[(pixel == p) & (index == 0)]
        assert sorted(np.floor(primal * 4).astype(int)) == [0, 0, 1, 1, 2, 2, 3, 3]


def test_joint_pilot_is_each_pixels_own_and_the_rest_joint():
    """Adaptive sampling: the pilot's film positions are each pixel's own sets (a
    pixel's samples never depend on the neighbours' pilots that set its count: their
    union is not a net), the samples after it one net over the image, scrambled apart
    from the pilots (another seed changes them; the pilot's numbers are not reused)."""
    s, pixel, sample = joint_streams(8, 8, 32, pilot=16)
    x, y = absolute_film(s, pixel, sample, 8, G=16)
    pilot = sample < 16
    assert not is_net(x[pilot], y[pilot])
    assert is_net(x[~pilot], y[~pilot])
    # each pixel's pilot is a net of its own, and the rest's 16 points another
    for part in (pilot, ~pilot):
        mine = part & (pixel == 27)
        assert is_net(x[mine] * 8 % 1, y[mine] * 8 % 1)
    assert not np.allclose(np.sort(x[pilot & (pixel == 27)]), np.sort(x[~pilot & (pixel == 27)]))


@pytest.mark.parametrize("width, height, spp", [(5, 3, 12), (1, 1, 6), (7, 7, 40)])
def test_joint_sets_with_counts_and_sizes_not_powers_of_two(width, height, spp):
    """Film positions stay in their pixel and uniform; adaptive counts above spp (more
    groups than a block) start a new epoch instead of repeating points."""
    import mitsuba as mi

    s, pixel, sample = joint_streams(width, height, spp)
    x, y = absolute_film(s, pixel, sample, width, G=spp // 2)
    assert len(set(zip(x.round(6), y.round(6)))) == len(x)
    joint = pixel_sets.JointSets(width, spp, 2, 2, 0, height)
    beyond = np.arange(4 * spp)  # samples of one pixel far above spp
    many = sampling.CorrelatedStreams(mi, mi.UInt32(np.zeros_like(beyond)),
                                      mi.UInt32(beyond // 2), mi.UInt32(beyond),
                                      mi.UInt32(7), mi.UInt32(0), joint=joint)
    film = many.film_2d(mi.UInt32(beyond // 2), mi.UInt32(beyond % 2), spp // 2)
    fx = np.asarray(film.x)
    assert len(set(fx.round(7))) == len(fx) and fx.min() >= 0 and fx.max() < 1


def test_a_modality_s_numbers_are_placed_in_its_reserved_slots():
    """A modality's own numbers (sampling.ModalityDimensions) lie in the slots the layout
    reserves, apart from the path loop's: the FMCW lidar's beam spot at the lane's
    dimensions 2-3 and its speckle phases at each bounce's offsets 6-7 (where its
    spectra have always read them); a declaration that does not fit is refused."""
    from dopplertof.fmcw.trace import DIMENSIONS

    loop_lane = {sampling.DIM_TIME, sampling.DIM_WAVELENGTH, sampling.DIM_APERTURE,
                 sampling.DIM_APERTURE + 1}
    assert DIMENSIONS.lane_dim("beam_film") == 2
    assert not loop_lane & {2, 3} and sampling.DIM_FIRST_BOUNCE > 3
    loop_bounce = {sampling.BOUNCE_EMITTER, sampling.BOUNCE_EMITTER + 1,
                   sampling.BOUNCE_BSDF_LOBE, sampling.BOUNCE_BSDF_DIR,
                   sampling.BOUNCE_BSDF_DIR + 1, sampling.BOUNCE_RR}
    for depth in (0, 3):
        phases = {DIMENSIONS.bounce_dim(depth, "phases", k) for k in (0, 1)}
        block = sampling.bounce_dim(depth, 0)
        assert phases == {block + 6, block + 7}
        assert not phases & {block + offset for offset in loop_bounce}
    with pytest.raises(ValueError, match="need 3 dimensions; the layout reserves 2"):
        sampling.ModalityDimensions(bounce=(("a", 2), ("b", 1)))
    with pytest.raises(ValueError, match="lane numbers"):
        sampling.ModalityDimensions(lane=(("spot", 3),))
