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
