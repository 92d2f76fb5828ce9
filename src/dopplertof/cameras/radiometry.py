"""Absolute radiometry of a camera preset: photons at each pixel from the illuminator's
power, the scene, the lens and the pixel (issue 38).

The renderer gives radiance in the units of the scene's light: a point light of
radiant intensity I_s (W/sr) makes a diffuse wall of albedo rho at distance d facing it
L = rho I_s / (pi d^2). Through an absolute preset (``sensor.auto_exposure = false``)
the scene's point and spot lights stand for the camera's illuminator: the illuminator's
mean optical power P spread uniformly over its field (a rectangle of full angles
h x v, solid angle Omega = 4 asin(sin(h/2) sin(v/2))) gives I = P / Omega, and the
rendered radiance is rescaled by I / I_s (the brightest scene light emits I; a scene
without lights gets the illuminator at the preset's offset, riding with the camera:
:func:`illuminator_xml`).

A lens of f-number N and transmission tau images radiance L onto the pixel as the
irradiance E = pi tau L cos^4(theta) / (4 N^2) (the camera equation, theta the pixel's
angle off the axis; the (1 + m)^2 of close-up imaging left out, under 0.1% beyond
5 cm at these focal lengths). A pixel of pitch p, binned b x b, with fill factor F
collects E F (b p)^2 watts, E F (b p)^2 lambda / (h c) photons per second.

Ambient light of spectral irradiance E_a (uW/cm^2/nm) on a diffuse surface of albedo
rho, through a band-pass filter of width dlambda, is the radiance rho E_a dlambda / pi:
unmodulated photons that both taps share (:mod:`.sensor`).
"""

from __future__ import annotations

import math

import numpy as np

from ..modulation import SPEED_OF_LIGHT

#: Planck's constant (J s), exact in the SI
PLANCK = 6.62607015e-34
#: uW/cm^2/nm in W/m^2/nm
UW_PER_CM2 = 1e-2

#: spectral irradiance of sunlight at 850 nm: ASTM G173-03 reference spectra, global
#: tilt (AM1.5, 37 deg tilted surface), 0.9 W/m^2/nm at 850 nm = 90 uW/cm^2/nm (read
#: from the NREL table of the standard, rounded; direct + circumsolar: 0.8)
SUNLIGHT_850NM_UW_CM2_NM = 90.0


def photon_energy(wavelength_nm: float) -> float:
    """h c / lambda (J)."""
    return PLANCK * SPEED_OF_LIGHT / (wavelength_nm * 1e-9)


def rectangle_solid_angle(h_deg: float, v_deg: float) -> float:
    """The solid angle (sr) of a rectangular pyramid of full angles h x v."""
    return 4.0 * math.asin(math.sin(math.radians(h_deg) / 2) * math.sin(math.radians(v_deg) / 2))


def radiant_intensity(illuminator: dict) -> float:
    """P / Omega (W/sr): the illuminator's power spread uniformly over its field."""
    return illuminator["power_w"] / rectangle_solid_angle(*illuminator["fov_deg"])


def collection(preset) -> float:
    """Watts on a pixel at the optical axis per unit of scene radiance (W/m^2/sr):
    pi tau F (b p)^2 / (4 N^2)  (m^2 sr)."""
    optics = preset.optics
    side = optics["binning"] * preset.pixel_pitch_um * 1e-6
    return (math.pi * optics["transmission"] * optics["fill_factor"] * side**2
            / (4.0 * optics["f_number"] ** 2))


def photons_per_unit(preset, scene_intensity: float, g_0: float) -> float:
    """K: photons per second at an on-axis pixel per unit of the rendered unmodulated
    value g0 R, when the scene's light of intensity ``scene_intensity`` (W/sr) stands for
    the illuminator: the rendered radiance R is in units of I_s, the light's mean
    emission is g0 I_s, so the physical radiance is g0 R I / (g0 I_s): K = I / (g0 I_s) times the
    photons per watt-steradian of :func:`collection`."""
    if not scene_intensity > 0:
        raise ValueError("the scene's light has no intensity")
    scale = radiant_intensity(preset.illuminator) / (g_0 * scene_intensity)
    return scale * collection(preset) / photon_energy(preset.illuminator["wavelength_nm"])


def ambient_photon_rate(preset, irradiance_uw_cm2_nm: float, albedo) -> np.ndarray:
    """Photons per second at a pixel from ambient light reflected by a diffuse surface of
    ``albedo`` (array), through the band-pass filter (on-axis; times cos^4 off it)."""
    radiance = (np.asarray(albedo, np.float64) * irradiance_uw_cm2_nm * UW_PER_CM2
                * preset.optics["filter_width_nm"] / math.pi)
    return radiance * collection(preset) / photon_energy(preset.illuminator["wavelength_nm"])


def illuminator_xml(preset) -> str:
    """The camera's illuminator as a Mitsuba point light riding with the camera at the
    preset's offset (given in OpenCV's camera axes, x right, y down, z forward; Mitsuba's
    camera has +x left and +y up), of intensity I = P / Omega: the scene's only light.
    The transform holds the offset only; :func:`..capture.with_illuminator` appends the
    camera's placement."""
    from ..scene.scene import CAMERA_ILLUMINATOR_ID

    x, y, z = preset.illuminator["offset_m"]  # OpenCV axes: Mitsuba's are (-x, -y, z)
    intensity = radiant_intensity(preset.illuminator)
    return (f'<emitter type="point" id="{CAMERA_ILLUMINATOR_ID}"><rgb name="intensity" '
            f'value="{intensity!r}"/><transform name="to_world"><translate x="{-x!r}" '
            f'y="{-y!r}" z="{z!r}"/></transform><animation name="to_world" '
            f'follow="sensor"/></emitter>')
