"""The light/camera colocation check (issue 24, section 4 item 3): a point or spot light
at the camera is colocated (a spot's position from its to_world), within a tolerance
relative to the scene's size; one offset is not."""

import pytest

import dopplertof
from dopplertof.tof.ground_truth import COLOCATION_FRACTION, light_colocation, scene_size

SCENE = """<scene version="3.0.0">
    <integrator type="dopplertof"/>
    <sensor type="perspective">
        <transform name="to_world"><lookat origin="0, 0, 4" target="0, 0, 0" up="0, 1, 0"/>
        </transform>
        <film type="hdrfilm"><integer name="width" value="4"/><integer name="height" value="4"/>
        </film>
    </sensor>
    {light}
    <shape type="rectangle"><transform name="to_world"><scale value="3"/></transform></shape>
</scene>"""

SPOT = """<emitter type="spot"><transform name="to_world">
    <lookat origin="{x}, 0, 4" target="0, 0, 0" up="0, 1, 0"/></transform></emitter>"""
POINT = """<emitter type="point"><point name="position" x="{x}" y="0" z="4"/></emitter>"""


def colocation(light, x):
    return light_colocation(dopplertof.load_string(SCENE.format(light=light.format(x=x))))


@pytest.mark.parametrize("light", [SPOT, POINT], ids=["spot", "point"])
def test_a_light_at_the_camera_is_colocated_and_one_offset_is_not(light):
    at = colocation(light, 0)
    assert at["colocated"] is True and at["lights"][0]["offset_from_camera_m"] < 1e-6
    off = colocation(light, 0.05)
    assert off["colocated"] is False
    assert off["lights"][0]["offset_from_camera_m"] == pytest.approx(0.05, rel=1e-5)


def test_the_tolerance_is_relative_to_the_scene_size():
    scene = dopplertof.load_string(SCENE.format(light=POINT.format(x=0)))
    size = scene_size(scene)
    assert size == pytest.approx((6**2 + 6**2 + 4**2) ** 0.5, rel=1e-6)
    tolerance = light_colocation(scene)["tolerance_m"]
    assert tolerance == pytest.approx(COLOCATION_FRACTION * size)
    # just inside and just outside the tolerance
    assert colocation(POINT, 0.5 * tolerance)["colocated"] is True
    assert colocation(POINT, 2.0 * tolerance)["colocated"] is False


def test_an_area_light_is_not_colocated():
    area = ('<shape type="sphere"><float name="radius" value="0.01"/>'
            '<point name="center" x="0" y="0" z="4"/><emitter type="area"/></shape>')
    result = colocation(area, 0)
    assert result["colocated"] is False and "offset_from_camera_m" not in result["lights"][0]
