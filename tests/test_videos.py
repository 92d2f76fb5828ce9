"""Videos of map sequences (dopplertof.videos): the frames drawn with their colour bars on
one scale, MP4 through imageio-ffmpeg where installed and GIF otherwise, and a stream's
video and contact sheet.

A decoded video frame is compared through its colour bar: GIF's palette and H.264's
chroma subsampling change colours, so the bar's rows are matched to the nearest entry of
the colour table, and the entries must run from the top of the table to its bottom in
order (the bar's own, drawn exactly, is checked against the table bit for bit)."""

import sys

import numpy as np
import pytest

T, H, W = 5, 6, 8


def maps(seed: int = 0):
    from dopplertof.videos import depth_velocity_amplitude

    rng = np.random.default_rng(seed)
    depth = 1.0 + rng.random((T, H, W))
    depth[:, 0, 0] = np.nan  # (nothing seen: hatched)
    velocity = rng.normal(size=(T, H, W))
    amplitude = 100.0 * rng.random((T, H, W))
    return depth_velocity_amplitude(depth, velocity, amplitude, velocity_is_truth=True)


def bar_box(drawing, panel: int):
    return dict(drawing.boxes)[f"panel {panel} bar"]


def nearest_entries(pixels, cmap: str) -> np.ndarray:
    """The index of the colour table entry nearest each pixel (N, 3)."""
    from dopplertof.previews import colour_table

    table = colour_table(cmap).astype(np.float64)
    return np.argmin(((pixels[:, None, :].astype(np.float64) - table[None]) ** 2).sum(-1), 1)


def assert_bar_runs_down_the_table(image, box, cmap: str) -> None:
    """The middle column of a colour bar (its arrows and outline left out) decodes to entries
    that fall from the top of the table to its bottom: rank correlation with the row
    below -0.99, the ends near the table's (the rows left out, arrows or not, and 5% for
    the encoding's colour changes)."""
    from dopplertof.previews import BAR_WIDTH, TABLE_SIZE

    x0, y0, x1, y1 = box
    column = np.asarray(image)[y0 + BAR_WIDTH + 1:y1 - BAR_WIDTH - 1, (x0 + x1) // 2]
    entries = nearest_entries(column, cmap)
    rows = np.arange(len(entries))
    assert np.corrcoef(np.argsort(np.argsort(entries)), rows)[0, 1] < -0.99
    slack = TABLE_SIZE * (2 * BAR_WIDTH / (y1 - y0) + 0.05)
    assert entries[0] > TABLE_SIZE - slack and entries[-1] < slack


def test_every_frame_has_the_maps_and_their_colour_bars_on_one_scale():
    from dopplertof.previews import BAR_WIDTH, colours
    from dopplertof.videos import draw_frames, frame_drawings

    shown = maps()
    titles = [f"frame {k}" for k in range(T)]
    drawings = frame_drawings(shown, titles)
    images = draw_frames(shown, titles)
    assert len(images) == T and len({i.shape for i in images}) == 1
    for drawing, image in zip(drawings, images):
        names = dict(drawing.boxes)
        assert {"panel 0 bar", "panel 1 bar", "panel 2 bar", "title"} <= set(names)
        for k, (_, _, cmap, scale, _) in enumerate(shown):
            x0, y0, x1, y1 = bar_box(drawing, k)
            top, bottom = ((BAR_WIDTH if drawing.extends[k] in ("max", "both") else 0),
                           (BAR_WIDTH if drawing.extends[k] in ("min", "both") else 0))
            inner = (y1 - y0) - top - bottom
            steps = (inner - 1 - np.arange(inner) + 0.5) / inner
            # (the outline covers the first and last rows)
            np.testing.assert_array_equal(image[y0 + top + 1:y1 - bottom - 1, x0 + 1],
                                          colours(cmap, steps[1:-1]))
    # one scale for the whole sequence: each map's scale spans every frame's values
    velocity = shown[1]
    assert velocity[3].vmin == -velocity[3].vmax


def test_without_imageio_ffmpeg_the_video_is_a_gif(tmp_path, monkeypatch):
    from PIL import Image

    from dopplertof import videos

    monkeypatch.setitem(sys.modules, "imageio_ffmpeg", None)  # (import raises ImportError)
    assert videos.mp4_writer() is None and videos.video_extension() == ".gif"
    titles = [f"frame {k}" for k in range(T)]
    images = videos.draw_frames(maps(), titles)
    path = videos.write_video(tmp_path / f"v{videos.video_extension()}", images, 25.0)
    gif = Image.open(path)
    assert gif.format == "GIF" and gif.n_frames == T
    assert gif.size == (images[0].shape[1], images[0].shape[0])
    assert gif.info["duration"] == 40  # ms: 25 frames per second
    drawing = videos.frame_drawings(maps(), titles)[T - 1]
    gif.seek(T - 1)
    assert_bar_runs_down_the_table(gif.convert("RGB"), bar_box(drawing, 0), "viridis")


def test_with_imageio_ffmpeg_the_video_is_an_mp4(tmp_path):
    ffmpeg = pytest.importorskip("imageio_ffmpeg")
    from dopplertof import videos
    from dopplertof.videos import MACRO_BLOCK

    assert videos.video_extension() == ".mp4"
    titles = [f"frame {k}" for k in range(T)]
    images = videos.draw_frames(maps(), titles)
    path = videos.write_video(tmp_path / "v.mp4", images, 30.0)
    reader = ffmpeg.read_frames(path)
    meta = next(reader)
    frames = [np.frombuffer(f, np.uint8).reshape(meta["size"][1], meta["size"][0], 3)
              for f in reader]
    h, w = images[0].shape[:2]
    assert len(frames) == T and meta["fps"] == 30.0
    assert meta["size"] == (MACRO_BLOCK * -(-w // MACRO_BLOCK), MACRO_BLOCK * -(-h // MACRO_BLOCK))
    drawing = videos.frame_drawings(maps(), titles)[2]
    assert_bar_runs_down_the_table(frames[2], bar_box(drawing, 2), "gray")


def test_a_contact_sheet_shows_evenly_spaced_frames_row_by_map(tmp_path):
    from PIL import Image

    from dopplertof.videos import SHEET_FRAMES, contact_sheet, sheet_indices, write_contact_sheet

    assert sheet_indices(3) == [0, 1, 2]
    assert sheet_indices(30) == [0, 4, 8, 12, 17, 21, 25, 29]
    assert len(sheet_indices(100)) == SHEET_FRAMES
    shown = maps()
    labels = {0: "first", 2: "middle", 4: "last"}
    drawing = contact_sheet(shown, labels, "a sheet")
    names = dict(drawing.boxes)
    for r, (_, _, cmap, _, _) in enumerate(shown):
        assert all(f"row {r} panel {k} image" in names for k in range(len(labels)))
        assert f"row {r} panel 3 image" not in names
    path = write_contact_sheet(tmp_path / "sheet.png", shown, labels, "a sheet")
    sheet = Image.open(path).convert("RGB")
    assert np.array_equal(np.asarray(sheet), np.asarray(drawing.image))
    for r, (_, _, cmap, _, _) in enumerate(shown):
        assert_bar_runs_down_the_table(sheet, names[f"row {r} bar"], cmap)
