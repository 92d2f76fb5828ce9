"""The splat film (integrators/film.py): filter weights, their exact integrals and the
normalization at the edges, unbiasedness against quadrature on every pixel (uniform and
forced uneven sample counts), determinism, and the importance film kept as it was."""

import json
import os
import sys

import numpy as np
import pytest
from analytic import filter_1d, filtered_axis, plane_scene, reference
from bounds import normal_bound, student_bound
from conftest import FIXTURES, PUBLISHED

import dopplertof
from dopplertof import allocation

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def film_with(kind, res=4):
    d = plane_scene(4.0, 30.0, res=res)
    d["sensor"]["film"]["rfilter"] = {"type": kind}
    return dopplertof.load_dict(d).sensor.film()


def splat_filter(kind):
    from dopplertof.integrators.film import SplatFilter

    return SplatFilter(film_with(kind))


@pytest.mark.parametrize("kind,reach", [("box", 0), ("tent", 1), ("gaussian", 2)])
def test_lane_weights_are_the_filter_and_integrate_to_the_cell_weights(kind, reach):
    import mitsuba as mi

    f = splat_filter(kind)
    assert f.reach == reach and len(f.offsets) == (2 * reach + 1) ** 2
    # a fine midpoint grid of offsets within the pixel
    n = 400
    u = (np.arange(n) + 0.5) / n - 0.5
    dx, dy = (a.ravel() for a in np.meshgrid(u, u))
    weights = f.lane_weights(mi, mi.Vector2f(dx, dy))
    if reach == 0:
        assert weights is None
        return
    for (ox, oy), w in zip(f.offsets, weights):
        w = np.array(w)
        # the weight of a sample at offset d from its own centre in pixel j + o
        exact = filter_1d(kind, dx - ox) * filter_1d(kind, dy - oy)
        assert np.allclose(w, exact, atol=2e-6)
        assert w.mean() == pytest.approx(f.cell_integral(ox) * f.cell_integral(oy),
                                         abs=2e-6)


def test_tent_weights_are_a_partition_of_unity():
    import mitsuba as mi

    f = splat_filter("tent")
    rng = np.random.default_rng(1)
    d = rng.uniform(-0.5, 0.5, size=(2, 10_000))
    total = sum(np.array(w) for w in f.lane_weights(mi, mi.Vector2f(*d)))
    assert np.allclose(total, 1.0, atol=1e-6)


@pytest.mark.parametrize("kind", ["tent", "gaussian"])
def test_expected_weights_count_only_sources_inside_the_window(kind):
    f = splat_filter(kind)
    h, w = 5, 7
    brute = np.zeros((h, w))
    for y in range(h):
        for x in range(w):
            for ox, oy in f.offsets:  # source (y - oy, x - ox)
                if 0 <= y - oy < h and 0 <= x - ox < w:
                    brute[y, x] += f.cell_integral(ox) * f.cell_integral(oy)
    assert np.allclose(f.expected_weights((h, w)), brute, rtol=1e-12)
    interior = (f.cell_integral(0) + 2 * sum(f.cell_integral(k)
                                             for k in range(1, f.reach + 1))) ** 2
    assert f.expected_weights((h, w))[2, 3] == pytest.approx(interior, rel=1e-12)
    # a corner receives from the sources on one side of it only, on both axes
    corner = (f.cell_integral(0) + sum(f.cell_integral(k) for k in range(1, f.reach + 1))) ** 2
    assert f.expected_weights((h, w))[0, 0] == pytest.approx(corner, rel=1e-12)


#: renders averaged by the splat films' comparisons with the quadrature
SPLAT_SEEDS = range(8)


def pixel_references(kind, res, h, offset):
    return np.array([[reference(4.0, 30.0, hetero_frequency=h, hetero_offset=offset,
                                film=(filtered_axis(kind, res, x), filtered_axis(kind, res, y)))
                      for x in range(res)] for y in range(res)])


def plane(kind, res, spp, **integrator):
    d = plane_scene(4.0, 30.0, spp=spp, res=res, integrator=integrator)
    d["sensor"]["film"]["rfilter"] = {"type": kind}
    return dopplertof.load_dict(d)


