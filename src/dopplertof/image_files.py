"""Image files, written atomically (io.atomic_path): EXR keeps the signed values, a PNG
is a preview (a raster with a colour bar and a title of what was measured, previews.py),
a Matplotlib figure is laid out to fit before it is saved; write_image picks the format
by the file's extension."""

from __future__ import annotations

import contextlib
import json
import threading

import numpy as np

from .file_formats import json_default, json_ready, write_npy
from .io import atomic_path, check_output_path, write_error
from .previews import (NAN_HATCHED, NO_SIGNAL_COLOUR, NOTHING_HIT, preview_scalar,
                       robust_limit)


def write_exr(path, image: np.ndarray, metadata: dict | None = None) -> None:
    """Float32 OpenEXR via Mitsuba's Bitmap (needs a Mitsuba variant set)."""
    import mitsuba as mi

    img = np.ascontiguousarray(np.asarray(image, dtype=np.float32))
    if img.ndim == 2:
        img = img[..., None]
    bitmap = mi.Bitmap(img)
    if metadata:
        props = bitmap.metadata()
        for key, value in metadata.items():
            text = (value if isinstance(value, str) else
                    json.dumps(json_ready(value), default=json_default))
            props[f"dopplertof.{key}"] = text
    with atomic_path(path) as tmp, _exr_writer_threads():
        try:
            bitmap.write(tmp)
        except RuntimeError as exc:  # Mitsuba's stream error ends in the system's reason
            raise write_error(path, exc) from exc


#: fewest Dr.Jit threads Mitsuba's EXR writer needs: OpenEXR (mi.Bitmap.write, Mitsuba
#: 3.9) hands its scan lines to Dr.Jit's thread pool and, with a pool of one thread (a
#: process on one CPU, ``taskset -c 0``), waits forever on a semaphore in writePixels
MIN_EXR_THREADS = 2
#: one thread-count change at a time (a writer restores the count it found)
_THREAD_COUNT_LOCK = threading.Lock()


@contextlib.contextmanager
def _exr_writer_threads():
    """Give Dr.Jit's pool at least MIN_EXR_THREADS threads while an EXR is written, then
    give it back the count it had."""
    import drjit as dr

    with _THREAD_COUNT_LOCK:
        before = dr.thread_count()
        if before >= MIN_EXR_THREADS:
            yield
            return
        dr.set_thread_count(MIN_EXR_THREADS)
        try:
            yield
        finally:
            dr.set_thread_count(before)


def measurement_title(kind: str, hetero_frequency: float, offset: float, w_g_mhz: float,
                      detail: str = "") -> str:
    """The title of a capture's preview: what was measured."""
    return (f"{kind} capture, offset {offset:.4g}, h={hetero_frequency:.4g}, "
            f"{w_g_mhz:.4g} MHz{detail}")


def render_title(metadata: dict) -> str:
    """The preview title of a render, from its metadata (h, offset, frequency, waveform)."""
    import math

    exposure = metadata["exposure_s"]
    h = metadata["omega_d_rad_s"] * exposure / (2 * math.pi)
    h = 0.0 if abs(h) < 1e-9 else h
    offset = (metadata["psi_rad"] / (2 * math.pi)) % 1.0
    kind = "homodyne" if h == 0 else "heterodyne"
    waveform = metadata.get("params", {}).get("wave_function_type", "")
    return measurement_title(kind, h, offset,
                             metadata["omega_g_rad_s"] / (2 * math.pi * 1e6),
                             f" {waveform}, {metadata['spp']} spp" if waveform else "")


def masked_note(counts: dict) -> str:
    """The caption of a preview's hatched (NaN) pixels, each kind by its own reason:
    ``counts`` maps a reason to its pixels, e.g. "hatched magenta: NaN, 124 px footprint
    mixes surfaces, 3 px nothing hit" (kinds without pixels left out)."""
    kinds = [f"{n} px {why}" for why, n in counts.items() if n]
    return f"{NAN_HATCHED}, " + ", ".join(kinds) if kinds else "no NaN pixels"


