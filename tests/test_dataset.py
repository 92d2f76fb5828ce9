"""``dopplertof dataset``: geometry conventions (K, pose, depth), flow and scene flow
against the sampled motion, the splits (noise model, direct light), kill and resume,
a changed configuration refused, the reader's round trip, the example configuration."""

import copy
import json
import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

pytest.importorskip("h5py")

from dopplertof.dataset import Dataset, DatasetError  # noqa: E402
from dopplertof.dataset.config import config_from_mapping  # noqa: E402

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
EXAMPLE = os.path.join(ROOT, "examples", "dataset.toml")

#: a tiny dataset: 3 samples, one per shard, 12x10 pixels
TINY = {"samples": 3, "samples_per_shard": 1, "seed": 7,
        "render": {"resolution": [12, 10], "spp": 4, "max_depth": 4},
        "objects": {"count": [2, 2], "shapes": ["sphere", "cube", "rectangle"],
                    "materials": ["diffuse", "plastic", "conductor"]}}


def _config(changes=None, base=TINY):
    data = copy.deepcopy(base)
    for section, values in (changes or {}).items():
        data.setdefault(section, {}).update(values)
    return config_from_mapping(data, "<test>")


def _truth(config, index, folder="."):
    """(description, loaded scene, truth arrays) of sample ``index`` (no render)."""
    import dopplertof
    from dopplertof.cameras.preset import load_preset
    from dopplertof.dataset.generate import draw_scene
    from dopplertof.dataset.sample import sample_truth
    from dopplertof.dataset.scene_text import scene_xml

    dopplertof.set_variant()
    description = draw_scene(config, index, load_preset(config["render"]["camera"]))
    scene = dopplertof.scene.load_string(scene_xml(description, 4, 4), {}, base_dir=folder)
    return description, scene, sample_truth(scene, description)


def _pixel_rays(truth):
    """Unit rays through the pixel centres in camera coordinates, from K."""
    height, width = truth["depth"].shape
    u, v = np.meshgrid(np.arange(width) + 0.5, np.arange(height) + 0.5)
    rays = np.stack([u, v, np.ones_like(u)], -1) @ np.linalg.inv(truth["K"]).T
    return rays / np.linalg.norm(rays, axis=-1, keepdims=True)


def _ray_cast(scene, origin, directions):
    """Distances to the nearest surface of a still scene (static part and bodies)."""
    import mitsuba as mi

    rays = mi.Ray3f(mi.Point3f(*[np.full(len(directions), c, np.float32) for c in origin]),
                    mi.Vector3f(*[np.ascontiguousarray(directions[:, i], np.float32)
                                  for i in range(3)]))
    best = np.full(len(directions), np.inf)
    for part in [scene.static] + [b.scene for b in scene.bodies]:
        si = part.ray_intersect(rays)
        t = np.where(np.asarray(si.is_valid()), np.asarray(si.t, np.float64), np.inf)
        best = np.minimum(best, t)
    return best


MOVING_CAMERA = {"camera": {"position": [-0.3, 0.3], "yaw_deg": [-15, 15],
                            "pitch_deg": [-8, 8], "speed": [1.0, 3.0],
                            "angular_speed": [0.5, 2.0]}}


@pytest.mark.parametrize("index,backdrop", [(0, "room"), (1, "room"), (2, "wall")])
def test_depth_unprojected_with_k_and_pose_lies_on_the_surfaces(index, backdrop):
    """Every valid pixel's depth along its K ray, placed by the pose, is on a surface of
    the scene at mid-exposure (a ray cast, 1e-4 relative); z-depth is range x the ray's
    z through K."""
    config = _config({**MOVING_CAMERA, "backdrop": {"kind": backdrop}})
    description, _, truth = _truth(config, index)
    still = _still_scene(description, ".")  # the mid-exposure poses, held still
    rays = _pixel_rays(truth)
    valid = truth["mask"]
    assert valid.sum() > 50 and np.isfinite(truth["depth"][valid]).all()
    pose = truth["pose"]
    world = rays[valid] @ pose[:3, :3].T
    cast = _ray_cast(still, pose[:3, 3], world)
    np.testing.assert_allclose(cast, truth["depth"][valid], rtol=1e-4)
    np.testing.assert_allclose(truth["depth_z"][valid], truth["depth"][valid] * rays[valid][:, 2],
                               rtol=1e-5)
    assert np.isnan(truth["depth"][~valid]).all()
    objects = truth["instance"][valid]
    assert set(np.unique(objects)) <= set(range(len(description["objects"]) + 1))


def _project(K, pose, points):
    q = (points - pose[:3, 3]) @ pose[:3, :3]
    return (q @ K.T)[..., :2] / q[..., 2:3], q


def _object_pixels(truth, description):
    """(pixel mask, object per pixel, hit points in world) of the pixels on objects."""
    on = truth["instance"] >= 1
    rays = _pixel_rays(truth) @ truth["pose"][:3, :3].T
    points = truth["pose"][:3, 3] + truth["depth"][..., None].astype(np.float64) * rays
    return on, truth["instance"] - 1, points


@pytest.mark.parametrize("motion,rtol", [({"speed": [2.0, 10.0], "angular_speed": [0, 0]}, 1e-4),
                                         ({"speed": [0, 0], "angular_speed": [10.0, 50.0]},
                                          1e-2)])
