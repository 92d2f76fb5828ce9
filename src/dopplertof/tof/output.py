"""Files of a capture: arrays (.npy), previews (.png), the comparison figure, camera.json
(and pointcloud.ply when asked: :mod:`.geometry`), summary.json (each declared in
:data:`dopplertof.outputs.DTOF`).

All writes are atomic (:mod:`dopplertof.io`), and the folder's files are replaced all or
nothing (the output set "capture" of :func:`dopplertof.io.output_folder`).
"""

from __future__ import annotations

import os

import numpy as np

from .. import file_formats, io, previews
from ..outputs import DTOF, STD_MAPS
from ..previews import NOTHING_HIT

from .. import image_files
from ..capture_summary import SUMMARY_JSON, write_summary
from . import figures
from . import reconstruct as rec
from .geometry import write_camera_files


#: an output folder that cannot be used
OutputFolderError = io.OutputError


def prepare_folder(folder, create: bool = False) -> str:
    """Check (before any work) that ``folder`` can receive the outputs: an existing
    writable folder or one that can be created with its parents (created when
    ``create``); see :func:`dopplertof.io.check_output_folder`."""
    return io.make_output_folder(folder) if create else io.check_output_folder(folder)


def write_result(result, folder, pointcloud: bool = False) -> list:
    """Every file of a capture (see the module docstring) into ``folder`` (created if
    missing), all or nothing (:func:`dopplertof.io.output_folder`: the files of an
    earlier capture there are replaced together, those it wrote and this one does not
    are removed); camera.json, and pointcloud.ply with ``pointcloud``;
    returns the paths in the order written."""
    summary = result.summary
    noisy = " (with sensor noise)" if summary.get("noise") else ""
    recon, truth = result.reconstruction, result.truth
    with io.output_folder(prepare_folder(folder), "capture") as staged:
        path = staged.path
        _write_captures(result, path, noisy)
        _write_velocity_maps(recon, truth, path, noisy)
        _write_depth_maps(recon, truth, summary["depth"], path, noisy)
        figures.write_comparison(path("comparison.png"), result.radiance, recon.velocity,
                                 truth.velocity, f"{os.path.basename(summary['scene'])}: "
                                 f"{summary['spp_per_capture']} spp per capture{noisy}",
                                 note=masked_caption(recon.velocity_reasons, truth))
        if getattr(result, "uncertainty", None) is not None:
            # NaN where the noise-free reconstruction is
            write_uncertainty(result.uncertainty, path, result.noise_free or recon, truth)
        _write_geometry(result, path, pointcloud)
        write_summary(path(SUMMARY_JSON), "dtof", summary)
    return staged.written


def _write_geometry(result, path, pointcloud: bool) -> None:
    """camera.json and (``pointcloud``) pointcloud.ply of a capture."""
    recon = result.reconstruction
    write_camera_files(path, result.geometry, pointcloud, recon.depth, recon.amplitude,
                       recon.velocity, result.truth.velocity)


def masked_caption(reasons, truth, with_truth: bool = False) -> str:
    """The caption of a map's NaN pixels, each by its reason (rec.INVALID_REASONS): a
    weak signal where the pixel-centre ray hits nothing (``truth.body``) is "nothing
    hit"; ``with_truth``: a map that also needs the truth (an error), NaN where that
    ray hits nothing."""
    nothing = truth.body == -2
    weak_nothing = (reasons == rec.WEAK_SIGNAL) & nothing
    counts = {NOTHING_HIT: int(weak_nothing.sum())}
    counts.update(rec.reason_counts(np.where(weak_nothing, rec.VALID, reasons)))
    if with_truth:
        counts[f"{NOTHING_HIT} at the pixel centre"] = int(np.sum(nothing & (reasons == rec.VALID)))
    return image_files.masked_note(counts)


def truth_caption(truth) -> str:
    """The caption of a truth map's NaN pixels (their rays hit nothing)."""
    return image_files.nothing_hit_note(truth.body == -2)


def _write_captures(result, path, noisy: str) -> None:
    """The captures as the camera records them (.npy) with their previews (.png, the
    capture record as metadata), and the radiance image; ``path(name)`` gives a file's
    path in the output folder, ``noisy`` the titles' noise note."""
    for record in result.summary["captures"]:
        name = record["name"]
        if record["kind"] == "radiance":
            continue
        image = result.captures[name]
        file_formats.write_npy(path(f"{name}.npy"), image)
        title = image_files.measurement_title(record["kind"], record["hetero_frequency"],
                                     record["hetero_offset"], record["w_g_MHz"], noisy)
        image_files.write_png(path(f"{name}.png"), image, title=title,
                     label="time-averaged correlation (scene units)", metadata=record)
    file_formats.write_npy(path("radiance.npy"), result.radiance)
    figures.write_radiance(path("radiance.png"), result.radiance,
                           "radiance, time-averaged over the exposure")


