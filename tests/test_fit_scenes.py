"""benchmarks/fit_scenes.py (issue 42, 2026-12-04): issue 42's fit target on every starter
scene. Its rows and table from a fit.json (fast), and one tiny scene end to end (slow)."""

import json
import os

import pytest

from conftest import load_script


@pytest.fixture(scope="module")
def script():
    return load_script("benchmarks/fit_scenes.py")


def _fit_json():
    """fit.json's fields the script reads: two bodies, the second's truth 0 and one
    component without an uncertainty."""
    body = {"name": "ball", "interior_pixels": 40, "radial_velocity_m_s": -9.9,
            "radial_velocity_uncertainty_m_s": 0.1, "capture_velocity_gt_median_m_s": -10.0,
            "linear_velocity_error_sigmas": [0.5, -1.0, 3.5],
            "angular_velocity_error_sigmas": [None, None, None],
            "unfitted_rotation": {"chi_square": 0.0, "threshold": 25.9}}
    cube = dict(body, name="cube", radial_velocity_m_s=0.05,
                capture_velocity_gt_median_m_s=0.0,
                linear_velocity_error_sigmas=[0.2, None, -0.4],
                unfitted_rotation={"chi_square": 1e4, "threshold": 25.9})
    return {"bodies": [body, cube], "iterations": 3, "warnings": ["body cube: ..."]}


def test_rows_table_and_last_line_from_a_fit_json(script):
    saved = _fit_json()
    rows = script.rows_from_fit(saved, "scene", "direct", 1, "linear")
    assert [r["body"] for r in rows] == ["ball", "cube"]
    ball, cube = rows
    assert ball["truth"] == -10.0 and ball["error_m_s"] == pytest.approx(0.1)
    assert ball["error_pct"] == pytest.approx(1.0)
    assert ball["components"] == {"vx": 0.5, "vy": -1.0, "vz": 3.5}
    assert cube["error_pct"] is None and cube["error_m_s"] == pytest.approx(0.05)
    assert script.unfitted_rotation(saved)
    line = script.format_row(ball)
    assert "| ball (40 px) |" in line and "+1.00%" in line and "vz +3.5" in line
    assert "vy -" in script.format_row(cube)
    assert script.summary_line(rows).startswith("1 of 2 fitted bodies within 2%")
    assert "4 of 5 components with an sd within 3 sd (1 without one)" in \
        script.summary_line(rows)
    assert ball["radial_z"] == pytest.approx(1.0)
    summary = script.summarize(rows + script.rows_from_fit(saved, "scene", "direct", 2, "linear"))
    assert [(s["body"], s["seeds"], s["within_2"]) for s in summary] == [("ball", 2, 2),
                                                                          ("cube", 2, 0)]
    assert summary[0]["within_3"] == 4 and summary[0]["worst_z"] == 3.5
    assert "| 2 of 2 | +1.0 | 4 of 6 (6) | +3.5 |" in script.format_summary(summary[0])
    angular = script.rows_from_fit(saved, "scene", "direct", 1, "angular")
    assert list(angular[0]["components"]) == ["vx", "vy", "vz", "wx", "wy", "wz"]


def test_scenes_and_a_skipped_light(script, tmp_path):
    scenes = script.starter_scenes()
    assert "translating_sphere" in scenes and "user_meshes" in scenes
    assert script.declared_defaults("waveforms")["max_depth"] == "2"
    # written with direct light: no second, identical measurement, and no render
    (row,) = script.measure("waveforms", "multipath", 1, 16, 8, str(tmp_path))
    assert "direct light only" in row["note"] and "| waveforms |" in script.format_row(row)
    assert script._parse_res("48x48") == script._parse_res("48") == 48


@pytest.mark.slow  # a capture and a fit at 16x16, 8 spp (about 20 s: the kernels compile)
def test_one_tiny_scene_end_to_end(script, tmp_path):
    import dopplertof

    dopplertof.set_variant("llvm_ad_rgb")
    rows = script.measure("translating_sphere", "direct", 1, 16, 8, str(tmp_path), 1)
    assert [r["body"] for r in rows] == ["ball"] and "note" not in rows[0]
    with open(tmp_path / "translating_sphere_direct_1_fit" / "fit.json") as f:
        body = json.load(f)["bodies"][0]
    assert rows[0]["truth"] == body["capture_velocity_gt_median_m_s"]
    assert rows[0]["radial"] == body["radial_velocity_m_s"]
    assert set(rows[0]["components"]) == {"vx", "vy", "vz"}
    assert "ball" in script.format_row(rows[0]) and os.path.isdir(tmp_path)
