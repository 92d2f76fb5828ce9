"""Pictures that show everything they draw (issue 24, section 6): every title, label,
caption, colour bar and legend inside the figure, no wide empty margins, colour bars
with arrows where the data passes their range, the precision map's check circles in
its legend, the angular fit's convergence plot showing omega. Each kind is drawn at two
image sizes (16x16 and 128x128) and measured on the figure as it is saved."""

import os
import types

import matplotlib
import numpy as np
import pytest

matplotlib.use("Agg")

from dopplertof import image_files, io, previews  # noqa: E402
from dopplertof.tof import figures  # noqa: E402

SIZES = (16, 128)
#: an empty border wider than this (inches) on any side is a wasted margin
MAX_MARGIN_INCHES = 0.3
LONG_TITLE = "heterodyne capture, offset 0.25, h=1, 30 MHz sinusoidal, 1024 spp (with sensor noise)"
LONG_CAPTION = ("wraps every 4.997 m; white cross-hatch: 3380 px beyond it, shown wrapped; "
                "hatched magenta: NaN (nothing hit or signal too weak)")


def outside(fig, tolerance=1.0) -> list:
    """What ``fig`` draws past its edges: each axes (with its title, labels, tick labels
    and legend; colour bars are axes too) and each figure text, by tight bounding box
    (pixels, ``tolerance`` of rounding), after ``fig.canvas.draw()``."""
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    width, height = fig.bbox.width, fig.bbox.height
    items = [(f"axes {ax.get_title() or ax.get_ylabel()!r}", ax.get_tightbbox(renderer))
             for ax in fig.axes]
    texts = list(fig.texts) + ([fig._suptitle] if fig._suptitle is not None else [])
    items += [(f"text {t.get_text()!r}", t.get_window_extent(renderer)) for t in texts]
    for ax in fig.axes:
        if ax.get_legend() is not None:
            items.append(("legend", ax.get_legend().get_window_extent(renderer)))
    return [name for name, box in items
            if box.x0 < -tolerance or box.y0 < -tolerance or box.x1 > width + tolerance
            or box.y1 > height + tolerance]


def margins(fig) -> list:
    """The empty border on each side (left, bottom, right, top) in inches."""
    fig.canvas.draw()
    box = fig.get_tightbbox(fig.canvas.get_renderer())
    width, height = fig.get_size_inches()
    return [box.x0, box.y0, width - box.x1, height - box.y1]


@pytest.fixture
def saved(monkeypatch):
    """The figures saved through Figure.savefig, measured as they are saved: a list of
    (file name, what is outside, margins, figure)."""
    from matplotlib.figure import Figure

    found = []
    original = Figure.savefig

    def measure_then_save(fig, path, *args, **kwargs):
        if kwargs.get("dpi") not in (None, "figure"):  # (measured at the saved resolution)
            fig.set_dpi(kwargs["dpi"])
        found.append((os.path.basename(str(path)), outside(fig), margins(fig), fig))
        return original(fig, path, *args, **kwargs)

    monkeypatch.setattr(Figure, "savefig", measure_then_save)
    return found


def assert_laid_out(found):
    for name, off, border, _ in found:
        assert not off, f"{name}: drawn past the figure's edge: {off}"
        assert max(border) < MAX_MARGIN_INCHES, f"{name}: empty margins {border} in"


#: the resolution the previews' texts are set for (pixels per inch)
PREVIEW_DPI = image_files.PREVIEW_DPI


@pytest.fixture
def drawn(monkeypatch):
    """The previews saved through image_files.save_png (dopplertof.previews, no Matplotlib): a
    list of (file name, Drawing)."""
    found = []
    original = image_files.save_png

    def record_then_save(path, drawing, metadata=None):
        found.append((os.path.basename(str(path)), drawing))
        return original(path, drawing, metadata)

    monkeypatch.setattr(image_files, "save_png", record_then_save)
    return found


def _overlap(a, b) -> bool:
    return a[0] < b[2] and b[0] < a[2] and a[1] < b[3] and b[1] < a[3]


def assert_previews_laid_out(found):
    """Every part of each preview inside the picture, no text over an image, a bar or
    another text, and no empty border wider than MAX_MARGIN_INCHES (measured on the
    pixels: the box of everything not white)."""
    for name, drawing in found:
        width, height = drawing.image.size
        for part, box in drawing.boxes:
            assert 0 <= box[0] <= box[2] <= width and 0 <= box[1] <= box[3] <= height, \
                f"{name}: {part} {box} past the edge of {width}x{height}"
        texts = [(p, b) for p, b in drawing.boxes if not p.endswith(("image", "bar"))]
        for k, (part, box) in enumerate(texts):
            for other, other_box in drawing.boxes:
                if other != part and (other, other_box) not in texts[:k + 1]:
                    assert not _overlap(box, other_box), f"{name}: {part} over {other}"
        pixels = np.asarray(drawing.image.convert("RGB"))
        rows = np.flatnonzero(np.any(pixels < 250, axis=(1, 2)))
        cols = np.flatnonzero(np.any(pixels < 250, axis=(0, 2)))
        border = [cols[0], rows[0], width - 1 - cols[-1], height - 1 - rows[-1]]
        assert max(border) < MAX_MARGIN_INCHES * PREVIEW_DPI, f"{name}: empty margins {border} px"


