"""A camera preset's frame masks the pixels whose footprint mixes surfaces, as
dopplertof's own capture does (issue 24, section 4 item 1): the same mask
(ground_truth.mixed_footprints over the raw frame sequence), the same reason and the
same option (keep_mixed_pixels / --keep-mixed-pixels). Before, `capture --camera`
reconstructed the starter sphere's silhouette to errors of hundreds of m/s."""

import json
import os

import numpy as np
import pytest

import dopplertof
from dopplertof.cameras.capture import capture_camera
from dopplertof.cameras.scene_view import load_scene_for_camera
from dopplertof.cameras.preset import load_preset
from dopplertof.tof import reconstruct as rec
from dopplertof.tof.capture import CaptureError

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SPHERE = os.path.join(ROOT, "examples", "translating_sphere.xml")
MIXED = rec.reason_name(rec.MIXED_FOOTPRINT)


def sphere_through(preset, keep: bool):
    # direct light only, no sensor noise: every kept pixel's error is Monte Carlo noise
    scene = load_scene_for_camera(SPHERE, preset, (24, 24), {"max_depth": "2"})
    return capture_camera(scene, preset, spp=16, noise=False, progress=False,
                          keep_mixed_pixels=keep)


@pytest.fixture(scope="module")
def frames():
    dopplertof.set_variant("llvm_ad_rgb")
    preset = load_preset("paper-dtof")  # heterodyne frames: depth and velocity
    return {keep: sphere_through(preset, keep) for keep in (False, True)}


def test_silhouette_pixels_are_nan_counted_by_their_reason(frames):
    result = frames[False]
    mixed, recon = result.mixed_footprints, result.reconstruction
    assert 20 < mixed.sum() < 0.2 * mixed.size  # the sphere's silhouette ring at 24 x 24
    assert np.array_equal(recon.mixed, mixed) and np.array_equal(recon.masked, mixed)
    for values in (recon.depth, recon.depth_z, recon.velocity):
        assert np.all(np.isnan(values[mixed])) and np.all(np.isfinite(values[~mixed]))
    summary = result.summary
    assert summary["depth"]["masked_pixels"][MIXED] == int(mixed.sum())
    assert summary["mixed_pixels"] == "NaN" and summary["mixed_footprints"] == int(mixed.sum())
    # kept out of the statistics: the errors are those of the other pixels
    assert summary["errors"]["velocity_m_s"]["pixels"] == int((~mixed).sum())
    error = recon.velocity - result.velocity_gt
    assert np.nanmax(np.abs(error)) < 10.0


def test_keep_mixed_pixels_reconstructs_them_and_says_so(frames):
    kept, masked = frames[True], frames[False]
    mixed = masked.mixed_footprints
    assert np.array_equal(kept.mixed_footprints, mixed)
    assert kept.summary["mixed_pixels"] == "kept"
    assert kept.summary["depth"]["masked_pixels"][MIXED] == 0
    assert np.all(np.isfinite(kept.reconstruction.velocity[mixed]))
    # what the mask removes: silhouettes far from either surface's velocity
    error = kept.reconstruction.velocity - kept.velocity_gt
    assert np.max(np.abs(error[mixed])) > 50.0
    # elsewhere the two frames are the same numbers
    assert np.array_equal(kept.reconstruction.velocity[~mixed],
                          masked.reconstruction.velocity[~mixed])


def test_keep_mixed_pixels_must_be_a_bool():
    preset = load_preset("pmd-argos3d-p320")
    scene = load_scene_for_camera(SPHERE, preset, (4, 4))
    with pytest.raises(CaptureError, match="keep_mixed_pixels must be True or False"):
        capture_camera(scene, preset, spp=1, progress=False, keep_mixed_pixels="yes")


@pytest.mark.parametrize("keep", [False, True])
def test_capture_camera_command_writes_the_mask_and_takes_the_option(tmp_path, capsys,
                                                                     keep):
    from dopplertof.cli import main

    out = tmp_path / "out"
    assert main(["capture", SPHERE, "--camera", "pmd-argos3d-p320", "--res", "12x12",
                 "--spp", "4", "--quiet", "-o", str(out)]
                + (["--keep-mixed-pixels"] if keep else [])) == 0
    printed = capsys.readouterr().out
    mask = np.load(out / "mask_mixed_footprint.npy")
    summary = json.loads((out / "summary.json").read_text())
    assert summary["mixed_pixels"] == ("kept" if keep else "NaN")
    assert summary["mixed_footprints"] > 0
    # the geometry's mask either way (issue 42: kept, it was written all False)
    assert int(mask.sum()) == summary["mixed_footprints"]
    depth = np.load(out / "depth.npy")
    assert np.all(np.isfinite(depth[mask]) if keep else np.isnan(depth[mask]))
    if not keep:  # the printed summary counts them
        assert f"{summary['mixed_footprints']} px {MIXED}" in printed, printed
