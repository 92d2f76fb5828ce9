"""Previews that do not mislead (issue 15, item 19): NaN unmistakable, robust signed
limits, the render's PNG title says what was measured, one radiance gamma."""

import os
import pathlib

import numpy as np
import pytest
from PIL import Image

from dopplertof import io
from dopplertof.tof import figures

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SPHERE = os.path.join(ROOT, "examples", "translating_sphere.xml")
MAGENTA = np.array([0xFF, 0x00, 0xFF])


def _rgb(path):
    return np.asarray(Image.open(path).convert("RGB"), dtype=np.int64)


def test_no_signal_is_a_colour_outside_every_map(tmp_path):
    import matplotlib

    for name in ("RdBu_r", "PuOr_r", "viridis", "gray"):
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
    assert io.robust_limit(data) == pytest.approx(1e-3)
    assert io.robust_limit(np.zeros((4, 4))) == 1.0


def test_median_3x3_is_scipys_median_filter():
    """The robust limit's 3x3 median (NumPy, no scipy.ndimage import) has SciPy's values,
    edges repeated ("nearest"), whatever the shape and the block of rows."""
    from scipy.ndimage import median_filter

    rng = np.random.default_rng(7)
    for shape in [(1, 1), (1, 6), (6, 1), (2, 2), (17, 33), (70, 41)]:
        image = np.abs(rng.normal(size=shape))
        image[rng.random(shape) < 0.3] = 0.0
        for rows in (1, 2, 256):
            assert np.array_equal(io.median_3x3(image, rows),
                                  median_filter(image, size=3, mode="nearest")), (shape, rows)


