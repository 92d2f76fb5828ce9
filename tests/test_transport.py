"""Light transport against stock Mitsuba: with a vanishing modulation frequency the D-ToF
weight is the constant g1 C(psi) = g1 cos(psi) / 2, so the D-ToF image must equal that
constant times Mitsuba's own `path` render (area light, MIS, Russian roulette, GI).

Statistics: every comparison is |t| = |difference of the means over 16 seeds| / their
combined standard error, held under the Student quantile (15 degrees of freedom,
conservatively: Welch gives about 30) that gives the file's 90 comparisons (5 x 6 + 2 x 6
regions + 30 crop blocks + 3 x 6 regions) a family-wise false-failure rate of 1e-3
(Bonferroni): about 6.4. Measured over 20 x 16 other seeds, the |t| scatter with a
standard deviation of 0.83-0.88 and never passed 2.4. The whole-image mean's relative
standard error is 0.10-0.15% (region means up to 0.5%, crop blocks up to 4%), so a bias
of 1% of the whole image fails a case 90-95% of the time (the measured renders scaled by
1.01), and one shared by the 5 cases fails at least one almost surely. (A relative
tolerance of 0.5% on
every region, as before, was only 1.3-2 of those standard errors: it failed 2 of 10
legitimate changes of seeds.)
"""

import numpy as np
import pytest

import dopplertof
from bounds import student_bound

SEEDS = range(16)
SPP = 256
#: |t| bound per comparison (see the module docstring)
T_BOUND = student_bound(1e-3, 90, len(SEEDS) - 1)


def cornell(integrator, rfilter="box"):
    import mitsuba as mi

    d = mi.cornell_box()
    d["integrator"] = integrator
    d["sensor"]["film"]["width"] = d["sensor"]["film"]["height"] = 16
    d["sensor"]["film"]["rfilter"] = {"type": rfilter}
    d["sensor"]["sampler"] = {"type": "independent", "sample_count": SPP}
    return d


#: the D-ToF weight of every contribution at a vanishing frequency: g1 * C(psi)
WEIGHT = 0.5 * 0.5 * np.cos(2 * np.pi * 0.1)


def dtof(max_depth, **extra):
    """The D-ToF integrator whose image is WEIGHT times stock `path`'s."""
    return {"type": "dopplertof", "max_depth": max_depth, "w_g": 1e-6, "hetero_offset": 0.1,
            "time_sampling_method": "uniform", "path_correlation_depth": 0, **extra}


def render_both(stock_scene, ours_scene, reduce):
    """``reduce`` of each seed's stock image and of ours divided by WEIGHT."""
    import mitsuba as mi

    stock = np.array([reduce(np.array(mi.render(stock_scene, spp=SPP, seed=s)))
                      for s in SEEDS])
    ours = np.array([reduce(dopplertof.render(ours_scene, spp=SPP, seed=s)) / WEIGHT
                     for s in SEEDS])
    return stock, ours


def assert_agree(stock, ours):
    """Means over seeds agree within T_BOUND combined standard errors."""
    se = np.sqrt(stock.var(axis=0, ddof=1) / len(SEEDS) + ours.var(axis=0, ddof=1) / len(SEEDS))
    assert np.all(se > 0)
    t = np.abs(stock.mean(axis=0) - ours.mean(axis=0)) / se
    assert np.all(t < T_BOUND), (t, T_BOUND, stock.mean(axis=0), ours.mean(axis=0), se)


def regions(img):
    lum = img.mean(axis=-1)
    border = np.ones_like(lum, dtype=bool)
    border[1:-1, 1:-1] = False
    return np.array([lum.mean(), lum[:8].mean(), lum[8:].mean(), lum[:, :8].mean(),
                     lum[4:12, 4:12].mean(), lum[border].mean()])


@pytest.mark.parametrize("max_depth,rfilter", [(2, "box"), (3, "box"), (6, "box"),
                                                (3, "tent"), (3, "gaussian")])
