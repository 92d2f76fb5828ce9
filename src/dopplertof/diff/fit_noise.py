"""The fit's noise: each residual's variance, estimated from what the fit already has,
and the sandwich covariance of the fitted parameters.

The fit's residuals are block sums of render - capture. Their noise is not the same
everywhere (the Monte Carlo noise of a block depends on its brightness, its pixel count
and the light's paths), and the capture kinds of one block are correlated (the renders
of one seed, like the capture, use common random numbers for every kind). So
s^2 (J^T J)^+ (one variance for every residual) misstates it. Here:

* **the renders' noise**: the two seeds' renders differ by their noise only, so
  delta = (render_A - render_B) / 2, per pixel and capture kind, is a sample of the noise
  of the two renders' mean, which is what the fitted velocities see (their steps average
  the seeds). Per block i the covariance across the kinds of that noise's block sum is
  S_R,i = sum over the block's pixels of delta delta^T (:func:`block_covariances`: the
  pixels' noise is independent, the examples' box filter splatting each sample into one
  pixel): an estimate from the block's pixels, not from its one block sum. Without the
  per-pixel renders (a problem that has none) d_i d_i^T, d = (r_A - r_B) / 2 of the
  block sums, one sample per block: unbiased, consistent summed over the blocks;
* **the capture's noise**, by what the capture folder says of it:
  ``maps``: its Monte Carlo standard deviations (``<kind>_std_mc.npy``, written by
  ``dopplertof capture --mc-batches``): per block the sum of its pixels' variances;
  ``spp``: a capture without sensor noise is a render of the same estimator at its own
  samples: its variance is one fit render's times spp_fit / spp_capture, i.e.
  S_C = 2 (spp_fit / spp_capture) S_R, with the same correlation across the kinds;
  ``residuals`` (sensor noise, whose variance the folder does not hold): the
  cluster-robust estimate from the residuals of the two renders' mean themselves
  (each block's residual vector, its leverage taken out), which holds the renders'
  noise as well;
* **outlying blocks**: a block whose residual r_i is improbable under its estimated
  noise S_i (r_i^T S_i^+ r_i above the chi-square's 1e-3 quantile, :data:`OUTLIER_CHI2`)
  takes r_i r_i^T as its capture noise: a rare bright path in the capture (Monte Carlo
  noise of indirect light is heavy-tailed) that the renders' difference cannot show
  (only with the per-pixel estimate: one sample per block tests nothing);
* **the covariance**: the fit solves G theta = -g with the metric G (the Jacobians of
  the two seeds crossed) over the directions the captures constrain, so
  cov = G^+ M G^+ with the meat M = sum over blocks of J_i^T S_i J_i (the sandwich;
  J_i the block's rows of the Jacobian: the two seeds' for the renders' part, each
  seed's Jacobian against the other seed's noise, their mean for the capture's);
* **the Birge ratio** B = |r|^2 / E|r|^2: the squared residual of the two renders'
  mean against what the estimated noise predicts after the fit, tr((I - H) S) (H the
  fit's hat matrix). B near 1: the noise explains the residuals. Its standard
  deviation under that hypothesis is sqrt(2 / nu + 2 / nu'), nu = (tr S)^2 / |S|^2 the
  residuals' effective number and nu' that of the pixels S is estimated from (one
  sample per block: nu / 3, a one-sample variance's fourth moment being 3 times its
  square); the covariance is scaled by B only where B exceeds 1 by more than
  :data:`BIRGE_SIGMAS` of them (misfit or noise the estimate misses), never scaled
  down. With the ``residuals`` route B compares with the renders' noise only (the
  capture's is unknown) and never scales.
"""

from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np

#: the covariance is scaled by the Birge ratio B where B > 1 + BIRGE_SIGMAS sd(B)
BIRGE_SIGMAS = 2.0

#: a block's leverage is capped here in the ``residuals`` route (1 / (1 - h) at most 10)
MAX_LEVERAGE = 0.9


