"""``dopplertof dataset export DIR --format flat|torf -o OUT``: a
dataset in the layouts networks were trained on. Every field, its source and what of
ours fills it are in docs/dataset.md (*Exports*); the sources were read for their layouts
only (NVlabs/FLAT: README.md, sim/kinect_prepare.py, sim/kinect_spec.py, sim/tof_class.py,
pipe/kinect_init.py; benattal/torf: datasets/tof_dataset.py, datasets/mitsuba_dataset.py,
utils/utils.py, utils/projection_utils.py), no code taken.

OUT is written whole (:func:`dopplertof.io.new_folder`): a folder that exists and is not
empty is refused, and an export that fails leaves nothing. A dataset with failed samples
is refused, naming them, unless ``skip_missing`` (``--skip-missing``) exports the others,
export.json then listing the samples left out.
"""

from __future__ import annotations

import json
import os

import numpy as np

from ..modulation import SPEED_OF_LIGHT
from .config import DatasetError

FORMATS = ("flat", "torf")

# ---- FLAT (Kinect v2) --------------------------------------------------------------------

#: FLAT's Kinect images: (rows, columns) and 9 channels
FLAT_SHAPE = (424, 512)
#: the channels' frequencies in FLAT's order (kinect_spec.py's periods T = 2e4, 1e5,
#: 1.33e4 ps, libfreenect2's order of ab_multiplier_per_frq: the Kinect's 80, 16, 120 MHz),
#: channel 3 k + j being frequency k at phase FLAT_PHASES_DEG[j]
FLAT_FREQUENCIES_MHZ = (80.0, 16.0, 120.0)
FLAT_PHASES_DEG = (0.0, 120.0, 240.0)
#: FLAT's saturation: |value| >= map_max (tof_class.py) is written as +map_max
FLAT_MAP_MAX = 3500
#: FLAT's gt is rendered at 4 x the raw images' resolution (kinect_prepare.py)
FLAT_GT_SCALE = 4
#: FLAT's folders of raw images and the split of ours that fills each: full (multipath
#: and noise), reflection (multipath, no noise), ideal (no multipath, no noise); FLAT's
#: "noise" (noise without multipath) has no split here
FLAT_FOLDERS = {"full": "full", "reflection": "ideal", "ideal": "direct"}


def flat_row_signs(rows: int = FLAT_SHAPE[0]) -> np.ndarray:
    """FLAT's kinect_mask: +1 on row 0, the sign flipping from each row to the next
    except between the two middle rows (rows / 2 - 1 and rows / 2 share theirs)."""
    signs = np.empty(rows)
    sign = 1.0
    for row in range(rows):
        signs[row] = sign
        if row != rows // 2 - 1:
            sign = -sign
    return signs


def flat_channel_frames(preset: dict, source: str) -> list:
    """The raw frame of ours behind each of FLAT's 9 channels, or a DatasetError: the
    export needs the kinect-v2 preset's frames (3 frequencies x 3 phases) at 512 x 424."""
    frames = preset["frames"]
    order = []
    for f_mhz in FLAT_FREQUENCIES_MHZ:
        for phase in FLAT_PHASES_DEG:
            found = [k for k, f in enumerate(frames)
                     if f["frequency_mhz"] == f_mhz and f["phase_deg"] == phase]
            if len(found) != 1:
                raise DatasetError(
                    f"{source}: --format flat needs FLAT's Kinect frames (80, 16, 120 MHz x "
                    f"0, 120, 240 deg: render.camera = 'kinect-v2'); {preset['name']} has "
                    f"{len(frames)} frames, none at {f_mhz:g} MHz, {phase:g} deg")
            order.append(found[0])
    return order


def flat_raw(raw: np.ndarray, order: list, sensor: dict) -> np.ndarray:
    """(424, 512, 9) int32 of FLAT from our (K, H, W) DN: offset removed (the signed
    A - B), rounded to the nearest integer, +FLAT_MAP_MAX where the ADC is at an end or
    |value| >= FLAT_MAP_MAX (saturated), each row times :func:`flat_row_signs`."""
    top = 2 ** int(sensor["adc_bits"]) - 1
    frames = np.asarray(raw, np.float64)[order]
    value = np.rint(frames - sensor["offset_dn"])
    saturated = (frames <= 0) | (frames >= top) | (np.abs(value) >= FLAT_MAP_MAX)
    value = np.where(saturated, FLAT_MAP_MAX, value)
    value = value * flat_row_signs(value.shape[1])[None, :, None]
    return np.ascontiguousarray(np.moveaxis(value, 0, -1)).astype(np.int32)