def test_flow_and_scene_flow_follow_the_sampled_motion(motion, rtol):
    """Flow (px over the sequence) and scene flow (m) are the projected motion of the
    sampled velocities: exact for translation, first order for rotation."""
    config = _config({"motion": motion})
    checked = 0
    for index in range(3):
        description, _, truth = _truth(config, index)
        times = description["times_s"]
        span = times["end"] - times["start"]
        on, which, points = _object_pixels(truth, description)
        for k, obj in enumerate(description["objects"]):
            mask = on & (which == k)
            if not mask.any():
                continue
            p = points[mask]
            step = (np.asarray(obj["velocity_m_s"]) + np.cross(
                obj["angular_velocity_rad_s"], p - obj["centre_m"])) * (span / 2)
            ends = [_project(truth["K"], truth["pose"], p + s * step) for s in (-1, 1)]
            flow = ends[1][0] - ends[0][0]
            scale = np.abs(flow).max() + 1e-3
            np.testing.assert_allclose(truth["flow"][mask], flow, rtol=0, atol=rtol * scale + 1e-4)
            scene_flow = ends[1][1] - ends[0][1]
            np.testing.assert_allclose(truth["scene_flow"][mask], scene_flow, rtol=0,
                                       atol=rtol * np.abs(scene_flow).max() + 1e-6)
            checked += mask.sum()
    assert checked > 30


@pytest.mark.parametrize("camera", [{}, MOVING_CAMERA["camera"]])
def test_radial_velocity_truth_is_the_scene_flow_along_the_ray(camera):
    """velocity_point is the scene flow's component along the pixel's ray (per
    second); velocity_gt, the rate of the distance along the fixed ray that the phase
    follows, is the scene flow along the normal over the ray's cosine to it."""
    config = _config({"motion": {"speed": [2.0, 10.0], "angular_speed": [10.0, 50.0]},
                      "camera": camera})
    checked = 0
    for index in range(3):
        description, _, truth = _truth(config, index)
        span = description["times_s"]["end"] - description["times_s"]["start"]
        rays = _pixel_rays(truth)
        flow = truth["scene_flow"].astype(np.float64) / span  # m/s
        normals = truth["normals"].astype(np.float64)
        cosine = np.sum(rays * normals, -1)
        valid = truth["mask"] & (np.abs(cosine) > 0.3)
        along = np.sum(flow * rays, -1)
        scale = np.abs(along[valid]).max()
        np.testing.assert_allclose(truth["velocity_point"][valid], along[valid], rtol=0,
                                   atol=1e-2 * scale + 1e-4)
        radial = np.sum(flow * normals, -1) / cosine
        np.testing.assert_allclose(truth["velocity_gt"][valid], radial[valid], rtol=0,
                                   atol=1e-2 * np.abs(radial[valid]).max() + 1e-4)
        checked += valid.sum()
        moving = truth["instance"][valid] >= 1
        assert np.abs(truth["velocity_gt"][valid][moving]).max() > 0.5  # (something moves)
    assert checked > 100


# ---- Rendered datasets ---------------------------------------------------------------------

@pytest.fixture(scope="module")
def in_process_client():
    """One in-process Dask worker thread (the renders run in this process)."""
    from distributed import Client, LocalCluster

    cluster = LocalCluster(n_workers=1, threads_per_worker=1, processes=False,
                           dashboard_address=":0")
    with Client(cluster) as client:
        yield client
    cluster.close()


def _write_toml(path, data):
    """``data`` (two levels) as a TOML file."""
    lines = [f"{k} = {json.dumps(v)}" for k, v in data.items() if not isinstance(v, dict)]
    for section, values in data.items():
        if isinstance(values, dict):
            lines.append(f"[{section}]")
            lines += [f"{k} = {json.dumps(v)}" for k, v in values.items()]
    with open(path, "w") as f:
        f.write("\n".join(lines) + "\n")
    return str(path)


@pytest.fixture(scope="module")
def tiny(tmp_path_factory, in_process_client):
    """The TINY dataset rendered once: (its configuration file, its folder)."""
    from dopplertof.dataset import load_config
    from dopplertof.dataset.driver import run_dataset

    folder = tmp_path_factory.mktemp("tiny")
    config_file = _write_toml(folder / "tiny.toml", TINY)
    summary = run_dataset(load_config(config_file), folder / "out", client=in_process_client,
                          progress=False)
    assert summary.ok and summary.rendered == 3 and summary.samples_per_hour > 0
    return config_file, str(folder / "out")


def _shard_bytes(folder):
    return {n: open(os.path.join(folder, n), "rb").read()
            for n in sorted(os.listdir(folder)) if n.endswith(".h5")}


def test_full_minus_ideal_has_the_noise_models_mean_and_variance(tiny):
    """raw - raw_ideal over the unclipped pixels: mean 0 and the predicted variance
    raw_variance (standardized: mean 0 +- 5 sigma of the mean, variance 1 +- 5 sigma;
    false failure about 1e-6)."""
    ds = Dataset(tiny[1])
    z = []
    for i in range(len(ds)):
        s = ds[i]
        raw = s["raw"].astype(np.float64)
        inside = (raw > 0) & (raw < 4095)
        z.append(((raw - s["raw_ideal"]) / np.sqrt(s["raw_variance"]))[inside])
    z = np.concatenate(z)
    assert z.size > 1000
    assert abs(z.mean()) < 5 / np.sqrt(z.size)
    assert abs(z.var() - 1) < 5 * np.sqrt(2 / z.size)
    assert np.array_equal(Dataset(tiny[1], split="full")[0]["raw"], ds[0]["raw"])


