"""Every output, declared once: the files of a capture folder (a D-ToF frame, a camera
preset's frame, an FMCW frame) and the arrays of a dataset sample, each with its name,
unit, type, shape, preview and meaning.

The writers (tof/output.py, cameras/output.py, fmcw/capture.py, dataset/sample.py) write
what is declared here under these names, units and types; the dataset's units and its
camera outputs come from here, and tests/test_outputs.py holds the docs' file tables
(docs/camera.md, docs/cameras.md, docs/fmcw.md, docs/dataset.md) to these declarations.

One quantity has one name. A capture's measured map ``NAME.npy`` is ``camera_NAME`` in a
dataset sample (the camera's velocity is ``camera_radial_velocity`` there, as
``camera_velocity`` is the camera's own motion), the truth ``NAME_gt.npy`` is the
sample's ``NAME`` (``velocity_gt`` keeps its suffix), and the hit point's velocity along
the ray is ``velocity_point`` everywhere. A name that changed is still read under its
old one (:data:`RENAMED`), with a warning naming the new one.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Output:
    """One output: an array (``NAME.npy`` in a capture folder, key ``NAME`` in a dataset
    sample) or another file (``name`` with its extension: ``comparison.png``)."""

    name: str  #: the file stem of an array (or the file name of another file)
    unit: str  #: "m", "m/s", "DN", "1" (a count, a flag, a ratio)...
    dtype: str  #: the type as written: "float32", "bool"... ("" for a file)
    shape: str  #: "(H, W)", "(frames, H, W)"...
    what: str  #: its meaning, one line
    preview: bool = False  #: also written as NAME.png
    when: str = ""  #: the condition it is written under ("" always)
    dataset: str | None = None  #: the same quantity's key in a dataset sample

    @property
    def files(self) -> tuple:
        """The file names it writes in a capture folder."""
        if "." in self.name and not self.dtype:
            return (self.name,)
        return (f"{self.name}.npy",) + ((f"{self.name}.png",) if self.preview else ())

    @property
    def npy(self) -> str:
        return f"{self.name}.npy"

    @property
    def png(self) -> str:
        return f"{self.name}.png"

    def array(self, data) -> np.ndarray:
        """``data`` as written: in the declared dtype (an integer raw frame as it is)."""
        data = np.asarray(data)
        return data if self.dtype in ("", "integer") else data.astype(self.dtype, copy=False)


def _table(*outputs: Output) -> dict:
    return {o.name: o for o in outputs}


def files(table: dict) -> tuple:
    """Every file name of a table of outputs, in its order."""
    return tuple(f for o in table.values() for f in o.files)


#: a capture's geometry and summary, in every kind of capture folder but FMCW's
CAMERA_JSON = Output("camera.json", "", "", "", "the camera's geometry (K, distortion, "
                     "resolution, pose)")
POINTCLOUD_PLY = Output("pointcloud.ply", "", "", "", "the reconstructed depth unprojected "
                        "into the world", when="--pointcloud")
SUMMARY = Output("summary.json", "", "", "", "every setting, the methods, counts and errors")

#: the standard deviations a D-ToF capture predicts with mc_batches: name -> title
STD_MAPS = {f"{q}_std{part}": (f"{q}: predicted standard deviation, {words}",
                               "m/s" if q == "velocity" else "m")
            for part, words in (("_mc", "Monte Carlo"), ("_sensor", "sensor noise"),
                                ("", "total"))
            for q in ("velocity", "depth")}

#: the files of a D-ToF capture (``dopplertof capture``); a capture's own files are
#: named by its record (``homodyne_0.25``, ``heterodyne_0``, ``homodyne_30MHz_0.5``)
DTOF = _table(
    Output("homodyne_<o>", "1", "float32", "(H, W)", "a homodyne capture at offset o",
           preview=True),
    Output("heterodyne_<o>", "1", "float32", "(H, W)", "a heterodyne capture", preview=True),
    Output("homodyne_<F>MHz_<o>", "1", "float32", "(H, W)", "an unwrapping capture",
           preview=True),
    Output("radiance", "1", "float32", "(H, W, 3)", "time-averaged radiance", preview=True),
    Output("velocity", "m/s", "float32", "(H, W)", "reconstructed radial velocity",
           preview=True),
    Output("velocity_gt", "m/s", "float32", "(H, W)", "(u . n) / (d . n) at mid-exposure",
           preview=True),
    Output("velocity_point", "m/s", "float32", "(H, W)", "u . d at mid-exposure",
           preview=True),
    Output("velocity_error.png", "m/s", "", "(H, W)", "reconstructed - truth"),
    Output("depth", "m", "float32", "(H, W)", "reconstructed depth along the ray",
           preview=True),
    Output("depth_gt", "m", "float32", "(H, W)", "true depth along the ray", preview=True),
    Output("comparison.png", "", "", "", "radiance, velocity, truth, error side by side"),
    *(Output(name, unit, "float32", "(H, W)", title, preview=True, when="mc_batches")
      for name, (title, unit) in STD_MAPS.items()),
    Output("<capture>_std_mc", "1", "float32", "(H, W)", "a capture's Monte Carlo standard "
           "error", when="mc_batches"),
    CAMERA_JSON, POINTCLOUD_PLY, SUMMARY)

#: the masks of a camera's frame: name -> (the reconstruction's attribute, meaning)
MASKS = {"mask_saturated": ("saturated", "a tap at the full well or the ADC at an end"),
         "mask_low_confidence": ("low_confidence", "amplitude below min_amplitude_dn, or "
                                 "phase noise above 1 / min_snr"),
         "mask_unwrap_failed": ("unwrap_failed", "a wrong wrap nearly as likely as the best, "
                                "or the frequencies disagree beyond their noise"),
         "mask_out_of_range": ("out_of_range", "nearer than min_range_m (by 3 sigma) or "
                               "beyond max_range_m"),
         "mask_edge": ("edge", "the edge filter: the 3 x 3 neighbourhood's depths span more "
                       "than edge_range_m"),
         "mask_mixed_footprint": ("mixed", "the footprint mixes surfaces during the "
                                  "sequence (from the scene's geometry; NaN in the maps "
                                  "unless kept: --keep-mixed-pixels)"),
         "mask_unlit": ("unlit", "wholly outside the field the camera's illuminator "
                        "lights: none of its light")}

#: a camera preset's frame (``dopplertof capture --camera``); ``dataset``: the key of the
#: same quantity in a dataset sample (its camera outputs ``camera_*`` per split)
CAMERA = _table(
    Output("raw", "DN", "integer", "(frames, H, W)", "the raw frames as the camera delivers "
           "them (the preview: side by side)", preview=True, dataset="raw"),
    Output("raw_ideal", "DN", "float32", "(frames, H, W)", "no noise, no rounding, no "
           "clipping", dataset="raw_ideal"),
    Output("depth", "m", "float32", "(H, W)", "radial range, NaN where masked", preview=True,
           dataset="camera_depth"),
    Output("depth_z", "m", "float32", "(H, W)", "z depth, NaN where masked",
           dataset="camera_depth_z"),
    Output("amplitude", "DN", "float32", "(H, W)", "the smallest of the frequencies' "
           "N-phase amplitudes", preview=True, dataset="camera_amplitude"),
    Output("depth_std", "m", "float32", "(H, W)", "predicted standard deviation of depth",
           dataset="camera_depth_std"),
    Output("depth_gt", "m", "float32", "(H, W)", "true radial range at mid-sequence",
           preview=True, dataset="depth"),
    Output("depth_gt_z", "m", "float32", "(H, W)", "true z depth at mid-sequence",
           dataset="depth_z"),
    Output("depth_error.png", "m", "", "(H, W)", "range error (camera - truth)"),
    *(Output(name, "1", "bool", "(H, W)", meaning, dataset=f"camera_{name}")
      for name, (_, meaning) in MASKS.items()),
    Output("shutter", "1", "float32", "(H, W)", "each pixel's fraction of the integration "
           "(raw and amplitude are in DN of it)", when="sensors with several shutters"),
    Output("velocity", "m/s", "float32", "(H, W)", "the camera's radial velocity",
           preview=True, when="heterodyne presets", dataset="camera_radial_velocity"),
    Output("velocity_gt", "m/s", "float32", "(H, W)", "true radial velocity at "
           "mid-sequence", preview=True, when="heterodyne presets", dataset="velocity_gt"),
    CAMERA_JSON, POINTCLOUD_PLY, SUMMARY)

#: an FMCW frame (``dopplertof fmcw``)
FMCW = _table(
    Output("spectrum", "1", "float32", "(H, W, 2, M)", "mean contribution per bin, up "
           "chirp first"),
    Output("frequencies", "Hz", "float64", "(M,)", "the bins' centres"),
    Output("range", "m", "float64", "(H, W)", "range from the strongest peaks", preview=True),
    Output("velocity", "m/s", "float64", "(H, W)", "radial velocity from the strongest "
           "peaks", preview=True),
    Output("range_gt", "m", "float64", "(H, W)", "true distance along the pixel-centre ray",
           preview=True),
    Output("velocity_point", "m/s", "float64", "(H, W)", "true u . d relative to the camera",
           preview=True),
    Output("points", "1", "float64", "(K, 5)", "the point cloud with velocity"),
    Output("returns_range", "m", "float64", "(H, W, N)", "the N strongest returns' ranges",
           when="returns > 1"),
    Output("returns_velocity", "m/s", "float64", "(H, W, N)", "the N strongest returns' "
           "velocities", when="returns > 1"),
    Output("speckle", "1", "float32", "(H, W, 2, M)", "the coherent sums' spectra",
           when="speckle"),
    Output("ambiguous", "1", "bool", "(H, W)", "beats that fit the folded reading too"),
    SUMMARY)

#: what a camera reports from one split's raw frames, in a dataset sample as
#: ``camera_<name><split suffix>``: name -> unit (CAMERA's where a capture writes it too)
SAMPLE_CAMERA = {
    name: next((o.unit for o in CAMERA.values() if o.dataset == f"camera_{name}"), unit)
    for name, unit in (("depth", None), ("depth_z", None), ("amplitude", None),
                       ("depth_std", None), ("phase", "rad"), ("radial_velocity", None),
                       ("valid", "1"), *((name, None) for name in MASKS))}

#: the key suffix of each split's camera outputs (``camera_depth`` is the full split's,
#: ``camera_depth_ideal`` the ideal one's...)
CAMERA_SPLITS = {"full": "", "ideal": "_ideal", "direct": "_direct"}

#: every array of a dataset sample: key -> unit (a preset without heterodyne frames has
#: no ``camera_radial_velocity*``)
SAMPLE = {
    "raw": "DN", "raw_ideal": "DN", "raw_direct": "DN", "raw_variance": "DN^2",
    "depth": "m", "depth_z": "m", "velocity_gt": "m/s", "velocity_point": "m/s",
    "flow": "px", "scene_flow": "m", "instance": "1", "mask": "1", "normals": "1",
    "albedo": "1", "incidence": "deg", "grazing": "1", "truth_valid": "1", "K": "px",
    "pose": "m", "pose_start": "m", "pose_end": "m",
    "camera_velocity": "m/s", "camera_angular_velocity": "rad/s",
    "camera_frequencies": "MHz",
    **{f"camera_{name}{suffix}": unit for suffix in CAMERA_SPLITS.values()
       for name, unit in SAMPLE_CAMERA.items()},
}

#: the files of a TöRF scan (``dopplertof dataset export --format torf``, a scan per
#: sample): path in the scan's folder -> the sample's keys it is made of
TORF = {
    "tof/0000.npy": ("camera_phase", "camera_amplitude", "camera_valid",
                     "camera_frequencies"),
    "depth/0000.npy": ("depth",),
    "color/0000.npy": ("albedo",),
    "cams/depth_range.npy": ("camera_frequencies",),
    **{f"cams/{kind}_{what}.npy": keys for kind in ("tof", "color")
       for what, keys in (("intrinsics", ("K",)), ("extrinsics", ("pose",)),
                          ("light_extrinsics", ("pose",)))},
}

#: names that changed: (where, old name) -> new name; readers still read the old one
RENAMED = {
    ("dataset", "camera_confidence"): "camera_depth_std",
    ("dataset", "velocity_along_ray"): "velocity_point",
    ("fmcw", "velocity_gt"): "velocity_point",
}


def renamed(where: str, old: str, source: str) -> str:
    """The new name of ``old`` (read from ``source``, a file or folder written before
    the rename), with a FutureWarning saying so."""
    new = RENAMED[(where, old)]
    warnings.warn(f"{source}: {old!r} is now named {new!r} (written before the rename; "
                  f"read as {new!r})", FutureWarning, stacklevel=3)
    return new
