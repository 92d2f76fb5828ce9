"""Absolute radiometry of a camera preset: photons at each pixel from the illuminator's
power, the scene, the lens and the pixel.

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


def illuminator_xml(preset, view=None) -> str:
    """The camera's illuminator as a Mitsuba light riding with the camera at the preset's
    offset (given in OpenCV's camera axes, x right, y down, z forward; Mitsuba's camera
    has +x left and +y up), of intensity I = P / Omega inside its field ``fov_deg`` and
    none outside (:func:`light_xml`): the scene's only light. ``view``: the
    (tan_x, tan_y) of the view's half extents (:func:`view_tangents`; default the
    preset's). The transform holds the offset only;
    :func:`.scene_view.with_illuminator` appends the camera's placement."""
    from ..scene.scene import CAMERA_ILLUMINATOR_ID

    x, y, z = preset.illuminator["offset_m"]  # OpenCV axes: Mitsuba's are (-x, -y, z)
    view = view or view_tangents(preset.fov_deg, *preset.resolution)
    placement = (f'<transform name="to_world"><translate x="{-x!r}" y="{-y!r}" '
                 f'z="{z!r}"/></transform>')
    return light_xml(radiant_intensity(preset.illuminator),
                     confined_field(preset, view, (x, y, z)), placement,
                     ident=CAMERA_ILLUMINATOR_ID)


def view_tangents(fov_deg: float, width: int, height: int) -> tuple:
    """(tan_x, tan_y): the half extents of a pinhole view of horizontal field of view
    ``fov_deg`` and width x height square pixels, on the plane at unit depth."""
    tan_x = math.tan(math.radians(fov_deg) / 2)
    return tan_x, tan_x * height / width


def confined_field(preset, view, offset=(0.0, 0.0, 0.0)):
    """The illuminator's [horizontal, vertical] full angles (deg) when its light must be
    confined to them, None when it lights every pixel of the view anyway: an illuminator
    at the lens (``offset`` zero) whose rectangle of directions holds the pinhole
    ``view`` ((tan_x, tan_y), :func:`view_tangents`) through an undistorted lens. An
    auto-exposed preset's light is no illuminator: None."""
    if not preset.absolute or preset.illuminator is None:
        return None
    h, v = (float(a) for a in preset.illuminator["fov_deg"])
    covers = (math.tan(math.radians(h) / 2) >= view[0]
              and math.tan(math.radians(v) / 2) >= view[1]
              and not any(offset) and not any(preset.distortion))
    return None if covers else [h, v]


def outside_field(field_deg, K, width: int, height: int, reach: float = 0.5) -> np.ndarray:
    """(H, W) bool: the pixels of a pinhole of intrinsics ``K`` (OpenCV's: pixel (u, v)
    covers [u, u + 1] x [v, v + 1]) whose whole footprint, the square of half side
    ``reach`` pixels about its centre (the reconstruction filter's radius; 1/2 for a
    box), lies outside the rectangle of directions of full angles ``field_deg`` = [h, v]
    about the axis: pixels an illuminator at the lens confined to that field
    (:func:`confined_field`) never lights."""
    K = np.asarray(K, np.float64)
    tan_h, tan_v = (math.tan(math.radians(float(a)) / 2) for a in field_deg)

    def beyond(count: int, centre: float, focal: float, limit: float) -> np.ndarray:
        nearest = (np.abs(np.arange(count) + 0.5 - centre) - reach) / focal
        return nearest > limit

    return (beyond(width, K[0, 2], K[0, 0], tan_h)[None, :]
            | beyond(height, K[1, 2], K[1, 1], tan_v)[:, None])


def light_xml(intensity: float, field_deg, placement: str, ident: str | None = None) -> str:
    """A light of radiant intensity ``intensity`` (W/sr) riding with the camera
    (``placement``: its to_world transform element, the camera's axes): a point light
    when ``field_deg`` is None; else lighting only the directions inside the rectangular
    pyramid of full angles ``field_deg`` = [h, v] about the camera's axis (x
    horizontal), as uniformly.

    The pyramid is a Mitsuba spot light whose beam holds the pyramid's corners (every
    direction inside at full intensity) times a texture that is 1 inside the rectangle
    and 0 outside. The spot evaluates its texture at u = 1/2 + x / (2 z T), v likewise
    with y, T = tan(cutoff). A checkerboard is color0 where frac(a) > 1/2 equals
    frac(b) > 1/2, (a, b) = to_uv (u, v); with a = u/2 + (1 - r)/4 and b = -u/2 +
    (3 - r)/4, r = tan(h/2) / T, both fractions stay at or under 1/2 exactly for
    |x/z| <= tan(h/2) and one of them passes 1/2 outside (a, b in [0, 1) over the
    beam): color0 is the interval of x. The same in v, nested as its color0, gives the
    rectangle."""
    name = f' id="{ident}"' if ident else ""
    if field_deg is None:
        return (f'<emitter type="point"{name}><rgb name="intensity" value="{intensity!r}"/>'
                f'{placement}<animation name="to_world" follow="sensor"/></emitter>')
    tan_h, tan_v = (math.tan(math.radians(a) / 2) for a in field_deg)
    corner = math.degrees(math.atan(math.hypot(tan_h, tan_v)))
    margin = min(1.0, (90.0 - corner) / 2)
    beam, cutoff = corner + margin / 2, corner + margin
    scale = math.tan(math.radians(cutoff))

    def interval(role: str, axis: int, ratio: float, inside: str) -> str:
        rows = [[0.0] * 4 for _ in range(4)]
        rows[0][axis], rows[0][3] = 0.5, 0.25 - 0.25 * ratio
        rows[1][axis], rows[1][3] = -0.5, 0.75 - 0.25 * ratio
        rows[2][2] = rows[3][3] = 1.0
        matrix = " ".join(repr(v) for row in rows for v in row)
        return (f'<texture type="checkerboard" name="{role}">{inside}'
                '<float name="color1" value="0"/><transform name="to_uv">'
                f'<matrix value="{matrix}"/></transform></texture>')

    vertical = interval("color0", 1, tan_v / scale, '<float name="color0" value="1"/>')
    texture = interval("texture", 0, tan_h / scale, vertical)
    return (f'<emitter type="spot"{name}><rgb name="intensity" value="{intensity!r}"/>'
            f'<float name="cutoff_angle" value="{cutoff!r}"/>'
            f'<float name="beam_width" value="{beam!r}"/>{texture}{placement}'
            '<animation name="to_world" follow="sensor"/></emitter>')
