"""The frame loop every capture runs: its renders (a D-ToF frame's captures, a camera's
raw frames and its radiance), each in its own exposure window and in order, kept in a
checkpoint folder where one is given (:mod:`.checkpoint`), each with its error-bar
batches where asked (:func:`.precision.render_batches`), and a callback after each.

What a render is (its name, window, parameters, seed) is the capture's to say; what
the loop returns is each render's image, time and dropped samples, in the renders'
order. The records and summaries built from them are the capture's too.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class FrameRender:
    """One render of a capture."""

    name: str  #: its name: the checkpoint file's and the records'
    scene: object  #: the scene in the render's exposure window
    params: object  #: its RenderParams
    seed: int  #: its seed (error-bar batch 0's; precision.batch_seeds gives the others)


@dataclass
class Rendered:
    """What one render gave."""

    image: np.ndarray  #: (H, W, C) float32: the render with the FrameRender's seed
    seconds: float  #: its render time
    dropped: int  #: its non-finite samples dropped
    stack: np.ndarray | None = None  #: (B, H, W, C): every error-bar batch's image
    extra_seconds: float | None = None  #: the other batches' render time


def render_frames(scene, renders, spp: int, *, batches: int = 0, progress=None,
                  checkpoint=None, what: str = "renders", on_render=None) -> list:
    """Every render of ``renders`` (FrameRenders of ``scene``) at ``spp`` samples per
    pixel, in order: a list of :class:`Rendered`. ``batches``: error-bar batches per
    render (0: none). ``checkpoint``: a folder that keeps every render, keyed by
    ``scene``'s fingerprint and every render's settings (``what`` names them in its
    report). ``on_render(render, rendered)`` is called after each."""
    from ..render import render_result
    from . import precision as prec
    from .checkpoint import CaptureCheckpoint, batch_name

    saved = None
    if checkpoint is not None:
        saved = CaptureCheckpoint.open(checkpoint, scene, [
            (batch_name(r.name, b), r.scene.shutter_window, r.params, spp, batch_seed)
            for r in renders
            for b, batch_seed in enumerate(prec.batch_seeds(r.seed, batches)
                                           if batches else [r.seed])])
    out = []
    for r in renders:
        if batches:
            image, stack, seconds, extra, dropped = prec.render_batches(
                r.scene, spp, r.seed, r.params, batches, progress, saved, r.name)
            rendered = Rendered(image, seconds, dropped, stack, extra)
        else:
            result = render_result(r.scene, spp=spp, seed=r.seed, params=r.params,
                                   progress=progress,
                                   checkpoint=None if saved is None else saved.path(r.name))
            if saved is not None:
                saved.count(result.metadata)
            rendered = Rendered(result.image, result.metadata["render_seconds"],
                                result.metadata["nonfinite_samples_dropped"])
        out.append(rendered)
        if on_render is not None:
            on_render(r, rendered)
    if saved is not None:
        saved.report(what)
    return out
