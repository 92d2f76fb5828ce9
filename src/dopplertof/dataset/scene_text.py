"""A sample's description (:mod:`.generate`) as Mitsuba 3 XML with <animation> keyframes:
the text every sample stores, from which it re-renders bitwise."""

from __future__ import annotations

from xml.sax.saxutils import quoteattr

import numpy as np

from .generate import OPENCV_TO_MITSUBA, camera_pose, object_matrix


def _matrix(m) -> str:
    """A <matrix> of a 4x4 array (row-major, shortest exact decimal of each entry)."""
    return f'<matrix value="{" ".join(repr(float(x)) for x in np.asarray(m).ravel())}"/>'


def _keyframes(matrix_at, times: dict) -> str:
    """An <animation name="to_world"> of start, middle and end of the sequence."""
    rows = [f'<transform time="{times[k]!r}">{_matrix(matrix_at(times[k] - times["mid"]))}'
            "</transform>" for k in ("start", "mid", "end")]
    return '<animation name="to_world">' + "".join(rows) + "</animation>"


def bsdf_xml(material: dict) -> str:
    """The material as a two-sided BSDF (a rectangle or a room is seen from either side)."""
    colour = ", ".join(repr(float(c)) for c in material["colour"])
    alpha = repr(float(material.get("roughness", 0.0)))  # none for a diffuse one
    inner = {
        "diffuse": f'<bsdf type="diffuse"><rgb name="reflectance" value="{colour}"/></bsdf>',
        "plastic": (f'<bsdf type="roughplastic"><float name="alpha" value="{alpha}"/>'
                    f'<rgb name="diffuse_reflectance" value="{colour}"/></bsdf>'),
        "conductor": (f'<bsdf type="roughconductor"><float name="alpha" value="{alpha}"/>'
                      f'<rgb name="specular_reflectance" value="{colour}"/></bsdf>'),
    }[material["kind"]]
    return f'<bsdf type="twosided">{inner}</bsdf>'


def _object(obj: dict, times: dict) -> str:
    shape = obj["shape"]
    mesh = ""
    if shape == "mesh":
        shape = "obj" if obj["mesh"].lower().endswith(".obj") else "ply"
        mesh = f"<string name=\"filename\" value={quoteattr(obj['mesh'])}/>"
    motion = _keyframes(lambda tau: object_matrix(obj, tau), times)
    return (f'<shape type="{shape}" id="{obj["id"]}">{mesh}{motion}'
            f'{bsdf_xml(obj["material"])}</shape>')


def _backdrop(backdrop: dict) -> str:
    """The room (a cube around the camera, its back 1 m behind it) or a wall."""
    width, height, depth = backdrop["size_m"]
    grey = {"kind": "diffuse", "colour": [backdrop["albedo"]] * 3}
    if backdrop["kind"] == "none":
        return ""
    m = np.eye(4)
    if backdrop["kind"] == "room":
        m[:3, :3] = np.diag([width / 2, height / 2, depth / 2])
        m[2, 3] = 1.0 - depth / 2
        return f'<shape type="cube" id="backdrop">{_matrix_transform(m)}{bsdf_xml(grey)}</shape>'
    m[:3, :3] = np.diag([width / 2, height / 2, 1.0])
    m[2, 3] = -depth
    return f'<shape type="rectangle" id="backdrop">{_matrix_transform(m)}{bsdf_xml(grey)}</shape>'


def _matrix_transform(m) -> str:
    return f'<transform name="to_world">{_matrix(m)}</transform>'


def _sensor(description: dict, spp: int) -> str:
    camera, times = description["camera"], description["times_s"]
    width, height = description["resolution"]
    to_mitsuba = (lambda tau: camera_pose(camera, tau) @ OPENCV_TO_MITSUBA)
    placement = (_keyframes(to_mitsuba, times) if camera["moving"]
                 else _matrix_transform(to_mitsuba(0.0)))
    return (f'<sensor type="perspective"><float name="fov" value="{description["fov_deg"]!r}"/>'
            '<string name="fov_axis" value="x"/>' + placement
            + f'<float name="shutter_open" value="0"/>'
            f'<float name="shutter_close" value="{times["end"]!r}"/>'
            f'<sampler type="independent"><integer name="sample_count" value="{spp}"/>'
            f'</sampler><film type="hdrfilm"><integer name="width" value="{width}"/>'
            f'<integer name="height" value="{height}"/><rfilter type="box"/></film></sensor>')


def _light(description: dict) -> str:
    """A point light riding with the camera: at its centre, or at the offset (camera
    frame, m) from it; confined to the illuminator's field where the description gives
    one (``field_deg``), and then, at the lens, the camera's illuminator (its id, by
    which a capture reports the pixels wholly outside that field: mask_unlit)."""
    from ..cameras.radiometry import light_xml
    from ..scene.scene import CAMERA_ILLUMINATOR_ID

    light, camera = description["light"], description["camera"]
    offset = np.eye(4)
    if light["placement"] == "offset":
        offset[:3, 3] = light["offset_m"]
    first = description["times_s"]["start"] - description["times_s"]["mid"]
    placed = camera_pose(camera, first if camera["moving"] else 0.0) @ offset
    at_lens = light.get("field_deg") is not None and not offset[:3, 3].any()
    return light_xml(light["intensity"], light.get("field_deg"), _matrix_transform(placed),
                     CAMERA_ILLUMINATOR_ID if at_lens else None)


def scene_xml(description: dict, spp: int, max_depth: int) -> str:
    """The Mitsuba 3 XML of a sample's scene."""
    times = description["times_s"]
    parts = [f'<integrator type="dopplertof"><integer name="max_depth" value="{max_depth}"/>'
             "</integrator>", _sensor(description, spp), _light(description),
             _backdrop(description["backdrop"])]
    parts += [_object(obj, times) for obj in description["objects"]]
    return '<scene version="3.0.0">\n' + "\n".join(p for p in parts if p) + "\n</scene>\n"
