"""Values that were silently wrong (issue 22, items 4-7, the unit mistakes, 14 and 17):
each is now a correct result or a one-line refusal naming the argument."""

import numpy as np
import pytest

import dopplertof
from dopplertof.demo import demo_scene_path
from dopplertof.experiments import ConfigError, config_from_mapping, plan_sweep


def sweep_config(run_seeds, reference_seed):
    """A 6x6 Cornell box sweep over ``run_seeds`` against a reference at ``reference_seed``
    that samples like the runs (the same spp): only the seed tells them apart."""
    return config_from_mapping({
        "name": "seeds", "scene": demo_scene_path(), "defines": {"res": 6, "max_depth": 2},
        "fixed": {"spp": 4, "hetero_frequency": 1.0},
        "grid": {"seed": list(run_seeds)},
        "reference": {"spp": 4, "seed": reference_seed}}, source="seeds.toml")


# ---- Item 5: the reference must not share a stream key with the runs -----------------

def test_a_reference_at_seed_2_to_the_32_is_not_the_runs_seed_0(tmp_path):
    """Seed 2^32 wrapped onto seed 0: the reference passed the 'must not share a seed'
    check and every run's MSE was 0.0. Now its stream key differs and so does its image."""
    tasks = plan_sweep(sweep_config([0], 1 << 32), str(tmp_path / "out"))
    run, = [t for t in tasks if t.kind == "run"]
    reference, = [t for t in tasks if t.kind == "reference"]
    assert (run.seed, reference.seed) == (0, 1 << 32)
    scene = dopplertof.load_file(run.scene, run.defines)
    images = [dopplertof.render(scene, spp=t.spp, seed=t.seed, params=t.params,
                                progress=False) for t in (run, reference)]
    assert np.mean((images[0] - images[1]) ** 2) > 0


def test_a_reference_sharing_the_runs_stream_key_is_refused():
    with pytest.raises(ConfigError, match=r"reference.seed 4294967296 is also a seed of the "
                                          "runs"):
        sweep_config([1, 1 << 32], 1 << 32)
    with pytest.raises(ConfigError, match=r"seed must be an integer in \[0, 2\^64\)"):
        sweep_config([1 << 64], 5)