def test_direct_split_is_a_max_depth_2_render(tiny):
    """raw_direct re-rendered from the stored scene alone at max_depth 2 (no noise, the
    stored photon scale), bitwise; and it differs from the ideal split (multipath)."""
    import dopplertof
    from dopplertof.cameras.capture import capture_camera
    from dopplertof.cameras.preset import load_preset
    from dopplertof.cameras.sensor import read_frames

    ds = Dataset(tiny[1], split="direct")
    attrs, sample = ds.attributes(0), ds[0]
    dopplertof.set_variant()
    scene = ds.scene(0)
    preset = load_preset(attrs["camera_preset"]["name"])
    direct = capture_camera(scene, preset, 4, attrs["render_seed"], params={"max_depth": 2},
                            noise=False, progress=False)
    readout = read_frames(direct.rendered, direct.radiance.mean(-1),
                          [f.integration_s for f in preset.frames], preset.sensor,
                          preset.contrast, None, photons_per_unit=attrs["photons_per_unit"])
    assert np.array_equal(readout.raw_ideal.astype(np.float32), sample["raw"])
    assert np.array_equal(sample["raw"], sample["raw_direct"])
    assert np.abs(sample["raw_direct"] - sample["raw_ideal"]).max() > 1.0


def test_reader_round_trip_of_every_key_with_its_units(tiny):
    """Every key comes back as rendered (sample 0 rendered again here), with its unit
    in the file and in Dataset.units."""
    import h5py

    import dopplertof
    from dopplertof.dataset import load_config
    from dopplertof.dataset.sample import UNITS, render_sample

    dopplertof.set_variant()
    arrays, attributes = render_sample(load_config(tiny[0]), 0, tiny[1])
    ds = Dataset(tiny[1])
    assert len(ds) == 3 and ds.failed == [] and ds.units == UNITS
    sample = ds[0]
    assert set(UNITS) <= set(sample) and int(sample["seed"]) == attributes["render_seed"]
    for key in UNITS:
        assert sample[key].dtype == arrays[key].dtype, key
        np.testing.assert_array_equal(sample[key], arrays[key], err_msg=key)
    with h5py.File(os.path.join(tiny[1], "shard_00000.h5")) as f:
        group = f["sample_00000000"]
        assert {k: group[k].attrs["units"] for k in group} == UNITS
        assert group["depth"].compression == "gzip" and group["depth"].chunks
    assert ds.attributes(0)["scene_xml"] == attributes["scene_xml"]
    with pytest.raises(DatasetError, match="unknown split"):
        Dataset(tiny[1], split="noisy")


def test_a_changed_config_in_the_same_folder_is_refused(tiny, tmp_path, capsys):
    from dopplertof.cli import main

    before = _shard_bytes(tiny[1])
    changed = copy.deepcopy(TINY)
    changed["render"]["spp"] = 8
    code = main(["dataset", _write_toml(tmp_path / "changed.toml", changed), "-o", tiny[1],
                 "--quiet"])
    err = capsys.readouterr().err.strip()
    assert code == 2 and len(err.splitlines()) == 1
    assert "another configuration" in err and "Traceback" not in err
    assert _shard_bytes(tiny[1]) == before
    with open(os.path.join(tiny[1], "dataset.json")) as f:
        assert json.load(f)["config"]["render"]["spp"] == 4


def test_the_hash_is_the_presets_contents_not_where_its_file_lies(tmp_path, monkeypatch):
    """A built-in preset read from another checkout or install (its folder elsewhere)
    defines the same samples: one hash; an edited copy of it, another."""
    import shutil

    from dopplertof.cameras import preset
    from dopplertof.dataset.driver import config_hash

    config = _config({"render": {"camera": "paper-dtof"}})
    here = config_hash(config, "llvm_ad_rgb")
    elsewhere = tmp_path / "install" / "presets"
    shutil.copytree(preset.PRESET_FOLDER, elsewhere)
    monkeypatch.setattr(preset, "PRESET_FOLDER", str(elsewhere))
    assert preset.load_preset("paper-dtof").describe()["file"].startswith(str(elsewhere))
    assert config_hash(config, "llvm_ad_rgb") == here
    edited = elsewhere / "paper-dtof.toml"
    edited.write_text(edited.read_text().replace("description = ", "description = \"edited\" # ",
                                                 1))
    assert config_hash(config, "llvm_ad_rgb") != here


def test_a_wrong_variant_does_not_claim_the_folder(tmp_path, capsys):
    """issue 39, O04: `--variant nonsense_rgb` wrote dataset.json, and the corrected
    rerun was refused as "another configuration" though nothing was rendered."""
    from dopplertof.cli import main

    config = _write_toml(tmp_path / "tiny.toml", TINY)
    for variant in ("nonsense_rgb", "llvm_nonsense"):
        code = main(["dataset", config, "-o", str(tmp_path / "out"), "--variant", variant])
        err = capsys.readouterr().err.strip()
        assert code == 2 and len(err.splitlines()) == 1 and "unknown variant" in err, err
    assert not (tmp_path / "out").exists()


def test_a_cuda_variant_without_a_gpu_is_refused_before_the_folder(tmp_path, capsys):
    """issue 39, O09: `--variant cuda_ad_rgb` on a machine without a GPU claimed the
    folder and failed every shard (exit 1)."""
    import mitsuba

    from dopplertof.backend import _has_cuda
    from dopplertof.cli import main

    if "cuda_ad_rgb" not in mitsuba.variants() or _has_cuda():
        pytest.skip("needs a Mitsuba with cuda_ad_rgb on a machine without a CUDA device")
    config = _write_toml(tmp_path / "tiny.toml", TINY)
    code = main(["dataset", config, "-o", str(tmp_path / "out"), "--variant", "cuda_ad_rgb"])
    err = capsys.readouterr().err.strip()
    assert code == 2 and len(err.splitlines()) == 1 and "no CUDA device" in err, err
    assert not (tmp_path / "out").exists()


