"""Map previews drawn directly with Pillow: images on a colour scale, each with its colour
bar, titles and a caption, in a few milliseconds each.

A capture writes a dozen previews, each one image with a colour bar. Drawing them with
Matplotlib cost about 0.15 s apiece and its import half a second (a small capture
spent most of its time outside rendering on its pictures); here a
preview is a NumPy raster of the data's colours with the texts set by FreeType. Plots
(curves, legends, axes) stay with Matplotlib.

What a preview shows, as the Matplotlib previews before it did:

- the data, each pixel a block of the preview (nearest neighbour), on a linear, power
  (display gamma) or log colour scale (:class:`ColourScale`);
- NaN (nothing seen, a signal too weak, a mixed footprint) hatched black on magenta
  (:data:`NO_SIGNAL_COLOUR`), a colour none of the maps contains;
- ``marked`` pixels cross-hatched in white over their colours;
- a colour bar with an arrow at each end that the data passes (:func:`colorbar_extend`),
  ticks at round values and its label along it;
- a title over each image, a title over the whole, a caption under it, each wrapped to
  the picture's width: nothing is drawn past an edge, and the picture ends where its
  content does.

:func:`draw` returns the picture and where it put each part (:class:`Drawing`);
:func:`dopplertof.image_files.save_png` writes it. Nothing here imports Matplotlib: the colour
tables are data of the package (``data/colormaps.npz``, Matplotlib's tables at 256
entries, checked against it by the tests); another map is read from Matplotlib.
"""

from __future__ import annotations

import functools
import math
import os
from dataclasses import dataclass

import numpy as np

#: "no signal" (NaN) in every preview: black hatching on a magenta that none of the colour
#: maps used (RdBu, PuOr, viridis, gray, magma) contains, so that it cannot pass for a value
NO_SIGNAL_COLOUR = "#ff00ff"
#: how every caption names those pixels
NAN_HATCHED = "hatched magenta: NaN"
NO_SIGNAL_NOTE = f"{NAN_HATCHED} (nothing hit or signal too weak)"
#: why a truth map's pixel is NaN: its pixel-centre ray hits nothing
NOTHING_HIT = "nothing hit"

#: the colour tables shipped with the package (name -> 256 x 3 uint8)
COLOUR_TABLES = os.path.join(os.path.dirname(os.path.abspath(__file__)), "data",
                             "colormaps.npz")
#: entries of a colour table
TABLE_SIZE = 256

# ---- Sizes, in pixels of the picture ------------------------------------------------------

PAD = 10            # empty border around everything drawn
TITLE_SIZE = 17     # a panel's title (10 pt at 120 dpi)
SUPTITLE_SIZE = 17  # the title over several panels
TICK_SIZE = 13      # colour bar tick labels (8 pt)
LABEL_SIZE = 15     # the colour bar's label (9 pt)
CAPTION_SIZE = 13   # the caption under the panels
BAR_GAP = 18        # between an image and its colour bar
BAR_WIDTH = 22
BAR_MIN_LENGTH = 120
MIN_IMAGE_SIDE = 48  # the shortest side of an image (a very wide or tall one's pixels stretch)
TICK_LENGTH = 5
TICK_SPACING = 70   # the least room between two ticks of a linear colour bar
TITLE_GAP = 12      # under the title over all panels
TITLE_MIN_WIDTH = 200  # the narrowest a panel's title is wrapped to
PANEL_GAP = 28      # between two panels
TEXT_GAP = 6        # between a text and what it labels
CAPTION_COLOUR = (0x44, 0x44, 0x44)
HATCH_PERIOD, HATCH_WIDTH = 9, 3      # the NaN hatching: black stripes "////"
MARK_PERIOD, MARK_WIDTH = 12, 2       # the marked pixels: white lines "xx"
MARK_COLOUR = (255, 255, 255)


# ---- What the colours mean ----------------------------------------------------------------