def test_matches_stock_path_tracer(max_depth, rfilter):
    """Also with filters wider than a pixel: at the image's edges Mitsuba's film averages
    the filter over the part inside the crop window, and so do we (13% darker edge
    pixels with a tent filter before)."""
    import mitsuba as mi

    # The directly visible light is hidden in both: its few, very bright edge pixels would
    # dominate the noise of every region mean. Hidden emitters let camera rays through
    # (Mitsuba 3.9): from depth 3 on, the ceiling seen through the light counts.
    stock_scene = mi.load_dict(cornell({"type": "path", "max_depth": max_depth,
                                        "hide_emitters": True}, rfilter))
    ours_scene = dopplertof.load_dict(cornell(dtof(max_depth, hide_emitters=True), rfilter))
    # a 1% bias in how hidden emitters were handled once passed the earlier, 8 x 64 spp
    # version of this test; here it is 7-10 standard errors of the whole image (module
    # docstring)
    assert_agree(*render_both(stock_scene, ours_scene, regions))


def with_light(d, kind):
    """The Cornell box lit by a point or a spot light instead of its area light."""
    import mitsuba as mi

    d = dict(d)
    d.pop("light")
    if kind == "point":
        d["lamp"] = {"type": "point", "position": [0.3, 0.8, 0.2],
                     "intensity": {"type": "rgb", "value": 2.0}}
    else:
        d["lamp"] = {"type": "spot", "cutoff_angle": 40,
                     "to_world": mi.ScalarTransform4f().look_at(
                         origin=[0, 0.9, 0.5], target=[0, -1, 0], up=[0, 0, 1]),
                     "intensity": {"type": "rgb", "value": 3.0}}
    return d


@pytest.mark.parametrize("kind", ["point", "spot"])
def test_delta_lights_match_stock_path_tracer(kind):
    """Next-event estimation toward point and spot lights (the camera pipeline's lights)
    agrees with stock Mitsuba within T_BOUND combined standard errors (the regions'
    relative standard errors 0.2-0.6%)."""
    import mitsuba as mi

    stock_scene = mi.load_dict(with_light(cornell({"type": "path", "max_depth": 3}), kind))
    ours_scene = dopplertof.load_dict(with_light(cornell(dtof(3)), kind))
    stock, ours = render_both(stock_scene, ours_scene, regions)
    assert np.all(stock.mean(axis=0) > 0.01)
    assert_agree(stock, ours)


def test_crop_window_matches_stock_path_tracer():
    """A crop window renders the same part of the frame as stock Mitsuba, with a tent
    filter restricted to the window at its edges."""
    import mitsuba as mi

    def cropped(integrator):
        d = cornell(integrator, "tent")
        d["sensor"]["film"].update({"width": 24, "height": 20, "crop_offset_x": 5,
                                    "crop_offset_y": 3, "crop_width": 12, "crop_height": 10})
        return d

    def blocks(img):  # 2 x 2 blocks of pixels: each must agree
        assert img.shape[:2] == (10, 12)
        return img.mean(axis=-1).reshape(5, 2, 6, 2).mean(axis=(1, 3))

    stock_scene = mi.load_dict(cropped({"type": "path", "max_depth": 2}))
    ours_scene = dopplertof.load_dict(cropped(dtof(2)))
    assert_agree(*render_both(stock_scene, ours_scene, blocks))


@pytest.mark.parametrize("variant,channels,rfilter", [
    ("llvm_ad_spectral", 3, "box"), ("llvm_ad_spectral", 3, "gaussian"),
    ("llvm_ad_mono", 1, "box")])
def test_spectral_and_mono_variants_match_stock(variant, channels, rfilter):
    """Spectral variants sample wavelengths per path and convert each sample to RGB, as
    Mitsuba's film does (before splatting it, with a gaussian); mono variants give one
    channel."""
    dopplertof.set_variant(variant)
    import mitsuba as mi

    stock_scene = mi.load_dict(cornell({"type": "path", "max_depth": 3, "hide_emitters": True},
                                       rfilter))
    ours_scene = dopplertof.load_dict(cornell(dtof(3, hide_emitters=True), rfilter))
    assert dopplertof.render(ours_scene, spp=4).shape == (16, 16, channels)
    assert_agree(*render_both(stock_scene, ours_scene, regions))


def test_polarized_variants_are_refused():
    with pytest.raises(dopplertof.BackendError, match="polarized light transport"):
        dopplertof.set_variant("llvm_ad_spectral_polarized")
