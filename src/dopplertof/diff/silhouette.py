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
pixels: :func:`dopplertof.diff.fit_capture.interior`), its ``silhouette`` (footprints that see
more than one surface, :func:`dopplertof.tof.ground_truth.mixed_footprints`, within the
filter's reach of the body), its ``rim`` (the rest of the pixels whose footprint reaches
the body: the interior's margin by the silhouette, a box's edges, where one face gives
way to another) and ``other`` (the static surfaces and other bodies beyond that reach).
"""

from __future__ import annotations

import math
from contextlib import contextmanager
from dataclasses import dataclass, field, replace

import numpy as np

from .render import (_MOTION_NAME, AXES, DerivativeError, _floats, check_names,
                     render_derivatives)

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
    return _classes(_geometry(scene), k)


def _geometry(scene) -> tuple:
    """(ground truth, mixed footprints, the film filter's reach in whole pixels)."""
    from ..integrators.film import _filter_of
    from ..tof.ground_truth import ground_truth, mixed_footprints

    reach = max(1, math.ceil(_filter_of(scene.sensor.film())[1]))
    return ground_truth(scene), mixed_footprints(scene), reach


def _classes(geometry, k: int) -> dict:
    """:func:`pixel_classes` from :func:`_geometry`'s tuple."""
    from .fit_capture import interior

    truth, mixed, reach = geometry
    inner = interior(truth, k, reach)
    footprint = _near(truth.body == k, reach)
    silhouette = mixed & footprint & ~inner
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


@contextmanager
def _stepped(ds, name: str, delta: float):
    """``ds`` with motion parameter ``name`` (a body's velocity or angular velocity,
    the camera's velocity) moved by ``delta``, put back afterwards."""
    m = _MOTION_NAME.match(name)
    motion = ds.camera_motion if m.group(2) is None else ds.motions[int(m.group(2))]
    attribute = "velocity" if m.group(3) == "v" else "angular_velocity"
    saved = getattr(motion, attribute)
    values = _floats(saved)
    values[AXES.index(m.group(4))] += delta
    setattr(motion, attribute, values)
    try:
        yield ds
    finally:
        setattr(motion, attribute, saved)


def central_difference(ds, name: str, step: float, spp: int, seed: int,
                       pixels=None) -> np.ndarray:
    """(image(x + step) - image(x - step)) / (2 step) for the motion parameter ``name``
    (``body<k>.v*``, ``body<k>.w*``, ``camera.v*``), both renders with ``seed`` (common
    random numbers); ``pixels``: flat indices to render (others are 0)."""
    check_names(ds, [name])
    if _MOTION_NAME.match(name) is None:
        raise DerivativeError(f"{name}: central differences step a motion parameter "
                              "(body<k>.v<x|y|z>, body<k>.w<x|y|z>, camera.v<x|y|z>)")
    images = []
    for sign in (1.0, -1.0):
        with _stepped(ds, name, sign * step):
            images.append(render_derivatives(ds, [], spp=spp, seed=seed, pixels=pixels).image)
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
    fit's residual blocks, :func:`dopplertof.diff.fit_solve._blocks`)."""
    from .fit_solve import _blocks

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


# ---- Opt-in: central differences where visibility moves --------------------------

#: the default steps of :func:`with_visibility` (m/s for velocities, rad/s for angular
#: velocities): on the starter scenes (1.5 ms exposures) large enough that samples
#: switch surface in every silhouette pixel, small enough that the image stays linear
#: (the interior's difference within 0.1% of the derivative)
VISIBILITY_STEPS = {"v": 20.0, "w": 10.0}


def visibility_pixels(scene) -> np.ndarray:
    """(H, W) bool: every body's silhouette and rim (:func:`pixel_classes`): the pixels
    whose footprint reaches a body but that are not its interior."""
    geometry = _geometry(scene)
    out = np.zeros(geometry[1].shape, bool)
    for k in range(len(scene.bodies)):
        classes = _classes(geometry, k)
        out |= classes["silhouette"] | classes["rim"]
    return out


def with_visibility(ds, derivatives, pixels=None, steps=None, spp_factor: int = 4):
    """Opt-in: ``derivatives`` (:func:`render_derivatives` of ``ds``) with each motion
    parameter's tangent replaced, at ``pixels`` ((H, W) bool; default
    :func:`visibility_pixels`), by a central difference with common random numbers
    (``steps``: {name: step}, else :data:`VISIBILITY_STEPS`), which holds the camera
    rays' visibility term the derivative misses there, at ``spp_factor`` x the
    derivatives' spp (a difference is noisier than a derivative; the pixels are few).
    Other parameters (modulation, reflectances: no visibility term) are kept. Interior
    pixels keep the derivative: with indirect light it misses the bounce rays' visibility
    there too (docs/differentiable.md, "Silhouette bias (measured)")."""
    mask = visibility_pixels(ds.scene) if pixels is None else np.asarray(pixels, bool)
    flat = np.flatnonzero(mask)
    tangents = dict(derivatives.tangents)
    for name, tangent in derivatives.tangents.items():
        m = _MOTION_NAME.match(name)
        if m is None or not flat.size:
            continue
        step = (steps or {}).get(name, VISIBILITY_STEPS[m.group(3)])
        difference = central_difference(ds, name, step, derivatives.spp * int(spp_factor),
                                        derivatives.seed, pixels=flat)
        tangents[name] = np.where(mask[..., None], difference, tangent)
    return replace(derivatives, tangents=tangents)
