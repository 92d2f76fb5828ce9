"""Previews that do not mislead (issue 15, item 19): NaN unmistakable, robust signed
limits, the render's PNG title says what was measured, one radiance gamma; drawn by
dopplertof.previews (issue 24, section 7): each pixel the colour of its value on its
scale, Matplotlib's colour tables, the same bytes each time."""

import os
import pathlib

import numpy as np
import pytest
from PIL import Image

from dopplertof import image_files, io, previews

from dopplertof.tof import figures

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SPHERE = os.path.join(ROOT, "examples", "translating_sphere.xml")
MAGENTA = np.array([0xFF, 0x00, 0xFF])


def _rgb(path):
    return np.asarray(Image.open(path).convert("RGB"), dtype=np.int64)


def test_no_signal_is_a_colour_outside_every_map(tmp_path):
    import matplotlib

    for name in ("RdBu_r", "PuOr_r", "viridis", "gray", "magma"):
        colours = matplotlib.colormaps[name](np.linspace(0, 1, 256))[:, :3] * 255
        assert np.min(np.linalg.norm(colours - MAGENTA, axis=1)) > 100, name
    data = np.linspace(-1, 1, 40 * 40).reshape(40, 40)
    data[10:30, 10:30] = np.nan
    path = tmp_path / "map.png"
    figures.write_map(path, data, "t", "m/s", cmap="RdBu_r", symmetric=True)
    rgb = _rgb(path)
    assert np.sum(np.all(rgb == MAGENTA, axis=-1)) > 200  # the hatched block
    assert np.sum(np.all(rgb < 60, axis=-1)) > 50       # its black hatching


def test_signed_preview_limit_is_not_set_by_thin_silhouettes():
    data = np.full((64, 64), 1e-3)
    data[:, :32] = -1e-3
    data[20, :] = 0.1   # a one-pixel line of huge values (an edge sweeping a pixel row)
    data[:, 40] = -0.1
    assert np.percentile(np.abs(data), 99.5) == pytest.approx(0.1)
    assert previews.robust_limit(data) == pytest.approx(1e-3)
    assert previews.robust_limit(np.zeros((4, 4))) == 1.0


def test_median_3x3_is_scipys_median_filter():
    """The robust limit's 3x3 median (NumPy, no scipy.ndimage import) has SciPy's values,
    edges repeated ("nearest"), whatever the shape and the block of rows."""
    from scipy.ndimage import median_filter

    rng = np.random.default_rng(7)
    for shape in [(1, 1), (1, 6), (6, 1), (2, 2), (17, 33), (70, 41)]:
        image = np.abs(rng.normal(size=shape))
        image[rng.random(shape) < 0.3] = 0.0
        for rows in (1, 2, 256):
            assert np.array_equal(previews.median_3x3(image, rows),
                                  median_filter(image, size=3, mode="nearest")), (shape, rows)


def test_render_png_title_says_h_offset_and_frequency(tmp_path, monkeypatch, capsys):
    from dopplertof.cli import main

    titles = []
    original = image_files.write_png
    monkeypatch.setattr(image_files, "write_png", lambda path, image, **kw: (
        titles.append(kw.get("title")), original(path, image, **kw)))
    out = tmp_path / "r.png"
    assert main(["render", SPHERE, "-D", "res=8", "--spp", "4", "--quiet", "-P",
                 "hetero_offset=0.25", "-o", str(out)]) == 0
    assert titles == ["heterodyne capture, offset 0.25, h=1, 30 MHz sinusoidal, 4 spp"]
    assert out.stat().st_size > 0
    titles.clear()
    assert main(["render", SPHERE, "-D", "res=8", "--spp", "4", "--quiet", "-P",
                 "hetero_frequency=0", "-P", "w_g=20", "-o", str(out)]) == 0
    assert titles[0].startswith("homodyne capture, offset 0, h=0, 20 MHz")


def test_one_radiance_gamma_everywhere():
    norm = figures.radiance_norm(2.0)
    assert norm(1.0) == pytest.approx(0.5 ** (1 / 2.2))
    assert figures.radiance_scale(2.0).position(1.0) == pytest.approx(0.5 ** (1 / 2.2))
    assert figures.RADIANCE_GAMMA_LABEL == "gamma 2.2"
    src = pathlib.Path(ROOT, "src", "dopplertof")
    for path in src.rglob("*.py"):
        text = path.read_text()
        assert "gamma 0.5" not in text and "1 / 2.2" not in text, path