@pytest.mark.parametrize("normalization", ["weights", "expected"])
@pytest.mark.parametrize("kind", ["tent", "gaussian"])
@pytest.mark.parametrize("h,offset", [(0.0, 0.25), (1.0, 0.0)])
def test_every_splat_pixel_matches_quadrature(kind, h, offset, normalization):
    # A 4x4 film of the plane receding at 30 m/s: every pixel, corners and edges
    # included, is the filter-weighted mean over the part of its support inside the
    # film (a wrong edge normalization is off by 12-40% there).
    # False failures (16 pixels): measured over 24 other seeds, a pixel's standard
    # deviation per render is up to 1.6e-3 of the largest pixel at h = 1 (2e-6 to 2.4e-4
    # homodyne); the mean of SPLAT_SEEDS renders puts the 3.3e-3 tolerance at 5.7 or
    # more of its standard deviations: 2e-7 for the test's 64 pixels at h = 1 (the mean
    # of 2 renders, as before, was 2.9 of them: 1e-2 per test).
    expected = pixel_references(kind, 4, h, offset)
    scene = plane(kind, 4, 1024, hetero_frequency=h, hetero_offset=offset,
                  film_normalization=normalization)
    image = np.mean([dopplertof.render(scene, seed=s)[..., 0] for s in SPLAT_SEEDS], axis=0)
    assert np.abs(image - expected).max() <= 2e-3 * np.abs(expected).max() + 2e-7


