"""Pixels whose footprint mixes surfaces (issue 24, section 4 item 1): NaN with their own
reason, counted, kept out of every statistic; and the previews caption each masked kind
by its own reason (item 2)."""

import os

import numpy as np
import pytest

import dopplertof
from dopplertof.tof import format_summary
from dopplertof.tof import reconstruct as rec
from dopplertof.tof.capture import CaptureError
from dopplertof.tof.ground_truth import ground_truth, mixed_footprints

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SPHERE = os.path.join(ROOT, "examples", "translating_sphere.xml")


def sphere(**defines):
    # direct light only: no multipath on the wall, so every kept pixel's error is noise
    return dopplertof.load_file(SPHERE, {"res": 24, "spp": 16, "max_depth": 2, **defines})


@pytest.fixture(scope="module")
def frames():
    dopplertof.set_variant("llvm_ad_rgb")
    return {keep: dopplertof.capture(sphere(), keep_mixed_pixels=keep) for keep in (False, True)}


def test_silhouette_pixels_are_nan_with_their_own_reason_and_counted(frames):
    result = frames[False]
    mixed = result.truth.mixed
    assert mixed.sum() > 20  # the sphere's silhouette ring at 24 x 24
    assert np.all(result.reconstruction.velocity_reasons[mixed] == rec.MIXED_FOOTPRINT)
    assert np.all(np.isnan(result.velocity[mixed])) and np.all(np.isnan(result.depth[mixed]))
    name = rec.reason_name(rec.MIXED_FOOTPRINT)
    assert result.summary["velocity"]["nan_pixels"] == {name: int(mixed.sum())}
    assert result.summary["depth"]["nan_pixels"] == {name: int(mixed.sum())}
    assert result.summary["velocity"]["mixed_pixels"] == "NaN"
    assert name in format_summary(result.summary)


def test_kept_pixels_are_within_noise_of_the_truth_and_the_mean_error_is_small(frames):
    result = frames[False]
    error = result.velocity - result.truth.velocity
    kept = np.isfinite(error)
    # 16 spp: the noise of a kept pixel stays under 2 m/s; a silhouette reads hundreds
    assert kept.sum() > 0.9 * error.size - result.truth.mixed.sum()
    assert np.max(np.abs(error[kept])) < 4.0
    ball = result.summary["bodies"][0]
    assert abs(ball["velocity_error_m_s"]["mean_signed"]) < 0.5
    assert ball["velocity_error_m_s"]["p95_abs"] < 4.0


def test_keep_mixed_pixels_reconstructs_them_and_says_so(frames):
    kept, masked = frames[True], frames[False]
    mixed = masked.truth.mixed
    assert np.array_equal(kept.truth.mixed, mixed)
    assert kept.summary["velocity"]["mixed_pixels"] == "kept"
    assert not kept.summary["velocity"]["nan_pixels"]
    assert np.all(np.isfinite(kept.velocity[mixed]))
    # what the mask removes: silhouettes far from any surface's velocity
    assert np.max(np.abs(kept.velocity[mixed] - kept.truth.velocity[mixed])) > 50.0
    # outside the mask the two reconstructions are the same numbers
    assert np.array_equal(kept.velocity[~mixed], masked.velocity[~mixed])


def test_the_footprint_mask_is_the_silhouette_and_spares_the_interiors():
    scene = sphere()
    mixed = mixed_footprints(scene)
    body = ground_truth(scene).body
    # an edge between two pixel centres of different surfaces crosses one of the footprints
    for axis in (0, 1):
        a, b = body, np.roll(body, -1, axis)
        differ = a != b
        differ[(slice(-1, None) if axis == 0 else slice(None)),
               (slice(-1, None) if axis == 1 else slice(None))] = False
        assert np.all((mixed | np.roll(mixed, -1, axis))[differ])
    # a pixel whose 3 x 3 neighbours all see its surface has a footprint of one surface
    uniform = np.ones(body.shape, bool)
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            uniform &= np.roll(np.roll(body, dy, 0), dx, 1) == body
    uniform[[0, -1], :] = uniform[:, [0, -1]] = False
    assert not np.any(mixed & uniform)