def nothing_hit_note(nothing) -> str:
    """The caption of a truth map's NaN pixels, ``nothing`` (bool): their pixel-centre
    rays hit nothing."""
    return masked_note({NOTHING_HIT: int(np.sum(nothing))})


def no_signal_colours(cmap: str):
    """The colour map ``cmap`` with NaN transparent: the hatching behind shows through."""
    import matplotlib

    return matplotlib.colormaps[cmap].with_extremes(bad=(0.0, 0.0, 0.0, 0.0))


def show_no_signal(ax, shape):
    """Hatch the area of an image of ``shape`` (drawn on ``ax`` above zorder 0); returns
    the hatched rectangle."""
    from matplotlib.patches import Rectangle

    h, w = shape[:2]
    return ax.add_patch(Rectangle((-0.5, -0.5), w, h, facecolor=NO_SIGNAL_COLOUR,
                                  edgecolor="black", hatch="////", linewidth=0, zorder=0))


def hide_axes(ax) -> None:
    """No axis lines, ticks or labels on ``ax`` (an image's axes), and no ticks made for
    them: Matplotlib measures even a hidden axis's tick labels each time it places the
    title (Axes._update_title_position), unless the axis itself is invisible."""
    ax.set_axis_off()
    ax.xaxis.set_visible(False)
    ax.yaxis.set_visible(False)


def write_png(path, image: np.ndarray, title: str = "D-ToF measurement",
              label: str = "time-averaged correlation (mean of channels)",
              cmap: str = "RdBu_r", metadata: dict | None = None,
              signed: bool = True) -> None:
    """Signed preview (:mod:`dopplertof.previews`): a diverging colour map centred on
    zero, its limit robust (:func:`robust_limit`: the colour bar's arrows show what
    saturates), with a colour bar; with ``signed=False`` a colour scale from zero to the
    maximum (counts, magnitudes)."""
    from .previews import ColourScale, Panel, draw

    data = preview_scalar(image)
    finite = data[np.isfinite(data)]
    if signed:
        vmax = robust_limit(data)
    else:
        vmax = float(finite.max()) if finite.size and finite.max() > 0 else 1.0
    scale = ColourScale.fitted(data, -vmax if signed else 0.0, vmax)
    save_png(path, draw([Panel(data, title, label, cmap, scale)]), metadata)


def save_png(path, drawing, metadata: dict | None = None) -> None:
    """Write a preview (:class:`dopplertof.previews.Drawing`) as PNG atomically, with
    ``metadata`` as its description (as :func:`save_figure` does for figures)."""
    from PIL.PngImagePlugin import PngInfo

    info = PngInfo()
    for key, value in _png_texts(metadata).items():
        info.add_text(key, value)
    with atomic_path(path) as tmp:
        drawing.image.save(tmp, format="png", pnginfo=info, dpi=(PREVIEW_DPI, PREVIEW_DPI),
                           compress_level=PNG_COMPRESS_LEVEL)


#: the resolution written into the previews (the size their texts were set for)
PREVIEW_DPI = 120


def _png_texts(metadata: dict | None) -> dict:
    """The text chunks of a saved picture: the software, ``metadata`` as JSON."""
    info = {"Software": "dopplertof"}
    if metadata:
        info["Description"] = json.dumps(json_ready(metadata), default=json_default)
    return info


#: room left around everything a figure draws when it is fitted (inches)
FIGURE_PAD_INCHES = 0.08


def _figure_texts(fig) -> list:
    """Every text of ``fig`` that a layout can push off its edges: the axes' titles and
    axis labels (colour bars' included), the figure's texts and its suptitle."""
    texts = [t for t in fig.texts]
    if getattr(fig, "_suptitle", None) is not None:
        texts.append(fig._suptitle)
    for ax in fig.axes:
        texts += [ax.title, ax._left_title, ax._right_title, ax.xaxis.label, ax.yaxis.label]
    return [t for t in texts if t.get_visible() and t.get_text()]


