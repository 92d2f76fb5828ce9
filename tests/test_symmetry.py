"""Axes of rotational symmetry of a body (diff/symmetry.py, issue 42, 2026-12-03): the
spins a D-ToF capture cannot see."""

import os

import numpy as np
import pytest

import dopplertof

ROOT = os.path.join(os.path.dirname(__file__), "..")


@pytest.fixture(scope="module", autouse=True)
def variant():
    dopplertof.set_variant()


def _bodies(name, defines=None):
    from dopplertof.scene import load_file

    scene = load_file(os.path.join(ROOT, "examples", name), defines or {"res": "16"})
    return {body.names[0]: body for body in scene.bodies}


def _axes(body, t=0.0):
    from dopplertof.diff.motion import VelocityMotion
    from dopplertof.diff.symmetry import symmetry_axes

    motion = VelocityMotion.from_motion(body.motion, 0.0, 1e-3, t_ref=t)
    return symmetry_axes(body, body.motion.relative_matrix(t), motion.pivot)


def test_a_sphere_is_symmetric_about_every_axis_and_a_cube_about_none():
    assert len(_axes(_bodies("translating_sphere.xml")["ball"])) == 3
    assert _axes(_bodies("rotating_cube.xml")["cube"]) == []


def test_a_torus_is_symmetric_about_its_axis_only_and_a_lumpy_blob_about_none():
    """examples/user_meshes.xml's torus: its file's y axis turned 60 degrees about x, so
    (0, cos 60, sin 60) in the world; a mesh of 48 x 12 quads."""
    bodies = _bodies("user_meshes.xml")
    axes = _axes(bodies["torus"])
    assert len(axes) == 1
    assert abs(axes[0] @ [0.0, 0.5, np.sqrt(3) / 2]) == pytest.approx(1.0, abs=1e-5)
    assert _axes(bodies["blob"]) == []


def test_a_turn_about_an_axis_off_the_pivot_is_no_symmetry():
    """The torus's axis through a point 0.3 m beside its centre: turning about it moves
    the surface."""
    from dopplertof.diff.symmetry import symmetry_axes

    torus = _bodies("user_meshes.xml")["torus"]
    matrix = torus.motion.relative_matrix(0.0)
    centre = torus.motion.world_matrix(0.0)[:3, 3]
    assert symmetry_axes(torus, matrix, centre + [0.3, 0.0, 0.0]) == []


def test_the_spin_along_a_symmetry_axis_is_left_out_of_the_errors_and_warned():
    from dopplertof.diff.symmetry import _errors_across

    axis = np.array([0.0, 0.5, np.sqrt(3) / 2])
    entry = {"angular_velocity_error_rad_s": (-30.0 * axis + [0.02, 0.0, 0.0]).tolist(),
             "angular_velocity_uncertainty_rad_s": [0.01, 0.01, 0.01]}
    _errors_across(entry, [axis])
    np.testing.assert_allclose(entry["angular_velocity_error_sigmas"], [2.0, 0.0, 0.0],
                               atol=1e-9)


def test_the_fit_notes_name_the_torus_axis_and_only_with_angular_warn():
    from dopplertof.diff.motion import VelocityMotion
    from dopplertof.diff.symmetry import symmetry_notes
    from dopplertof.scene import load_file

    scene = load_file(os.path.join(ROOT, "examples", "user_meshes.xml"), {"res": "16"})
    motions = [VelocityMotion.from_motion(b.motion, 0.0, 1e-3, t_ref=0.0)
               for b in scene.bodies]
    for angular, warned in ((False, 0), (True, 1)):
        entries = [{"name": b.names[0], "angular_velocity_rad_s": [0.0, 1.0, 0.0]}
                   for b in scene.bodies]
        warnings = symmetry_notes(scene, motions, 0.0, entries, angular)
        assert len(warnings) == warned and all("torus" in w for w in warnings), warnings
        torus = next(e for e in entries if e["name"] == "torus")
        assert len(torus["symmetry_axes"]) == 1
        assert ("angular_velocity_along_symmetry_axes_rad_s" in torus) == angular