@pytest.mark.parametrize("normalization", ["weights", "expected"])
@pytest.mark.parametrize("kind", ["tent", "gaussian"])
def test_adaptive_splat_matches_quadrature_with_uneven_counts(monkeypatch, kind,
                                                              normalization):
    # Counts forced to a checkerboard of 1024 and 2048 samples: each source pixel's
    # sums must be divided by its own count before they are splatted (dividing the
    # splatted sums by the target's count, or by the spp, is off by up to 50%).
    # False failures: as above (the mean of 2 renders was 3.6-6 standard deviations;
    # with SPLAT_SEEDS 7 or more: below 1e-10).
    def checkerboard(variance, spp, pilot, chunk):
        y, x = np.indices(variance.shape)
        return np.where((x + y) % 2 == 0, spp // 2, spp)

    monkeypatch.setattr(allocation, "sample_counts", checkerboard)
    expected = pixel_references(kind, 4, 1.0, 0.0)
    scene = plane(kind, 4, 2048, hetero_frequency=1.0, adaptive_sampling=True,
                  film_normalization=normalization)
    image = np.mean([dopplertof.render(scene, seed=s)[..., 0] for s in SPLAT_SEEDS], axis=0)
    assert np.abs(image - expected).max() <= 2e-3 * np.abs(expected).max() + 2e-7


def emitter_facing_camera(kind, normalization):
    """A 6x5 film (crop 4x3 at (1, 1)) filled by an area light: every sample has the
    same value, Le g1 C(0) at a vanishing frequency."""
    import mitsuba as mi

    d = plane_scene(4.0, 0.0, res=6, integrator={
        "max_depth": 1, "w_g": 1e-6, "film_normalization": normalization})
    d["sensor"]["film"].update(rfilter={"type": kind}, height=5, crop_offset_x=1,
                               crop_offset_y=1, crop_width=4, crop_height=3)
    del d["plane"], d["light"]
    d["wall"] = {"type": "rectangle", "emitter": {"type": "area", "radiance": 2.0},
                 "to_world": mi.ScalarTransform4f().translate([0, 0, 3]).rotate(
                     [0, 1, 0], 180).scale(50)}
    return dopplertof.load_dict(d)


@pytest.mark.parametrize("kind", ["tent", "gaussian"])
def test_a_constant_image_everywhere_in_the_crop_window(kind):
    # the sampled-weight normalization (a ratio) is exact for a constant; the expected
    # one (unbiased) is right in the mean, up to how well the pixel's film positions
    # integrate the filter (low-discrepancy sets: up to 2e-3 at 256 spp). That spread
    # is the scrambles': over 300 other seeds the largest pixel error is 1.5e-3 +- 3e-4
    # (at most 2.5e-3; a Gumbel tail fitted to them exceeds rtol 4e-3 with about 5e-5 per
    # filter) and the mean's standard deviation is 1.9e-4 (20 seeds: the 1e-3 bound is
    # 5.4 of them, 1e-7)
    value = 2.0 * 0.5 * 0.5
    ratio = dopplertof.render(emitter_facing_camera(kind, "weights"), spp=64, seed=1)
    assert ratio.shape == (3, 4, 3)
    # exact by construction: every sample's value is the power of two 1/2 (Le g1 C(0) =
    # 2 x 1/2 x 1/2, the cosine at a vanishing frequency rounding to 1), so the weighted
    # sum is 1/2 of the weights' sum in any order (scaling by 2^k rounds nothing), and the
    # ratio's one division rounds by at most u; rtol 1e-6 is 16 u
    assert np.allclose(ratio, value, rtol=1e-6)
    expected = dopplertof.render(emitter_facing_camera(kind, "expected"), spp=256, seed=1)
    assert np.allclose(expected, value, rtol=4e-3)
    assert expected.mean() == pytest.approx(value, rel=1e-3)
    assert not np.allclose(expected, value, rtol=1e-6)


@pytest.mark.parametrize("kind", ["tent", "gaussian"])
def test_splat_film_is_bitwise_independent_of_the_passes(kind):
    scene = plane(kind, 5, 64, hetero_frequency=1.0)
    a = dopplertof.render(scene, seed=3)
    b = dopplertof.render(scene, seed=3, pass_chunks=1)
    c = dopplertof.render(scene, seed=3, max_lanes=5 * 5 * 16)
    assert np.array_equal(a, b) and np.array_equal(a, c)


def test_box_splat_film_is_the_importance_film():
    scene = plane("box", 3, 64, hetero_frequency=1.0)
    a = dopplertof.render(scene, seed=2)
    b = dopplertof.render(scene, seed=2, params={"film_sampling": "importance"})
    assert np.array_equal(a, b)


def test_film_parameters_are_checked():
    scene = plane("tent", 2, 16)
    with pytest.raises(ValueError, match="unknown film_sampling 'splatter'"):
        dopplertof.render(scene, params={"film_sampling": "splatter"})
    with pytest.raises(ValueError, match="unknown film_normalization"):
        dopplertof.render(scene, params={"film_normalization": "sum"})


def test_importance_film_reproduces_its_recorded_images():
    """The hashes of tools/image_hashes.py's renders with film_sampling=importance added
    to every render, recorded when the first bounce's directions became a lattice
    (2026-12-02; before, from commit b1fb1c9 on: the images from before the splat film).
    Bitwise, so only on the machine and versions that recorded them."""
    with open(os.path.join(FIXTURES, "images_importance_film.json")) as f:
        before = json.load(f)
    sys.path.insert(0, os.path.join(ROOT, "tools"))
    import image_hashes

    if before["machine"] != image_hashes.machine():
        pytest.skip("the hashes were recorded on another machine or with other versions: "
                    f"{before['machine']}")
    found = image_hashes.hashes({"film_sampling": "importance"})
    assert {name: found.get(name) for name in before["images"]} == before["images"]
    assert PUBLISHED  # (the published scene is among them)


def test_motion_mapped_pairs_splat_to_the_quadrature():
    # A fast plane (300 m/s: 40% of a pixel per exposure), pairs followed on the body;
    # the partner is splatted from its own film position, its density the pixel's cell
    # (integrators/antithetic_map.py). Noisy (1.5% per pixel at 1024 spp): 16 seeds,
    # every pixel's |t| under the Student bound (15 degrees of freedom, Bonferroni over
    # 16 pixels for 5e-5: about 7.2) and their pooled z (sum of t / 4, standard deviation
    # sqrt(15/13)) under 4.36, another 5e-5: 1e-4 for the test (|t| < 5 and z < 4 before:
    # 2.5e-3 and 2e-4). A pixel biased by 3% (8 standard errors) fails it, and so does a
    # bias of 0.5% common to every pixel (the pooled z).
    d = plane_scene(4.0, 300.0, spp=1024, res=4, integrator={
        "hetero_frequency": 1.0, "time_sampling_method": "antithetic",
        "antithetic_mapping": "motion"})
    d["sensor"]["film"]["rfilter"] = {"type": "tent"}
    scene = dopplertof.load_dict(d)
    expected = np.array([[reference(4.0, 300.0, hetero_frequency=1.0,
                                    film=(filtered_axis("tent", 4, x), filtered_axis("tent", 4, y)))
                          for x in range(4)] for y in range(4)])
    images = np.array([dopplertof.render(scene, seed=s)[..., 0] for s in range(16)])
    t = (images.mean(0) - expected) / (images.std(0, ddof=1) / 4)
    pooled_bound = normal_bound(5e-5, 1) * np.sqrt(15 / 13)
    assert np.abs(t).max() < student_bound(5e-5, 16, 15) and abs(t.sum() / 4) < pooled_bound, t


@pytest.mark.slow
def test_ratio_normalization_bias_is_below_measurement_at_4_spp():
    # The ratio estimator's bias is O(1/spp); at 4 spp (2 film positions per pixel)
    # the mean of 200 renders of the homodyne plane is the quadrature within 2e-4
    # relative (measured: 5e-6 +- 2e-5: 10 standard errors, no false failures to speak
    # of), while each render's pixels scatter by 0.16% (the expected normalization's by
    # 7%: the weight sums' own noise; the bound on their ratio, 0.05, is twice it).
    expected = pixel_references("tent", 4, 0.0, 0.25)
    images = {}
    for normalization in ("weights", "expected"):
        scene = plane("tent", 4, 4, hetero_offset=0.25, film_normalization=normalization)
        images[normalization] = np.array([dopplertof.render(scene, seed=s)[..., 0]
                                          for s in range(200)])
    relative = images["weights"].mean(0) / expected - 1
    assert abs(relative.mean()) < 2e-4, relative
    spread = {k: (v.std(0, ddof=1) / expected).mean() for k, v in images.items()}
    assert spread["weights"] < 0.05 * spread["expected"], spread


# ---- Joint pixel sets (pixel_sets="joint") ----

@pytest.mark.parametrize("kind", ["tent", "gaussian"])
def test_joint_pixel_sets_splat_every_pixel_to_the_quadrature(kind):
    # As test_every_splat_pixel_matches_quadrature (h = 1, its tolerance), with the
    # film, time and decisions of neighbouring pixels stratified jointly: correlated
    # pixels, each still unbiased
    expected = pixel_references(kind, 4, 1.0, 0.0)
    scene = plane(kind, 4, 1024, hetero_frequency=1.0, pixel_sets="joint")
    image = np.mean([dopplertof.render(scene, seed=s)[..., 0] for s in SPLAT_SEEDS], axis=0)
    assert np.abs(image - expected).max() <= 2e-3 * np.abs(expected).max() + 2e-7
    independent = plane(kind, 4, 1024, hetero_frequency=1.0, pixel_sets="independent")
    assert not np.array_equal(dopplertof.render(scene, seed=0),
                              dopplertof.render(independent, seed=0))


def test_joint_pixel_sets_are_bitwise_independent_of_the_passes():
    scene = plane("gaussian", 5, 64, hetero_frequency=1.0, pixel_sets="joint")
    a = dopplertof.render(scene, seed=3)
    b = dopplertof.render(scene, seed=3, pass_chunks=1)
    c = dopplertof.render(scene, seed=3, max_lanes=5 * 5 * 16)
    assert np.array_equal(a, b) and np.array_equal(a, c)
    with pytest.raises(dopplertof.SceneError, match="unknown pixel_sets .tiles."):
        plane("tent", 4, 16, pixel_sets="tiles")
