"""capture()'s settings as one typed object (dopplertof.CaptureSettings): built by the
command line and the Python API and passed through; keyword arguments build the same."""

import numpy as np
import pytest
from analytic import plane_scene

import dopplertof
from dopplertof import CaptureSettings


def test_keywords_build_the_settings_and_override_given_ones():
    asked = CaptureSettings.of(None, spp=8, noise=True, mc_batches=4)
    assert asked == CaptureSettings(spp=8, noise=True, mc_batches=4)
    over = CaptureSettings.of(asked, seed=5, mc_batches=None)
    assert (over.spp, over.seed, over.noise, over.mc_batches) == (8, 5, True, None)
    with pytest.raises(TypeError, match="unexpected keyword argument 'mc_batch', did you "
                                        "mean 'mc_batches'"):
        CaptureSettings.of(None, mc_batch=4)
    with pytest.raises(TypeError, match="settings must be a CaptureSettings, got dict"):
        CaptureSettings.of({"spp": 8})


def test_a_capture_of_settings_is_bitwise_the_capture_of_the_same_keywords():
    scene = dopplertof.load_dict(plane_scene(2.0, 3.0, res=3, spp=4))
    settings = CaptureSettings(spp=4, seed=3, params={"max_depth": 2}, hetero_frequency=2,
                               progress=False)
    by_settings = dopplertof.capture(scene, settings=settings)
    by_keywords = dopplertof.capture(scene, 4, 3, params={"max_depth": 2},
                                     hetero_frequency=2, progress=False)
    # the arguments given over the settings' (seed 3 -> 4: another frame)
    overridden = dopplertof.capture(scene, seed=4, settings=settings)
    assert by_settings.captures.keys() == by_keywords.captures.keys()
    for name, image in by_settings.captures.items():
        assert np.array_equal(image, by_keywords.captures[name], equal_nan=True), name
    assert not np.array_equal(by_settings.captures["homodyne_0"],
                              overridden.captures["homodyne_0"])
    assert by_settings.summary["seed"] == 3 and overridden.summary["seed"] == 4
    assert by_settings.summary["modulation"]["hetero_frequency"] == 2
    with pytest.raises(TypeError, match="unexpected keyword argument 'noize'"):
        dopplertof.capture(scene, spp=4, noize=True)
