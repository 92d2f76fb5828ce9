"""Videos of map sequences (a camera stream's frames, a dataset clip's): each frame a
preview of :mod:`dopplertof.previews` (the maps side by side, each with its colour bar
on one scale for the whole sequence), written as MP4 (H.264) through imageio-ffmpeg
where it is installed (the ``video`` extra), else as an animated GIF through Pillow.

A depth camera's sequence is shown as three maps: the radial range, the radial
velocity (the reconstruction's where the camera measures one, else the truth) and the
amplitude (:func:`depth_velocity_amplitude`); :func:`write_contact_sheet` puts a few
of its frames side by side in one PNG, a row per map with one colour bar per row.
"""

from __future__ import annotations

import math

import numpy as np

from . import io
from .previews import NO_SIGNAL_NOTE, ColourScale, Panel, draw

MP4, GIF = ".mp4", ".gif"
#: each frame's maps are fitted into this box (pixels)
VIDEO_FIT = (320, 320)
#: the side lengths of an MP4 frame are a multiple of this (H.264's macroblocks: no
#: rescaling by the encoder; the frames are padded white to it)
MACRO_BLOCK = 16
#: the most frames a contact sheet shows (evenly spaced over the sequence)
SHEET_FRAMES = 8
SHEET_FIT = (160, 160)


def mp4_writer():
    """imageio_ffmpeg with a working ffmpeg, or None (then videos are GIFs)."""
    try:
        import imageio_ffmpeg

        imageio_ffmpeg.get_ffmpeg_exe()
    except (ImportError, RuntimeError):
        return None
    return imageio_ffmpeg


def video_extension() -> str:
    """The extension of the videos written here: .mp4 where imageio-ffmpeg can write them,
    else .gif."""
    return MP4 if mp4_writer() is not None else GIF


# ---- The maps ------------------------------------------------------------------------------

def depth_velocity_amplitude(depth, velocity, amplitude, velocity_is_truth: bool,
                             depth_gt=None) -> list:
    """The three maps of a depth camera's sequence, each (T, H, W), as (title, label,
    colour map, scale, frames): the range from the 0.5th to the 99.5th percentile of the
    finite ranges (``depth_gt``'s too, where given), the velocity on a symmetric scale
    (:func:`dopplertof.tof.figures.truth_limit`), the amplitude from 0 to its 99.5th
    percentile, each over the whole sequence."""
    from .tof.figures import truth_limit

    depth, velocity, amplitude = (np.asarray(a, np.float64) for a in (depth, velocity,
                                                                        amplitude))
    seen = [depth] + ([np.asarray(depth_gt, np.float64)] if depth_gt is not None else [])
    finite = np.concatenate([a[np.isfinite(a)] for a in seen])
    lo, hi = ((float(np.percentile(finite, 0.5)), float(np.percentile(finite, 99.5)))
              if finite.size else (None, None))
    limit = truth_limit(velocity, velocity)
    bright = amplitude[np.isfinite(amplitude)]
    top = float(np.percentile(bright, 99.5)) if bright.size else 1.0
    return [("radial range", "m along the ray", "viridis",
             ColourScale.fitted(depth, lo, hi), depth),
            ("true radial velocity" if velocity_is_truth else "radial velocity",
             "m/s (+ receding)", "RdBu_r", ColourScale.fitted(velocity, -limit, limit),
             velocity),
            ("amplitude", "DN", "gray", ColourScale.fitted(amplitude, 0.0, top if top > 0
                                                           else 1.0), amplitude)]


def frame_drawings(maps, titles, fit=VIDEO_FIT, caption: str = NO_SIGNAL_NOTE) -> list:
    """Frame k of every map of ``maps`` (:func:`depth_velocity_amplitude`) side by side,
    each with its colour bar, under ``titles[k]``: a previews Drawing per title."""
    return [draw([Panel(frames[k], name, label, cmap, scale)
                  for name, label, cmap, scale, frames in maps], fit, title=title,
                 caption=caption) for k, title in enumerate(titles)]


def draw_frames(maps, titles, fit=VIDEO_FIT, caption: str = NO_SIGNAL_NOTE) -> list:
    """:func:`frame_drawings` as (H, W, 3) uint8 images all of one size (the largest, the
    others padded white at the right and bottom): a video's frames."""
    images = [np.asarray(d.image) for d in frame_drawings(maps, titles, fit, caption)]
    return pad_to(images, max(i.shape[0] for i in images), max(i.shape[1] for i in images))


def pad_to(images, height: int, width: int) -> list:
    """Each image (H, W, 3) padded white at the right and bottom to ``height`` x ``width``."""
    out = []
    for image in images:
        canvas = np.full((height, width, 3), 255, np.uint8)
        canvas[:image.shape[0], :image.shape[1]] = image
        out.append(canvas)
    return out


# ---- The files -----------------------------------------------------------------------------

