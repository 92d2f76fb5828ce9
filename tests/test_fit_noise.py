"""The fit's uncertainties against heteroscedastic noise (dopplertof.diff.fit_noise; issue
42, 2026-12-04).

Issue 42's target is every fitted component within 3 of its reported standard
deviations. s^2 (J^T J)^+ (one variance for every residual) misstates the spread where
the noise differs from block to block and the capture kinds of a block are correlated,
as a render's Monte Carlo noise does; the sandwich G^+ (sum_i J_i^T S_i J_i) G^+ with
S_i from the two seeds' difference (and the capture's noise) does not.

The bound: over n fits the sample standard deviation of the z-scores (error / reported
standard deviation) scatters about its expectation with a standard deviation of about
1 / sqrt(2 n) for normals (0.022 at n = 1000), more for these heavy-tailed errors (the
brightest blocks dominate a fit); an estimated meat makes z-scores t-like, a few % wider
than normal. The test allows 0.15. Measured (seed 5, 1000 fits): the sandwich with the
renders' noise from 32 pixels per block 0.94-1.02, from the residuals 1.03-1.10 (with one
sample of the renders' noise per block 1.06-1.16: an independent one-sample variance widens
them most); s^2 (J^T J)^+ 1.47-1.60.
"""

import numpy as np
import pytest


class _HeteroscedasticProblem:
    """A linear fit problem without renders: 120 blocks of 2 capture kinds each, the
    Jacobian's rows scaled by a per-block brightness a_i (lognormal), the noise of
    each block's renders and capture proportional to a_i (brighter blocks weigh more in
    the fit and are noisier: s^2 averages them away) and correlated 0.8 across the two
    kinds (common random numbers); the capture's noise half one render's variance
    (a capture of twice the fit's samples); ``render_cov``: the renders' noise per block
    as the fit estimates it, from ``pixels`` pixels per block. Fresh noise every
    instance; the same noise per seed at every iteration (correlated sampling)."""

    names = ["body0.vx", "body0.vy", "body0.vz"]
    jacobian_spp = 1

    def __init__(self, rng, blocks=120, capture_ratio=0.5, pixels=32):
        brightness = np.exp(0.5 * rng.normal(size=blocks))
        J = rng.normal(size=(2, blocks, 3)) * brightness[None, :, None]
        J[:, :, 2] *= 0.3  # a weaker third column
        self.J = J.reshape(2 * blocks, 3)

        def correlated(scale):
            a, b = rng.normal(size=(2, blocks))
            pair = np.stack([a, 0.8 * a + 0.6 * b])  # (kinds, blocks), correlation 0.8
            return (scale * brightness * pair).ravel()

        capture = correlated(0.02 * np.sqrt(capture_ratio))
        self.noise = [correlated(0.02) - capture for _ in range(2)]
        # the renders' noise per block as the fit estimates it from its pixels: each of
        # ``pixels`` per block carries 1 / pixels of the block's variance, per seed
        delta = 0.5 * np.subtract(*(
            np.stack([correlated(0.02 / np.sqrt(pixels)).reshape(2, blocks)
                      for _ in range(pixels)]) for _ in range(2)))  # (pixels, kinds, blocks)
        self.render_cov = np.einsum("pkb,plb->bkl", delta, delta)
        self.pixels = pixels * blocks
        self.truth = np.array([1.0, -2.0, 0.5])
        self.theta = self.truth + 0.3
        self.seen = np.ones(3, bool)

    def values(self):
        return self.theta.copy()

    def set_values(self, theta):
        self.theta = np.array(theta, float)

    def evaluate(self, samples, jacobian=True):
        residuals = tuple(self.J @ (self.theta - self.truth) + n for n in self.noise)
        return residuals, (self.jacobians() if jacobian else (None, None))

    def jacobians(self):
        return self.J, self.J

    def record(self, iteration, loss, samples, theta, started):
        return {"iteration": iteration, "loss": loss, "parameters": list(theta),
                "radial_velocity_m_s": [0.0], "seconds": 0.0}


def _z_scores(noise_of, fits=1000, seed=5):
    """Per fit and component, the error in reported standard deviations, old (s^2
    (J^T J)^+) and new (the sandwich with ``noise_of(problem)``); and the Birge ratios."""
    from dopplertof.diff.fit_covariance import covariance as _covariance
    from dopplertof.diff.fit_solve import _fit_progress, _gauss_newton

    rng = np.random.default_rng(seed)
    old, new, birge = [], [], []
    for _ in range(fits):
        problem = _HeteroscedasticProblem(rng)
        theta, state, *_ = _gauss_newton(problem, 1, 20, 1e-9, 1e-6,
                                         _fit_progress(False, 20), 0.0)
        error = theta - problem.truth
        report = {}
        new.append(error / _covariance(state, problem.seen, None, noise_of(problem), report)[1])
        old.append(error / _covariance(state, problem.seen, kind="plain")[1])
        birge.append(report["birge_ratio"])
    return np.array(old), np.array(new), np.array(birge)


