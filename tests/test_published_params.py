"""Parameters of the published implementations' scenes and run scripts: accepted with
their published meaning (docs/parameters.md, "Porting from the published
implementations")."""

import sys

import numpy as np
import pytest

import dopplertof
from analytic import plane_scene, reference
from bounds import student_bound
from conftest import PUBLISHED
from dopplertof import sampling
from dopplertof.sampling import FULL_CORRELATION
from dopplertof.cli import main
from test_bad_input import GOOD

R = sys.modules["dopplertof.render"]  # the module (dopplertof.render is the function)

def load_xml(integrator="", sampler=""):
    """test_bad_input's good scene (correlated sampler, 8 spp) with more parameters."""
    return dopplertof.scene.load_string(
        GOOD.replace('<integer name="max_depth" value="3"/>',
                     '<integer name="max_depth" value="3"/>' + integrator)
        .replace('<integer name="sample_count" value="4"/>',
                 '<integer name="sample_count" value="8"/>' + sampler))


def published(res=8):
    return dopplertof.load_file(PUBLISHED, {"resx": res, "resy": res})


def count_passes(monkeypatch):
    """Counts the path tracing kernels launched (one per pass)."""
    import mitsuba as mi

    from dopplertof.integrators.dtof_path import integrator_class

    calls = []
    cls = integrator_class(mi)
    original = cls.trace

    def counted(*args):
        calls.append(1)
        return original(*args)

    monkeypatch.setattr(cls, "trace", counted)
    return calls


# ---- Parameters without effect --------------------------------------------------

def test_run_script_parameters_are_accepted_without_effect():
    """The Mitsuba 3 implementation's run script passes is_doppler_integrator, and its
    integrators take block_size: accepted in the XML and as overrides, the image the
    same bit for bit; a misspelt name stays an error."""
    plain = load_xml()
    xml = load_xml('<boolean name="is_doppler_integrator" value="true"/>'
                   '<integer name="block_size" value="32"/>')
    assert xml.params.is_doppler_integrator and xml.params.block_size == 32
    reference_image = dopplertof.render(plain, seed=2)
    assert np.array_equal(dopplertof.render(xml, seed=2), reference_image)
    assert np.array_equal(dopplertof.render(plain, seed=2, params={
        "is_doppler_integrator": False, "block_size": 4}), reference_image)
    with pytest.raises(dopplertof.scene.SceneError, match="unknown parameter 'block_sise'"):
        load_xml('<integer name="block_size" value="32"/><integer name="block_sise" value="3"/>')


# ---- samples_per_pass ------------------------------------------------------------

def test_samples_per_pass_sets_the_pass_size_and_not_the_image(monkeypatch):
    scene = published()
    full = dopplertof.render(scene, spp=64, seed=5)
    for per_pass, passes in ((16, 4), (32, 2), (64, 1), (-1, 1)):
        calls = count_passes(monkeypatch)
        image = dopplertof.render(scene, spp=64, seed=5, params={"samples_per_pass": per_pass})
        assert np.array_equal(image, full), per_pass
        assert len(calls) == passes, (per_pass, len(calls))
    # below one chunk (8 groups of K): whole chunks
    calls = count_passes(monkeypatch)
    assert np.array_equal(dopplertof.render(scene, spp=64, seed=5,
                                            params={"samples_per_pass": 4}), full)
    assert len(calls) == 4


def test_samples_per_pass_must_divide_spp():
    with pytest.raises(ValueError, match="spp 48 is not a multiple of samples_per_pass=32"):
        dopplertof.render(published(4), spp=48, params={"samples_per_pass": 32})
    with pytest.raises(dopplertof.ParameterError, match="samples_per_pass must be >= 1"):
        dopplertof.render(published(4), spp=48, params={"samples_per_pass": 0})


# ---- timeout --------------------------------------------------------------------

