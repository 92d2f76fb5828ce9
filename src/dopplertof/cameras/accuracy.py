"""A camera's depth accuracy on a flat diffuse wall, as makers specify it.

The wall faces the camera at distance d, albedo rho, with no light of its own: the
preset's illuminator lights it (:func:`.scene_view.with_illuminator`), with ambient light
of the preset's condition or the one given. A crop of ``crop`` x ``crop`` pixels of the
preset's own angular pitch around the optical axis is rendered once; the sensor and the
depth engine then run ``seeds`` times on the same renders (:meth:`CameraResult.read_again`).
Over the centre half of the crop:

* random error: the temporal standard deviation of each pixel's depth (the makers'
  definition, e.g. Microsoft's for the Azure Kinect), median over pixels;
* systematic error: each pixel's temporal mean minus the truth, median over pixels;
* valid: the fraction of (pixel, seed) depths the camera reports.

:func:`wrong_depths` sorts a capture's depths more than 0.5 m off by cause (the starter
scenes' check of ``benchmarks/camera_accuracy.py --starter``).
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
                   spp: int, angle_deg: float = 0.0) -> str:
    """A square diffuse wall (one-sided, facing the camera) at ``distance`` on the optical
    axis of a pinhole camera at the origin looking along +z, no light; ``angle_deg``:
    turned by that angle about the vertical axis through its centre (the angle between
    the axis and the wall's normal)."""
    size = 4.0 * distance * math.tan(math.radians(fov_deg) / 2) + 1.0
    turn = ""
    if angle_deg:
        size /= math.cos(math.radians(angle_deg))
        turn = f'<rotate y="1" angle="{float(angle_deg)!r}"/>'
    return f"""<scene version="3.0.0">
<integrator type="dopplertof"><integer name="max_depth" value="2"/></integrator>
<sensor type="perspective"><float name="fov" value="{fov_deg!r}"/>
<string name="fov_axis" value="x"/>
<transform name="to_world"><lookat origin="0,0,0" target="0,0,1" up="0,1,0"/></transform>
<sampler type="independent"><integer name="sample_count" value="{spp}"/></sampler>
<film type="hdrfilm"><integer name="width" value="{crop}"/><integer name="height" value="{crop}"/>
<rfilter type="box"/></film></sensor>
<shape type="rectangle"><transform name="to_world"><scale value="{size / 2!r}"/>
<rotate y="1" angle="180"/>{turn}<translate z="{distance!r}"/></transform>
<bsdf type="diffuse"><rgb name="reflectance" value="{albedo!r}"/></bsdf></shape>
</scene>
"""


def crop_fov(preset, crop: int) -> float:
    """The horizontal field of view (deg) of ``crop`` pixels of the preset's pitch."""
    half = math.atan(math.tan(math.radians(preset.fov_deg) / 2) * crop / preset.resolution[0])
    return math.degrees(2 * half)


def centre_half(crop: int) -> slice:
    """The rows (and columns) of a crop's centre half, where the errors are taken."""
    return slice(crop // 4, crop - crop // 4)


def render_wall(preset, distance: float, albedo: float, ambient: float | None = None,
                crop: int = 16, spp: int = 16, seed: int = 0, angle_deg: float = 0.0):
    """The noise-free :class:`CameraResult` of ``preset`` on the wall of
    :func:`wall_scene_xml` (a crop of ``crop`` x ``crop`` of its pixels about the axis),
    lit by its illuminator where absolute, under ``ambient``: read it again with noise
    (:meth:`CameraResult.read_again`) or with other sensor constants
    (:func:`predicted_random`)."""
    from ..scene import load_string
    from .capture import capture_camera
    from .scene_view import with_illuminator
    from .radiometry import view_tangents

    fov = crop_fov(preset, crop)
    text = wall_scene_xml(distance, albedo, fov, crop, spp, angle_deg)
    if preset.absolute:
        text = with_illuminator(text, preset, view_tangents(fov, crop, crop))
    scene = load_string(text, {}, source=f"wall at {distance:g} m")
    return capture_camera(scene, preset, spp, seed, noise=False, progress=False,
                          ambient_irradiance=ambient if preset.absolute else None)


def predicted_random(result, preset=None) -> float:
    """The median over the crop's centre of the predicted depth standard deviation (m,
    first order from the sensor's predicted variance of each raw frame: no noise drawn)
    of a wall's renders (:func:`render_wall`) read through ``preset`` (default the
    rendered one): an absolute preset of another illuminator power scales the photons
    by the ratio of the powers (the renders are linear in the light), one of other
    sensor constants reads them with its own. NaN where no centre pixel is reported."""
    from dataclasses import replace

    light = result.light
    if preset is None:
        preset = result.preset
    elif preset.absolute:
        ratio = preset.illuminator["power_w"] / result.preset.illuminator["power_w"]
        light = replace(light, photons_per_unit=light.photons_per_unit * ratio)
    _, recon = light.read(preset, None, result.mixed_footprints)
    crop = recon.depth.shape[0]
    centre = centre_half(crop)
    variance = np.where(np.isfinite(recon.depth[centre, centre]),
                        recon.depth_variance[centre, centre], np.nan)
    if not np.isfinite(variance).any():
        return float("nan")
    return float(np.sqrt(np.nanmedian(variance)))


def wall_accuracy(camera, distance: float, albedo: float, ambient: float | None = None,
                  seeds: int = 32, crop: int = 16, spp: int = 16,
                  seed: int = 0, angle_deg: float = 0.0) -> WallAccuracy:
    """The random and systematic depth error of ``camera`` (a preset or its name) on a
    wall at ``distance`` (m) of ``albedo``, under ``ambient`` (uW/cm^2/nm; None: the
    preset's condition), turned by ``angle_deg`` (:func:`wall_scene_xml`)."""
    from .preset import CameraPreset, load_preset

    preset = camera if isinstance(camera, CameraPreset) else load_preset(camera)
    result = render_wall(preset, distance, albedo, ambient, crop, spp, seed, angle_deg)
    centre = centre_half(crop)
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


def path_depth(result, scene) -> tuple:
    """((H, W) the depth a co-located camera's phase gives for each pixel's true surface,
    (H, W) bool where the scene's light does not see it): half the path light -> surface
    -> camera, with the scene's brightest point light where it stands for the illuminator
    (the truth's range, and no shadow, where the light is at the camera). The shadow is the
    scene's with the moving bodies at their reference pose."""
    import drjit as dr
    import mitsuba as mi

    from ..scene import bodies
    from ..tof.geometry import pixel_rays

    pose = np.asarray(result.geometry["pose_camera_to_world"], np.float64)
    lights = [(float(np.mean(np.asarray(v["intensity.value"]))), np.ravel(v["position"]))
              for v in (mi.traverse(e) for e in scene.static.emitters()) if "position" in v]
    none = np.zeros(result.depth_gt.shape, bool)
    if not lights:
        return result.depth_gt, none
    light = np.asarray(max(lights, key=lambda x: x[0])[1], np.float64)
    points = (result.depth_gt[..., None] * pixel_rays(result.geometry)) @ pose[:3, :3].T
    points = points + pose[:3, 3]
    to_point = points - light
    reach = np.linalg.norm(to_point, axis=-1)
    seen = np.isfinite(reach)
    direction = to_point[seen] / reach[seen][:, None]
    ray = mi.Ray3f(mi.Point3f(*[np.full(len(direction), c, np.float32) for c in light]),
                   mi.Vector3f(*[np.ascontiguousarray(direction[:, k], np.float32)
                                 for k in range(3)]))
    ray.maxt = mi.Float(np.asarray(reach[seen] * (1 - 1e-3), np.float32))
    shadow = none.copy()
    queries, active = bodies.QUERIES, mi.Bool(True)
    blocked = queries.blocked(scene.static, ray, active)
    for body in getattr(scene, "bodies", ()):  # at their reference pose
        blocked = blocked | queries.blocked(body.scene, ray, active)
    shadow[seen] = np.asarray(dr.detach(blocked), bool)
    return 0.5 * (reach + result.depth_gt), shadow


def wrong_depths(result, scene, preset) -> dict:
    """The reported pixels more than 0.5 m off, by cause: ``aliased`` (a surface beyond the
    preset's unambiguous range R reported a whole number of R nearer: every raw frame the
    same as there), ``bistatic`` (the scene's light is off the camera: right for the path
    via the light, or the surface in its shadow, lit only by longer indirect paths),
    ``other``."""
    from .unwrap import unambiguous_range

    period = unambiguous_range([f * 1e6 for f in preset.frequencies_mhz])
    error = result.depth - result.depth_gt
    wrong = np.isfinite(error) & (np.abs(error) > 0.5)
    expected, shadow = path_depth(result, scene)
    offset = result.depth - expected
    bistatic = wrong & ((np.abs(offset) <= 0.5) | shadow)
    wraps = np.rint(-offset / period)
    aliased = wrong & ~bistatic & (wraps >= 1) & (np.abs(offset + wraps * period) <= 0.5)
    return {"valid": int(np.isfinite(error).sum()), "wrong": int(wrong.sum()),
            "aliased": int(aliased.sum()), "bistatic": int(bistatic.sum()),
            "other": int((wrong & ~aliased & ~bistatic).sum()), "range_m": period}