@pytest.mark.parametrize("route", ["spp", "residuals"])
def test_sandwich_z_scores_scatter_as_normals_where_s2_does_not(route):
    """Heteroscedastic, kind-correlated noise: the sandwich's z-scores have a standard
    deviation within 0.15 of 1 per component (the module docstring's bound) and stay
    within 3 in all but a normal's share (0.27%; at most 2% of 3000); s^2's are 1.5-1.6
    times as wide. With the capture's noise from the spp ratio (and the renders' from
    the pixels, as the fit has them) the Birge ratio's median is 1 within 5%; from the
    residuals (the capture's noise unknown) the sandwich is the cluster-robust one."""
    from dopplertof.diff.fit_noise import CaptureNoise

    def noise_of(problem):
        return (CaptureNoise(2, "spp", ratio=0.5, render_cov=problem.render_cov,
                             estimate_samples=problem.pixels) if route == "spp"
                else CaptureNoise(2, "residuals"))

    old, new, birge = _z_scores(noise_of)
    sd_new, sd_old = new.std(0), old.std(0)
    assert np.all(np.abs(sd_new - 1) < 0.15), (sd_new, sd_old)
    assert np.all(sd_old > 1.4), sd_old  # the old covariance fails the same bound
    assert np.mean(np.abs(new) > 3) < 0.02, np.mean(np.abs(new) > 3)
    if route == "spp":
        assert abs(np.median(birge) - 1) < 0.05, np.median(birge)


def test_birge_ratio_scales_only_an_excess_beyond_its_noise():
    """A capture noise the estimate misses (told 0 where it is half a render's
    variance: the residuals then carry twice the predicted energy): over 40 fits the
    Birge ratio exceeds 1 by more than 2 of its standard deviations and scales the
    covariance in most (its sd is conservative with one sample per block: 0.4 reported,
    0.18 measured over 200 fits of 400 blocks); told right, its median is 1 within 0.1
    and it scales almost none (at most 10%)."""
    from dopplertof.diff.fit_noise import CaptureNoise
    from dopplertof.diff.fit_covariance import covariance as _covariance
    from dopplertof.diff.fit_solve import _fit_progress, _gauss_newton

    rng = np.random.default_rng(2)
    told_none, right = [], []
    for _ in range(40):
        problem = _HeteroscedasticProblem(rng, blocks=400)
        _, state, *_ = _gauss_newton(problem, 1, 20, 1e-9, 1e-6, _fit_progress(False, 20), 0.0)
        for ratio, out in ((0.0, told_none), (0.5, right)):
            report = {}
            _covariance(state, problem.seen, None, CaptureNoise(2, "spp", ratio=ratio), report)
            out.append(report)
    assert np.mean([r["scale"] == r["birge_ratio"] > 1 for r in told_none]) > 0.75
    assert np.mean([r["scale"] != 1.0 for r in right]) <= 0.1
    assert abs(np.median([r["birge_ratio"] for r in right]) - 1) < 0.1


@pytest.mark.slow  # (4 captures and fits: 4-10 s, the fast tier's longest test)
def test_fits_over_capture_seeds_land_within_3_reported_sd(tmp_path):
    """End to end: the translating sphere (32x32, direct light, 32 spp capture and
    fit) captured with 4 seeds and fitted: every fitted component within 3 of its
    reported standard deviations, the capture's noise taken from the spp ratio, and the
    Birge ratio (settings.noise) finite and below 3."""
    import contextlib
    import io
    import os

    from dopplertof.cli import main
    from dopplertof.diff.fit import fit

    scene = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))),
                         "examples", "translating_sphere.xml")
    z = []
    for seed in range(1, 5):
        cap = str(tmp_path / f"cap{seed}")
        with contextlib.redirect_stdout(io.StringIO()):
            assert main(["capture", scene, "-o", cap, "--spp", "32", "--seed", str(seed),
                         "--quiet", "-D", "res=32", "-D", "max_depth=2"]) == 0
        result = fit(cap, spp=32, progress=False)
        noise = result.settings["noise"]
        assert noise["capture_noise"].startswith("one fit render's Monte Carlo noise x")
        assert 0 < noise["birge_ratio"] < 3, noise
        z += [x for b in result.bodies for x in b["linear_velocity_error_sigmas"]]
    assert len(z) == 12 and all(x is not None and abs(x) <= 3 for x in z), z


def test_capture_noise_comes_from_maps_then_spp_then_residuals():
    """The capture's noise: its std_mc maps where the folder has them (per block the
    sum of its pixels' variances), else the spp ratio without sensor noise, else the
    residuals (sensor noise: its variance is not in the folder)."""
    from types import SimpleNamespace

    from dopplertof.diff.fit_noise import capture_noise

    groups = np.array([0, 0, 1, 1])
    problem = SimpleNamespace(
        fitted=("heterodyne_0", "heterodyne_0.25"), pixels=np.arange(4), groups=groups,
        n_groups=2, pool=lambda v: np.bincount(groups, weights=v, minlength=2),
        pixel_renders=[np.ones((2, 4)), np.zeros((2, 4))])
    maps = {k: np.full((2, 2), 0.5) for k in problem.fitted}
    data = SimpleNamespace(summary={"spp_per_capture": 64, "noise": None}, std_mc=maps)
    noise = capture_noise(data, problem, 16)
    assert noise.source == "maps" and np.allclose(noise.variance, 0.5)  # 2 pixels x 0.25
    assert np.allclose(noise.render_cov, 0.5)  # 2 pixels x (1/2)^2, each kind and across
    data.std_mc = {}
    noise = capture_noise(data, problem, 16)
    assert noise.source == "spp" and noise.ratio == 0.25
    data.summary["noise"] = {"read_noise_e": 5}
    assert capture_noise(data, problem, 16).source == "residuals"