def test_depth_preview_marks_the_pixels_beyond_the_wrap(tmp_path, monkeypatch):
    """At 40 MHz depth wraps at 3.747 m: the sphere's wall (4.6 m and more) is beyond it.
    depth.png cross-hatches exactly the pixels whose true depth is beyond the wrap and its
    caption counts them; with a range beyond the wall (unwrapped) nothing is marked."""
    import dopplertof
    from dopplertof.tof import output

    drawn = {}
    original = figures.draw
    monkeypatch.setattr(figures, "draw", lambda panels, *args, **kwargs: drawn.setdefault(
        "depth", []).append((panels, kwargs.get("caption", ""))) or original(panels, *args,
                                                                              **kwargs))
    scene = dopplertof.load_file(SPHERE, {"res": "12", "spp": "4"})
    result = dopplertof.capture(scene, params={"w_g": 40.0}, progress=False)
    depth_info = result.summary["depth"]
    beyond = result.truth.depth >= depth_info["wrap_distance_m"]
    for info, marked in ((depth_info, True), (dict(depth_info, unambiguous_range_m=10.0),
                                              False)):
        drawn.clear()
        output._write_depth_maps(result.reconstruction, result.truth, info,
                                 lambda n: str(tmp_path / n), "")
        (panels, caption), _ = drawn["depth"]  # (depth.png, then depth_gt.png)
        if not marked:
            assert panels[0].marked is None and "beyond" not in caption
            continue
        assert beyond.any() and not beyond.all()
        assert f"{int(beyond.sum())} px beyond it" in caption
        assert np.array_equal(panels[0].marked, beyond)


def _preview_specs(size):
    """(file name, writer) pairs covering each kind of pooled figure: signed and unsigned
    captures, maps with captions, marks, arrows and NaN, a log map, radiance, the
    side-by-side comparison."""
    rng = np.random.default_rng(size)
    data = rng.normal(0.0, 10.0, (size, size + 3))
    data[1:4, 2:6] = np.nan
    data[0, 0] = 900.0
    return [
        ("capture.png", lambda p, k: image_files.write_png(p, data * (k + 1), title=f"capture {k}")),
        ("counts.png", lambda p, k: image_files.write_png(p, np.abs(data) + k, title="counts",
                                                 signed=False)),
        ("error.png", lambda p, k: figures.write_map(
            p, data + k, f"error {k}", "m/s", cmap="PuOr_r", symmetric=True, vmax=33.0,
            note=f"caption {k}: " + "long " * 20 * k)),
        ("depth.png", lambda p, k: figures.write_map(
            p, np.abs(data) + k, "depth", "m", vmin=-1.0, vmax=20.0 + k, note="wrapped",
            marked=np.abs(data) > 12 + k)),
        ("std.png", lambda p, k: figures.write_log_map(p, np.abs(data) * (k + 1), "std",
                                                       "m/s (log scale)", note="x")),
        ("radiance.png", lambda p, k: figures.write_radiance(p, np.abs(data) * (k + 1),
                                                             f"radiance {k}")),
        ("comparison.png", lambda p, k: figures.write_comparison(
            p, np.abs(data) * (k + 1), data * (k + 1), data * 0.9, f"scene {k}",
            note=f"note {k}")),
    ]


def test_previews_are_the_same_bytes_each_time(tmp_path):
    """Every kind of preview drawn twice from the same data is the same file, byte for
    byte; drawn from other data, another file."""
    for name, write in _preview_specs(12):
        for k, tag in ((1, "a"), (1, "b"), (0, "c")):
            write(tmp_path / f"{tag}_{name}", k)
        a, b, c = ((tmp_path / f"{tag}_{name}").read_bytes() for tag in "abc")
        assert a == b, name
        assert a != c, name


def _panel_pixels(drawing, k=0):
    (x0, y0, x1, y1), = [b for p, b in drawing.boxes if p == f"panel {k} image"]
    return np.asarray(drawing.image.convert("RGB"))[y0:y1, x0:x1].astype(np.int64)


@pytest.mark.parametrize("scale", [previews.ColourScale(-2.0, 2.0),
                                   previews.ColourScale(0.0, 4.0, "power", 1 / 2.2),
                                   previews.ColourScale(1e-3, 10.0, "log")])
