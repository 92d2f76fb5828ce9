"""``dopplertof dataset show DIR [--samples 0,1,2] -o preview.png``: a row
per sample of what a network sees and learns: the first raw frame, the camera's depth
beside the truth and their error, the radial velocity truth and the camera's, the optical
flow's magnitude and the instances, each with its colour bar; masked pixels hatched as
in every preview (:mod:`dopplertof.previews`). A clip's row is its frame 0, and its
camera depth, velocity and amplitude are written beside the PNG as a video
(``preview_item3.mp4`` or ``.gif``)."""

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


def show_dataset(folder, samples, output: str, split: str = "full",
                 statistics: bool = False) -> str:
    """Draw ``samples`` (``--samples`` text or None) of the dataset in ``folder`` into
    the PNG ``output`` (written atomically); ``statistics``: the one-page statistics of
    those samples (None: every sample) instead; returns its path."""
    from .. import io
    from .. import image_files
    from ..previews import NO_SIGNAL_NOTE, draw
    from .reader import Dataset, clip_frame

    if not str(output).lower().endswith(".png"):
        raise DatasetError(f"-o must be a .png file, got {output!r}")
    io.check_output_path(output)
    ds = Dataset(folder, split=split)
    if not len(ds):
        raise DatasetError(f"{folder}: the dataset holds no sample to show")
    if statistics:
        indices = list(range(len(ds))) if samples is None else parse_samples(samples, len(ds))
        write_statistics(ds, indices, output, f"{folder}: statistics of {len(indices)} items")
        return output
    indices = parse_samples(samples, len(ds))
    rows, clips = [], ""
    for i in indices:
        sample = ds[i]
        if np.ndim(sample["depth"]) == 3:  # a clip: its frame 0, and its video
            write_clip_video(sample, i, output, ds.attributes(i)["fps"])
            sample = clip_frame(sample, 0)
            clips = "; clips: frame 0 of each, their videos beside this file"
        rows.append(sample_panels(sample, i))
    columns = max(len(r) for r in rows)
    panels = [p for r in rows for p in r]
    caption = (f"{NO_SIGNAL_NOTE}; truth hatched where it is not truth_valid (nothing hit, "
               "grazing), the camera's where a mask is set (docs/dataset.md)")
    drawing = draw(panels, FIT, title=f"{ds.info['config'].get('dataset', {}).get('name', '')}"
                   f" ({folder}), split {split}: items {', '.join(map(str, indices))}{clips}",
                   caption=caption, columns=columns)
    image_files.save_png(output, drawing)
    return output


def clip_video_path(output: str, item: int) -> str:
    """Where ``show -o output`` writes item ``item``'s clip video: beside it, named
    after it and the item (.mp4 or .gif: :func:`dopplertof.videos.video_extension`)."""
    from ..videos import video_extension

    return f"{str(output)[:-4]}_item{item}{video_extension()}"


def write_clip_video(sample: dict, item: int, output: str, fps: float) -> str:
    """A clip's camera depth, velocity (the camera's where it measures one, else the
    truth) and amplitude as a video at the clip's frame rate (:mod:`dopplertof.videos`)."""
    from ..videos import depth_velocity_amplitude, draw_frames, write_video

    measured = "camera_radial_velocity" in sample
    maps = depth_velocity_amplitude(
        sample["camera_depth"], sample["camera_radial_velocity" if measured else "velocity_gt"],
        sample["camera_amplitude"], not measured, sample["depth"])
    frames = len(sample["camera_depth"])
    titles = [f"item {item}: frame {k} of {frames}" for k in range(frames)]
    return write_video(clip_video_path(output, item), draw_frames(maps, titles), fps)


