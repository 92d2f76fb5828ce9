"""`dopplertof capture` and `dopplertof demo` end to end (tiny settings), and their errors."""

import json
import subprocess
import sys

import numpy as np
import pytest

PLANE_XML = """<scene version="3.0.0">
    <default name="res" value="6"/>
    <integrator type="dopplertof"><integer name="max_depth" value="2"/></integrator>
    <sensor type="perspective">
        <float name="fov" value="6"/>
        <float name="near_clip" value="0.01"/>
        <transform name="to_world"><lookat origin="0, 0, 0" target="0, 0, 1" up="0, 1, 0"/></transform>
        <float name="shutter_open" value="0"/>
        <float name="shutter_close" value="0.0015"/>
        <sampler type="independent"><integer name="sample_count" value="16"/></sampler>
        <film type="hdrfilm">
            <integer name="width" value="$res"/><integer name="height" value="$res"/>
            <rfilter type="box"/>
        </film>
    </sensor>
    <emitter type="point"><point name="position" x="0" y="0" z="0"/><rgb name="intensity" value="10"/></emitter>
    <shape type="rectangle">
        <bsdf type="diffuse"/>
        <animation name="to_world">
            <transform time="0"><scale value="50"/><rotate y="1" angle="180"/><translate z="6.5"/></transform>
            <transform time="0.0015"><scale value="50"/><rotate y="1" angle="180"/><translate z="6.53"/></transform>
        </animation>
    </shape>
</scene>
"""


def run(*args, timeout=300):
    return subprocess.run([sys.executable, "-m", "dopplertof.cli", *args],
                          capture_output=True, text=True, timeout=timeout)


@pytest.fixture()
def plane_xml(tmp_path):
    path = tmp_path / "plane.xml"
    path.write_text(PLANE_XML)
    return path


def test_capture_command_writes_everything(tmp_path, plane_xml):
    out = tmp_path / "out"
    proc = run("capture", str(plane_xml), "--spp", "32", "-o", str(out), "--quiet",
               "--unwrap-frequency", "25", "--noise", "--full-well", "1e6", "--gain", "250",
               "-D", "res=5")
    assert proc.returncode == 0, proc.stderr
    for name in ("homodyne_0", "homodyne_0.75", "heterodyne_0.25", "homodyne_25MHz_0.5",
                 "velocity", "velocity_gt", "depth", "depth_gt"):
        assert np.load(out / f"{name}.npy").shape == (5, 5)
        assert (out / f"{name}.png").stat().st_size > 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["noise"]["full_well_electrons"] == 1e6
    assert summary["depth"]["unwrap_frequency_MHz"] == 25.0
    assert summary["velocity"]["ground_truth_time_s"] == pytest.approx(0.00075)
    gt = np.load(out / "velocity_gt.npy")
    assert np.allclose(gt, 20.0, rtol=2e-3)  # 0.03 m in 1.5 ms, receding (v / d_z)
    depth = np.load(out / "depth.npy")
    assert np.allclose(depth, np.load(out / "depth_gt.npy"), atol=0.05)  # unwrapped, noisy
    assert "velocity error" in proc.stdout and "without noise" in proc.stdout


@pytest.mark.parametrize("args,message", [
    (["capture", "missing.xml", "-o", "{dir}/o"], "scene file not found"),
    (["capture", "{xml}", "-o", "{dir}/o", "--unwrap-frequency", "30"],
     "equals the modulation frequency"),
    (["capture", "{xml}", "-o", "{dir}/o", "--hetero-frequency", "0.5"],
     "integer hetero_frequency"),
    (["capture", "{xml}", "-o", "{dir}/o", "--bits", "0"], "bits must be an integer"),
    (["capture", "{xml}", "-o", "{xml}/o"], "is a file"),
    (["capture", "{xml}", "-o", "{xml}"], "not a folder"),
])
def test_capture_errors_are_one_line_exit_2(tmp_path, plane_xml, args, message):
    args = [a.format(dir=tmp_path, xml=plane_xml) for a in args]
    proc = run(*args)
    assert proc.returncode == 2, proc.stderr
    assert message in proc.stderr
    assert proc.stderr.count("\n") == 1 and "Traceback" not in proc.stderr
    assert not (tmp_path / "o").exists()  # nothing written, not even the folder


def test_demo_runs_the_capture_pipeline_at_tiny_settings(tmp_path):
    proc = run("demo", "-o", str(tmp_path), "--spp", "4", "--res", "16", "--quiet")
    assert proc.returncode == 0, proc.stderr
    for name in ("homodyne_0", "homodyne_0.25", "homodyne_0.5", "homodyne_0.75",
                 "heterodyne_0", "heterodyne_0.25", "velocity", "velocity_gt", "depth",
                 "depth_gt"):
        assert np.load(tmp_path / f"{name}.npy").shape == (16, 16)
    assert (tmp_path / "comparison.png").stat().st_size > 0
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert [b["name"] for b in summary["bodies"]] == ["short_box", "tall_box"]
    short, tall = summary["bodies"]
    assert short["velocity_gt_median_m_s"] < -9 and tall["velocity_gt_median_m_s"] > 9
    assert "velocity error" in proc.stdout and "tall_box" in proc.stdout