def robust_limit(data: np.ndarray, percentile: float = 99.5) -> float:
    """A colour limit for |data| that thin features (silhouettes sweeping through pixels
    during the exposure, one or two pixels wide) do not set: the ``percentile`` of |data|
    after a 3x3 median filter (:func:`median_3x3`), or of |data| itself when the filter
    leaves nothing."""
    values = np.abs(np.asarray(data, np.float64))
    finite = np.isfinite(values)
    if not finite.any():
        return 1.0
    smooth = median_3x3(np.where(finite, values, 0.0))
    for candidate in (smooth[finite], values[finite]):
        limit = float(np.percentile(candidate, percentile))
        if limit > 0:
            return limit
    return 1.0


def median_3x3(image: np.ndarray, rows_per_block: int = 256) -> np.ndarray:
    """The median of each pixel's 3x3 neighbourhood in ``image`` (H, W, no NaN), the
    edge pixels repeated beyond the border: SciPy's ``median_filter(image, size=3,
    mode="nearest")``, the same values without importing scipy.ndimage (0.4 s, in a
    capture's first preview), ``rows_per_block`` rows at a time (9 copies of them)."""
    image = np.asarray(image)
    windows = np.lib.stride_tricks.sliding_window_view(np.pad(image, 1, mode="edge"), (3, 3))
    smooth = np.empty_like(image)
    for start in range(0, image.shape[0], rows_per_block):
        block = windows[start:start + rows_per_block]
        nine = block.reshape(*block.shape[:2], 9)
        smooth[start:start + rows_per_block] = np.partition(nine, 4, axis=-1)[..., 4]
    return smooth


def preview_scalar(image: np.ndarray) -> np.ndarray:
    """The signed scalar a preview shows: the mean over channels."""
    img = np.asarray(image, dtype=np.float64)
    return img.mean(axis=-1) if img.ndim == 3 else img


def colorbar_extend(data, vmin, vmax) -> str:
    """A colour bar's ``extend`` for ``data`` shown from ``vmin`` to ``vmax``: an arrow
    at each end that finite values pass ("both", "min", "max" or "neither")."""
    values = np.asarray(data, np.float64)
    values = values[np.isfinite(values)]
    low = bool(values.size and vmin is not None and values.min() < vmin)
    high = bool(values.size and vmax is not None and values.max() > vmax)
    return {(True, True): "both", (True, False): "min", (False, True): "max"}.get(
        (low, high), "neither")


@dataclass(frozen=True)
class ColourScale:
    """Values to positions on a colour map: ``kind`` "linear", "power" (position =
    ((v - vmin) / (vmax - vmin)) ** gamma, a display gamma) or "log" (vmin > 0).
    Positions outside [0, 1] take the end colours (the colour bar's arrows say so)."""

    vmin: float
    vmax: float
    kind: str = "linear"
    gamma: float = 1.0

    def __post_init__(self):
        if self.kind not in ("linear", "power", "log"):
            raise ValueError(f"unknown colour scale {self.kind!r} (linear, power, log)")
        if self.kind == "log" and not self.vmin > 0:
            raise ValueError(f"a log colour scale needs vmin > 0, not {self.vmin!r}")

    @classmethod
    def fitted(cls, data, vmin=None, vmax=None, kind: str = "linear", gamma: float = 1.0):
        """The scale with the limits that are None taken from ``data``'s finite values
        (their minimum and maximum; 0 and 1 when there are none) and a range of zero
        widened, as Matplotlib's autoscaling does."""
        values = np.asarray(data, np.float64)
        values = values[np.isfinite(values)]
        lo = float(values.min()) if vmin is None and values.size else vmin
        hi = float(values.max()) if vmax is None and values.size else vmax
        lo, hi = (0.0 if lo is None else float(lo)), (1.0 if hi is None else float(hi))
        if hi == lo:  # (nothing to spread: one colour in the middle)
            lo, hi = lo - 0.5 * max(abs(lo), 1e-12), hi + 0.5 * max(abs(hi), 1e-12)
            if kind == "log":
                lo = hi / 10.0
        return cls(lo, hi, kind, gamma)

    def position(self, values) -> np.ndarray:
        """Where ``values`` fall on the colour map, 0 at vmin and 1 at vmax (NaN stays)."""
        v = np.asarray(values, np.float64)
        with np.errstate(invalid="ignore", divide="ignore"):
            if self.kind == "log":
                return (np.log10(v) - math.log10(self.vmin)) / math.log10(self.vmax / self.vmin)
            t = (v - self.vmin) / (self.vmax - self.vmin)
            if self.kind == "power":
                t = np.where(t > 0, np.abs(t) ** self.gamma, np.minimum(t, 0.0))
            return t

    def ticks(self, most: int = 7) -> list:
        """(value, label) of the colour bar's ticks: round values inside the range, at
        most ``most`` on a linear or power scale."""
        if self.kind == "log":
            values = log_ticks(self.vmin, self.vmax)
            if len(values) >= 2:
                return [(v, format_number(v, v)) for v in values]
        values, step = linear_ticks(self.vmin, self.vmax, most)
        return [(v, format_number(v, step)) for v in values]