def test_a_failing_sample_is_retried_then_listed(tmp_path, monkeypatch, in_process_client):
    """Sample 1 raises every time: tried 1 + retries times, its shard written without it,
    dataset.json and the reader list it; the others are there. A rerun tries it again."""
    from dopplertof.dataset import load_config, sample
    from dopplertof.dataset.driver import run_dataset

    calls = []
    real = sample.render_sample

    def flaky(config, index, folder):
        calls.append(index)
        if index == 1:
            raise RuntimeError("out of luck")
        return real(config, index, folder)

    monkeypatch.setattr(sample, "render_sample", flaky)
    data = {**TINY, "samples": 2, "samples_per_shard": 2}
    config = load_config(_write_toml(tmp_path / "two.toml", data))
    summary = run_dataset(config, tmp_path / "out", client=in_process_client, retries=1,
                          progress=False)
    assert calls == [0, 1, 1] and not summary.ok
    assert summary.failed == [{"index": 1, "error": "RuntimeError: out of luck"}]
    with open(tmp_path / "out" / "dataset.json") as f:
        assert json.load(f)["failed_samples"] == summary.failed
    ds = Dataset(tmp_path / "out")
    assert len(ds) == 1 and ds.failed == summary.failed and int(ds[0]["index"]) == 0
    # issue 39, T01: a rerun (the failure was transient) tries the sample again (its
    # shard, written without it, counted as complete: never retried)
    monkeypatch.setattr(sample, "render_sample", real)
    again = run_dataset(config, tmp_path / "out", client=in_process_client, progress=False)
    assert again.ok and again.rendered == 2 and again.skipped_shards == 0
    ds = Dataset(tmp_path / "out")
    assert len(ds) == 2 and ds.failed == [] and int(ds[1]["index"]) == 1


def test_bad_configs_are_one_line_with_the_key(tmp_path, capsys):
    from dopplertof.cli import main

    for data, words in (({**TINY, "sampels": 3}, "unknown key sampels, did you mean 'samples'"),
                        ({**TINY, "objects": {"shapes": ["torus"]}}, "objects.shapes"),
                        ({**TINY, "render": {"resolution": [8, 8]}}, "missing key render.spp"),
                        ({**TINY, "motion": {"speed": [3.0, 1.0]}}, "motion.speed out of range"),
                        ({**TINY, "motion": {"angular_speed": [0.0, 5000.0]}},
                         "motion.angular_speed: 5000 rad/s turns more than"),
                        # issue 39, D34: a MemoryError after 50 s of planning
                        ({**TINY, "samples": 10**12},
                         "samples = 1000000000000 plans 1000000000000 shards"),
                        # issue 39, 2026-12-03 rerun of D09: every sample failed in the
                        # workers with Dr.Jit's jit_var_counter() error
                        ({**TINY, "render": {"resolution": [100000, 100000], "spp": 4}},
                         "render.resolution = [100000, 100000] at render.spp = 4: a render "
                         "pass holds 4e+10 samples"),
                        # issue 39, D14: every sample failed in the workers, exit 1
                        ({**TINY, "render": {"resolution": [8, 8], "spp": 3, "max_depth": 4}},
                         "render.spp = 3 is not a multiple of the correlated group size 2")):
        code = main(["dataset", _write_toml(tmp_path / "bad.toml", data), "-o",
                     str(tmp_path / "out")])
        err = capsys.readouterr().err.strip()
        assert code == 2 and len(err.splitlines()) == 1 and words in err, err
    assert not (tmp_path / "out").exists()


