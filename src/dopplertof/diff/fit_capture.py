"""A capture folder as the fit reads it (the scene, its parameters, the captures) and
its geometry: each body's interior pixels, the closed-form start, radial velocities.
See :mod:`dopplertof.diff.fit`."""

from __future__ import annotations

import math
import os
import re
from dataclasses import dataclass, field, replace

import numpy as np

from .fit_noise import load_std_maps
from .motion import VelocityMotion

#: captures fitted (their Doppler content is what the velocities change)
FIT_CAPTURES = ("heterodyne_0", "heterodyne_0.25")

#: captures fitted beside them with ``reflectances`` (the heterodyne captures scale
#: with albedo x velocity: the homodyne ones separate the two)
REFLECTANCE_CAPTURES = ("homodyne_0", "homodyne_0.25")


class FitError(ValueError):
    """A capture folder, start or setting that cannot be fitted; the message names it."""


@dataclass
class CaptureData:
    scene: object  #: DopplerScene, loaded as the capture saw it
    base: object  #: RenderParams of the capture
    summary: dict
    captures: dict  #: name -> (H, W) float64
    records: dict  #: name -> summary.json's capture record
    velocity: np.ndarray | None  #: closed-form radial velocity (H, W) or None
    #: name -> (H, W) the capture's Monte Carlo standard deviation, where the folder has
    #: ``<name>_std_mc.npy`` (``dopplertof capture --mc-batches``)
    std_mc: dict = field(default_factory=dict)


# ---- Reading a capture folder ------------------------------------------------------

def _declared_defaults(path: str) -> set:
    with open(path, encoding="utf-8") as f:
        return set(re.findall(r"<default\s+name=\"([^\"]+)\"", f.read()))


def load_capture(folder, defines=None, fitted=FIT_CAPTURES) -> CaptureData:
    """The scene, parameters and captures of a capture folder. The scene is loaded with
    its resolution set to the captures' (through the <default> values it declares:
    res, resx/resy, width/height), the capture's -D values (summary.json's
    ``scene_defines``, written by ``dopplertof capture``) and ``defines`` (-D values of
    the fit, which take precedence)."""
    from ..capture_summary import CaptureFolderError, read_capture
    from ..params import RenderParams
    from ..scene.parameters import parsed

    try:
        summary = read_capture(folder, kind="dtof")
        records, width_height = summary.records, summary.resolution
        scene = _scene_at(summary, width_height, defines)
        params = summary["render_params"]
    except CaptureFolderError as e:
        raise FitError(str(e)) from None
    # (older summaries list the FMCW lidar's fmcw_* settings among them: parsed, unused)
    base = parsed({k: v for k, v in params.items() if v is not None},
                  f"{summary.path} render_params", RenderParams())[0]
    captures = {name: _capture_image(summary, records, name, width_height)
                for name in fitted}
    vpath = summary.file("velocity.npy")
    velocity = np.load(vpath).astype(np.float64) if os.path.isfile(vpath) else None
    return CaptureData(scene, base, summary.data, captures, records, velocity,
                       load_std_maps(summary.folder, fitted))


def _scene_at(summary, width_height, defines):
    """The capture's scene at the captures' resolution with its -D values and the fit's."""
    import dopplertof

    width, height = width_height
    scene_path = summary["scene"]
    if not os.path.isfile(scene_path):
        raise FitError(f"the capture's scene file is not found: {scene_path}")
    declared = _declared_defaults(scene_path)
    overrides = {}
    for name, value in (("res", width), ("resx", width), ("width", width),
                        ("resy", height), ("height", height)):
        if name in declared and (name != "res" or width == height):
            overrides[name] = str(value)
    # the capture's own -D values (summary.json's scene_defines), then the fit's
    overrides.update({str(k): str(v) for k, v in (summary.get("scene_defines") or {}).items()})
    overrides.update(defines or {})
    scene = dopplertof.load_file(scene_path, overrides)
    got = tuple(int(v) for v in scene.sensor.film().crop_size())
    if got != (width, height):
        raise FitError(f"the scene loads at {got[0]}x{got[1]} but the captures are "
                       f"{width}x{height}: pass the capture's -D values")
    if not scene.bodies:
        raise FitError(f"{scene_path} has no moving body: nothing to fit")
    return scene