def speckled(size, seed=0, spread=1.0):
    rng = np.random.default_rng(seed)
    data = rng.normal(0.0, spread, (size, size))
    data[: size // 4, : size // 4] = np.nan
    return data


@pytest.mark.parametrize("size", SIZES)
def test_render_preview_shows_its_title_without_margins(tmp_path, drawn, size):
    """`render -o x.png`: e6dc814 cut the title's start off and left about an inch empty
    above and below a square image."""
    image_files.write_png(tmp_path / "r.png", speckled(size), title=LONG_TITLE)
    assert_previews_laid_out(drawn)


@pytest.mark.parametrize("size", SIZES)
@pytest.mark.parametrize("shape", ["square", "wide", "tall"])
def test_capture_previews_show_titles_captions_and_bars(tmp_path, drawn, size, shape):
    """The capture's single maps (with a long caption), log maps, radiance and the
    side-by-side comparison: everything inside, nothing over anything, no wide margins;
    square, wide and tall images."""
    data = speckled(size)
    data = {"square": data, "wide": data[: max(2, size // 6)], "tall": data[:, :3]}[shape]
    figures.write_map(tmp_path / "depth.png", data + 3, "reconstructed depth (with sensor noise)",
                      "m from the camera centre along the ray", note=LONG_CAPTION)
    figures.write_log_map(tmp_path / "std.png", np.abs(data) + 1e-3,
                          "velocity: predicted standard deviation, total", "m/s (log scale)",
                          note=previews.NO_SIGNAL_NOTE + "; top colour: also first order fails (inf)")
    figures.write_radiance(tmp_path / "radiance.png", np.abs(data)[..., None].repeat(3, -1),
                           "radiance, time-averaged over the exposure")
    figures.write_comparison(tmp_path / "comparison.png", np.abs(data), data, data * 0.9,
                             "translating_sphere.xml: 1024 spp per capture (with sensor noise)")
    assert len(drawn) == 4
    assert_previews_laid_out(drawn)
    texts = [p for _, d in drawn for p, _ in d.boxes]
    assert sum(p == "caption" for p in texts) == 2 and sum(p == "title" for p in texts) == 1
    assert sum(p.endswith("label") for p in texts) == 7  # (every colour bar labelled)


def test_colour_bars_have_arrows_where_the_data_passes_their_range(tmp_path, drawn):
    """velocity_error.png at +-33 m/s with errors up to 900 m/s (issue 24): arrows at
    both ends; one end passed, one arrow; inside the range, none. The same on the
    comparison figure's panels. An arrow is drawn where there is one: beside its tip
    the bar's corner is white (the picture's background), where there is none the
    bar's colour."""
    error = speckled(64, spread=10.0)
    error[5, 5], error[6, 6] = 900.0, -900.0
    figures.write_map(tmp_path / "e.png", error, "velocity error", "m/s", cmap="PuOr_r",
                      symmetric=True, vmax=33.0)
    positive = np.abs(error)
    figures.write_map(tmp_path / "p.png", positive, "speed", "m/s", vmin=0.0, vmax=33.0)
    figures.write_map(tmp_path / "n.png", np.clip(error, -30, 30), "within", "m/s",
                      symmetric=True, vmax=33.0)
    figures.write_comparison(tmp_path / "c.png", positive, error, np.zeros_like(error), "t")
    extends = [drawing.extends for _, drawing in drawn]
    assert extends[:3] == [["both"], ["max"], ["neither"]]
    assert extends[3][1] == "both" and extends[3][3] == "both"  # velocity, error panels
    for (name, drawing), extend in zip(drawn[:3], ("both", "max", "neither")):
        (x0, y0, x1, y1), = [b for p, b in drawing.boxes if p == "panel 0 bar"]
        pixels = np.asarray(drawing.image.convert("RGB")).astype(int)
        top, bottom = pixels[y0 + 1, x0 + 2], pixels[y1 - 2, x0 + 2]
        assert np.all(top == 255) == (extend in ("both", "max")), name
        assert np.all(bottom == 255) == (extend in ("both", "min")), name


def test_precision_map_legend_has_the_check_circles_and_the_title_fits(tmp_path, saved):
    from dopplertof.tof.study import StudyResult, write_map

    f, t = np.geomspace(10, 300, 6), np.geomspace(0.5e-3, 50e-3, 6)
    std = 1.0 / np.outer(f, t * 1e3)
    study = StudyResult(f, t, std, std * 1e-3, np.ones(6), np.ones(6), 64, 1.0, {},
                        np.ones(6, int), checks=[{"w_g_MHz": 30.0, "exposure_s": 1.5e-3},
                                                 {"w_g_MHz": 100.0, "exposure_s": 5e-3}])
    write_map(tmp_path / "map.png", study, "translating_sphere.xml: predicted velocity "
              "precision (sensor: 20000 e- well, auto photon scale)")
    (_, _, _, fig), = saved
    legend = fig.axes[0].get_legend()
    labels = [text.get_text() for text in legend.get_texts()]
    assert any("check" in label for label in labels), labels
    circles = [h for h, label in zip(legend.legend_handles, labels) if "check" in label]
    assert circles[0].get_marker() == "o"
    assert_laid_out(saved)


@pytest.mark.parametrize("size", SIZES)
def test_animation_frames_show_their_colour_bar_label(tmp_path, monkeypatch, size):
    """The GIF's frames: e6dc814 cut the colour bar's label at both ends."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    from dopplertof.experiments.animate import write_velocity_gif

    tasks = []
    for k in range(2):
        folder = tmp_path / f"frame_{k}"
        folder.mkdir()
        np.save(folder / "velocity.npy", speckled(size, k) * 10)
        np.save(folder / "velocity_gt.npy", np.full((size, size), -10.0))
        np.save(folder / "radiance.npy", np.ones((size, size, 3)))
        tasks.append(types.SimpleNamespace(folder=str(folder), index=k,
                                           shutter_open=1.5e-3 * k,
                                           shutter_close=1.5e-3 * (k + 1)))
    found = []
    original = FigureCanvasAgg.buffer_rgba

    def measure(canvas):
        found.append(outside(canvas.figure))
        return original(canvas)

    monkeypatch.setattr(FigureCanvasAgg, "buffer_rgba", measure)
    write_velocity_gif(tasks, str(tmp_path / "v.gif"), 10.0)
    assert found == [[], []]


def test_angular_fit_convergence_plot_shows_omega(tmp_path, saved):
    """An --angular fit's convergence.png: e6dc814 showed the radial velocity only."""
    from dopplertof.diff.fit_output import FitResult
    from dopplertof.diff.fit_plots import write_convergence_plot

    names = [f"body0.{kind}{a}" for kind in "vw" for a in "xyz"]
    history = [{"iteration": i, "loss": 10.0 ** -i, "radial_velocity_m_s": [0.0],
                "parameters": [0, 0, 0, 0, 20.0 - 4 / (i + 1), 0]} for i in range(4)]
    result = FitResult([{"name": "door"}], 3, 1e-3, history,
                       {"parameters": names, "angular": True,
                        "unconstrained": ["body0.vz", "body0.wx", "body0.wz"]})
    write_convergence_plot(result, tmp_path / "convergence.png")
    (_, _, _, fig), = saved
    omega = [ax for ax in fig.axes if "angular velocity" in ax.get_ylabel()]
    assert len(omega) == 1 and "rad/s" in omega[0].get_ylabel()
    (line,) = omega[0].get_lines()
    np.testing.assert_allclose(line.get_ydata(), [h["parameters"][4] for h in history])
    assert "omega_y" in line.get_label()
    assert_laid_out(saved)


@pytest.mark.slow
def test_analysis_figures_show_their_titles_and_legends(tmp_path, saved):
    """`dopplertof figures --quick`: e6dc814 drew legends past the right and bottom edges
    (waveform_correlations.png, 0.6 in), titles past the bottom and the left edge
    (doppler_geometric_vs_photon.png, convergence_rates.png). Measured at the dpi each
    figure is saved at."""
    from dopplertof.analysis import FIGURE_FILES, write_figures

    write_figures(tmp_path / "figs", quick=True)
    assert len(saved) == len(FIGURE_FILES)
    assert_laid_out(saved)


@pytest.mark.parametrize("frames, size", [(9, (24, 32)), (8, (120, 160)), (4, (8, 8))])
def test_camera_raw_frame_grid_is_laid_out_with_one_bar(tmp_path, drawn, frames, size):
    """A camera capture's raw.png: the frames in rows of a frequency's phases, one shared
    colour bar (with an arrow at neither end: the scale is the frames' own range)."""
    from dopplertof.cameras import output

    rng = np.random.default_rng(frames)
    raw = rng.integers(800, 3000, (frames, *size)).astype(np.float32)
    per = 3 if frames == 9 else 4
    records = [{"w_g_MHz": 16.0 * (1 + k // per), "phase_deg": 360.0 * (k % per) / per}
               for k in range(frames)]
    output._write_raw_grid(tmp_path / "raw.png", raw, records, "kinect-v2")
    (name, drawing), = drawn
    assert_previews_laid_out(drawn)
    parts = [p for p, _ in drawing.boxes]
    assert sum(p.endswith("image") for p in parts) == frames and parts.count("bar") == 1
    assert drawing.extends == ["neither"]
    images = [b for p, b in drawing.boxes if p.endswith("image")]
    assert len({b[1] for b in images}) == -(-frames // per)  # (a row per frequency)