@pytest.mark.slow
def test_killed_run_resumes_bitwise(tiny, tmp_path):
    """The command killed (SIGKILL, its workers too) after its first shard, run again:
    the shards are bitwise those of the uninterrupted run."""
    out = tmp_path / "out"
    command = [sys.executable, "-m", "dopplertof.cli", "dataset", tiny[0], "-o", str(out),
               "--workers", "1", "--quiet"]
    env = {**os.environ, "PYTHONPATH": os.path.join(ROOT, "src")}
    process = subprocess.Popen(command, env=env, start_new_session=True,
                               stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        deadline = time.monotonic() + 300
        while not (out / "shard_00000.h5").exists() and process.poll() is None:
            assert time.monotonic() < deadline, "no shard after 300 s"
            time.sleep(0.05)
    finally:
        os.killpg(process.pid, signal.SIGKILL)
        process.wait()
    assert not (out / "shard_00002.h5").exists(), "the run finished before the kill"
    first = os.stat(out / "shard_00000.h5").st_ino
    again = subprocess.run(command, env=env, capture_output=True, text=True, timeout=600)
    assert again.returncode == 0, again.stderr
    assert _shard_bytes(out) == _shard_bytes(tiny[1])
    assert os.stat(out / "shard_00000.h5").st_ino == first  # resumed: not written again
    assert not [n for n in os.listdir(out) if ".tmp" in n]


def test_example_config_renders_4_samples_at_32x32(tmp_path, in_process_client):
    from dopplertof.dataset import load_config
    from dopplertof.dataset.driver import run_dataset

    summary = run_dataset(load_config(EXAMPLE), tmp_path / "out", client=in_process_client,
                          progress=False)
    ds = Dataset(tmp_path / "out")
    assert summary.ok and len(ds) == 4
    assert ds[3]["raw"].shape == (6, 32, 32) and ds[3]["flow"].shape == (32, 32, 2)


def _structure(description) -> tuple:
    """(body count, shape types, BSDF kinds) of a sample's description."""
    objects = description["objects"]
    return (len(objects), {o["shape"] for o in objects},
            {o["material"]["kind"] for o in objects})


def _other_structures(config, preset) -> tuple:
    """Sample 0, the first sample of its body count whose shape types and BSDF kinds
    both differ from its own, and the first sample of another body count (drawn, not
    rendered)."""
    from dopplertof.dataset.generate import draw_scene

    drawn = [_structure(draw_scene(config, index, preset)) for index in range(100)]
    count, shapes, kinds = drawn[0]
    same = next(i for i, s in enumerate(drawn) if s[0] == count and s[1] != shapes
                and s[2] != kinds)
    other = next(i for i, s in enumerate(drawn) if s[0] != count)
    return 0, same, other


#: the kernels a new body count compiles: the ones that trace rays against the bodies (a
#: body traced alone, two or more visited by a call over their scenes): the full and the
#: direct split's renders, the truth's rays and the mixed footprints' rays
#: (dopplertof.dataset.structure)
BODY_COUNT_KERNELS = 4


def test_samples_of_other_shapes_and_materials_compile_no_new_kernel(tmp_path):
    """A dataset's samples share their kernels whatever shapes and materials they draw
    (issue 40): every shape type and BSDF kind is kept alive beside them and the
    registries' id bounds are held (dopplertof.dataset.structure), so that a sample of
    other shapes and other materials compiles nothing new after another of its body
    count, and one of another body count only the kernels that trace the bodies."""
    import gc

    import dopplertof
    from dopplertof.cameras.preset import load_preset
    from dopplertof.dataset.sample import render_sample
    from test_startup import _kernels_of

    dopplertof.set_variant()
    config = _config({"objects": {"count": [1, 3]}})
    first, same, other = _other_structures(config, load_preset(config["render"]["camera"]))
    gc.collect()  # (no other test's Mitsuba objects freed between the renders)
    drawn = {}

    def sample(index):
        def run():
            drawn[index] = _structure(json.loads(
                render_sample(config, index, str(tmp_path))[1]["description"]))
        return run

    kernels = _kernels_of(sample(first))
    again = _kernels_of(sample(same))
    assert drawn[first][0] == drawn[same][0]
    assert drawn[first][1] != drawn[same][1] and drawn[first][2] != drawn[same][2]
    assert kernels and again <= kernels, (len(again - kernels), "new kernels")
    counted = _kernels_of(sample(other))
    assert drawn[other][0] != drawn[first][0]
    assert 0 < len(counted - kernels) <= BODY_COUNT_KERNELS, len(counted - kernels)



def test_the_kinds_kept_alive_are_released_on_request():
    """structure.release_kinds drops every set kinds_alive keeps (one per configuration's
    kinds and variant), so a process that renders other scenes after a dataset traces
    only their instances (2026-12-04: six sets kept a later fit's trace 7x slower)."""
    from dopplertof.dataset import structure

    structure.release_kinds()
    scenes = structure.kinds_alive(_config({"objects": {"count": [1, 3]}}))
    assert scenes and structure.kinds_alive(_config({"objects": {"count": [1, 3]}})) is scenes
    structure.kinds_alive(_config({"objects": {"count": [1, 2]}}))
    assert structure.release_kinds() == 2 and structure.release_kinds() == 0
    assert structure.kinds_alive(_config({"objects": {"count": [1, 3]}})) is not scenes

OCTAHEDRON = """v 1 0 0
v -1 0 0
v 0 1 0
v 0 -1 0
v 0 0 1
v 0 0 -1
f 1 3 5
f 3 2 5
f 2 4 5
f 4 1 5
f 3 1 6
f 2 3 6
f 4 2 6
f 1 4 6
"""


def _still_scene(description, folder):
    """The scene of ``description`` with everything held at its mid-exposure pose."""
    import dopplertof
    from dopplertof.dataset.scene_text import scene_xml

    description = copy.deepcopy(description)
    for thing in description["objects"] + [description["camera"]]:
        thing["velocity_m_s"] = thing["angular_velocity_rad_s"] = [0.0, 0.0, 0.0]
    description["camera"]["moving"] = False
    return dopplertof.scene.load_string(scene_xml(description, 4, 4), {}, base_dir=folder)


def test_meshes_are_drawn_copied_into_the_dataset_and_seen(tmp_path, in_process_client):
    """A mesh folder's files are objects; the dataset holds its own copy (the sample's
    scene loads with the folder gone) and the pixels on them unproject onto them."""
    import shutil

    from dopplertof.dataset.driver import run_dataset

    (tmp_path / "config" / "shapes").mkdir(parents=True)
    (tmp_path / "config" / "shapes" / "octahedron.obj").write_text(OCTAHEDRON)
    data = copy.deepcopy(TINY)
    data.update(samples=1)
    data["objects"].update(shapes=["mesh"], mesh_folder="shapes", size=[0.6, 0.8])
    config = config_from_mapping(data, "<test>", str(tmp_path / "config"))
    out = str(tmp_path / "out")
    assert run_dataset(config, out, client=in_process_client, progress=False).ok
    shutil.rmtree(tmp_path / "config")
    ds = Dataset(out)
    description, truth = ds.attributes(0)["description"], ds[0]
    assert {o["mesh"] for o in description["objects"]} == {"meshes/octahedron.obj"}
    assert len(ds.scene(0).bodies) == 2
    on = truth["instance"] >= 1
    assert on.sum() > 5
    world = _pixel_rays(truth)[on] @ truth["pose"][:3, :3].T
    np.testing.assert_allclose(_ray_cast(_still_scene(description, out), truth["pose"][:3, 3],
                                         world), truth["depth"][on], rtol=1e-4)
    with pytest.raises(DatasetError, match="holds no"):
        config_from_mapping({**data, "objects": {**data["objects"], "mesh_folder": "."}},
                            "<test>", str(tmp_path))


@pytest.mark.parametrize("name, content, words", [
    ("cut.obj", "v 0 0 0\nv 1 0 0\nv 0 1\n",
     "cut.obj: line 3: a vertex with 2 of 3 coordinates (is the file cut off?)"),
    ("n.obj", "v 0 0 0\nv nan -1 0\nv 0 1 0\nf 1 2 3\n", "n.obj: line 2: non-finite vertex"),
    ("junk.obj", "v 0 0 0\0\x01\x02", "junk.obj: binary data (a NUL byte at offset 7)"),
])
def test_a_broken_mesh_in_the_mesh_folder_is_named_at_load(tmp_path, name, content, words):
    """The 2026-12-03 rerun of campaign D28bad and D28nan (issue 39): a cut-off .obj was
    refused with NumPy's "setting an array element with a sequence ... inhomogeneous
    shape", a NaN vertex as a mesh that "spans nan x 2 x 0" and must be rescaled; the
    mesh check of scenes (scene/meshes.py) names the line and the problem now."""
    (tmp_path / "shapes").mkdir()
    (tmp_path / "shapes" / name).write_bytes(content.encode("latin-1"))
    data = copy.deepcopy(TINY)
    data["objects"].update(shapes=["mesh"], mesh_folder="shapes")
    with pytest.raises(DatasetError, match="objects.mesh_folder") as caught:
        config_from_mapping(data, "<test>", str(tmp_path))
    assert words in str(caught.value) and len(str(caught.value).splitlines()) == 1


@pytest.mark.parametrize("placement,offset", [("camera", [0.0, 0.0, 0.0]),
                                              ("offset", [0.4, -0.1, 0.2])])
def test_the_light_rides_with_the_camera_at_its_offset(placement, offset):
    """The point light is where the camera's frame puts it (x right, y down, z forward)
    at the first keyframe, and moves with the camera."""
    import mitsuba as mi

    from dopplertof.dataset.generate import camera_pose

    config = _config({**MOVING_CAMERA, "light": {"placement": placement, "offset": offset}})
    description, scene, _ = _truth(config, 0)
    times = description["times_s"]
    pose = camera_pose(description["camera"], times["start"] - times["mid"])
    (emitter,) = scene.static.emitters()
    position = np.array(mi.traverse(emitter)["position"], np.float64).ravel()
    np.testing.assert_allclose(position, pose[:3, :3] @ offset + pose[:3, 3], atol=1e-5)
    assert [m for _, m in scene.light_motions] == [scene.sensor_motion]


def test_a_complete_dataset_run_again_renders_nothing(tiny, capsys):
    """The same command on a complete folder: every shard skipped, no cluster started,
    exit 0, the shards untouched."""
    from dopplertof.cli import main

    before = _shard_bytes(tiny[1])
    assert main(["dataset", tiny[0], "-o", tiny[1]]) == 0
    out = capsys.readouterr().out
    assert "0 rendered now, 3 shards already complete, 0 samples failed" in out
    assert _shard_bytes(tiny[1]) == before


# ---- issue 39: shards that prove their integrity ---------------------------------------

def _flip_bit_in(path, key, index):
    """Flip one bit in the stored bytes of sample ``index``'s dataset ``key``."""
    import h5py

    with h5py.File(path, "r") as f:
        offset = f[f"sample_{index:08d}"][key].id.get_chunk_info(0).byte_offset
    with open(path, "r+b") as f:
        f.seek(offset + 3)
        byte = f.read(1)[0]
        f.seek(offset + 3)
        f.write(bytes([byte ^ 0x10]))


def _rewrite(path, index, change):
    """An edit HDF5 itself makes (its own checksums stay valid): ``change(group)``."""
    import h5py

    with h5py.File(path, "r+") as f:
        change(f[f"sample_{index:08d}"])


def _cut(path, keep):
    data = open(path, "rb").read()
    with open(path, "wb") as f:
        f.write(data[:keep(len(data))])


def _flip_signature(path):
    with open(path, "r+b") as f:
        f.seek(3)
        byte = f.read(1)[0]
        f.seek(3)
        f.write(bytes([byte ^ 0xFF]))


def _swap(folder):
    a, b = os.path.join(folder, "shard_00000.h5"), os.path.join(folder, "shard_00001.h5")
    os.rename(a, a + ".x")
    os.rename(b, a)
    os.rename(a + ".x", b)


def _set_scene_xml(group):
    group.attrs["scene_xml"] = group.attrs["scene_xml"].replace("0", "1", 1)


def _set_k(group):
    group["K"][0, 0] = group["K"][0, 0] + 1e-9


#: (campaign id, damage, the shard named, found when the folder is opened)
DAMAGES = [
    ("S01", lambda d: _cut(os.path.join(d, "shard_00001.h5"), lambda n: n // 2), 1, True),
    ("S02", lambda d: _cut(os.path.join(d, "shard_00001.h5"), lambda n: 0), 1, True),
    ("S03", lambda d: _flip_bit_in(os.path.join(d, "shard_00000.h5"), "pose", 0), 0, False),
    ("S04", lambda d: _flip_bit_in(os.path.join(d, "shard_00000.h5"), "raw", 0), 0, False),
    ("S05", lambda d: _rewrite(os.path.join(d, "shard_00001.h5"), 1, _set_k), 1, False),
    ("S06", lambda d: os.unlink(os.path.join(d, "shard_00001.h5")), 1, True),
    ("S07", lambda d: _flip_signature(os.path.join(d, "shard_00002.h5")), 2, True),
    ("S08", lambda d: _rewrite(os.path.join(d, "shard_00002.h5"), 2, _set_scene_xml), 2,
     False),
    ("S09", lambda d: _cut(os.path.join(d, "shard_00002.h5"), lambda n: n - 16), 2, True),
    ("S12", _swap, 0, True),
]


def _damaged_copy(tiny, tmp_path, damage) -> str:
    """A copy of the tiny dataset with ``damage`` done to it."""
    import shutil

    out = str(tmp_path / "out")
    shutil.copytree(tiny[1], out)
    damage(out)
    return out


@pytest.mark.parametrize("case, damage, shard, at_open", DAMAGES, ids=[d[0] for d in DAMAGES])
def test_a_damaged_shard_is_named_by_the_reader_and_verify(tiny, tmp_path, capsys, case,
                                                           damage, shard, at_open):
    """A truncated, emptied, deleted, bit-flipped, edited or swapped shard: the reader
    names it (at open, or reading the sample) instead of serving fewer samples or the
    damage; on_damage="skip" reads the others with a warning; `dataset verify` names it
    (exit 1). (Before: len 4 of 6 without a word, the flipped pose or the edited scene_xml
    served as data; swapped shards out of index order.)"""
    from dopplertof.cli import main

    out = _damaged_copy(tiny, tmp_path, damage)
    name = f"shard_{shard:05d}.h5"
    with pytest.raises(DatasetError, match=name):
        ds = Dataset(out)
        for i in range(len(ds)):
            ds.attributes(i)
    if at_open:
        with pytest.warns(UserWarning) as warned:
            ds = Dataset(out, on_damage="skip")
        assert name in str(warned[0].message) and "skipped" in str(warned[0].message)
        assert ds.missing_shards == [name] or case == "S12"
        assert [int(ds[i]["index"]) for i in range(len(ds))] == sorted(
            int(ds[i]["index"]) for i in range(len(ds)))
    assert main(["dataset", "verify", out]) == 1
    lines = capsys.readouterr().out.strip().splitlines()
    assert lines[0].startswith(name) and "a rerun renders it again" in lines[0]
    assert lines[-1].endswith(name) or case == "S12"


#: the rerun of every damage (a Dask cluster each, 2.5 s): two in the quick tier (make quick,
#: issue 42), every one in the whole suite
RERUNS = [pytest.param(*d, id=d[0], marks=() if d[0] in ("S01", "S12") else pytest.mark.slow)
          for d in DAMAGES]


@pytest.mark.parametrize("case, damage, shard, at_open", RERUNS)
def test_a_damaged_shard_is_rendered_again_by_a_rerun(tiny, tmp_path, capsys, case, damage,
                                                      shard, at_open):
    """A rerun renders the damaged shard again, bitwise the undamaged dataset, and
    verify then finds nothing. (Before: a rerun called every shard complete.)"""
    from dopplertof.cli import main

    out = _damaged_copy(tiny, tmp_path, damage)
    assert main(["dataset", tiny[0], "-o", out, "--quiet"]) == 0
    capsys.readouterr()
    assert _shard_bytes(out) == _shard_bytes(tiny[1])
    assert len(Dataset(out)) == 3 and main(["dataset", "verify", out]) == 0
    assert capsys.readouterr().out.strip().endswith("a rerun would render again: nothing")


def test_dataset_verify_on_a_folder_that_is_no_dataset_is_one_line(tmp_path, capsys):
    from dopplertof.cli import main

    assert main(["dataset", "verify", str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "dataset.json: not a dataset folder" in err


@pytest.mark.parametrize("call, error, words", [
    (lambda ds: Dataset(None), TypeError, "folder must be a file path"),  # A01
    (lambda ds: Dataset(42), TypeError, "folder must be a file path"),  # A02
    (lambda ds: Dataset(b"/bytes/path"), TypeError, "folder must be a file path"),  # A16
    (lambda ds: Dataset(ds.folder, split=3), TypeError, "split must be one of"),
    (lambda ds: Dataset(ds.folder, on_damage="ignore"), DatasetError, "unknown on_damage"),
    (lambda ds: ds["0"], TypeError, "Dataset item must be an integer"),  # A08
    (lambda ds: ds[0:2], TypeError, "Dataset item must be an integer"),  # A10
    (lambda ds: ds[3], IndexError, "Dataset item 3 out of range: 3 item"),
])
def test_wrong_arguments_of_the_reader_name_the_argument(tiny, call, error, words):
    """issue 39, A01, A02, A08, A10, A16: os.fspath's or a comparison's TypeError from
    inside, naming no argument."""
    with pytest.raises(error, match=words):
        call(Dataset(tiny[1]))


def test_a_shards_bytes_do_not_depend_on_when_its_datasets_are_closed(tmp_path, monkeypatch):
    """The same samples give the same shard bytes whether each HDF5 dataset is closed as
    soon as it is written or held open to the file's end (as a garbage collector's or a
    traceback's late release does): no chunk is placed in the file by a cache eviction.
    Found in the whole suite, where a resumed run's shard 1 had every array equal to the
    uninterrupted run's but the depth chunk elsewhere in the file."""
    import h5py

    from dopplertof.dataset.shards import write_shard

    rng = np.random.default_rng(3)
    arrays = {k: rng.standard_normal((16, 16)).astype(np.float32)
              for k in ("albedo", "depth", "depth_z", "flow", "normals")}
    samples = [(arrays, {"index": 1})]
    units = dict.fromkeys(arrays, "m")
    write_shard(str(tmp_path / "closed.h5"), samples, [], {"config_hash": "x"}, units)

    held = []
    create = h5py.Group.create_dataset

    def create_and_hold(self, name, *args, **kwargs):  # holds "depth" only
        dataset = create(self, name, *args, **kwargs)
        if name == "depth":
            held.append(dataset)
        return dataset

    monkeypatch.setattr(h5py.Group, "create_dataset", create_and_hold)
    write_shard(str(tmp_path / "held.h5"), samples, [], {"config_hash": "x"}, units)
    assert held
    assert (tmp_path / "closed.h5").read_bytes() == (tmp_path / "held.h5").read_bytes()


def test_a_dataset_of_days_per_sample_is_refused_and_a_long_one_announced(
        tmp_path, capsys, monkeypatch):
    """issue 39, 2026-12-03 campaign D49: spp = 10**9 at 16x16 ran without a word (no
    estimate, nothing for 300 s), where `render` says what a long render takes."""
    from dopplertof.dataset.config import DatasetError, load_config
    from dopplertof.dataset.driver import announce_time

    monkeypatch.setattr(os, "cpu_count", lambda: 2)  # (the estimate counts the cores)
    data = copy.deepcopy(TINY)
    data["render"].update(resolution=[16, 16], spp=10**9)
    with pytest.raises(DatasetError) as error:
        load_config(_write_toml(tmp_path / "huge.toml", data))
    message = str(error.value)
    assert "huge.toml: render.spp = 1000000000: each sample takes" in message
    assert "on 2 core(s)" in message and "lower render.spp or render.resolution" in message

    long = _config({"render": {"resolution": [16, 16], "spp": 2**20}})
    announce_time(long, 3)
    err = capsys.readouterr().err.strip()
    assert err.startswith("dopplertof: dataset: 3 sample(s), each ") and "in all" in err, err
    announce_time(_config(), 3)
    assert capsys.readouterr().err == ""


@pytest.mark.parametrize("changes, words", [
    # D46: each sample failed "nothing in the image is lit ...; give photons_per_unit"
    ({"backdrop": {"kind": "none"}, "objects": {"count": [0, 0]}},
     "backdrop.kind = 'none' with objects.count [0, 0]: a sample without objects has "
     "nothing to see"),
    # D47: the same, for a light of intensity 0
    ({"render": {"light_intensity": [0.0, 0.0]}},
     "render.light_intensity out of range (point light, W/sr, > 0), got [0.0, 0.0]"),
    # D55: the same, for a light 1e9 m away
    ({"light": {"placement": "offset", "offset": [1e9, 0.0, 0.0]}},
     "light.offset [1000000000.0, 0.0, 0.0] puts the light farther than 1000 m"),
    ({"light": {"placement": "offset", "offset": [5.0, 0.0, 0.0]}},
     "light.offset [5.0, 0.0, 0.0] puts the light outside the room [6.0, 4.0, 8.0]"),
    ({"backdrop": {"kind": "wall"}, "light": {"placement": "offset", "offset": [0, 0, 9.0]}},
     "puts the light behind the wall 8 m ahead")])
def test_a_configuration_with_nothing_lit_to_see_is_refused_at_load(changes, words):
    """issue 39, 2026-12-03 campaign D46, D47, D55: accepted, then every sample failed
    naming photons_per_unit, a key no dataset configuration has."""
    with pytest.raises(DatasetError) as error:
        _config(changes)
    assert words in str(error.value)


def test_a_diffuse_object_has_no_roughness_and_the_scenes_are_drawn_as_before():
    """A diffuse object's description carries no roughness (a diffuse BSDF has none),
    yet the number is still drawn, so a seed's scenes are the ones recorded: the
    descriptions of 8 samples against tests/fixtures/dataset_draws.json. Every choice,
    name and count is compared exactly; every float within 1e-12 relative (1e-15
    absolute): the draws are NumPy's PCG64, bitwise on any machine, but the rotations
    take sines and cosines from the CPU's libm, which may differ by an ulp (1.1e-16
    relative), and an entry is a product of a few such (a hash of the scene XML was
    one CPU's bits: another CPU failed it)."""
    from dopplertof.cameras.preset import load_preset
    from dopplertof.dataset.generate import draw_scene

    config = _config({"objects": {"count": [3, 3]}})
    preset = load_preset(config["render"]["camera"])
    with open(os.path.join(ROOT, "tests", "fixtures", "dataset_draws.json")) as f:
        recorded = json.load(f)
    kinds = set()
    for index in range(8):
        description = json.loads(json.dumps(draw_scene(config, index, preset),
                                            default=lambda o: o.tolist()))
        _assert_close_tree(description, recorded[index], f"sample {index}")
        for obj in description["objects"]:
            material = obj["material"]
            kinds.add(material["kind"])
            assert ("roughness" in material) == (material["kind"] != "diffuse"), material
    assert kinds == {"diffuse", "plastic", "conductor"}


def _assert_close_tree(got, expected, where: str):
    """``got`` equals ``expected`` (JSON values): floats within 1e-12 relative or 1e-15
    absolute, everything else exactly."""
    if isinstance(expected, dict):
        assert isinstance(got, dict) and set(got) == set(expected), where
        for key in expected:
            _assert_close_tree(got[key], expected[key], f"{where}.{key}")
    elif isinstance(expected, list):
        assert isinstance(got, list) and len(got) == len(expected), where
        for k, (a, b) in enumerate(zip(got, expected)):
            _assert_close_tree(a, b, f"{where}[{k}]")
    elif isinstance(expected, float):
        assert isinstance(got, (int, float)) and not isinstance(got, bool), where
        assert abs(got - expected) <= max(1e-12 * abs(expected), 1e-15), (where, got, expected)
    else:
        assert got == expected and type(got) is type(expected), (where, got, expected)


def test_a_samples_description_is_written_with_json_ready_floats(tiny):
    """issue 42 item 11 (2026-12-04): the HDF5 attributes description and camera_preset
    held floats such as 0.006500000000000001; they go through file_formats.json_ready (15
    significant digits, float32 values as their shortest decimal)."""
    from dopplertof.file_formats import json_ready

    ds = Dataset(tiny[1])
    for item in range(len(ds)):
        attributes = ds.attributes(item)
        for key in ("description", "camera_preset"):
            assert json.dumps(json_ready(attributes[key]), sort_keys=True) == \
                json.dumps(attributes[key], sort_keys=True), key
