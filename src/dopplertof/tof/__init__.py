"""The D-ToF camera: captures, velocity and depth reconstruction, sensor noise, truth.

    import dopplertof
    scene = dopplertof.load_file("scene.xml")
    result = dopplertof.capture(scene, spp=1024, seed=0)
    result.velocity, result.velocity_gt, result.depth, result.summary
    result.write("out/")

See docs/camera.md for the conventions and formulas.
"""

from .capture import (CaptureError, CaptureResult, CaptureSettings, CaptureSpec,
                      Reconstruction, capture, plan_captures)
from .ground_truth import GroundTruth, ground_truth, light_colocation
from .noise import NoiseError, NoiseModel, apply_noise
from .output import OutputFolderError, prepare_folder
from .reconstruct import CaptureModel, ReconstructionError
from .summary import error_stats, format_summary

__all__ = [
    "capture", "CaptureSettings", "CaptureResult", "CaptureSpec", "CaptureError", "Reconstruction",
    "plan_captures", "format_summary", "error_stats", "GroundTruth", "ground_truth",
    "light_colocation", "NoiseModel", "NoiseError", "apply_noise", "CaptureModel",
    "ReconstructionError", "OutputFolderError", "prepare_folder",
]
