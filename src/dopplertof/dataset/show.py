"""``dopplertof dataset show DIR [--samples 0,1,2] -o preview.png`` (issue 41): a row
per sample of what a network sees and learns: the first raw frame, the camera's depth
beside the truth and their error, the radial velocity truth and the camera's, the optical
flow's magnitude and the instances, each with its colour bar; masked pixels hatched as
in every preview (:mod:`dopplertof.previews`)."""

from __future__ import annotations

import numpy as np

from .config import DatasetError

#: the box (pixels) each image is fitted into
FIT = (192, 192)
#: samples shown when --samples is not given
DEFAULT_SAMPLES = 4


def parse_samples(text, count: int) -> list:
    """``--samples`` "0,1,2" as indices of a dataset of ``count`` samples (None: the
    first DEFAULT_SAMPLES); a DatasetError naming the option otherwise."""
    if text is None:
        return list(range(min(count, DEFAULT_SAMPLES)))
    try:
        indices = [int(v) for v in str(text).split(",")]
    except ValueError:
        raise DatasetError(f"--samples must be item numbers separated by commas (0,1,2), "
                           f"got {text!r}") from None
    wrong = [i for i in indices if not 0 <= i < count]
    if wrong:
        raise DatasetError(f"--samples {text}: the dataset holds items 0-{count - 1}, "
                           f"not {', '.join(map(str, wrong))}")
    return indices


def sample_panels(sample: dict, item: int) -> list:
    """The panels of one sample's row (NaN: hatched)."""
    from ..previews import ColourScale, Panel
    from ..tof.figures import symmetric_limit, truth_limit

    trusted = sample.get("truth_valid", sample["mask"])
    depth = np.where(trusted, sample["depth"], np.nan)
    camera = sample["camera_depth"] if "camera_depth" in sample else np.full(depth.shape, np.nan)
    finite = np.concatenate([a[np.isfinite(a)] for a in (camera, depth)])
    lo, hi = ((float(np.percentile(finite, 0.5)), float(np.percentile(finite, 99.5)))
              if finite.size else (0.0, 1.0))
    depth_scale = ColourScale.fitted(finite, lo, hi)
    error = camera - depth
    limit = symmetric_limit(error)
    velocity = np.where(trusted, sample["velocity_gt"], np.nan)
    measured = sample.get("camera_radial_velocity")
    speed = truth_limit(velocity, velocity if measured is None else measured)
    raw = np.asarray(sample["raw"][0], np.float64)
    panels = [Panel(raw, f"item {item}: raw frame 0", "DN", "gray", ColourScale.fitted(raw)),
              Panel(camera, "camera depth", "m", "viridis", depth_scale),
              Panel(depth, "truth depth", "m", "viridis", depth_scale),
              Panel(error, "camera - truth", "m", "PuOr_r", ColourScale(-limit, limit)),
              Panel(velocity, "radial velocity truth", "m/s", "RdBu_r",
                    ColourScale(-speed, speed))]
    if measured is not None:
        panels.append(Panel(measured, "camera velocity", "m/s", "RdBu_r",
                            ColourScale(-speed, speed)))
    flow = np.where(sample["mask"], np.linalg.norm(sample["flow"], axis=-1), np.nan)
    instance = np.where(sample["instance"] >= 0, sample["instance"], np.nan).astype(np.float64)
    panels += [Panel(flow, "optical flow |du, dv|", "px over the sequence", "magma",
                     ColourScale.fitted(flow, 0.0)),
               Panel(instance, "instances (0: backdrop)", "id", "viridis",
                     ColourScale.fitted(instance, -0.5, max(np.nanmax(instance), 0) + 0.5
                                        if np.isfinite(instance).any() else 1.0))]
    return panels


def show_dataset(folder, samples, output: str, split: str = "full") -> str:
    """Draw ``samples`` (``--samples`` text or None) of the dataset in ``folder`` into
    the PNG ``output`` (written atomically); returns its path."""
    from .. import io
    from ..previews import NO_SIGNAL_NOTE, draw
    from .reader import Dataset

    if not str(output).lower().endswith(".png"):
        raise DatasetError(f"-o must be a .png file, got {output!r}")
    io.check_output_path(output)
    ds = Dataset(folder, split=split)
    if not len(ds):
        raise DatasetError(f"{folder}: the dataset holds no sample to show")
    indices = parse_samples(samples, len(ds))
    rows = [sample_panels(ds[i], i) for i in indices]
    columns = max(len(r) for r in rows)
    panels = [p for r in rows for p in r]
    caption = (f"{NO_SIGNAL_NOTE}; truth hatched where it is not truth_valid (nothing hit, "
               "grazing), the camera's where a mask is set (docs/dataset.md)")
    drawing = draw(panels, FIT, title=f"{ds.info['config'].get('dataset', {}).get('name', '')}"
                   f" ({folder}), split {split}: items {', '.join(map(str, indices))}",
                   caption=caption, columns=columns)
    io.save_png(output, drawing)
    return output
