"""A camera's depth accuracy on a flat diffuse wall, as makers specify it (issue 38).

The wall faces the camera at distance d, albedo rho, with no light of its own: the
preset's illuminator lights it (:func:`.capture.with_illuminator`), with ambient light
of the preset's condition or the one given. A crop of ``crop`` x ``crop`` pixels of the
preset's own angular pitch around the optical axis is rendered once; the sensor and the
depth engine then run ``seeds`` times on the same renders (:meth:`CameraResult.read_again`).
Over the centre half of the crop:

* random error: the temporal standard deviation of each pixel's depth (the makers'
  definition, e.g. Microsoft's for the Azure Kinect), median over pixels;
* systematic error: each pixel's temporal mean minus the truth, median over pixels;
* valid: the fraction of (pixel, seed) depths the camera reports.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


@dataclass
class WallAccuracy:
    preset: str
    distance_m: float
    albedo: float
    ambient_uw_cm2_nm: float
    random_m: float  #: median temporal standard deviation (m)
    systematic_m: float  #: median of temporal mean minus truth (m)
    valid: float  #: fraction of reported depths
    predicted_random_m: float  #: median predicted standard deviation (first order)
    seeds: int


def wall_scene_xml(distance: float, albedo: float, fov_deg: float, crop: int,
                   spp: int) -> str:
    """A square diffuse wall (one-sided, facing the camera) at ``distance`` on the optical
    axis of a pinhole camera at the origin looking along +z, no light."""
    size = 4.0 * distance * math.tan(math.radians(fov_deg) / 2) + 1.0
    return f"""<scene version="3.0.0">
<integrator type="dopplertof"><integer name="max_depth" value="2"/></integrator>
<sensor type="perspective"><float name="fov" value="{fov_deg!r}"/>
<string name="fov_axis" value="x"/>
<transform name="to_world"><lookat origin="0,0,0" target="0,0,1" up="0,1,0"/></transform>
<sampler type="independent"><integer name="sample_count" value="{spp}"/></sampler>
<film type="hdrfilm"><integer name="width" value="{crop}"/><integer name="height" value="{crop}"/>
<rfilter type="box"/></film></sensor>
<shape type="rectangle"><transform name="to_world"><scale value="{size / 2!r}"/>
<rotate y="1" angle="180"/><translate z="{distance!r}"/></transform>
<bsdf type="diffuse"><rgb name="reflectance" value="{albedo!r}"/></bsdf></shape>
</scene>
"""


def crop_fov(preset, crop: int) -> float:
    """The horizontal field of view (deg) of ``crop`` pixels of the preset's pitch."""
    half = math.atan(math.tan(math.radians(preset.fov_deg) / 2) * crop / preset.resolution[0])
    return math.degrees(2 * half)


def wall_accuracy(camera, distance: float, albedo: float, ambient: float | None = None,
                  seeds: int = 32, crop: int = 16, spp: int = 16,
                  seed: int = 0) -> WallAccuracy:
    """The random and systematic depth error of ``camera`` (a preset or its name) on a
    wall at ``distance`` (m) of ``albedo``, under ``ambient`` (uW/cm^2/nm; None: the
    preset's condition)."""
    from ..scene import load_string
    from .capture import capture_camera, with_illuminator
    from .preset import CameraPreset, load_preset

    preset = camera if isinstance(camera, CameraPreset) else load_preset(camera)
    text = wall_scene_xml(distance, albedo, crop_fov(preset, crop), crop, spp)
    if preset.absolute:
        text = with_illuminator(text, preset)
    scene = load_string(text, {}, source=f"wall at {distance:g} m")
    result = capture_camera(scene, preset, spp, seed, noise=False, progress=False,
                            ambient_irradiance=ambient if preset.absolute else None)
    centre = slice(crop // 4, crop - crop // 4)
    truth = result.depth_gt[centre, centre]
    depths, predicted = [], []
    for noise_seed in range(seeds):
        _, recon = result.read_again(noise_seed)
        depths.append(recon.depth[centre, centre])
        predicted.append(recon.depth_variance[centre, centre])
    depths = np.stack(depths)
    valid = np.isfinite(depths)
    with np.errstate(all="ignore"):
        counts = valid.sum(axis=0)
        usable = counts >= 2
        std = np.nanstd(np.where(valid, depths, np.nan), axis=0, ddof=1)
        mean = np.nanmean(np.where(valid, depths, np.nan), axis=0)
    nan = float("nan")
    return WallAccuracy(
        preset.name, float(distance), float(albedo),
        float(result.summary["noise"].get("radiometry", {})
              .get("ambient_irradiance_uW_cm2_nm", 0.0)),
        float(np.median(std[usable])) if usable.any() else nan,
        float(np.median((mean - truth)[usable])) if usable.any() else nan,
        float(valid.mean()), float(np.sqrt(np.nanmedian(np.stack(predicted)))), seeds)