def dataset_statistics(ds, indices) -> dict:
    """What the statistics page plots, over items ``indices`` of ``ds``: truth depths
    and |radial velocities| where truth_valid holds, the objects' distances and speeds,
    each item's valid fractions and, per split, the camera's |depth error| (modulo its
    unambiguous range: a one-frequency camera's depth wraps) and predicted depth std over
    its valid pixels (a clip's over every frame; its objects as in frame 0)."""
    from ..cameras.unwrap import unambiguous_range
    from .sample import CAMERA_SPLITS

    stats = {"depth": [], "speed": [], "distance": [], "object_speed": [],
             "valid": {"truth": [], **{s: [] for s in CAMERA_SPLITS}},
             "error": {s: [] for s in CAMERA_SPLITS}, "std": {s: [] for s in CAMERA_SPLITS}}
    for item in indices:
        sample, description = ds[item], ds.attributes(item)["description"]
        trusted = sample.get("truth_valid", sample["mask"])
        stats["depth"].append(sample["depth"][trusted])
        stats["speed"].append(np.abs(sample["velocity_gt"][trusted]))
        centre = np.asarray(description["camera"]["rest"])[:3, 3]
        for obj in description["objects"]:
            stats["distance"].append(np.linalg.norm(np.asarray(obj["centre_m"]) - centre))
            stats["object_speed"].append(np.linalg.norm(obj["velocity_m_s"]))
        stats["valid"]["truth"].append(trusted.mean())
        for split, suffix in CAMERA_SPLITS.items():
            valid = sample.get(f"camera_valid{suffix}")
            if valid is None:  # (layout 1)
                continue
            stats["valid"][split].append(valid.mean())
            frequencies = np.asarray(sample["camera_frequencies"])  # (a clip's: (T, F))
            wrap = unambiguous_range(frequencies.reshape(-1, frequencies.shape[-1])[0] * 1e6)
            error = (sample[f"camera_depth{suffix}"] - sample["depth"])[valid]
            stats["error"][split].append(np.abs(error - wrap * np.round(error / wrap)))
            stats["std"][split].append(sample[f"camera_depth_std{suffix}"][valid])
    return stats


def write_statistics(ds, indices, output: str, title: str) -> None:
    """The one-page statistics figure (:func:`dataset_statistics`) as a PNG."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    from .. import image_files

    stats = dataset_statistics(ds, indices)
    fig = Figure(figsize=(12.0, 6.4), dpi=100, layout="constrained")
    FigureCanvasAgg(fig)
    axes = fig.subplots(2, 3)
    for ax, values, label in ((axes[0, 0], stats["depth"], "truth depth (m), truth_valid pixels"),
                              (axes[0, 1], stats["speed"], "|radial velocity truth| (m/s), "
                               "truth_valid pixels"),
                              (axes[0, 2], [stats["distance"]], "object distance (m)"),
                              (axes[1, 0], [stats["object_speed"]], "object speed (m/s)")):
        data = np.concatenate([np.ravel(v) for v in values]) if values else np.zeros(0)
        ax.hist(data[np.isfinite(data)], bins=30, color="#4477aa")
        ax.set_xlabel(label)
        ax.set_ylabel("count")
    splits = list(stats["valid"])
    axes[1, 1].bar(splits, [np.mean(stats["valid"][s]) if stats["valid"][s] else 0.0
                            for s in splits], color="#66aa55")
    axes[1, 1].set_ylabel("mean valid fraction (truth_valid; camera_valid per split)")
    cameras = [s for s in splits if stats["error"].get(s)]
    for offset, key, name in ((-0.2, "error", "|camera - truth| mod range"),
                              (0.2, "std", "predicted std")):
        axes[1, 2].bar(np.arange(len(cameras)) + offset,
                       [np.median(np.concatenate(stats[key][s])) if np.concatenate(
                           stats[key][s]).size else 0.0 for s in cameras], 0.4, label=name)
    axes[1, 2].set_xticks(np.arange(len(cameras)), cameras)
    axes[1, 2].set_yscale("log")
    axes[1, 2].set_ylabel("camera depth, median over valid pixels (m)")
    axes[1, 2].legend(fontsize=8)
    fig.suptitle(title)
    image_files.save_figure(fig, output)