@pytest.mark.parametrize("film", ["splat", "importance"])
def test_timeout_stops_after_the_pass_normalizes_and_resumes(tmp_path, capsys, film):
    """timeout 0 expires during the first pass: the render stops after it (whatever the
    machine's speed), the image is that pass's sum over its 16 samples, stderr and the
    metadata say so, and the checkpoint resumes to the uninterrupted image."""
    scene = published()
    ckpt = tmp_path / "r.ckpt"
    base = {"film_sampling": film, "hetero_frequency": 0.0}  # homodyne: signal, not noise
    stop = dict(base, samples_per_pass=16, timeout=0)
    result = dopplertof.render_result(scene, spp=64, seed=3, params=stop, checkpoint=ckpt)
    err = capsys.readouterr().err
    assert "timeout of 0 s expired" in err and "16 of 64 samples per pixel" in err
    assert err.count("\n") == 1
    md = result.metadata
    assert md["timed_out"] and md["samples_taken"] == 16 and md["spp"] == 64
    with np.load(ckpt) as saved:
        assert int(saved["next"]) == 1  # one chunk of 16 samples
        if film == "importance":  # the sums divided by the 16 samples taken
            expected = (saved["total"] / 16).astype(np.float32).reshape(result.image.shape)
            assert np.array_equal(result.image, expected)
    # the partial image is an image of 16 samples: its least-squares scale to the full
    # one is 1 within noise (measured 0.99-1.01; normalizing by spp would give 1/4; over
    # 20 other seeds its standard deviation is 0.009: 0.05 is 5.8 of them, a false-failure
    # rate of 1e-8 per film)
    full = dopplertof.render(scene, spp=64, seed=3, params=base)
    scale = float(np.sum(result.image * full) / np.sum(full * full))
    assert 0.95 < scale < 1.05, scale
    # resumable with the timeout (one more pass) and without it (to the end)
    again = dopplertof.render_result(scene, spp=64, seed=3, params=stop, checkpoint=ckpt)
    assert again.metadata["samples_taken"] == 32 and again.metadata["timed_out"]
    assert "32 of 64 samples per pixel" in capsys.readouterr().err
    resumed = dopplertof.render_result(scene, spp=64, seed=3, params=base, checkpoint=ckpt)
    assert not resumed.metadata["timed_out"] and resumed.metadata["samples_taken"] == 64
    assert np.array_equal(resumed.image, full)
    assert "timeout" not in capsys.readouterr().err
    # a timeout that never expires changes nothing
    late = dopplertof.render_result(scene, spp=64, seed=3, params=dict(
        base, timeout=1e6, samples_per_pass=16))
    assert np.array_equal(late.image, full) and not late.metadata["timed_out"]


def test_cli_keeps_the_checkpoint_of_a_timed_out_render(tmp_path, capsys):
    out, ckpt = tmp_path / "out.npy", tmp_path / "r.ckpt"
    args = ["render", PUBLISHED, "-o", str(out), "-D", "resx=6", "-D", "resy=6", "--spp", "32",
            "--seed", "1", "--quiet", "--checkpoint", str(ckpt)]
    assert main(args + ["-P", "timeout=0", "-P", "samples_per_pass=16"]) == 0
    assert "timeout of 0 s expired" in capsys.readouterr().err
    assert ckpt.exists()  # resumable
    assert main(args) == 0
    assert not ckpt.exists()
    scene = dopplertof.load_file(PUBLISHED, {"resx": 6, "resy": 6})
    assert np.array_equal(np.load(out), dopplertof.render(scene, spp=32, seed=1))


# ---- path_correlate_number (Kp) --------------------------------------------------

def test_sampler_path_correlate_number_is_kp_not_the_depth():
    scene = load_xml(sampler='<integer name="path_correlate_number" value="4"/>')
    assert scene.params.path_correlate_number == 4
    assert scene.params.path_correlation_depth == dopplertof.params.FULL_CORRELATION
    assert load_xml().params.path_group_size == 2  # default: Kp = K