@dataclass
class CaptureNoise:
    """What the fit knows of the capture's noise (see the module docstring)."""

    kinds: int = 1  #: capture kinds fitted: residual k * blocks + i is kind k of block i
    source: str = "residuals"  #: "maps", "spp" or "residuals"
    ratio: float = 0.0  #: ``spp``: the capture's variance over one fit render's
    variance: np.ndarray | None = None  #: ``maps``: per residual, the capture's variance
    #: (blocks, kinds, kinds) the renders' noise per block (:func:`block_covariances`);
    #: None: one sample per block from the two seeds' block sums
    render_cov: np.ndarray | None = None
    estimate_samples: float = 0.0  #: the pixels ``render_cov`` is estimated from
    outliers: bool = True  #: a block's improbable residual as its capture noise

    def describe(self) -> str:
        return {"maps": "the capture's Monte Carlo standard deviations (<kind>_std_mc.npy)",
                "spp": "one fit render's Monte Carlo noise x spp_fit / spp_capture "
                       f"({self.ratio:.4g}: a capture without sensor noise)",
                "residuals": "the residuals themselves (cluster-robust: the capture's "
                             "noise is not in its folder)"}[self.source]


def capture_noise(data, problem, spp: int) -> CaptureNoise:
    """The capture's noise for the fit's ``problem`` at ``spp`` samples: its
    ``<kind>_std_mc.npy`` maps where the folder has them for every fitted kind and no
    sensor noise was added, else the spp ratio where no sensor noise was added and the
    capture's samples are known, else the residuals."""
    kinds = len(problem.fitted)
    renders = getattr(problem, "pixel_renders", None)
    cov = (None if renders is None
           else block_covariances(renders, problem.groups, problem.n_groups))
    common = {"render_cov": cov, "estimate_samples": float(len(problem.pixels))}
    sensor = bool(data.summary.get("noise"))
    maps = getattr(data, "std_mc", None) or {}
    if not sensor and all(c in maps for c in problem.fitted):
        variance = np.concatenate([problem.pool(np.square(maps[c].ravel()[problem.pixels]))
                                   for c in problem.fitted])
        return CaptureNoise(kinds, "maps", variance=variance, **common)
    capture_spp = data.summary.get("spp_per_capture")
    if not sensor and capture_spp:
        return CaptureNoise(kinds, "spp", ratio=float(spp) / float(capture_spp), **common)
    return CaptureNoise(kinds, "residuals", **common)


def load_std_maps(folder, names) -> dict:
    """name -> (H, W) Monte Carlo standard deviation of each capture in ``names`` that
    the folder holds as ``<name>_std_mc.npy`` (``dopplertof capture --mc-batches``)."""
    out = {}
    for name in names:
        path = os.path.join(os.fspath(folder), f"{name}_std_mc.npy")
        if os.path.isfile(path):
            out[name] = np.load(path).astype(np.float64)
    return out