def linear_ticks(lo: float, hi: float, most: int = 7) -> tuple:
    """(round values in [lo, hi], their step): steps 1, 2, 2.5 or 5 x 10^k, at most
    ``most`` of them."""
    span = hi - lo
    if not span > 0:
        return [lo], abs(lo) or 1.0
    raw = span / (most - 1)
    magnitude = 10.0 ** math.floor(math.log10(raw))
    step = next(m * magnitude for m in (1.0, 2.0, 2.5, 5.0, 10.0) if m * magnitude >= raw)
    first = math.ceil(lo / step - 1e-9)
    values = [k * step for k in range(first, math.floor(hi / step + 1e-9) + 1)]
    return [0.0 if abs(v) < 1e-9 * step else v for v in values], step


def log_ticks(lo: float, hi: float) -> list:
    """Round values in [lo, hi] for a log scale: the decades, or 1, 2 and 5 times them
    when the range holds fewer than two decades."""
    decades = range(math.floor(math.log10(lo)), math.ceil(math.log10(hi)) + 1)
    inside = [10.0 ** k for k in decades if lo * (1 - 1e-9) <= 10.0 ** k <= hi * (1 + 1e-9)]
    if len(inside) >= 2:
        return inside
    return [m * 10.0 ** k for k in decades for m in (1.0, 2.0, 5.0)
            if lo * (1 - 1e-9) <= m * 10.0 ** k <= hi * (1 + 1e-9)]


MINUS = "\u2212"  # (the typographic minus, as Matplotlib writes it)


def format_number(value: float, step: float) -> str:
    """``value`` written with the decimals its tick ``step`` needs; in powers of ten
    (2.5e−5) when it is very large or very small."""
    size = max(abs(value), abs(step))
    if (size >= 1e5 or size < 1e-3) and value != 0:
        exponent = math.floor(math.log10(abs(value)))
        mantissa = round(value / 10.0 ** exponent, 2)
        if abs(mantissa) >= 10:
            mantissa, exponent = mantissa / 10, exponent + 1
        text = f"{mantissa:g}e{exponent}"
    elif size >= 1e5 or size < 1e-3:
        text = "0"
    else:
        digit = math.floor(math.log10(abs(step)) + 1e-9) if step else 0  # (its leading digit)
        decimals = max(0, -digit) + bool(step and round(step / 10.0 ** digit, 3) == 2.5)
        text = f"{value:.{decimals}f}"
    return text.replace("-", MINUS)


# ---- Colours, fonts and texts -------------------------------------------------------------

@functools.lru_cache(maxsize=None)
def colour_table(name: str) -> np.ndarray:
    """The colour map ``name`` as TABLE_SIZE x 3 uint8: the package's tables, or
    Matplotlib's map of that name (an unknown one: Matplotlib's ValueError)."""
    with np.load(COLOUR_TABLES) as tables:
        if name in tables.files:
            return tables[name]
    import matplotlib

    colours = matplotlib.colormaps[name](np.linspace(0.0, 1.0, TABLE_SIZE))[:, :3]
    return np.round(colours * 255).astype(np.uint8)