def test_render_png_title_says_h_offset_and_frequency(tmp_path, monkeypatch, capsys):
    from dopplertof.cli import main

    titles = []
    original = io.write_png
    monkeypatch.setattr(io, "write_png", lambda path, image, **kw: (
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

    figures_drawn = {}
    monkeypatch.setattr(figures, "save_figure", lambda fig, path, metadata=None:
                        figures_drawn.__setitem__(os.path.basename(path), fig))
    scene = dopplertof.load_file(SPHERE, {"res": "12", "spp": "4"})
    result = dopplertof.capture(scene, params={"w_g": 40.0}, progress=False)
    depth_info = result.summary["depth"]
    beyond = result.truth.depth >= depth_info["wrap_distance_m"]
    for info, marked in ((depth_info, True), (dict(depth_info, unambiguous_range_m=10.0),
                                              False)):
        figures_drawn.clear()
        output._write_depth_maps(result.reconstruction, result.truth, info,
                                 lambda n: str(tmp_path / n), "")
        fig = figures_drawn["depth.png"]
        hatched = [c for c in fig.axes[0].collections if c.get_hatch() == figures.MARK_HATCH]
        caption = " ".join(t.get_text() for t in fig.texts)
        if not marked:
            assert not hatched and "beyond" not in caption
            continue
        assert beyond.any() and not beyond.all()
        assert len(hatched) == 1 and f"{int(beyond.sum())} px beyond it" in caption
        covered = np.zeros_like(beyond)
        for path in hatched[0].get_paths():
            (x0, y0), (x1, y1) = path.vertices.min(axis=0), path.vertices.max(axis=0)
            covered[int(round(y0 + 0.5)):int(round(y1 + 0.5)),
                    int(round(x0 + 0.5)):int(round(x1 + 0.5))] = True
        assert np.array_equal(covered, beyond)


def _preview_specs(size):
    """(file name, writer) pairs covering each kind of pooled figure: signed and unsigned
    captures, maps with captions, marks, arrows and NaN, a log map, radiance, the
    side-by-side comparison."""
    rng = np.random.default_rng(size)
    data = rng.normal(0.0, 10.0, (size, size + 3))
    data[1:4, 2:6] = np.nan
    data[0, 0] = 900.0
    return [
        ("capture.png", lambda p, k: io.write_png(p, data * (k + 1), title=f"capture {k}")),
        ("counts.png", lambda p, k: io.write_png(p, np.abs(data) + k, title="counts",
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


def test_reused_previews_are_the_pictures_of_fresh_ones(tmp_path, monkeypatch):
    """A preview drawn in a figure that showed another one before (io.take_figure's
    pool) has the pixels of the same preview drawn in a new figure: nothing of the
    earlier data, texts, caption, marks, fitted size or tight layout is left."""
    made = []
    for kind in (io.ImagePreview, figures.ComparisonFigure):
        def counting_init(self, key, settings, original_init=kind.__init__):
            made.append(key)
            original_init(self, key, settings)

        monkeypatch.setattr(kind, "__init__", counting_init)
    monkeypatch.setattr(io, "_PREVIEW_POOL", [])
    specs = _preview_specs(12)
    for name, write in specs:  # each in a new figure (the pool emptied before each)
        io._PREVIEW_POOL.clear()
        write(tmp_path / f"fresh_{name}", 1)
    fresh_figures = len(made)
    for name, write in specs:  # each after another of its kind, in that one's figure
        io._PREVIEW_POOL.clear()
        write(tmp_path / f"before_{name}", 0)
        write(tmp_path / f"reused_{name}", 1)
    assert len(made) == 2 * fresh_figures  # (the second of each pair reused the first)
    for name, _ in specs:
        fresh, reused = _rgb(tmp_path / f"fresh_{name}"), _rgb(tmp_path / f"reused_{name}")
        assert fresh.shape == reused.shape, name
        assert np.array_equal(fresh, reused), name
        assert not np.array_equal(_rgb(tmp_path / f"before_{name}"), reused), name


def test_reused_previews_have_the_arrows_of_their_own_data(tmp_path, monkeypatch):
    """The colour bar's arrows follow each preview's data when figures are reused: within
    the range none, past both ends both, past the top only max, and none again."""
    from matplotlib.figure import Figure

    extends = []
    original = Figure.savefig

    def record(fig, path, *args, **kwargs):
        extends.append([ax._colorbar.extend for ax in fig.axes
                        if getattr(ax, "_colorbar", None) is not None])
        return original(fig, path, *args, **kwargs)

    monkeypatch.setattr(Figure, "savefig", record)
    monkeypatch.setattr(io, "_PREVIEW_POOL", [])
    data = np.linspace(-1.0, 1.0, 64).reshape(8, 8)
    for k, scale in enumerate((1.0, 50.0, 1.0, 50.0, 1.0)):
        shown = data * scale if k != 3 else np.abs(data) * scale
        figures.write_map(tmp_path / f"{k}.png", shown, "v", "m/s", cmap="RdBu_r",
                          vmin=-33.0 if k != 3 else 0.0, vmax=33.0)
    assert extends == [["neither"], ["both"], ["neither"], ["max"], ["neither"]]


def test_previews_follow_matplotlib_settings_changed_between_them(tmp_path, monkeypatch):
    """A preview made after a change of Matplotlib's settings (rcParams) is drawn in a new
    figure with them, not in a pooled one made before; saving a figure twice puts it
    into the pool once."""
    import matplotlib

    monkeypatch.setattr(io, "_PREVIEW_POOL", [])
    data = np.linspace(-1.0, 1.0, 64).reshape(8, 8)
    io.write_png(tmp_path / "a.png", data)
    (before,) = io._PREVIEW_POOL
    with matplotlib.rc_context({"axes.linewidth": 3.0}):
        io.write_png(tmp_path / "b.png", data)
        assert len(io._PREVIEW_POOL) == 2 and io._PREVIEW_POOL[0] is before
    io.write_png(tmp_path / "c.png", data)  # (settings back: the first figure again)
    assert io._PREVIEW_POOL[-1] is before
    assert np.array_equal(_rgb(tmp_path / "a.png"), _rgb(tmp_path / "c.png"))
    assert not np.array_equal(_rgb(tmp_path / "a.png"), _rgb(tmp_path / "b.png"))  # (bolder)
    io.save_figure(before.fig, tmp_path / "d.png")
    assert io._PREVIEW_POOL.count(before) == 1