def _capture_image(summary, records, name: str, width_height):
    """The capture ``name`` of the folder (float64), checked against its summary."""
    width, height = width_height
    path = summary.file(f"{name}.npy")
    if name not in records or not os.path.isfile(path):
        raise FitError(f"{summary.folder} has no {name}.npy: the fit needs the "
                       f"{name.split('_')[0]} captures")
    image = np.load(path).astype(np.float64)
    if image.shape != (height, width):
        raise FitError(f"{path} is {image.shape}, not the summary's {height}x{width}")
    bad = int(np.count_nonzero(~np.isfinite(image)))
    if bad:
        raise FitError(f"{path}: {bad} of {image.size} pixels are NaN or infinite: the "
                       "fit needs finite captures (write the folder again with "
                       "`dopplertof capture`)")
    return image


def check_start_velocity(velocity, where: str) -> list:
    """A start velocity (m/s, 3 finite components below the speed of light), as floats;
    a FitError naming ``where`` (--start's item, start's body) otherwise."""
    from ..modulation import SPEED_OF_LIGHT

    try:
        v = [float(x) for x in np.asarray(velocity, float).reshape(3)]
    except (TypeError, ValueError):
        raise FitError(f"{where}: a start velocity is 3 numbers (m/s), got "
                       f"{velocity!r}") from None
    if not all(map(math.isfinite, v)):
        raise FitError(f"{where}: a start velocity must be finite, got {v}")
    if math.hypot(*v) >= SPEED_OF_LIGHT:
        raise FitError(f"{where}: a start velocity of {math.hypot(*v):.3g} m/s is not below "
                       f"the speed of light ({SPEED_OF_LIGHT:.6g} m/s): give a start of "
                       "the bodies' speeds, or none (the closed form)")
    return v


def _capture_params(data: CaptureData, name: str):
    from ..tof.capture import CaptureSpec

    r = data.records[name]
    return CaptureSpec(name, r["kind"], r["w_g_MHz"], r["hetero_frequency"],
                       r["hetero_offset"]).params(data.base)


# ---- Geometry and the closed-form start --------------------------------------------

def _scene_with(scene, motions):
    return replace(scene, bodies=tuple(replace(b, motion=m, _swept={})
                                       for b, m in zip(scene.bodies, motions)))


def _truth(scene, motions, params):
    from ..tof.ground_truth import ground_truth

    return ground_truth(_scene_with(scene, [_plain(m) for m in motions]), params)


def _plain(m: VelocityMotion) -> VelocityMotion:
    return VelocityMotion(m.pivot, [float(x) for x in m.velocity],
                          [float(x) for x in m.angular_velocity], m.t_ref, m.reference,
                          m.interval, m.base)


#: neighbouring normals further apart than this (cosine) mark a crease between faces
#: (a box's edge: 90 degrees); curvature between neighbouring pixels stays below it
CREASE_COS = math.cos(math.radians(45.0))


def interior(truth, k: int, reach: int = 1) -> np.ndarray:
    """Pixels of body k whose footprint sees body k only, in one piece: every pixel
    within ``reach`` (the film filter's radius, at least 1) hits body k (not its
    silhouette against another body, a static surface or the background, whose motion
    the derivatives do not model), and no two neighbouring normals there meet at a
    crease (:data:`CREASE_COS`: a box's edge, whose integrand jumps). Curved faces,
    and meshes with smooth normals, are kept: their integrand is continuous."""
    on = truth.body == k
    n = np.nan_to_num(truth.normal)
    inner = on.copy()
    for dy in range(-reach, reach + 1):
        for dx in range(-reach, reach + 1):
            inner &= np.roll(np.roll(on, dy, 0), dx, 1)
            if max(abs(dy), abs(dx)) == 1:  # a crease: between the pixel and a neighbour
                shifted = np.roll(np.roll(n, dy, 0), dx, 1)
                inner &= np.sum(n * shifted, -1) > CREASE_COS
    inner[:reach, :] = inner[-reach:, :] = False  # the image's border: footprint unknown
    inner[:, :reach] = inner[:, -reach:] = False
    return inner


def closed_form_velocity(truth, radial, mask) -> np.ndarray:
    """The linear velocity u whose radial velocities (u . n) / (d . n) best match
    ``radial`` on ``mask`` (least squares; minimum norm where faces leave it open)."""
    ok = mask & np.isfinite(radial)
    if ok.sum() < 3:
        return np.zeros(3)
    n, d = truth.normal[ok], truth.direction[ok]
    rhs = radial[ok] * np.sum(d * n, -1)
    u, *_ = np.linalg.lstsq(n, rhs, rcond=1e-3)
    return u


def radial_velocity(truth, k: int):
    """summary.json's velocity_gt_median_m_s: the median radial velocity of body k's
    pixels at mid-exposure."""
    on = truth.body == k
    return float(np.median(truth.velocity[on])) if on.any() else None
