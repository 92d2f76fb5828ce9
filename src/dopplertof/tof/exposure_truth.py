"""The truth over the exposure, not only at its middle.

``velocity_gt.npy`` is the radial velocity at mid-exposure along each pixel-centre ray
(:mod:`.ground_truth`). A sinusoidal heterodyne capture with h beat periods per exposure
measures instead, to first order in the Doppler phase, the exposure's weighted mean

    v_w = (1/T) integral_0^T v(t) (1 - cos(2 pi h t / T)) dt

(the combined ratio is proportional to the integral of the path length L(t) against
sin(2 pi h t / T); integrated by parts, to that of L'(t) = 2 v(t) against
1 - cos(2 pi h t / T): for h = 1 a Hann window centred on mid-exposure). The two agree
while v(t) is linear over the exposure; they do not where a pixel's ray sees the surface
under it change during the exposure, as the facets of a spinning mesh pass by.

:func:`ray_histories` traces each pixel's fixed rays (its centre, or an F x F grid over
its footprint) at K times of the exposure: distance, radial velocity, brightness.
:func:`weighted_velocity` is v_w per pixel; :func:`history_velocity` what the camera's
two offsets reconstruct from those histories (captures by quadrature of the modulation's
correlation, summed over the footprint's rays, brightness included or not): a
deterministic pixel, whose difference from a render is Monte Carlo noise only.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from . import reconstruct as rec
from .ground_truth import mid_exposure, radial_velocity_at, trace_pixels


@dataclass
class RayHistories:
    """Per time k, footprint ray f and pixel (y, x): arrays (K, F, H, W)."""

    times: np.ndarray  #: (K,) absolute times (midpoints of K equal parts of the exposure)
    start: float  #: the exposure's start (s)
    exposure: float  #: T (s)
    distance: np.ndarray  #: m from the camera centre along the fixed ray (NaN: no hit)
    velocity: np.ndarray  #: radial velocity ds/dt (m/s; NaN: no hit)
    brightness: np.ndarray  #: |n_s . d| / s^2: a diffuse surface under a colocated light
    body: np.ndarray  #: the body hit (index, -1 static, -2 nothing)


def ray_histories(scene, params=None, samples: int = 32, footprint: int = 1) -> RayHistories:
    """Each pixel's fixed rays traced at ``samples`` times over the exposure: its centre
    (``footprint`` 1) or a footprint x footprint grid over the pixel (a box filter's
    footprint). A static camera only (its rays do not move)."""
    if scene.sensor_motion is not None:
        raise ValueError("ray_histories needs a static camera: a moving camera's rays move")
    start, _, end = mid_exposure(scene, params)
    exposure = end - start
    times = start + (np.arange(samples) + 0.5) / samples * exposure
    offsets = (np.arange(footprint) + 0.5) / footprint - 0.5
    nudges = [(a, b) for b in offsets for a in offsets]
    fields = {"distance": [], "velocity": [], "brightness": [], "body": []}
    for t in times:
        rows = {key: [] for key in fields}
        for nudge in nudges:
            hit = trace_pixels(scene, t, params, nudge)
            rows["distance"].append(hit["depth"])
            rows["velocity"].append(radial_velocity_at(scene, hit, t, exposure))
            with np.errstate(divide="ignore", invalid="ignore"):
                cosine = np.abs(np.sum(hit["shading_normal"] * hit["direction"], axis=-1))
                rows["brightness"].append(np.where(hit["body"] > -2,
                                                   cosine / hit["depth"] ** 2, 0.0))
            rows["body"].append(hit["body"])
        for key in fields:
            fields[key].append(np.stack(rows[key]))
    return RayHistories(times, start, exposure,
                        **{key: np.stack(value) for key, value in fields.items()})


def exposure_weights(histories: RayHistories, hetero_frequency: float) -> np.ndarray:
    """(K,) 1 - cos(2 pi h t / T) at the histories' times (t from the exposure's start):
    the weights of the radial velocity in a sinusoidal heterodyne capture's ratio."""
    phase = 2 * math.pi * hetero_frequency * (histories.times - histories.start)
    return 1.0 - np.cos(phase / histories.exposure)


def weighted_velocity(histories: RayHistories, hetero_frequency: float = 1.0) -> np.ndarray:
    """(H, W) v_w: the radial velocity's mean over the exposure with the weights of
    :func:`exposure_weights`, averaged over the footprint's rays (NaN where a ray hits
    nothing at some time)."""
    w = exposure_weights(histories, hetero_frequency)[:, None, None, None]
    per_ray = np.sum(w * histories.velocity, axis=0) / np.sum(w)
    return per_ray.mean(axis=0)


def history_velocity(histories: RayHistories, model: rec.CaptureModel,
                     brightness: bool = True) -> np.ndarray:
    """(H, W) the velocity the camera's offsets 0 and 1/4 reconstruct (exact inversion,
    no calibration) from captures computed from the histories: per ray and time the
    phase omega_g 2 s(t) / c, the beat omega_d t and the brightness (constant with
    ``brightness`` False), summed over the times and the footprint's rays."""
    phase = 2 * model.omega_g * histories.distance / rec.SPEED_OF_LIGHT
    phase = np.where(np.isfinite(phase), phase, 0.0)
    b = histories.brightness if brightness else (histories.body > -2).astype(np.float64)
    beat = (model.omega_d * (histories.times - histories.start))[:, None, None, None]
    H, E = [], []
    for offset in rec.VELOCITY_OFFSETS:
        theta = phase + 2 * math.pi * offset
        H.append(np.sum(b * rec.correlation(model.waveform, theta), axis=(0, 1)))
        E.append(np.sum(b * rec.correlation(model.waveform, theta + beat), axis=(0, 1)))
    return rec.velocity_from_ratio(rec.combined_ratio(H, E)[0], model)
