"""Files of a camera frame: raw DN, depth, amplitude, masks, truth, previews, summary
(each declared in :data:`dopplertof.outputs.CAMERA`).

All writes are atomic (:mod:`dopplertof.io`).
"""

from __future__ import annotations

import numpy as np

from .. import file_formats, io

from .. import image_files
from ..capture_summary import SUMMARY_JSON, write_summary
from ..outputs import CAMERA, MASKS
from ..previews import NOTHING_HIT
from ..tof import figures
from ..tof.geometry import write_camera_files
from ..tof.output import prepare_folder


def write_camera_result(result, folder, pointcloud: bool = False) -> list:
    """Every file of a camera frame into ``folder``, all or nothing (the output set
    "capture" of :func:`dopplertof.io.output_folder`, as a ToF capture's: an interrupted
    write leaves the earlier capture whole); returns the paths in order."""
    with io.output_folder(prepare_folder(folder), "capture") as staged:
        _write_camera_files(result, staged.path)
        recon = result.reconstruction
        write_camera_files(staged.path, result.geometry, pointcloud, recon.depth,
                           recon.amplitude, recon.velocity, result.velocity_gt)
    return staged.written


def _write_camera_files(result, path) -> None:
    """The files of :func:`write_camera_result`, each at ``path(name)``."""
    recon, readout, summary = result.reconstruction, result.readout, result.summary
    camera = summary["camera"]["name"]
    arrays = {"raw": readout.raw, "raw_ideal": readout.raw_ideal,
              "depth": recon.depth, "depth_z": recon.depth_z, "amplitude": recon.amplitude,
              "depth_std": np.sqrt(recon.depth_variance), "depth_gt": result.depth_gt,
              "depth_gt_z": result.depth_gt_z}
    if recon.velocity is not None:
        arrays.update(velocity=recon.velocity, velocity_gt=result.velocity_gt)
    arrays.update({name: _mask(result, attribute)
                   for name, (attribute, _) in MASKS.items()})
    if readout.shutter is not None:
        arrays["shutter"] = readout.shutter
    for name, data in arrays.items():
        file_formats.write_npy(path(CAMERA[name].npy), CAMERA[name].array(data))
    _write_previews(result, path, camera)
    write_summary(path(SUMMARY_JSON), "camera", summary)


def _mask(result, attribute: str) -> np.ndarray:
    """The reconstruction's mask ``attribute``; the mixed footprints from the geometry,
    whether masked or kept (kept, the reconstruction's mask is all False and
    the information was lost)."""
    if attribute == "mixed" and result.mixed_footprints is not None:
        return np.asarray(result.mixed_footprints, bool)
    return result.reconstruction.mask(attribute)


def masked_caption(recon, truth=None) -> str:
    """The caption of a camera map's NaN pixels, each mask by its name and count (as the
    summary's masked_pixels: a pixel can be in several), and with ``truth`` (a map that
    needs it) the others where the truth's ray hits nothing."""
    counts = dict(recon.describe()["masked_pixels"])
    if truth is not None:
        # (the depth is NaN where a mask is: those are counted by their masks)
        counts[NOTHING_HIT] = int(np.sum(~np.isfinite(truth) & np.isfinite(recon.depth)))
    return image_files.masked_note(counts)


def _write_previews(result, path, camera: str) -> None:
    """depth, truth, error, amplitude (and velocity) maps and the raw frames' grid."""
    recon = result.reconstruction
    nothing = image_files.nothing_hit_note(~np.isfinite(result.depth_gt))
    finite = np.concatenate([a[np.isfinite(a)] for a in (recon.depth, result.depth_gt)])
    lo, hi = ((float(np.percentile(finite, 0.5)), float(np.percentile(finite, 99.5)))
              if finite.size else (None, None))
    for name, data, title, note in (
            ("depth", recon.depth, f"{camera}: radial range", masked_caption(recon)),
            ("depth_gt", result.depth_gt, "ground truth range, mid-sequence", nothing)):
        figures.write_map(path(f"{name}.png"), data, title, "m along the ray", vmin=lo,
                          vmax=hi, note=note)
    figures.write_map(path("depth_error.png"), recon.depth - result.depth_gt,
                      f"{camera}: range error (camera - truth)", "m", cmap="PuOr_r",
                      symmetric=True, note=masked_caption(recon, result.depth_gt))
    figures.write_map(path("amplitude.png"), recon.amplitude, f"{camera}: amplitude", "DN",
                      cmap="gray")
    if recon.velocity is not None:
        limit = figures.truth_limit(result.velocity_gt, recon.velocity)
        for name, data, note in (("velocity", recon.velocity, masked_caption(recon)),
                                 ("velocity_gt", result.velocity_gt, nothing)):
            figures.write_map(path(f"{name}.png"), data, f"{camera}: {name}",
                              "m/s (+ receding)", cmap="RdBu_r", vmax=limit, symmetric=True,
                              note=note)
    _write_raw_grid(path("raw.png"), result.readout.raw, result.summary["frames"], camera)


def _write_raw_grid(path, raw, records, camera: str) -> None:
    """The raw frames side by side (a row per modulation frequency when each has as many
    frames, else rows of 4), titled by frequency and phase, on one shared DN scale."""
    from ..previews import ColourScale, Panel, draw

    frequencies = [r["w_g_MHz"] for r in records]
    per_frequency = len(raw) // max(1, len(set(frequencies)))
    columns = per_frequency if per_frequency * len(set(frequencies)) == len(raw) else 4
    lo, hi = float(np.min(raw)), float(np.max(raw))
    scale = ColourScale(lo, max(hi, lo + 1))
    panels = [Panel(np.asarray(frame, np.float64), f"{r['w_g_MHz']:g} MHz, {r['phase_deg']:g} deg",
                    "DN", "gray", scale) for frame, r in zip(raw, records)]
    image_files.save_png(path, draw(panels, RAW_FRAME_FIT, title=f"{camera}: raw frames (DN)",
                           columns=min(columns, 6), shared_bar=True))


#: the box (pixels) each raw frame of raw.png is fitted into
RAW_FRAME_FIT = (256, 256)