def colours(name: str, positions) -> np.ndarray:
    """The colours (uint8 RGB) of ``positions`` on the map ``name``: [0, 1] in
    TABLE_SIZE equal steps, below and above it the end colours (NaN: the first)."""
    index = np.nan_to_num(np.asarray(positions, np.float64) * TABLE_SIZE, nan=0.0)
    return colour_table(name)[np.clip(index, 0, TABLE_SIZE - 1).astype(np.intp)]


@functools.lru_cache(maxsize=None)
def font(size: int):
    """DejaVu Sans (the font Matplotlib ships and draws with) at ``size`` pixels."""
    import importlib.util

    from PIL import ImageFont

    spec = importlib.util.find_spec("matplotlib")  # (finds it without importing it)
    if spec is not None and spec.origin:
        path = os.path.join(os.path.dirname(spec.origin), "mpl-data", "fonts", "ttf",
                            "DejaVuSans.ttf")
        if os.path.isfile(path):
            return ImageFont.truetype(path, size)
    return ImageFont.load_default(size)


def line_height(size: int) -> int:
    ascent, descent = font(size).getmetrics()
    return ascent + descent


def text_width(text: str, size: int) -> int:
    return int(math.ceil(font(size).getlength(text)))


def wrap(text: str, size: int, width: int) -> list:
    """``text`` in lines of at most ``width`` pixels (words longer than that stand on
    their own line)."""
    words, lines = " ".join(text.split()).split(" "), []
    for word in words:
        if lines and text_width(f"{lines[-1]} {word}", size) <= width:
            lines[-1] = f"{lines[-1]} {word}"
        else:
            lines.append(word)
    return lines or [""]


@dataclass
class TextBlock:
    """Lines of one text (drawn centred, or read upwards along a colour bar)."""

    lines: list
    size: int
    colour: tuple = (0, 0, 0)

    @classmethod
    def wrapped(cls, text: str, size: int, width: int, colour=(0, 0, 0)):
        return cls(wrap(text, size, width) if text else [], size, colour)

    @property
    def height(self) -> int:
        return len(self.lines) * line_height(self.size)

    @property
    def width(self) -> int:
        return max((text_width(line, self.size) for line in self.lines), default=0)


# ---- Layout -------------------------------------------------------------------------------

@dataclass
class Panel:
    """One image of a preview: ``data`` (H, W; NaN hatched) on ``scale`` in the colour map
    ``cmap``, titled ``title`` (wrapped to the panel), a colour bar labelled ``label``;
    ``marked`` (H, W bool or None): pixels cross-hatched in white."""

    data: np.ndarray
    title: str
    label: str
    cmap: str
    scale: ColourScale
    marked: np.ndarray | None = None

    @property
    def extend(self) -> str:
        return colorbar_extend(self.data, self.scale.vmin, self.scale.vmax)


@dataclass
class Drawing:
    """A drawn preview: ``image`` (a Pillow RGB image) and ``boxes``, (name, (x0, y0, x1,
    y1)) of everything drawn, in pixels (x1, y1 excluded); ``extends``: each panel's
    colour bar arrows."""

    image: object
    boxes: list
    extends: list


def image_size(shape, fit) -> tuple:
    """(width, height) in pixels of an image of ``shape`` (H, W) fitted into ``fit``
    (width, height), its aspect kept, except that no side is under MIN_IMAGE_SIDE
    pixels (a row of 300 pixels would be a line: its pixels are drawn taller then)."""
    h, w = shape[:2]
    scale = min(fit[0] / w, fit[1] / h)
    return (max(min(MIN_IMAGE_SIDE, fit[0]), int(round(w * scale))),
            max(min(MIN_IMAGE_SIDE, fit[1]), int(round(h * scale))))


