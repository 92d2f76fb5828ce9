"""The bias of the interior-only derivatives at silhouettes, measured against central
differences of renders with common random numbers (docs/differentiable.md, "Silhouette
bias (measured)"; benchmarks/silhouettes.py prints the table).

:func:`render_derivatives` differentiates the integrand at fixed random numbers: where a
moving body's silhouette crosses a pixel's footprint, the samples that change surface
(visibility) are not differentiated. A central difference with the same seed at both
steps sees them: with a step large enough that some samples switch surface (their number
grows with the step, the image's interior part stays linear in a velocity far beyond
it), it measures the whole derivative, the visibility term included.

Pixels are split into classes (:func:`pixel_classes`): a body's ``interior`` (the fit's
pixels: :func:`dopplertof.diff.fit.interior`), its ``silhouette`` (footprints that see
more than one surface, :func:`dopplertof.tof.ground_truth.mixed_footprints`, within the
filter's reach of the body), its ``rim`` (the rest of the pixels whose footprint reaches
the body: the interior's margin by the silhouette, a box's edges, where one face gives
way to another) and ``other`` (the static surfaces and other bodies beyond that reach).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .render import _MOTION_NAME, AXES, DerivativeError, render_derivatives

#: the pixel classes of :func:`pixel_classes`, in the table's order
PIXEL_CLASSES = ("interior", "silhouette", "rim", "other")


def _near(mask: np.ndarray, reach: int) -> np.ndarray:
    """Pixels within ``reach`` pixels (a square) of ``mask``."""
    out = np.zeros_like(mask)
    padded = np.pad(mask, reach)
    height, width = mask.shape
    for dy in range(2 * reach + 1):
        for dx in range(2 * reach + 1):
            out |= padded[dy:dy + height, dx:dx + width]
    return out


def pixel_classes(scene, k: int) -> dict:
    """{class: (H, W) bool} for body k of ``scene``: its interior (the fit's pixels), its
    silhouette (mixed footprints within the film filter's reach of the body), its rim
    (the rest of ``footprint``: every pixel whose footprint reaches the body) and the
    other pixels."""
    from ..integrators.film import _filter_of
    from ..tof.ground_truth import ground_truth, mixed_footprints
    from .fit import interior

    truth = ground_truth(scene)
    reach = max(1, math.ceil(_filter_of(scene.sensor.film())[1]))
    inner = interior(truth, k, reach)
    footprint = _near(truth.body == k, reach)
    silhouette = mixed_footprints(scene) & footprint & ~inner
    return {"interior": inner, "silhouette": silhouette,
            "rim": footprint & ~(inner | silhouette), "other": ~footprint,
            "footprint": footprint}


def body_parameter(name: str):
    """(body index, "v" or "w", axis index) of a body's motion parameter ``name``; a
    DerivativeError for any other name (the differences step a body's motion)."""
    m = _MOTION_NAME.match(name)
    if m is None or m.group(2) is None:
        raise DerivativeError(f"{name}: the silhouette measurement steps a body's motion "
                              "(body<k>.v<x|y|z> or body<k>.w<x|y|z>)")
    return int(m.group(2)), m.group(3), AXES.index(m.group(4))


def central_difference(ds, name: str, step: float, spp: int, seed: int) -> np.ndarray:
    """(image(x + step) - image(x - step)) / (2 step) for the body motion parameter
    ``name``, both renders with ``seed`` (common random numbers); the velocities are put
    back afterwards."""
    k, kind, axis = body_parameter(name)
    v, w = ds.body_velocity(k)
    images = []
    try:
        for sign in (1.0, -1.0):
            stepped = [list(v), list(w)]
            stepped[kind == "w"][axis] += sign * step
            ds.set_body_velocity(k, *stepped)
            images.append(render_derivatives(ds, [], spp=spp, seed=seed).image)
    finally:
        ds.set_body_velocity(k, v, w)
    return (images[0] - images[1]) / (2.0 * step)


@dataclass
class BiasMeasurement:
    """Per seed, the derivative and each step's central difference (channel 0)."""

    name: str
    spp: int
    seeds: list
    steps: list
    derivative: list = field(default_factory=list)  #: per seed, (H, W)
    difference: dict = field(default_factory=dict)  #: step -> per seed, (H, W)

    def sums(self, mask) -> tuple:
        """(derivative sums per seed, {step: difference sums per seed}) over ``mask``."""
        return ([float(d[mask].sum()) for d in self.derivative],
                {h: [float(f[mask].sum()) for f in fs] for h, fs in self.difference.items()})


def measure(ds, name: str, steps, spp: int, seeds) -> BiasMeasurement:
    """The derivative of ``name`` and its central differences at each of ``steps``, for
    each seed of ``seeds`` (each difference with the derivative's seed)."""
    out = BiasMeasurement(name, int(spp), list(seeds), list(steps))
    for seed in out.seeds:
        d = render_derivatives(ds, [name], spp=spp, seed=seed)
        out.derivative.append(d.tangents[name][..., 0])
        for h in out.steps:
            fd = central_difference(ds, name, h, spp, seed)
            out.difference.setdefault(h, []).append(fd[..., 0])
    return out


def relative_bias(derivative_sums, difference_sums) -> tuple:
    """mean derivative / mean difference - 1 over the seeds (+1: the derivative is twice
    the difference, whatever their sign), and the difference's own noise in the same
    unit (from its standard error over the seeds; NaN for one seed); NaN, NaN where the
    difference is exactly 0."""
    reference = float(np.mean(difference_sums))
    if reference == 0.0:  # nothing there moves (a static surface, direct light only)
        return math.nan, math.nan
    ratio = float(np.mean(derivative_sums)) / reference
    if len(difference_sums) < 2:  # one seed: no noise estimate
        return ratio - 1.0, math.nan
    noise = float(np.std(difference_sums, ddof=1) / math.sqrt(len(difference_sums)))
    return ratio - 1.0, abs(ratio) * noise / abs(reference)


def block_sums(values: np.ndarray, mask: np.ndarray, block: int = 8) -> np.ndarray:
    """Sums of ``values`` over the block x block tiles of the pixels of ``mask`` (the
    fit's residual blocks, :func:`dopplertof.diff.fit._blocks`)."""
    from .fit import _blocks

    labels = _blocks([mask], block)
    return np.bincount(labels, weights=values.ravel()[mask.ravel()])


def step_ratio(derivative: np.ndarray, difference: np.ndarray, mask, block: int = 8) -> float:
    """The fraction of the way a Gauss-Newton step on one parameter goes with the
    derivative's block sums as its Jacobian J when the residuals move as the
    difference's F: (J . F) / (J . J) (1: exact; the fit's fixed point J . r = 0 is the
    same, its steps and its uncertainty s / |J| scale by this)."""
    jacobian = block_sums(derivative, mask, block)
    moved = block_sums(difference, mask, block)
    return float(jacobian @ moved / (jacobian @ jacobian))