def write_video(path, images, fps: float) -> str:
    """``images`` (equal-size (H, W, 3) uint8) at ``fps`` frames per second into ``path``,
    atomically: MP4 or GIF by its extension (:func:`video_extension` picks the one this
    installation writes). Returns ``path``."""
    if str(path).endswith(MP4):
        return write_mp4(path, images, fps)
    return write_gif(path, images, fps)


def write_mp4(path, images, fps: float) -> str:
    """H.264 MP4 (yuv420p, the pixel format players read) through imageio-ffmpeg, the
    frames padded white to a multiple of MACRO_BLOCK pixels."""
    writer = mp4_writer()
    if writer is None:
        raise RuntimeError("writing MP4 needs imageio-ffmpeg (pip install dopplertof[video])")
    h, w = images[0].shape[:2]
    size = (MACRO_BLOCK * math.ceil(h / MACRO_BLOCK), MACRO_BLOCK * math.ceil(w / MACRO_BLOCK))
    with io.atomic_path(path) as tmp:
        frames = writer.write_frames(tmp, (size[1], size[0]), fps=float(fps),
                                     macro_block_size=MACRO_BLOCK, ffmpeg_log_level="error")
        frames.send(None)  # (starts ffmpeg)
        try:
            for image in pad_to(images, *size):
                frames.send(np.ascontiguousarray(image).tobytes())
        finally:
            frames.close()
    return str(path)


def write_gif(path, images, fps: float) -> str:
    """An animated GIF (looping) through Pillow; GIF counts a frame's time in hundredths
    of a second, so ``fps`` is kept to that (and at most 50 frames per second)."""
    from PIL import Image

    frames = [image if isinstance(image, Image.Image) else Image.fromarray(image)
              for image in images]
    duration = max(20, int(round(1000.0 / fps)))
    with io.atomic_path(path) as tmp:
        frames[0].save(tmp, format="GIF", save_all=True, append_images=frames[1:],
                       duration=duration, loop=0)
    return str(path)


def sheet_indices(count: int, most: int = SHEET_FRAMES) -> list:
    """At most ``most`` frame indices of ``count``, evenly spaced, the first and last
    included."""
    if count <= most:
        return list(range(count))
    return sorted({int(round(k * (count - 1) / (most - 1))) for k in range(most)})


def write_contact_sheet(path, maps, labels, title: str) -> str:
    """:func:`contact_sheet` as a PNG at ``path``; returns it."""
    from .image_files import save_png

    save_png(path, contact_sheet(maps, labels, title))
    return str(path)


def contact_sheet(maps, labels, title: str):
    """The frames ``labels`` (index -> caption of that frame, e.g. its time) of every map
    of ``maps`` (:func:`depth_velocity_amplitude`): a row per map, one colour bar per
    row (the map's scale), the rows stacked under ``title``. A previews Drawing, its
    boxes named "row R ..." after each row's own."""
    drawings = [draw([Panel(frames[k], text, label, cmap, scale) for k, text in labels.items()],
                     SHEET_FIT, title=name, columns=len(labels), shared_bar=True)
                for name, label, cmap, scale, frames in maps]
    rows = [np.asarray(d.image) for d in drawings]
    width = max(r.shape[1] for r in rows)
    stacked = np.concatenate([pad_to([r], r.shape[0], width)[0] for r in rows], axis=0)
    sheet = _titled(stacked, title, NO_SIGNAL_NOTE)
    y = sheet.boxes.pop()[1][1]  # (where the rows start)
    for r, (d, row) in enumerate(zip(drawings, rows)):
        sheet.boxes += [(f"row {r} {name}", (x0, y0 + y, x1, y1 + y))
                        for name, (x0, y0, x1, y1) in d.boxes]
        sheet.extends += d.extends
        y += row.shape[0]
    return sheet


def _titled(image: np.ndarray, title: str, caption: str):
    """``image`` under ``title`` and over ``caption`` (each wrapped to its width) as a
    previews Drawing, the image's box last."""
    from PIL import Image, ImageDraw

    from .previews import (CAPTION_COLOUR, CAPTION_SIZE, PAD, SUPTITLE_SIZE, TEXT_GAP,
                           TITLE_GAP, Drawing, TextBlock, _write_block)

    width = image.shape[1] - 2 * PAD
    top = TextBlock.wrapped(title, SUPTITLE_SIZE, width)
    bottom = TextBlock.wrapped(caption, CAPTION_SIZE, width, CAPTION_COLOUR)
    y = PAD + top.height + TITLE_GAP
    canvas = np.full((y + image.shape[0] + TEXT_GAP + bottom.height + PAD, image.shape[1], 3),
                     255, np.uint8)
    canvas[y:y + image.shape[0]] = image
    picture = Image.fromarray(canvas)
    pen = ImageDraw.Draw(picture)
    boxes = (_write_block(pen, top, image.shape[1] // 2, PAD, "title")
             + _write_block(pen, bottom, image.shape[1] // 2, y + image.shape[0] + TEXT_GAP,
                            "caption"))
    return Drawing(picture, boxes + [("image", (0, y, image.shape[1], y + image.shape[0]))],
                   [])
