"""scene/kinds.py: with the common kinds kept alive, a scene of other shapes (and of more
of them) through the same capture compiles no kernel; without them it does. Each case
runs in a process of its own: the kinds must be alive before a process's first scene."""

import json
import os
import subprocess
import sys

import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

#: the translating sphere with a disk, then itself with the sphere a cube and one more
#: disk, of another grey (scenes of other shape types, another count of shapes and BSDFs;
#: a scene of one static shape makes code of its own, Mitsuba's, however many are alive)
PROGRAM = r"""
import json, sys
import drjit as dr
import dopplertof
from dopplertof.scene.kinds import keep_common_alive

dopplertof.set_variant("llvm_ad_rgb")
if sys.argv[1] == "kept":
    keep_common_alive()

def disk(z, grey):
    return (f'<shape type="disk"><transform name="to_world"><translate z="{z}"/></transform>'
            f'<bsdf type="diffuse"><rgb name="reflectance" value="{grey}"/></bsdf></shape>')

sphere = open(sys.argv[2]).read()
text = sphere.replace("</scene>", disk(-1.5, 0.2) + "</scene>")
other = sphere.replace('type="sphere"', 'type="cube"').replace(
    "</scene>", disk(-1.5, 0.3) + disk(-1.7, 0.4) + "</scene>")
assert other.count('type="cube"') == 1 and other != text

def kernels(xml):
    scene = dopplertof.load_string(xml, res=8)
    dr.kernel_history()
    dr.set_flag(dr.JitFlag.KernelHistory, True)
    dopplertof.capture(scene, spp=4, progress=False)
    history = dr.kernel_history()
    dr.set_flag(dr.JitFlag.KernelHistory, False)
    return {k["hash"] for k in history if k["type"] == dr.KernelType.JIT}

first, second = kernels(text), kernels(other)
print(json.dumps([len(first), len(second - first)]))
"""


def _new_kernels(mode: str) -> tuple:
    out = subprocess.run([sys.executable, "-c", PROGRAM, mode,
                          os.path.join(ROOT, "examples", "translating_sphere.xml")],
                         capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stderr[-2000:]
    return tuple(json.loads(out.stdout.strip().splitlines()[-1]))


@pytest.mark.parametrize("mode", ["kept", "not kept"])
def test_a_scene_of_other_shapes_compiles_nothing_with_the_common_kinds_alive(mode):
    launched, new = _new_kernels(mode)
    assert launched > 0
    if mode == "kept":
        assert new == 0, f"{new} kernels of {launched} new"
    else:  # the control: the same scenes without them trace other code
        assert new > 0, "no new kernel without the kinds kept: the test shows nothing"


def test_common_kinds_are_made_once_per_variant_and_released():
    import dopplertof
    from dopplertof.scene import kinds

    dopplertof.set_variant("llvm_ad_rgb")
    try:
        scenes = kinds.keep_common_alive()
        assert kinds.keep_common_alive() is scenes
        assert len(scenes) == len(kinds.COMMON_SHAPES) + len(kinds.COMMON_MESHES)
    finally:
        assert kinds.release("common") == 1
    assert kinds.release("common") == 0