def test_each_pixel_shows_the_colour_of_its_value(scale):
    """A 3x4 map drawn on a linear, gamma and log scale: the middle of each pixel's block
    is the colour table's entry floor(256 t) of its value's position t (t = (v - lo) /
    (hi - lo), its 1/2.2 power, or log10's share of the decades), the end colours past
    the ends; the colour bar's rows run from the first entry (bottom) to the last."""
    values = np.array([[-3.0, -2.0, -0.5, 0.0], [1e-3, 0.02, 0.5, 1.0], [2.0, 3.9, 10.0, 50.0]])
    panel = previews.Panel(values, "t", "m/s", "viridis", scale)
    drawing = previews.draw([panel], fit=(400, 300))
    pixels = _panel_pixels(drawing)
    table = previews.colour_table("viridis").astype(np.int64)
    h, w = pixels.shape[:2]
    for (r, c), v in np.ndenumerate(values):
        if scale.kind == "log" and v <= 0:
            t = -1.0  # (log of zero or less: below the range, the first colour)
        elif scale.kind == "log":
            t = (np.log10(v) + 3.0) / 4.0
        else:
            t = (v - scale.vmin) / (scale.vmax - scale.vmin)
            t = t ** scale.gamma if t > 0 else t
        expected = table[int(np.clip(np.floor(256 * t), 0, 255))]
        got = pixels[int((r + 0.5) * h / 3), int((c + 0.5) * w / 4)]
        assert np.array_equal(got, expected), (v, got, expected)
    (x0, y0, x1, y1), = [b for p, b in drawing.boxes if p == "panel 0 bar"]
    bar = np.asarray(drawing.image.convert("RGB"))[:, (x0 + x1) // 2].astype(np.int64)
    inside = [k for k in range(y0, y1) if any(np.array_equal(bar[k], c) for c in table)]
    assert np.array_equal(bar[inside[0]], table[-1]) and np.array_equal(bar[inside[-1]], table[0])


def test_hatching_and_marks_stay_inside_their_pixels():
    """NaN pixels are black and magenta only, both; marked pixels have white lines over
    their colour; every other pixel is its plain colour."""
    values = np.full((4, 4), 0.5)
    values[0, 0] = np.nan
    marked = np.zeros((4, 4), bool)
    marked[3, 3] = True
    panel = previews.Panel(values, "t", "", "RdBu_r", previews.ColourScale(0.0, 1.0), marked)
    pixels = _panel_pixels(previews.draw([panel], fit=(200, 200)))
    block = pixels.shape[0] // 4
    nan_block, marked_block = pixels[:block, :block], pixels[-block:, -block:]
    plain = pixels[block:2 * block, block:2 * block]
    kinds = {tuple(c) for c in nan_block.reshape(-1, 3)}
    assert kinds == {(255, 0, 255), (0, 0, 0)}
    colour = tuple(previews.colours("RdBu_r", 0.5))
    assert {tuple(c) for c in plain.reshape(-1, 3)} == {colour}
    assert {tuple(c) for c in marked_block.reshape(-1, 3)} == {colour, (255, 255, 255)}


def test_colour_tables_are_matplotlibs():
    """The package's colour tables (data/colormaps.npz, tools/make_colour_tables.py) are
    the installed Matplotlib's maps at 256 entries, within one step of rounding; a map
    the package does not ship comes from Matplotlib."""
    import matplotlib

    with np.load(previews.COLOUR_TABLES) as tables:
        names = tables.files
    assert {"RdBu_r", "PuOr_r", "viridis", "gray", "magma"} <= set(names)
    for name in names + ["plasma"]:
        expected = matplotlib.colormaps[name](np.linspace(0, 1, 256))[:, :3] * 255
        assert np.max(np.abs(previews.colour_table(name) - expected)) <= 0.5 + 1e-9, name


def test_colour_bar_ticks_are_round_values_inside_the_range():
    """Ticks at 1, 2, 2.5 or 5 x 10^k steps inside the range, written with the decimals
    their step needs, a typographic minus, powers of ten for tiny values; decades on a
    log scale."""
    ticks = previews.ColourScale(-23.4, 23.4).ticks()
    assert [label for _, label in ticks] == ["\u221220", "\u221210", "0", "10", "20"]
    assert [v for v, _ in previews.ColourScale(3.5, 4.9).ticks()] == pytest.approx(
        [3.5, 3.75, 4.0, 4.25, 4.5, 4.75])
    assert [label for _, label in previews.ColourScale(3.5, 4.9).ticks()][:2] == ["3.50", "3.75"]
    assert [label for _, label in previews.ColourScale(0, 3e-5).ticks(4)] == \
        ["0", "1e\u22125", "2e\u22125", "3e\u22125"]
    assert [v for v, _ in previews.ColourScale(2e-3, 30.0, "log").ticks()] == pytest.approx(
        [1e-2, 1e-1, 1.0, 10.0])
    assert [v for v, _ in previews.ColourScale(3.0, 40.0, "log").ticks()] == pytest.approx(
        [5.0, 10.0, 20.0])


def test_a_very_wide_image_is_not_drawn_as_a_line():
    """A 2 x 300 map is fitted to the preview's width with its pixels drawn taller: at
    least MIN_IMAGE_SIDE pixels high, each data row a band of equal height."""
    data = np.tile(np.array([[0.0], [1.0]]), (1, 300))
    panel = previews.Panel(data, "wide", "m", "viridis", previews.ColourScale(0.0, 1.0))
    pixels = _panel_pixels(previews.draw([panel], fit=(576, 576)))
    assert pixels.shape[0] >= previews.MIN_IMAGE_SIDE and pixels.shape[1] == 576
    half = pixels.shape[0] // 2
    assert np.all(pixels[:half] == previews.colours("viridis", 0.0))
    assert np.all(pixels[-half:] == previews.colours("viridis", 1.0))