def test_keep_mixed_pixels_must_be_a_bool():
    with pytest.raises(CaptureError, match="keep_mixed_pixels"):
        dopplertof.capture(sphere(res=4, spp=4), keep_mixed_pixels="yes")


def test_previews_caption_each_masked_kind_by_its_own_reason(frames):
    from types import SimpleNamespace

    from dopplertof.tof.output import masked_caption, truth_caption

    result = frames[False]
    caption = masked_caption(result.reconstruction.velocity_reasons, result.truth)
    assert caption == f"hatched magenta: NaN, {int(result.truth.mixed.sum())} px footprint " \
                      "mixes surfaces"
    assert truth_caption(result.truth) == "no NaN pixels"  # the wall fills the view
    # one pixel of every kind, a weak signal where the ray hits nothing included
    body = np.array([[-2, 0, 0, 0, 0, 0]])
    reasons = np.array([[rec.WEAK_SIGNAL, rec.WEAK_SIGNAL, rec.OUT_OF_RANGE, rec.SATURATED,
                         rec.TOO_UNCERTAIN, rec.MIXED_FOOTPRINT]])
    caption = masked_caption(reasons, SimpleNamespace(body=body))
    for why in ("nothing hit", "homodyne signal too weak", "heterodyne/homodyne ratio outside",
                "a tap saturated", "predicted standard deviation above the trust limit",
                "footprint mixes surfaces"):
        assert f"1 px {why}" in caption, (why, caption)
    assert "nothing hit or signal too weak" not in caption


def test_camera_previews_caption_unwrap_failures_as_such():
    from types import SimpleNamespace

    from dopplertof.cameras.output import masked_caption

    mask = np.zeros((2, 3), bool)
    failed = mask.copy()
    failed[0, :2] = True
    recon = SimpleNamespace(saturated=mask, low_confidence=mask, unwrap_failed=failed,
                            depth=np.zeros((2, 3)))
    recon.describe = lambda: {"masked_pixels": {"saturated": 0, "low confidence": 0,
                                                "unwrapping failed": 2}}
    truth = np.array([[1.0, 1.0, 1.0], [np.nan, 1.0, 1.0]])
    assert masked_caption(recon) == "hatched magenta: NaN, 2 px unwrapping failed"
    assert masked_caption(recon, truth) == ("hatched magenta: NaN, 2 px unwrapping failed, "
                                            "1 px nothing hit")


def test_an_occluding_edge_is_a_depth_jump_and_a_grazing_plane_is_not():
    from dopplertof.tof.ground_truth import FOOTPRINT_DEPTH_JUMP, _depth_jump

    ramp = 5.0 * (1 + 0.5 * FOOTPRINT_DEPTH_JUMP) ** np.arange(5.0)  # steep but continuous
    grazing = np.broadcast_to(ramp, (5, 5))
    edge = np.full((5, 5), 2.0)
    edge[:, 3:] = 2.0 * (1 + 2 * FOOTPRINT_DEPTH_JUMP)  # a box's edge in front of a wall
    missed = edge.copy()
    missed[:, 3:] = np.nan  # nothing hit there: the bodies' test's business, not a jump
    assert _depth_jump(np.stack([grazing, edge, edge.T, missed])).tolist() == \
        [False, True, True, False]


def test_the_command_line_keeps_them_on_request(tmp_path, capsys):
    import json

    from dopplertof.cli import main

    for flag, expected in (([], "NaN"), (["--keep-mixed-pixels"], "kept")):
        out = tmp_path / expected
        assert main(["capture", SPHERE, "-D", "res=8", "--spp", "4", "--quiet", "-o",
                     str(out), *flag]) == 0
        summary = json.loads((out / "summary.json").read_text())
        assert summary["velocity"]["mixed_pixels"] == expected
    assert "footprint mixes surfaces" in capsys.readouterr().out


def test_the_footprints_traced_a_row_at_a_time_are_the_same(monkeypatch):
    import sys

    gt = sys.modules["dopplertof.tof.ground_truth"]  # (the package's name is the function)
    scene = sphere(res=12)
    whole = mixed_footprints(scene)
    monkeypatch.setattr(gt, "FOOTPRINT_LANES", 1)  # (one row of pixels per kernel)
    assert np.array_equal(mixed_footprints(scene), whole) and whole.any()