def _write_velocity_maps(recon, truth, path, noisy: str) -> None:
    """Reconstructed and true radial velocity, the hit point's velocity along the ray
    (.npy, .png on one symmetric colour scale) and the error's preview."""
    v_limit = figures.truth_limit(truth.velocity, recon.velocity)
    velocity_maps = (
        ("velocity", recon.velocity, f"reconstructed radial velocity{noisy}",
         masked_caption(recon.velocity_reasons, truth)),
        ("velocity_gt", truth.velocity, "ground truth radial velocity (u.n)/(d.n), mid-exposure",
         truth_caption(truth)),
        ("velocity_point", truth.velocity_point, "hit-point velocity along the ray u.d",
         truth_caption(truth)),
    )
    for name, data, title, note in velocity_maps:
        file_formats.write_npy(path(DTOF[name].npy), DTOF[name].array(data))
        figures.write_map(path(f"{name}.png"), data, title, "m/s (+ receding, - approaching)",
                          cmap="RdBu_r", vmax=v_limit, symmetric=True, note=note)
    error = recon.velocity - truth.velocity
    figures.write_map(path("velocity_error.png"), error, "velocity error (reconstructed - truth)",
                      "m/s", cmap="PuOr_r", symmetric=True,
                      note=masked_caption(recon.velocity_reasons, truth, with_truth=True))


def _write_depth_maps(recon, truth, depth_info: dict, path, noisy: str) -> None:
    """Reconstructed and true depth (.npy, .png); ``depth_info``: the summary's depth
    section (wrapped or unwrapped)."""
    wrap_note = (f"wraps every {depth_info['wrap_distance_m']:.3f} m"
                 if depth_info["unwrap_frequency_MHz"] is None else
                 f"unwrapped with {depth_info['unwrap_frequency_MHz']:g} MHz")
    # one colour scale for both maps when they are comparable (unwrapped depth)
    shared = (recon.depth, truth.depth) if depth_info["unwrap_frequency_MHz"] else ()
    finite = np.concatenate([a[np.isfinite(a)] for a in shared] or [np.zeros(0)])
    d_lo = float(np.percentile(finite, 0.5)) if finite.size else None
    d_hi = float(np.percentile(finite, 99.5)) if finite.size else None
    beyond, beyond_note = beyond_range(truth.depth, depth_info)
    for name, data, title, note, marked in (
            ("depth", recon.depth, f"reconstructed depth{noisy}",
             f"{wrap_note}{beyond_note}; {masked_caption(recon.depth_reasons, truth)}",
             beyond),
            ("depth_gt", truth.depth, "ground truth depth, mid-exposure",
             f"not wrapped; {truth_caption(truth)}", None)):
        file_formats.write_npy(path(DTOF[name].npy), DTOF[name].array(data))
        figures.write_map(path(f"{name}.png"), data, title,
                          "m from the camera centre along the ray", cmap="viridis",
                          vmin=d_lo, vmax=d_hi, note=note, marked=marked)


def beyond_range(depth_gt, depth_info: dict):
    """The pixels whose true depth lies beyond the range the camera's depth covers (the
    wrap distance c / (2 f_g), or the unambiguous range when unwrapped): there the
    reconstructed depth is the true one modulo that range. (H, W bool, or None when no
    pixel is; the depth preview's caption for them, '' when none)."""
    limit = depth_info["unambiguous_range_m"]
    with np.errstate(invalid="ignore"):
        beyond = np.asarray(depth_gt, np.float64) >= limit
    count = int(beyond.sum())
    if not count:
        return None, ""
    return beyond, f"; white cross-hatch: {count} px beyond it, shown wrapped"


def write_uncertainty(uncertainty, path, recon=None, truth=None) -> None:
    """The predicted standard deviations (.npy) and their log-scale previews (.png);
    ``path(name)`` gives a file's path in the output folder; ``recon`` and ``truth``
    (the reconstruction whose NaN pixels the maps share) caption the NaN pixels by
    their reasons."""
    for name, data in uncertainty.maps().items():
        title, unit = STD_MAPS[name]
        file_formats.write_npy(path(DTOF[name].npy), DTOF[name].array(data))
        if np.any(np.isfinite(data) & (data > 0)):
            masked = (previews.NO_SIGNAL_NOTE if recon is None else masked_caption(
                getattr(recon, f"{name.split('_')[0]}_reasons"), truth))
            figures.write_log_map(path(f"{name}.png"), data, title, f"{unit} (log scale)",
                                  note=f"{masked}; top colour: also first order fails (inf)")
    for name, data in (uncertainty.capture_std_mc or {}).items():
        file_formats.write_npy(path(f"{name}_std_mc.npy"), data)