def flat_gt(depth: np.ndarray) -> np.ndarray:
    """FLAT's gt: float32 radial distance (m) at FLAT_GT_SCALE x the resolution (each of
    our pixel-centre values repeated over its 4 x 4 block), 0 where nothing is hit."""
    block = np.ones((FLAT_GT_SCALE, FLAT_GT_SCALE), np.float32)
    return np.kron(np.nan_to_num(np.asarray(depth, np.float32), nan=0.0), block)


def _write_raw(path: str, array: np.ndarray) -> None:
    """``array``'s bytes as ``tofile`` writes them, a write error naming ``path`` and the
    system's reason (tofile's says only how many bytes were written)."""
    from .. import io

    try:
        with open(path, "wb") as f:
            f.write(np.ascontiguousarray(array).data)
    except OSError as exc:
        raise io.write_error(path, exc) from exc


def flat_name(index: int, frame: int | None = None) -> str:
    """A sample's file name in FLAT's folders (16 characters, as FLAT's scene ids); frame
    ``frame`` of a clip's: the index in 8 digits and the frame in 4."""
    return f"dtof{index:012d}" if frame is None else f"dtof{index:08d}{frame:04d}"


def sample_views(ds, item: int) -> tuple:
    """(sample arrays per frame, attributes) of item ``item``: one frame's, or each
    frame of a clip (:func:`dopplertof.dataset.reader.clip_frame`), with its number."""
    from .reader import clip_frame, clip_frames

    sample, attributes = ds[item], ds.attributes(item)
    frames = clip_frames(attributes)
    if frames == 1:
        return [(None, sample)], attributes
    return [(k, clip_frame(sample, k)) for k in range(frames)], attributes


def _export_flat(ds, staging: str) -> dict:
    """Every sample of ``ds`` into FLAT's kinect/{full,reflection,ideal,gt,list}."""
    root = os.path.join(staging, "kinect")
    for folder in list(FLAT_FOLDERS) + ["gt", "list"]:
        os.makedirs(os.path.join(root, folder))
    names = []
    for item in range(len(ds)):
        views, attributes = sample_views(ds, item)
        preset = attributes["camera_preset"]
        where = f"{ds.folder}: sample {attributes['index']}"
        order = flat_channel_frames(preset, where)
        for frame, sample in views:  # (a clip: each frame a FLAT scene of its own)
            if sample["depth"].shape != FLAT_SHAPE:
                raise DatasetError(
                    f"{where}: --format flat needs the Kinect's {FLAT_SHAPE[1]} x "
                    f"{FLAT_SHAPE[0]} pixels (render.resolution = [512, 424]), got "
                    f"{sample['depth'].shape[1]} x {sample['depth'].shape[0]}")
            name = flat_name(int(attributes["index"]), frame)
            for folder, split in FLAT_FOLDERS.items():
                _write_raw(os.path.join(root, folder, name),
                           flat_raw(sample[f"raw{'' if split == 'full' else '_' + split}"],
                                    order, preset["sensor"]))
            _write_raw(os.path.join(root, "gt", name), flat_gt(sample["depth"]))
            names.append(name)
    with open(os.path.join(root, "list", "all.txt"), "w", encoding="utf-8") as f:
        f.write("".join(f"{n}\n" for n in names))
    return {"files": names, "folders": {k: f"our split {v}" for k, v in FLAT_FOLDERS.items()}}


# ---- TöRF ---------------------------------------------------------------------------------

#: our camera axes (OpenCV: x right, y down, z forward) to TöRF's (NeRF's get_rays_np:
#: x right, y up, z backward)
OPENCV_TO_NERF = np.diag([1.0, -1.0, -1.0, 1.0])


def torf_tof(phase: np.ndarray, amplitude: np.ndarray, valid: np.ndarray) -> np.ndarray:
    """TöRF's ToF image (H, W, 3) float32: (A cos phi, A sin phi, A), 0 where the camera
    reports nothing (``valid`` false: a masked pixel's amplitude is still measured) and
    where a value is NaN."""
    phase, amplitude = np.nan_to_num(phase), np.where(valid, np.nan_to_num(amplitude), 0.0)
    return np.stack([amplitude * np.cos(phase), amplitude * np.sin(phase), amplitude],
                    -1).astype(np.float32)


def torf_extrinsics(pose: np.ndarray) -> np.ndarray:
    """TöRF's extrinsics (world to camera, its axes) of our camera-to-world ``pose``."""
    return np.linalg.inv(np.asarray(pose, np.float64) @ OPENCV_TO_NERF)