class _BarLayout:
    """A colour bar of ``length`` pixels for ``scale`` in ``cmap``: its arrows
    (``extend``), round ticks and ``label`` read upwards; positions from its top left."""

    def __init__(self, scale: ColourScale, cmap: str, label: str, length: int, extend: str):
        self.scale, self.cmap, self.length, self.extend = scale, cmap, length, extend
        self.ticks = scale.ticks(max(3, length // TICK_SPACING + 1))
        self.tick_w = max((text_width(text, TICK_SIZE) for _, text in self.ticks), default=0)
        self.label = TextBlock(wrap(label, LABEL_SIZE, length) if label else [], LABEL_SIZE)
        self.tick_x = BAR_WIDTH + TICK_LENGTH + 3
        self.label_x = self.tick_x + self.tick_w + TEXT_GAP
        self.width = self.label_x + self.label.height

    def arrows(self) -> tuple:
        """The lengths (top, bottom) of the arrows: one bar width each where ``extend``
        has them (at most a fifth of the bar)."""
        size = min(BAR_WIDTH, self.length // 5)
        return (size if self.extend in ("max", "both") else 0,
                size if self.extend in ("min", "both") else 0)

    def paint(self, canvas, x: int, y: int, name: str) -> list:
        """The bar's colours between its arrows, top row the highest value."""
        top, bottom = self.arrows()
        inner = self.length - top - bottom
        steps = (inner - 1 - np.arange(inner) + 0.5) / inner
        canvas[y + top:y + top + inner, x:x + BAR_WIDTH] = colours(self.cmap, steps)[:, None, :]
        return [(name, (x, y, x + BAR_WIDTH, y + self.length))]

    def write(self, image, pen, x: int, y: int, name: str) -> list:
        """The outline, the arrows, the ticks and the label; returns the texts' boxes."""
        x1, y1 = x + BAR_WIDTH - 1, y + self.length - 1
        top, bottom = self.arrows()
        table = colour_table(self.cmap)
        outline = [(x, y + top), (x1, y + top), (x1, y1 - bottom), (x, y1 - bottom)]
        pen.line(outline + [outline[0]], fill=(0, 0, 0), width=1)
        middle = (x + x1) / 2
        if top:
            pen.polygon([(x, y + top), (middle, y), (x1, y + top)],
                        fill=tuple(int(c) for c in table[-1]), outline=(0, 0, 0))
        if bottom:
            pen.polygon([(x, y1 - bottom), (middle, y1), (x1, y1 - bottom)],
                        fill=tuple(int(c) for c in table[0]), outline=(0, 0, 0))
        inner, boxes = self.length - top - bottom, []
        for value, text in self.ticks:
            t = float(self.scale.position(value))
            if not -1e-9 <= t <= 1 + 1e-9:
                continue
            ty = int(round(y + top + (inner - 1) * (1.0 - t)))
            pen.line([(x1 + 1, ty), (x1 + TICK_LENGTH, ty)], fill=(0, 0, 0), width=1)
            at = (x + self.tick_x, ty)
            pen.text(at, text, font=font(TICK_SIZE), fill=(0, 0, 0), anchor="lm")
            boxes.append((f"{name} tick {text}",
                          pen.textbbox(at, text, font=font(TICK_SIZE), anchor="lm")))
        if self.label.lines:
            boxes.append(_write_along(image, self.label, x + self.label_x, y, self.length,
                                      f"{name} label"))
        return boxes


class _PanelLayout:
    """Where a panel's parts go, relative to the panel's top left corner: its title, its
    image and (``with_bar``) its colour bar beside it."""

    def __init__(self, panel: Panel, fit, with_bar: bool = True):
        self.panel = panel
        self.image_w, self.image_h = image_size(panel.data.shape, fit)
        self.bar = (_BarLayout(panel.scale, panel.cmap, panel.label,
                               max(self.image_h, BAR_MIN_LENGTH), panel.extend)
                    if with_bar else None)
        content_w = self.image_w + (BAR_GAP + self.bar.width if self.bar else 0)
        # the title wrapped to the panel, at least TITLE_MIN_WIDTH wide (a narrow image's
        # panel grows to it, the image and its bar centred in it)
        self.title = TextBlock.wrapped(panel.title, TITLE_SIZE, max(content_w, TITLE_MIN_WIDTH))
        self.width = max(content_w, self.title.width)
        self.image_x = (self.width - content_w) // 2
        self.bar_x = self.image_x + self.image_w + BAR_GAP
        self.body_y = self.title.height + (TEXT_GAP if self.title.lines else 0)
        self.body_h = max(self.image_h, self.bar.length if self.bar else 0)
        self.height = self.body_y + self.body_h
        self.image_y = self.body_y + (self.body_h - self.image_h) // 2
        self.bar_y = self.body_y + (self.body_h - self.bar.length) // 2 if self.bar else 0


def draw(panels, fit=(576, 576), title: str = "", caption: str = "", columns=None,
         shared_bar: bool = False) -> Drawing:
    """The preview of ``panels`` in rows of ``columns`` (None: one row), each image
    fitted into ``fit`` (width, height in pixels), under ``title`` and over ``caption``
    (both wrapped to the picture's width); ``shared_bar``: one colour bar right of them
    all, the first panel's scale, colour map and label (give them all the same scale),
    with arrows where any panel's data passes it. See the module docstring."""
    from PIL import Image, ImageDraw

    layouts = [_PanelLayout(p, fit, with_bar=not shared_bar) for p in panels]
    grid = _Grid(layouts, columns or len(layouts))
    bar = None
    if shared_bar:
        first = panels[0]
        every = np.concatenate([np.ravel(p.data) for p in panels])
        bar = _BarLayout(first.scale, first.cmap, first.label,
                         max(grid.height - layouts[0].body_y, BAR_MIN_LENGTH),
                         colorbar_extend(every, first.scale.vmin, first.scale.vmax))
    inner_w = grid.width + (BAR_GAP + bar.width if bar else 0)
    top = TextBlock.wrapped(title, SUPTITLE_SIZE, inner_w)
    bottom = TextBlock.wrapped(caption, CAPTION_SIZE, inner_w, CAPTION_COLOUR)
    width = max(inner_w, top.width, bottom.width)  # (a word longer than the panels)
    grid_x = PAD + (width - inner_w) // 2
    grid_y = PAD + top.height + (TITLE_GAP if top.lines else 0)
    body_h = max(grid.height, layouts[0].body_y + bar.length if bar else 0)
    caption_y = grid_y + body_h + (TEXT_GAP if bottom.lines else 0)
    size = (width + 2 * PAD, caption_y + bottom.height + PAD)
    canvas = np.full((size[1], size[0], 3), 255, np.uint8)
    starts = [(grid_x + x, grid_y + y) for x, y in grid.corners]
    boxes = []
    for k, (lay, (x, y)) in enumerate(zip(layouts, starts)):
        boxes += _paint_panel(canvas, lay, x, y, k)
    bar_at = (grid_x + grid.width + BAR_GAP, grid_y + layouts[0].body_y)
    if bar:
        boxes += bar.paint(canvas, *bar_at, "bar")
    image = Image.fromarray(canvas)
    pen = ImageDraw.Draw(image)
    for k, (lay, (x, y)) in enumerate(zip(layouts, starts)):
        boxes += _write_panel_texts(image, pen, lay, x, y, k)
    if bar:
        boxes += bar.write(image, pen, *bar_at, "bar")
    boxes += _write_block(pen, top, size[0] // 2, PAD, "title")
    boxes += _write_block(pen, bottom, size[0] // 2, caption_y, "caption")
    extends = [bar.extend] if bar else [lay.bar.extend for lay in layouts]
    return Drawing(image, boxes, extends)


class _Grid:
    """Panels in rows of ``columns``: each column as wide as its widest panel, each row
    as tall as its tallest, the panels centred in their column and their bottoms
    aligned in their row; ``corners`` are their top left corners from the grid's."""

    def __init__(self, layouts, columns: int):
        columns = max(1, min(columns, len(layouts)))
        rows = [layouts[k:k + columns] for k in range(0, len(layouts), columns)]
        col_w = [max(row[c].width for row in rows if c < len(row)) for c in range(columns)]
        row_h = [max(lay.height for lay in row) for row in rows]
        self.width = sum(col_w) + PANEL_GAP * (columns - 1)
        self.height = sum(row_h) + PANEL_GAP * (len(rows) - 1)
        self.corners = []
        for r, row in enumerate(rows):
            y = sum(row_h[:r]) + PANEL_GAP * r
            for c, lay in enumerate(row):
                x = sum(col_w[:c]) + PANEL_GAP * c + (col_w[c] - lay.width) // 2
                self.corners.append((x, y + row_h[r] - lay.height))


def _paint_panel(canvas, lay: _PanelLayout, x: int, y: int, k: int) -> list:
    """The image (with its hatching and marks) and the colour bar's colours of panel
    ``k`` at (x, y) of ``canvas`` (H, W, 3 uint8, in place); returns their boxes."""
    panel = lay.panel
    h, w = panel.data.shape[:2]
    rows = np.minimum(np.arange(lay.image_h) * h // lay.image_h, h - 1)
    cols = np.minimum(np.arange(lay.image_w) * w // lay.image_w, w - 1)
    data = np.asarray(panel.data, np.float64)[np.ix_(rows, cols)]
    pixels = colours(panel.cmap, panel.scale.position(data))
    yy, xx = np.mgrid[0:lay.image_h, 0:lay.image_w]
    nan = ~np.isfinite(data)
    stripes = ((xx + yy) % HATCH_PERIOD) < HATCH_WIDTH
    pixels[nan] = _rgb(NO_SIGNAL_COLOUR)
    pixels[nan & stripes] = 0
    if panel.marked is not None:
        marked = np.asarray(panel.marked, bool)[np.ix_(rows, cols)]
        lines = (((xx + yy) % MARK_PERIOD) < MARK_WIDTH) | (((xx - yy) % MARK_PERIOD) < MARK_WIDTH)
        pixels[marked & lines] = MARK_COLOUR
    image_x, image_y = x + lay.image_x, y + lay.image_y
    canvas[image_y:image_y + lay.image_h, image_x:image_x + lay.image_w] = pixels
    boxes = [(f"panel {k} image", (image_x, image_y, image_x + lay.image_w,
                                   image_y + lay.image_h))]
    if lay.bar:
        boxes += lay.bar.paint(canvas, x + lay.bar_x, y + lay.bar_y, f"panel {k} bar")
    return boxes


def _write_panel_texts(image, pen, lay: _PanelLayout, x: int, y: int, k: int) -> list:
    """Panel ``k``'s title and its colour bar's outline, arrows, ticks and label;
    returns the boxes of the texts."""
    centre = x + lay.image_x + lay.image_w // 2  # (over the image, kept inside the panel)
    centre = min(max(centre, x + lay.title.width // 2), x + lay.width - lay.title.width // 2)
    boxes = _write_block(pen, lay.title, centre, y, f"panel {k} title")
    if lay.bar:
        boxes += lay.bar.write(image, pen, x + lay.bar_x, y + lay.bar_y, f"panel {k}")
    return boxes


def _write_block(pen, block: TextBlock, centre_x: int, y: int, name: str) -> list:
    """``block``'s lines centred on ``centre_x`` from ``y`` down; returns their box."""
    if not block.lines:
        return []
    step = line_height(block.size)
    for n, line in enumerate(block.lines):
        pen.text((centre_x, y + n * step), line, font=font(block.size), fill=block.colour,
                 anchor="ma")
    left = centre_x - block.width // 2
    return [(name, (left, y, left + block.width, y + block.height))]


def _write_along(image, block: TextBlock, x: int, y: int, length: int, name: str):
    """A colour bar's label read upwards at ``x``, centred on the bar (``y``,
    ``length``); returns its box."""
    from PIL import Image, ImageDraw

    mask = Image.new("L", (max(block.width, 1), block.height), 0)
    pen = ImageDraw.Draw(mask)
    step = line_height(block.size)
    for n, line in enumerate(block.lines):
        pen.text((mask.width / 2, n * step), line, font=font(block.size), fill=255,
                 anchor="ma")
    mask = mask.rotate(90, expand=True)
    top = y + (length - mask.height) // 2
    image.paste(block.colour, (x, top), mask)
    return (name, (x, top, x + mask.width, top + mask.height))


def _rgb(colour: str) -> tuple:
    """(r, g, b) of a "#rrggbb" colour."""
    return tuple(int(colour[i:i + 2], 16) for i in (1, 3, 5))