def wrap_texts(fig, renderer=None) -> bool:
    """Break every text of ``fig`` longer than the figure (wider, or taller when it
    runs vertically) into lines that fit; returns whether any text changed."""
    import textwrap

    if renderer is None:
        renderer = laid_out_renderer(fig)
    width, height = fig.bbox.width, fig.bbox.height
    changed = False
    for text in _figure_texts(fig):
        box = text.get_window_extent(renderer)
        vertical = box.height > box.width
        size, room = (box.height, height) if vertical else (box.width, width)
        room -= 2 * FIGURE_PAD_INCHES * fig.dpi
        if size <= room:
            continue
        words = " ".join(text.get_text().split())
        text.set_text(textwrap.fill(words, max(8, int(0.92 * len(words) * room / size))))
        changed = True
    return changed


def laid_out_renderer(fig):
    """The renderer of ``fig``'s canvas, with the figure's layout engine (if any) run:
    what measuring its texts and bounding boxes needs, without drawing a pixel (each
    Axes' tight box places its title, ticks and aspect itself). A layout done once
    (``fig.tight_layout()``) leaves a placeholder engine that lays out nothing."""
    from matplotlib.layout_engine import PlaceHolderLayoutEngine

    if not isinstance(fig.get_layout_engine(), (type(None), PlaceHolderLayoutEngine)):
        fig.draw_without_rendering()
    return fig.canvas.get_renderer()


def fit_figure(fig, pad: float = FIGURE_PAD_INCHES) -> None:
    """Make the figure the size of what it draws: long texts wrapped (:func:`wrap_texts`),
    then the figure cropped or grown to the tight box of its artists with ``pad`` inches
    around (no title, label, colour bar or legend past an edge, no empty margins); the
    axes and the figure's texts keep their places relative to each other."""
    renderer = laid_out_renderer(fig)
    if fig.get_layout_engine() is not None:  # (the layout is done: keep it as laid out;
        fig.set_layout_engine(None)          # no engine, not even a placeholder, saves a
                                             # layout pass in savefig)
    wrap_texts(fig, renderer)
    box = fig.get_tightbbox(renderer)  # inches
    old_w, old_h = fig.get_size_inches()
    x0, y0 = box.x0 - pad, box.y0 - pad
    new_w, new_h = box.width + 2 * pad, box.height + 2 * pad
    places = [(ax, ax.get_position()) for ax in fig.axes]
    texts = [(t, t.get_position()) for t in fig.texts
             + ([fig._suptitle] if getattr(fig, "_suptitle", None) is not None else [])]
    fig.set_size_inches(new_w, new_h)
    for ax, p in places:
        ax.set_axes_locator(None)
        ax.set_position([(p.x0 * old_w - x0) / new_w, (p.y0 * old_h - y0) / new_h,
                         p.width * old_w / new_w, p.height * old_h / new_h])
    for text, (x, y) in texts:
        text.set_position(((x * old_w - x0) / new_w, (y * old_h - y0) / new_h))


#: zlib level of the saved figures: the same pixels as the default 6 in about 60% of the
#: time (a capture's 14 previews: 0.21-0.25 s against 0.38 s) for files about 25% larger
PNG_COMPRESS_LEVEL = 3


def pyplot():
    """matplotlib.pyplot, on the Agg backend unless one was chosen (figures of plots;
    the previews are :mod:`dopplertof.previews`)."""
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    return plt


def save_figure(fig, path, metadata: dict | None = None) -> None:
    """Save a matplotlib figure as PNG atomically, with ``metadata`` as its description,
    fitted to what it draws (:func:`fit_figure`); closed if pyplot made it."""
    fit_figure(fig)
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png", metadata=_png_texts(metadata),
                    pil_kwargs={"compress_level": PNG_COMPRESS_LEVEL})
    if fig.canvas.manager is not None:  # (a pyplot figure)
        import matplotlib.pyplot as plt

        plt.close(fig)


def write_image(path, image: np.ndarray, metadata: dict | None = None, **png_kwargs) -> None:
    """Write by extension: .exr (float32), .npy (raw array), .png (signed preview)."""
    ext = check_output_path(path)
    if ext == ".npy":
        write_npy(path, image)
    elif ext == ".exr":
        write_exr(path, image, metadata)
    else:
        write_png(path, image, metadata=metadata, **png_kwargs)