def test_kp_consecutive_samples_share_the_path_stream():
    """Kp = 4 with K = 2: samples 0-3 share film position and path numbers (two time
    pairs on one path stream), sample 4 does not; the time stream stays the pair's."""
    import mitsuba as mi

    sample = mi.UInt32([0, 1, 2, 3, 4])
    s = sampling.CorrelatedStreams(mi, mi.UInt32(7), sample // 2, sample, mi.UInt32(1),
                                   mi.UInt32(3), path_group=sample // 4)
    film = np.array(s.film_2d(sample // 2, sample % 2, 8))
    stage1 = np.array(s.get_2d(mi.UInt32(1), sampling.bounce_dim(0, sampling.BOUNCE_BSDF_DIR)))
    stage3 = np.array(s.get_1d(mi.UInt32(3), sampling.bounce_dim(2, sampling.BOUNCE_RR)))
    for values in (film, stage1):
        assert np.all(values[:, :4] == values[:, :1]) and np.all(values[:, 4] != values[:, 0])
    assert len(set(stage3.tolist())) == 5  # stage 3 >= depth 3: every sample its own
    time_keys = np.array(s.key_group)
    assert time_keys[0] == time_keys[1] != time_keys[2] == time_keys[3]


def test_kp_one_is_independent_paths_whatever_the_depth():
    """Kp = 1: no path sharing (the image of path_correlation_depth 0, bit for bit), the
    time pairs kept; Kp = 2 and 4 share paths (other images)."""
    scene = published()
    common = dict(time_sampling_method="antithetic", hetero_frequency=1.0)
    independent = dopplertof.render(scene, spp=16, seed=2,
                                    params=dict(common, path_correlation_depth=0))
    for depth in (1, 4, FULL_CORRELATION):
        kp1 = dopplertof.render(scene, spp=16, seed=2, params=dict(
            common, path_correlate_number=1, path_correlation_depth=depth))
        assert np.array_equal(kp1, independent), depth
    kp2 = dopplertof.render(scene, spp=16, seed=2, params=dict(common, path_correlate_number=2))
    kp4 = dopplertof.render(scene, spp=16, seed=2, params=dict(common, path_correlate_number=4))
    assert np.array_equal(kp2, dopplertof.render(scene, spp=16, seed=2, params=common))
    assert not np.array_equal(kp4, kp2) and not np.array_equal(kp2, independent)


def test_kp_variance_on_the_published_scene():
    """At one beat per exposure, shared paths cancel the beat within each antithetic pair:
    Kp = 2 and Kp = 4 (two pairs on one path) have far less variance than Kp = 1
    (measured: 0.016x and 0.025x; per-pixel variance over 8 seeds, 16x16 pixels; over 4 x 8
    other seeds at most 0.022x, far from the 0.1x bound: no false failures to speak of)."""
    scene = published(16)
    common = dict(time_sampling_method="antithetic", hetero_frequency=1.0)

    def variance(kp):
        images = np.array([dopplertof.render(scene, spp=64, seed=s, params=dict(
            common, path_correlate_number=kp)) for s in range(8)])
        return images.var(axis=0, ddof=1).mean()

    v1, v2, v4 = variance(1), variance(2), variance(4)
    assert v2 < 0.1 * v1 and v4 < 0.1 * v1, (v1, v2, v4)


#: the 3 Kp comparisons' family-wise false-failure rate (Student, 15 degrees of freedom,
#: Bonferroni: |t| under about 5.8)
KP_FALSE_FAILURE = 1e-4


@pytest.mark.parametrize("kp", [1, 2, 4])
def test_kp_is_unbiased_against_quadrature(kp):
    """The moving plane at one beat: every Kp converges to the exact value, within the
    Student bound of KP_FALSE_FAILURE over 16 seeds (4 standard errors of 6 seeds, as
    before, was a false-failure rate of 9e-3 each: the 1e-3 allowance for the reference
    is 0.2 of those standard errors). Measured over 30 other seeds: 1.28% relative
    standard deviation per render, no bias (0.05 +- 0.23%); a 3% bias fails it."""
    expected = reference(4.0, 30.0, hetero_frequency=1.0, hetero_offset=0.1)
    scene = dopplertof.load_dict(plane_scene(4.0, 30.0, spp=1 << 12, integrator={
        "hetero_frequency": 1.0, "hetero_offset": 0.1, "time_sampling_method": "antithetic",
        "path_correlate_number": kp, "use_stratified_sampling_for_each_interval": False}))
    values = np.array([dopplertof.render(scene, seed=s)[0, 0, 0] for s in range(16)])
    se = values.std(ddof=1) / np.sqrt(len(values))
    bound = student_bound(KP_FALSE_FAILURE, 3, len(values) - 1)
    assert abs(values.mean() - expected) < bound * se + 1e-3 * abs(expected), (values, expected)


def test_kp_must_divide_spp():
    with pytest.raises(ValueError, match="spp 6 is not a multiple of path_correlate_number=4"):
        dopplertof.render(published(4), spp=6, params={"path_correlate_number": 4})
    with pytest.raises(dopplertof.ParameterError, match="path_correlate_number must be >= 1"):
        dopplertof.render(published(4), spp=6, params={"path_correlate_number": 0})
