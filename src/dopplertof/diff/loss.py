"""The unbiased two-seed (cross-seed) loss of renders against a target, and its gradient.

The plain squared loss of one render R against a target C,

    |R - C|^2 = |E R - C|^2 + |R - E R|^2 + (a zero-mean term),

adds the render's variance, which depends on the parameters (a faster body spreads its
samples' Doppler phases wider): its minimum is away from the truth by O(1/spp) (on the
demo the loss was lower at vz = 1.5 than at the true 3.0). The cross-seed loss of two
renders of independent seeds A and B,

    L = (R_A - C) . (R_B - C),

has the expectation |E R - C|^2 exactly, whose minimum is at the truth; its gradient
2 (R_B - C) . dR_A (one render B, one :func:`~dopplertof.diff.gradient` call at A) is an
unbiased estimate of that expectation's. ``dopplertof fit`` and
:func:`dopplertof.diff.inverse.fit_captures` minimize it; :func:`cross_seed_gradient`
offers it to a gradient-based optimisation of one's own (docs/differentiable.md).
"""

from __future__ import annotations

import numpy as np

from .render import DerivativeError


def cross_loss(residual_a, residual_b) -> float:
    """(R_A - C) . (R_B - C) of two residuals of independent seeds: its expectation is
    the squared distance of the expected render to the target, without the renders'
    variance. It can be negative (the two renders' noise), most often near the minimum."""
    return float(np.dot(np.asarray(residual_a, np.float64).ravel(),
                        np.asarray(residual_b, np.float64).ravel()))


def residual(image, target, mask=None) -> np.ndarray:
    """``image`` (H, W, C) minus ``target``: (H, W, C) channel by channel, or (H, W)
    (e.g. a capture, the mean of a render's channels) against the channels' mean;
    zero outside ``mask`` ((H, W) booleans or weights, default every pixel)."""
    image = np.asarray(image, np.float64)
    target = np.asarray(target, np.float64)
    if target.shape == image.shape[:2]:
        out = image.mean(-1) - target
    elif target.shape == image.shape:
        out = image - target
    else:
        raise DerivativeError(
            f"target of shape {target.shape}: expected the image's {image.shape} or "
            f"{image.shape[:2]} (a capture: compared with the channels' mean)")
    if mask is not None:
        weight = np.asarray(mask, np.float64)
        if weight.shape != image.shape[:2]:
            raise DerivativeError(f"mask of shape {weight.shape}: expected the image's "
                                  f"{image.shape[:2]}")
        out = out * (weight if out.ndim == 2 else weight[..., None])
    return out


def residual_weighted_loss(mi, weights):
    """The loss (a callable of the image tensor, for :func:`~dopplertof.diff.gradient`)
    sum 2 weights x image, whose gradient is the cross loss's, 2 (R_B - C) . dR_A, for
    ``weights`` the other seed's residual (:func:`residual`: (H, W) weighs the channels'
    mean, (H, W, C) each channel); a constant when ``weights`` is None."""
    import drjit as dr

    if weights is None:  # a zero of the image (gradient refuses a loss detached from it)
        return lambda image: dr.sum(image - image, axis=None)

    def loss(image):
        channels = image.shape[-1]
        w = np.asarray(weights, np.float64)
        if w.ndim == 2:  # against the channels' mean
            w = np.repeat((2.0 / channels) * w[..., None], channels, axis=-1)
        else:
            w = 2.0 * w
        return dr.sum(image * mi.TensorXf(w.astype(np.float32)), axis=None)

    return loss


def cross_seed_gradient(dscene, target, names=None, spp: int | None = 64, seeds=(0, 1),
                        mask=None, params=None, method: str = "auto"):
    """The gradient of the cross-seed loss (R_A - C) . (R_B - C) of ``dscene``'s renders
    at seeds ``seeds`` = (A, B) against ``target`` (``C``: (H, W, C), or (H, W) such as
    a capture, compared with the render's channel mean), over ``mask`` (default every
    pixel): a :class:`~dopplertof.diff.adjoint.Gradient` of 2 (R_B - C) . dR_A (an
    unbiased estimate of the gradient of |E R - C|^2), whose ``loss`` is the cross loss,
    ``image`` R_A and ``other_image`` R_B. ``names``, ``spp``, ``params``, ``method``:
    as :func:`~dopplertof.diff.gradient`'s. Give the seeds of an optimisation's
    iterations new values (never the target's own seed: its noise would correlate)."""
    from .adjoint import gradient

    seed_a, seed_b = (int(s) for s in seeds)
    if seed_a == seed_b:
        raise DerivativeError(f"cross_seed_gradient: seeds {seed_a} and {seed_b} are the "
                              "same: the cross loss needs two independent renders")
    other = gradient(dscene, residual_weighted_loss(dscene.mi, None), names=[], spp=spp,
                     seed=seed_b, params=params, method=method)
    residual_b = residual(other.image, target, mask)
    out = gradient(dscene, residual_weighted_loss(dscene.mi, residual_b), names=names,
                   spp=spp, seed=seed_a, params=params, method=method)
    out.loss = cross_loss(residual(out.image, target, mask), residual_b)
    out.other_image = other.image
    return out
