"""Render a D-ToF image: the public entry points.

The pipeline (passes of bounded memory, deterministic accumulation, checkpoints,
progress) is :mod:`dopplertof.integrators.pipeline`; the path tracer is the integrator
class of :mod:`dopplertof.integrators.dtof_path` (``DopplerToFPath``).
"""

from __future__ import annotations

import numpy as np

from .integrators.pipeline import (  # noqa: F401  (the pipeline's public names)
    Checkpoint, CheckpointError, RenderResult)


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


def render(scene, spp: int | None = None, seed: int = 0, params=None, **kwargs) -> np.ndarray:
    """Render a D-ToF image: float32 (H, W, C), the time-averaged measurement.

    ``spp`` defaults to the scene's sampler count; ``params`` (a dict or RenderParams)
    overrides integrator parameters of the scene. The value is signed and equals
    (1/T) * the integral over the exposure; multiply by T for the integrated charge.
    """
    return render_result(scene, spp, seed, params, **kwargs).image
