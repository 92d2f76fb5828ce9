"""Render a D-ToF image: the public entry points.

The pipeline (passes of bounded memory, deterministic accumulation, checkpoints,
progress) is :mod:`dopplertof.integrators.pipeline`; the path tracer is the integrator
class of :mod:`dopplertof.integrators.dtof_path` (``DopplerToFPath``).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from .lazy import lazy_exports

if TYPE_CHECKING:  # (the annotations' names)
    import numpy

    from .integrators.pipeline import RenderResult

# the pipeline's public names, imported on first use (with NumPy and the pipeline)
__getattr__, __dir__, _PIPELINE_NAMES = lazy_exports(__name__, {
    ".integrators.checkpoint": ("Checkpoint", "CheckpointError"),
    ".integrators.pipeline": ("RenderResult",),
})
__all__ = ["render", "render_result", *_PIPELINE_NAMES]


def render_result(scene, spp: int | None = None, seed: int = 0, params=None,
                  **options) -> RenderResult:
    """Render ``scene`` (a DopplerScene, or a plain ``mi.Scene`` as a static one: see
    :func:`dopplertof.scene.scene.as_doppler_scene`): the image and what produced it.

    ``options``: ``progress`` (a bar on stderr; default: when it is a terminal),
    ``checkpoint`` (a path: saved after every pass, resumed from, bitwise the same
    image), ``max_lanes`` and ``pass_chunks`` (the pass size; the image ignores them).
    """
    from .backend import require_variant
    from .integrators.dtof_path import integrator_class
    from .scene.scene import as_doppler_scene

    integrator = integrator_class(require_variant())()
    return integrator.render_result(as_doppler_scene(scene), spp, seed, params, **options)


def render(scene, spp: int | None = None, seed: int = 0, params=None, **kwargs) -> "numpy.ndarray":
    """Render a D-ToF image: float32 (H, W, C), the time-averaged measurement.

    ``spp`` defaults to the scene's sampler count; ``params`` (a dict or RenderParams)
    overrides integrator parameters of the scene. The value is signed and equals
    (1/T) * the integral over the exposure; multiply by T for the integrated charge.
    """
    return render_result(scene, spp, seed, params, **kwargs).image