def _clusters(rows: int, kinds: int) -> np.ndarray:
    """(blocks, kinds): the residuals of each block, one per capture kind."""
    kinds = kinds if kinds > 0 and rows % kinds == 0 else 1
    return np.arange(rows).reshape(kinds, rows // kinds).T


def _cluster_sums(J, values, index) -> np.ndarray:
    """Per block, sum over its kinds of J_r^T values_r: (blocks, parameters)."""
    return np.einsum("bkp,bk->bp", J[index], values[index])


def block_covariances(pixel_renders, groups, blocks: int) -> np.ndarray:
    """(blocks, kinds, kinds): per block, the covariance across the capture kinds of
    the noise of the two seeds' mean render's block sum, from the per-pixel renders
    (per seed (kinds, pixels), each kind's rendered pixels): the sum over the block's
    pixels of delta delta^T, delta = (render_A - render_B) / 2 per kind (independent
    pixels: the examples' box filter splats every sample into one pixel)."""
    a, b = (np.asarray(x, np.float64) for x in pixel_renders)
    delta = 0.5 * (a - b)  # (kinds, pixels)
    kinds = delta.shape[0]
    out = np.zeros((blocks, kinds, kinds))
    for k in range(kinds):
        for m in range(k, kinds):
            out[:, k, m] = out[:, m, k] = np.bincount(groups, weights=delta[k] * delta[m],
                                                      minlength=blocks)
    return out


def sandwich(residuals, jacobians, inverse, noise: CaptureNoise | None = None):
    """(cov = inverse M inverse, the diagnostics) with ``inverse`` G^+ (zero outside the
    directions the fit sees) and the meat M of the residuals' estimated covariance
    (the module docstring)."""
    noise = noise or CaptureNoise()
    (r_a, r_b), (J_a, J_b) = residuals, jacobians
    index = _clusters(len(r_a), noise.kinds)
    d, mean, J = 0.5 * (r_a - r_b), 0.5 * (r_a + r_b), 0.5 * (J_a + J_b)
    S = noise.render_cov if noise.render_cov is not None else \
        np.einsum("bk,bl->bkl", d[index], d[index])  # one sample per block
    # the renders' part: each seed's Jacobian against the other seed's noise
    meat = 0.5 * sum(np.einsum("bkp,bkl,blq->pq", Js[index], S, Js[index])
                     for Js in (J_a, J_b))
    if noise.source == "spp":
        capture = 2.0 * noise.ratio * S
    elif noise.source == "maps":
        capture = np.einsum("bk,kl->bkl", noise.variance[index], np.eye(index.shape[1]))
    else:
        capture = None
    if capture is not None:
        outlying = 0
        if noise.outliers and noise.render_cov is not None:  # (not from one sample)
            capture, outlying = _outlying_blocks(capture, S, mean[index])
        meat = meat + np.einsum("bkp,bkl,blq->pq", J[index], capture, J[index])
        S = S + capture
    else:
        meat = _residual_meat(J, mean, inverse, index)
    left = float(np.einsum("bkk->", S) - np.einsum("bkp,pq,blq,bkl->", J[index], inverse,
                                                   J[index], S))
    birge = _birge(float(mean @ mean), left, S, noise)
    birge["outlying_blocks"] = outlying if capture is not None else None
    return birge["scale"] * (inverse @ meat @ inverse), birge


#: chi-square (of the capture kinds' number of degrees of freedom) above which a block's
#: residual is improbable under its estimated noise (once in 1000 blocks)
OUTLIER_CHI2 = {1: 10.83, 2: 13.82, 3: 16.27, 4: 18.47}


def _outlying_blocks(capture, render, residual):
    """The capture's noise per block, with each block whose residual r_i is improbable
    under its estimated noise (r_i^T S_i^+ r_i above :data:`OUTLIER_CHI2`: a rare
    bright path in the capture, which the renders' difference cannot show) given the
    residual's own r_i r_i^T instead; and the number of such blocks."""
    total = capture + render
    q = np.einsum("bk,bkl,bl->b", residual, np.linalg.pinv(total), residual)
    out = capture.copy()
    far = q > OUTLIER_CHI2.get(residual.shape[1], 18.47)
    out[far] = np.einsum("bk,bl->bkl", residual[far], residual[far])
    return out, int(far.sum())


def _residual_meat(J, mean, inverse, index):
    """The cluster-robust meat from the residuals of the two renders' mean: per block
    J_i^T r_i scaled by 1 / sqrt(1 - h_i), h_i its mean leverage (at most
    :data:`MAX_LEVERAGE`): a fitted residual is smaller than its noise by it."""
    leverage = np.einsum("rp,pq,rq->r", J, inverse, J)[index].mean(1)
    U = _cluster_sums(J, mean, index) / np.sqrt(1.0 - np.minimum(leverage, MAX_LEVERAGE))[:, None]
    return U.T @ U


def _birge(energy: float, expected: float, S, noise: CaptureNoise) -> dict:
    """fit.json's ``noise`` diagnostics: the Birge ratio |r|^2 / E|r|^2, its standard
    deviation without misfit (sqrt(2 / nu + 2 / nu'), nu the residuals' effective
    number (tr S)^2 / |S|^2, nu' that of the noise's estimate: per pixel (its pixels'
    number) or, one sample per block, nu / 3), and the scale applied to the covariance
    (B where it exceeds 1 by more than :data:`BIRGE_SIGMAS` of them, else 1; never
    with the ``residuals`` route, whose B compares with the renders' noise only)."""
    nu = float(np.einsum("bkk->", S)) ** 2 / max(float(np.sum(S * S)), 1e-300)
    nu_estimate = noise.estimate_samples if noise.render_cov is not None else nu / 3.0
    # no noise predicted (renders without noise): no ratio (null in fit.json), no scale
    ratio = float(energy / expected) if expected > 0 else None
    sd = float(np.sqrt(2.0 / max(nu, 1.0) + 2.0 / max(nu_estimate, 1.0)))
    scaled = (noise.source != "residuals" and ratio is not None
              and ratio > 1.0 + BIRGE_SIGMAS * sd)
    return {"birge_ratio": ratio, "birge_ratio_sd": sd,
            "effective_residuals": float(nu), "scale": ratio if scaled else 1.0}