def light_pose(pose: np.ndarray, light: dict) -> np.ndarray:
    """The point light's camera-to-world pose: the camera's, moved to the light's offset
    (camera axes; 0 for placement = 'camera')."""
    moved = np.asarray(pose, np.float64).copy()
    offset = light["offset_m"] if light["placement"] == "offset" else [0.0, 0.0, 0.0]
    moved[:3, 3] = moved[:3, 3] + moved[:3, :3] @ np.asarray(offset, np.float64)
    return moved


def _export_torf(ds, staging: str) -> dict:
    """Every sample of ``ds`` as a TöRF scan: sample_<index>/{tof, depth, color}/0000.npy
    and cams/, a view per frame (a clip's frames 0000, 0001...; TöRF's scans are
    sequences)."""
    from .. import file_formats
    from ..outputs import TORF

    scans = []
    for item in range(len(ds)):
        views, attributes = sample_views(ds, item)
        first = views[0][1]
        frequencies = np.asarray(first["camera_frequencies"])
        k = int(np.argmin(frequencies))  # (the longest range)
        scan = os.path.join(staging, f"sample_{int(attributes['index']):08d}")
        for folder in ("tof", "depth", "color", "cams"):
            os.makedirs(os.path.join(scan, folder))
        files = {}
        for view, (_, sample) in enumerate(views):
            files.update({
                f"tof/{view:04d}.npy": torf_tof(sample["camera_phase"][k],
                                                sample["camera_amplitude"],
                                                sample["camera_valid"]),
                f"depth/{view:04d}.npy": np.nan_to_num(sample["depth"]).astype(np.float32),
                f"color/{view:04d}.npy": np.nan_to_num(sample["albedo"]).astype(np.float32)})
        files["cams/depth_range.npy"] = np.float32(SPEED_OF_LIGHT / (frequencies[k] * 1e6))
        light = attributes["description"]["light"]
        extrinsics = np.stack([torf_extrinsics(s["pose"]) for _, s in views])
        lights = np.stack([torf_extrinsics(light_pose(s["pose"], light)) for _, s in views])
        for kind in ("tof", "color"):
            files[f"cams/{kind}_intrinsics.npy"] = np.asarray(first["K"], np.float32)
            files[f"cams/{kind}_extrinsics.npy"] = extrinsics.astype(np.float32)
            files[f"cams/{kind}_light_extrinsics.npy"] = lights.astype(np.float32)
        for name in TORF:  # (a view's file, tof/0000.npy...: every view's)
            folder, base = os.path.split(name)
            for one in ([f"{folder}/{v:04d}.npy" for v in range(len(views))]
                        if base == "0000.npy" else [name]):
                file_formats.write_npy(os.path.join(scan, one), files[one])
        scans.append(os.path.basename(scan))
    return {"scans": scans}


def export_dataset(folder, fmt: str, output, skip_missing: bool = False) -> dict:
    """Write the dataset in ``folder`` in layout ``fmt`` into the new folder ``output``
    (with export.json saying what it holds); returns export.json's content. A dataset
    with failed samples is refused (a DatasetError naming them) unless ``skip_missing``:
    the present ones are exported, export.json's ``missing_samples`` listing the others."""
    from .. import io
    from .reader import Dataset
    from .shards import index_span

    if fmt not in FORMATS:
        raise DatasetError(f"--format must be one of {', '.join(FORMATS)}, got {fmt!r}")
    if output is None:
        raise DatasetError("dataset export needs -o OUT (a new folder)")
    ds = Dataset(folder)
    missing = sorted(int(f["index"]) for f in ds.failed)
    if missing and not skip_missing:
        raise DatasetError(
            f"{os.path.join(ds.folder, 'dataset.json')}: sample(s) {index_span(missing)} of "
            f"{len(ds) + len(missing)} failed ('failed_samples'): a rerun of the dataset "
            f"renders them again; --skip-missing exports the {len(ds)} others")
    with io.new_folder(output) as staging:
        written = (_export_flat if fmt == "flat" else _export_torf)(ds, staging)
        info = {"format": fmt, "dataset": os.path.abspath(ds.folder), "samples": len(ds),
                **({"missing_samples": missing} if missing else {}),
                "documentation": "docs/dataset.md, Exports", **written}
        with open(os.path.join(staging, "export.json"), "w", encoding="utf-8") as f:
            json.dump(info, f, indent=2)
    return info
