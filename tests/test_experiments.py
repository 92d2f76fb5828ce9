"""Sweeps, animations and reports on Dask distributed (tiny images, 2 worker processes)."""

import argparse
import glob
import json
import os
import signal
import threading
import time
import types

import numpy as np
import pytest

from dopplertof.demo import demo_scene_path
from dopplertof.experiments import (ConfigError, ReportError, config_from_mapping,
                                    load_config, plan_sweep, preset_config, run_animation,
                                    run_sweep, write_report)
from dopplertof.experiments.cli import add_subcommands
from dopplertof.experiments.cluster import run_tasks
from dopplertof.experiments.tasks import COMPLETE_MARKER

SCENE = demo_scene_path()
RUN_FILES = {"image.npy", "image.exr", "params.json", COMPLETE_MARKER}


def tiny_config(**changes):
    """2 methods x 2 correlation depths on an 8x8 heterodyne Cornell box + a reference."""
    data = {
        "name": "tiny-test",
        "scene": SCENE,
        "defines": {"res": 8, "max_depth": 3},
        "fixed": {"spp": 8, "seed": 0, "hetero_frequency": 1.0},
        "grid": {"time_sampling_method": ["uniform", "antithetic"],
                 "path_correlation_depth": [0, "full"]},
        "reference": {"spp": 64},
    }
    data.update(changes)
    data = {k: v for k, v in data.items() if v is not None}  # None: leave the table out
    return config_from_mapping(data, source="test.toml")


class UnusableClient:
    """Stands in for a Dask client that must not be touched."""

    def __getattr__(self, name):
        raise AssertionError(f"the Dask client was used ({name}) although nothing should run")


def partial_files(root):
    return glob.glob(os.path.join(glob.escape(str(root)), "**", ".*.tmp*"), recursive=True)


def snapshot(root):
    return {p: os.stat(p).st_mtime_ns
            for p in glob.glob(os.path.join(glob.escape(str(root)), "**", "*"), recursive=True)
            if os.path.isfile(p) and not p.endswith("summary.json")}


@pytest.fixture(scope="module")
def client():
    from distributed import Client, LocalCluster
    import logging

    cluster = LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                           dashboard_address=":0", silence_logs=logging.ERROR)
    with Client(cluster) as c:
        yield c
    cluster.close()


# ---- Configuration: rejected before anything runs --------------------------------------

@pytest.mark.parametrize("changes, message", [
    ({"grid": {}}, "the grid is empty"),
    ({"grid": {"hetero_offset": []}}, "grid.hetero_offset is an empty list"),
    ({"grid": {"hetero_frequencyy": [0, 1]}}, "unknown parameter 'hetero_frequencyy'"),
    ({"fixed": {"colour": "red"}}, "unknown parameter 'colour'"),
    ({"grid": {"hetero_offset": 0.5}}, "must be a list of values"),
    ({"grid": {"path_correlation_depth": [1, "deep"]}}, "must be an integer"),
    ({"grid": {"time_sampling_method": ["uniform", "sobol"]}}, "unknown time_sampling_method"),
    ({"grid": {"hetero_offset": [0.25, 0.25]}}, "repeats the value 0.25"),
    ({"grid": {"spp": [8, 16]}, "fixed": {"spp": 8}}, "both fixed and in the grid"),
    ({"reference": {"spp": 64, "seed": 0}}, "also a seed of the runs"),
    ({"reference": {"spp": 64, "hetero_frequency": 0}}, "changes the expected image"),
    ({"reference": {"seed": 5}}, "give the reference's spp"),
    ({"scene": "missing.xml"}, "scene file not found"),
    ({"outputs": "x"}, "unknown key outputs"),
    ({"varaint": "x"}, "unknown key varaint, did you mean 'variant'?"),
    ({"name": 3}, "name must be a string (the sweep's label"),
    ({"fixed": 3}, "[fixed] must be a table, got 3"),
])
def test_bad_config_is_rejected_with_the_reason(changes, message):
    with pytest.raises(ConfigError) as err:
        tiny_config(**changes)
    text = str(err.value)
    assert message in text and "\n" not in text


def test_bad_config_is_rejected_before_any_task_starts(tmp_path):
    out = tmp_path / "results"
    # valid on its own, refused against the scene: 3 spp cannot form pairs (K = 2)
    config = tiny_config(fixed={"hetero_frequency": 1.0}, grid={"spp": [8, 3]})
    with pytest.raises(ConfigError, match="spp 3 is not a multiple"):
        run_sweep(config, out, client=UnusableClient(), progress=False)
    assert not out.exists()
    # through the command line: a TOML naming an unknown parameter
    toml = tmp_path / "bad.toml"
    toml.write_text(f'scene = "{SCENE}"\n[grid]\nhetero_frequncy = [0, 1]\n')
    args = parse(["sweep", str(toml), "-o", str(out), "--workers", "2", "--quiet"])
    with pytest.raises(ConfigError, match="unknown parameter 'hetero_frequncy'"):
        args.func(args)
    assert not out.exists()


def parse(argv):
    parser = argparse.ArgumentParser(prog="dopplertof")
    add_subcommands(parser.add_subparsers(dest="command", required=True))
    return parser.parse_args(argv)


def test_cli_refuses_mixed_inputs(tmp_path):
    out = str(tmp_path / "r")
    for argv, message in (
            (["sweep", "--preset", "time-sampling", "-o", out], "needs --scene"),
            (["sweep", "-o", out], "give a sweep configuration"),
            (["sweep", "examples/sweep_tiny.toml", "--spp", "8", "-o", out], "--spp applies"),
    ):
        args = parse(argv)
        with pytest.raises(ConfigError, match=message):
            args.func(args)
    assert not os.path.exists(out)


def test_shipped_example_is_valid():
    here = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    config = load_config(os.path.join(here, "examples", "sweep_tiny.toml"))
    assert len(config.points()) >= 4 and config.reference is not None
    assert os.path.isfile(config.scene)


def test_presets_reproduce_the_paper_grids(tmp_path):
    ts = preset_config("time-sampling", SCENE)
    assert len(ts.points()) == 4 * 4 * 11 * 11
    tasks = plan_sweep(ts, tmp_path / "ts")
    runs = [t for t in tasks if t.kind == "run"]
    refs = [t for t in tasks if t.kind == "reference"]
    assert len(runs) == 1936 and len(refs) == 121  # one reference per (frequency, offset)
    assert len({t.folder for t in tasks}) == len(tasks)
    assert {r.reference for r in runs} == {os.path.relpath(r.folder, tmp_path / "ts")
                                           for r in refs}
    assert all(r.seed != runs[0].seed for r in refs)
    shift = preset_config("antithetic-shift", SCENE, quick=True)
    assert set(shift.grid["antithetic_shift"]) == {0.0, 0.25, 0.5, 0.75, 1.0}
    nfs = preset_config("no-further-stratification", SCENE)
    assert nfs.grid["use_stratified_sampling_for_each_interval"] == (True, False)
    ref = preset_config("reference", SCENE, spp=64)
    assert ref.reference is None and len(ref.points()) == 4 and ref.fixed["spp"] == 64
    assert not (tmp_path / "ts").exists()  # planning writes nothing


# ---- Running -----------------------------------------------------------------------------

def test_tiny_sweep_writes_everything_and_a_rerun_does_nothing(tmp_path, client):
    out = tmp_path / "results" / "tiny"  # as in the README: the parent is missing too
    summary = run_sweep(tiny_config(), out, client=client, progress=False)
    assert summary.ok and summary.done == 5 and summary.skipped == 0

    names = sorted(os.listdir(out / "runs"))
    assert names == sorted(f"time_sampling_method={m}__path_correlation_depth={d}"
                           for m in ("uniform", "antithetic") for d in ("0", "full"))
    import mitsuba as mi

    for folder in [out / "runs" / n for n in names] + [out / "reference" / "default"]:
        assert set(os.listdir(folder)) == RUN_FILES
        image = np.load(folder / "image.npy")
        assert image.shape == (8, 8, 3) and np.isfinite(image).all()
        exr = np.array(mi.Bitmap(str(folder / "image.exr")))
        np.testing.assert_array_equal(exr, image)
        record = json.loads((folder / "params.json").read_text())
        assert record["versions"]["mitsuba"] and record["versions"]["distributed"]
        assert record["task_seconds"] > 0 and record["seed"] == (0 if record["kind"] == "run"
                                                                 else 1_000_003)
        assert record["params"]["hetero_frequency"] == 1.0
        if record["kind"] == "run":
            assert record["params"]["time_sampling_method"] == record["grid_point"][
                "time_sampling_method"]
            assert record["reference"] == os.path.join("reference", "default")
    assert not partial_files(out)
    assert json.loads((out / "summary.json").read_text())["done"] == 5

    before = snapshot(out)
    again = run_sweep(tiny_config(), out, client=UnusableClient(), progress=False)
    assert again.done == 0 and again.skipped == 5 and again.ok
    after = snapshot(out)
    assert {p: t for p, t in after.items() if not p.endswith("sweep.json")} == \
        {p: t for p, t in before.items() if not p.endswith("sweep.json")}

    # an interrupted task (no marker, a truncated array, a temporary file left by a
    # killed write) and a task whose marker describes other settings are redone
    broken = out / "runs" / names[0]
    (broken / COMPLETE_MARKER).unlink()
    (broken / "image.npy").write_bytes(b"truncated")
    (broken / ".image.k3j2.tmp.npy").write_bytes(b"partial")
    stale = out / "runs" / names[1]
    marker = json.loads((stale / COMPLETE_MARKER).read_text())
    marker["spec_hash"] = "0" * 64
    (stale / COMPLETE_MARKER).write_text(json.dumps(marker))
    repaired = run_sweep(tiny_config(), out, client=client, progress=False)
    assert repaired.done == 2 and repaired.skipped == 3 and repaired.ok
    # the interrupted one is reported as left incomplete (the stale one is not)
    assert repaired.partial == [names[0]]
    assert json.loads((out / "summary.json").read_text())["partial_before"] == [names[0]]
    assert np.load(broken / "image.npy").shape == (8, 8, 3)
    assert not partial_files(out)

    # a different fixed setting makes every point stale (folder names hold only grid values)
    changed = tiny_config(fixed={"spp": 16, "seed": 0, "hetero_frequency": 1.0})
    assert len(plan_sweep(changed, out)) == 5
    from dopplertof.experiments.sweep import pending_tasks
    assert len(pending_tasks(plan_sweep(changed, out), clean=False)) == 4

    report = write_report(out, tmp_path / "report")
    written = {os.path.basename(f) for f in report.files}
    assert {"relative_mse_by_method.png", "images.png", "metrics.csv", "summary.md"} <= written
    for f in report.files:
        assert os.path.getsize(f) > 0
    md = (tmp_path / "report" / "summary.md").read_text()
    assert "| antithetic | full |" in md and "relative MSE" in md
    rows = (tmp_path / "report" / "metrics.csv").read_text().splitlines()
    assert len(rows) == 1 + 4
    # antithetic time with the whole path shared beats uniform time with independent
    # paths on a heterodyne image (design.md section 2), even at 8 spp (relative MSE
    # ratio against a 64 spp reference: over 300 other seeds median 0.0014, 1% above
    # 0.08, at most 0.15; a power-law tail fitted to them exceeds 1/4 with about 1e-4)
    metrics = {r.split(",")[0]: float(r.split(",")[5]) for r in rows[1:]}
    best = metrics["time_sampling_method=antithetic__path_correlation_depth=full"]
    worst = metrics["time_sampling_method=uniform__path_correlation_depth=0"]
    assert best < worst / 4


def test_report_refuses_a_folder_without_results(tmp_path):
    with pytest.raises(ReportError, match="not a sweep results folder"):
        write_report(tmp_path, tmp_path / "report")


def test_failing_task_is_retried_then_reported_without_stopping_the_others(tmp_path, client):
    out = tmp_path / "results"
    config = tiny_config(grid={"hetero_offset": [0.0, 0.25]}, reference=None)
    blocked = out / "runs" / "hetero_offset=0.25"
    blocked.parent.mkdir(parents=True)
    blocked.write_text("a file where the task's folder should be")
    summary = run_sweep(config, out, client=client, retries=1, progress=False)
    assert summary.done == 1 and [name for name, _ in summary.failed] == ["hetero_offset=0.25"]
    error = summary.failed[0][1]
    assert "Error" in error and "\n" not in error
    assert set(os.listdir(out / "runs" / "hetero_offset=0")) == RUN_FILES
    recorded = json.loads((out / "summary.json").read_text())
    assert recorded["failed"][0]["task"] == "hetero_offset=0.25"


def test_retries_rerun_a_raising_task(tmp_path, client):
    attempts = tmp_path / "attempts"
    attempts.mkdir()

    def flaky(task):  # fails on its first two attempts (pickled by value)
        import os
        import uuid

        open(os.path.join(task.attempts, uuid.uuid4().hex), "w").close()
        if len(os.listdir(task.attempts)) < 3:
            raise RuntimeError("transient failure")
        return task.name

    task = types.SimpleNamespace(name="flaky", hash="0" * 16, attempts=str(attempts))
    outcome = run_tasks(client, flaky, [task], retries=2, progress=False)
    assert outcome.done == ["flaky"] and not outcome.failed
    assert len(os.listdir(attempts)) == 3

    for f in os.listdir(attempts):
        os.unlink(attempts / f)
    outcome = run_tasks(client, flaky, [types.SimpleNamespace(
        name="flaky2", hash="1" * 16, attempts=str(attempts))], retries=1, progress=False)
    assert outcome.failed == [("flaky2", "RuntimeError: transient failure")]
    assert len(os.listdir(attempts)) == 2


def test_two_runs_of_one_configuration_on_one_scheduler_each_fill_their_own_folder(
        tmp_path, client):
    """issue 39, P1-19 to P1-21: two runs of the same tasks (same names, same spec
    hashes) into two folders at the same time on one scheduler both run every task in
    their own folder (the Dask key held no folder: the second run's futures were the
    first run's tasks, its folder stayed empty while it reported them done)."""
    from dopplertof.experiments.cluster import run_in_folder

    def write_marker(task):  # (pickled by value)
        import os
        import time

        time.sleep(0.3)
        os.makedirs(task.folder, exist_ok=True)
        open(os.path.join(task.folder, "done"), "w").close()
        return task.folder

    outcomes = {}

    def run(name):
        tasks = [types.SimpleNamespace(name=f"t{i}", hash="5" * 16,
                                       folder=str(tmp_path / name / f"t{i}"))
                 for i in range(3)]
        outcomes[name] = run_in_folder(write_marker, tasks, str(tmp_path / name),
                                       client=client, progress=False)

    threads = [threading.Thread(target=run, args=(name,)) for name in "AB"]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join(timeout=60)
    for name in "AB":
        assert not outcomes[name].failed
        assert sorted(outcomes[name].done) == [str(tmp_path / name / f"t{i}") for i in range(3)]
        assert sorted(os.listdir(tmp_path / name)) == ["t0", "t1", "t2"]


def test_killed_worker_loses_nothing(tmp_path):
    """SIGKILL the worker process that is rendering a point: Dask reruns the point on a
    live worker, the sweep completes, no partial file is left, a rerun has nothing to do."""
    from distributed import Client, LocalCluster
    import logging

    out = tmp_path / "results"
    # renders long enough (about a second each) to be caught in the middle
    config = tiny_config(defines={"res": 16, "max_depth": 3},
                         fixed={"spp": 2048, "hetero_frequency": 1.0},
                         grid={"seed": [0, 1, 2, 3]}, reference=None)
    cluster = LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                           dashboard_address=":0", silence_logs=logging.CRITICAL)
    try:
        with Client(cluster) as c:
            pids = c.run(os.getpid)
            result = {}
            sweep = threading.Thread(target=lambda: result.update(
                summary=run_sweep(config, out, client=c, progress=False)))
            sweep.start()
            victim = None
            deadline = time.monotonic() + 90
            while victim is None and time.monotonic() < deadline and sweep.is_alive():
                for worker, keys in c.processing().items():
                    for key in keys:
                        name = key.split("dopplertof-", 1)[1].rsplit("-", 1)[0]
                        folder = out / "runs" / name
                        if folder.is_dir() and not (folder / COMPLETE_MARKER).exists():
                            victim = (worker, name)
                            break
                    if victim:
                        break
                time.sleep(0.05)
            assert victim is not None, "no task was seen running"
            killed_pid = pids[victim[0]]
            os.kill(killed_pid, signal.SIGKILL)
            sweep.join(timeout=180)
            assert not sweep.is_alive()
    finally:
        cluster.close()

    summary = result["summary"]
    assert summary.ok and summary.done == 4
    record = json.loads((out / "runs" / victim[1] / "params.json").read_text())
    assert record["worker"]["pid"] != killed_pid  # it was redone elsewhere
    for name in os.listdir(out / "runs"):
        assert set(os.listdir(out / "runs" / name)) == RUN_FILES
    assert not partial_files(out)
    again = run_sweep(config, out, client=UnusableClient(), progress=False)
    assert again.done == 0 and again.skipped == 4


def test_a_changed_mesh_makes_the_sweep_render_again(tmp_path, client):
    """Run markers hold the content of every file the scene references: after wall.obj
    changed, both runs are redone with the new wall (they were skipped: "0 done now, 2
    already complete", the old mesh's images)."""
    from test_faults_inputs import NARROW_WALL, write_scene

    (tmp_path / "scene").mkdir()
    scene = write_scene(tmp_path / "scene")
    config = config_from_mapping({"scene": str(scene), "fixed": {"spp": 8},
                                  "grid": {"seed": [0, 1]}}, source="mesh.toml")
    out = tmp_path / "out"
    assert run_sweep(config, out, client=client, progress=False).done == 2
    old = np.load(out / "runs" / "seed=0" / "image.npy")
    (tmp_path / "scene" / "wall.obj").write_text(NARROW_WALL)
    again = run_sweep(config, out, client=client, progress=False)
    assert again.ok and again.done == 2 and again.skipped == 0
    assert not np.array_equal(np.load(out / "runs" / "seed=0" / "image.npy"), old)


def test_a_sweep_task_given_up_by_its_run_writes_nothing(tmp_path, monkeypatch):
    """A sweep's tasks did not ask whether their run gave them up (as a dataset's shard
    tasks do since DK06/DK06b): a task still running on an external scheduler after the
    client's Ctrl-C, or after the sweep's folder was deleted, rendered and wrote its run,
    making the deleted folder again. Now it asks before the render and before the
    writes, and writes nothing."""
    import shutil

    import dopplertof
    from dopplertof.experiments import tasks as task_module
    from dopplertof.experiments.sweep import write_sweep_files
    from dopplertof.experiments.tasks import run_render_task

    out = tmp_path / "results"
    config = tiny_config(grid={"time_sampling_method": ["uniform"]}, reference=None)
    task = plan_sweep(config, out)[0]
    assert run_render_task(task)["given_up"] and not out.exists()  # (never made)
    write_sweep_files(config, [task], str(out))
    real = dopplertof.render_result

    def deleting(*args, **kwargs):  # the user gives up on the run during the render
        result = real(*args, **kwargs)
        shutil.rmtree(out)
        return result

    monkeypatch.setattr(dopplertof, "render_result", deleting)
    assert run_render_task(task)["given_up"] and not out.exists()
    monkeypatch.setattr(dopplertof, "render_result", real)
    monkeypatch.setattr(task_module, "task_abandoned", lambda: True)  # its Dask task cancelled
    write_sweep_files(config, [task], str(out))
    assert run_render_task(task)["given_up"] and not os.path.exists(task.folder)


def test_a_sweep_left_incomplete_is_reported_and_resumed(tmp_path, capsys):
    """A sweep folder whose earlier run stopped midway (one run folder begun, no
    complete.json, a temporary file): the dry run and the run name it as left
    incomplete; the run renders it again and nothing partial is left."""
    from dopplertof.experiments.sweep import write_sweep_files
    from dopplertof.experiments.tasks import begin_task

    out = tmp_path / "results"
    config = tiny_config(grid={"time_sampling_method": ["uniform", "antithetic"]},
                         reference=None)
    tasks = plan_sweep(config, out)
    write_sweep_files(config, tasks, str(out))
    begin_task(tasks[0].folder)
    (out / "runs" / tasks[0].name / ".image.x1.tmp.npy").write_bytes(b"partial")
    config_path = tmp_path / "sweep.toml"
    config_path.write_text(
        f"name = 'tiny-test'\nscene = {json.dumps(SCENE)}\n[defines]\nres = 8\n"
        "max_depth = 3\n[fixed]\nspp = 8\nseed = 0\nhetero_frequency = 1.0\n"
        "[grid]\ntime_sampling_method = ['uniform', 'antithetic']\n")
    parser = argparse.ArgumentParser()
    add_subcommands(parser.add_subparsers(dest="command"))
    line = (f"  1 left incomplete by an earlier run (stopped or abandoned midway: no "
            f"complete.json): {tasks[0].name}; ")
    args = parser.parse_args(["sweep", str(config_path), "-o", str(out), "--dry-run"])
    assert args.func(args) == 0
    assert line + "a run renders them again" in capsys.readouterr().out
    args = parser.parse_args(["sweep", str(config_path), "-o", str(out), "--workers", "1"])
    assert args.func(args) == 0
    printed = capsys.readouterr().out
    assert "2 done now" in printed and line + "rendered again" in printed
    assert not partial_files(out)
    assert set(os.listdir(out / "runs" / tasks[0].name)) == RUN_FILES


def test_report_calls_runs_of_another_spec_stale(tmp_path, capsys):
    """A complete sweep at 8 spp, then the same folder at 16 spp stopped after one run
    (sweep.json already rewritten, as a killed run leaves it): the report measures
    that run only and lists the other 8-spp run as stale, with its reason (it was
    reported as a 16-spp run with the 8-spp run's error). The tasks run in this
    process, as run_sweep's workers run them."""
    from dopplertof.experiments.sweep import pending_tasks, write_sweep_files
    from dopplertof.experiments.tasks import run_render_task

    out, grid = tmp_path / "results", {"time_sampling_method": ["uniform", "antithetic"]}
    rerun = tiny_config(grid=grid, fixed={"spp": 16, "seed": 0, "hetero_frequency": 1.0})
    for config, killed_after in ((tiny_config(grid=grid), None), (rerun, 1)):
        tasks = plan_sweep(config, out)
        write_sweep_files(config, tasks, str(out))
        for task in pending_tasks(tasks)[:killed_after]:
            run_render_task(task)
    redone, stale = (t.name for t in tasks if t.kind == "run")

    parser = argparse.ArgumentParser()
    add_subcommands(parser.add_subparsers(dest="command"))
    args = parser.parse_args(["report", str(out), "-o", str(tmp_path / "report")])
    assert args.func(args) == 0
    printed = capsys.readouterr().out
    assert "(1 runs, 1 with errors" in printed and "1 stale tasks excluded" in printed
    rows = (tmp_path / "report" / "metrics.csv").read_text().splitlines()
    assert len(rows) == 2 and rows[1].startswith(redone + ",")
    md = (tmp_path / "report" / "summary.md").read_text()
    assert "stale tasks (excluded): 1" in md
    assert f"- `runs/{stale}`: params.json says spp 8, the sweep's spec 16" in md


# ---- Animation -----------------------------------------------------------------------------

def test_animation_frames_shift_the_exposure(tmp_path):
    """The demo's boxes move during [0, 1.5 ms] and hold still afterwards: frame 0
    (exposure 0-1.5 ms) sees them move, frame 2 (3-4.5 ms) sees a still scene."""
    from PIL import Image

    out = tmp_path / "frames"
    summary = run_animation(SCENE, out, 3, defines={"res": 8, "max_depth": 3}, spp=8,
                            workers=2, progress=False)
    assert summary.ok and summary.done == 3
    starts = []
    for k in range(3):
        folder = out / f"frame_{k:04d}"
        assert (folder / COMPLETE_MARKER).is_file()
        for name in ("velocity.npy", "velocity_gt.npy", "velocity.exr", "heterodyne_0.npy",
                     "homodyne_0.25.npy", "radiance.npy", "depth.npy", "summary.json"):
            assert (folder / name).is_file(), name
        starts.append(json.loads((folder / "params.json").read_text())["exposure_start_s"])
    np.testing.assert_allclose(starts, [0.0, 0.0015, 0.003], atol=1e-9)
    moving = np.load(out / "frame_0000" / "velocity_gt.npy")
    still = np.load(out / "frame_0002" / "velocity_gt.npy")
    assert np.nanmax(np.abs(moving)) > 5  # 10 m/s boxes
    assert np.nanmax(np.abs(still)) == 0
    gif = Image.open(out / "velocity.gif")
    assert gif.n_frames == 3
    assert not partial_files(out)
    again = run_animation(SCENE, out, 3, defines={"res": 8, "max_depth": 3}, spp=8,
                          client=UnusableClient(), progress=False)
    assert again.done == 0 and again.skipped == 3 and again.video


def test_a_changed_mesh_changes_the_frames_markers_and_stops_a_planned_frame(tmp_path):
    """Frame markers hash the files the scene references like sweep markers; a frame
    planned before its mesh changed refuses to render (the check passes for the
    frame's own scene, whose shutter is rewritten)."""
    from dopplertof.experiments.animate import plan_animation, run_frame_task
    from test_faults_inputs import NARROW_WALL, write_scene

    scene = write_scene(tmp_path)
    planned = plan_animation(scene, tmp_path / "frames", 2, spp=8)
    run_frame_task(planned[0])
    assert (tmp_path / "frames" / "frame_0000" / COMPLETE_MARKER).is_file()
    (tmp_path / "wall.obj").write_text(NARROW_WALL)
    replanned = plan_animation(scene, tmp_path / "frames", 2, spp=8)
    assert [t.hash for t in replanned] != [t.hash for t in planned]
    with pytest.raises(RuntimeError, match="or a file it references changed"):
        run_frame_task(planned[1])


def test_animation_json_writes_float32_times_as_their_shortest_decimal(tmp_path):
    """The scene's exposure comes from Mitsuba's float32 shutter: animation.json says
    0.0015, not 0.001500000013038516 (and its frames' starts 0.0015 apart)."""
    from dopplertof.experiments.animate import (AnimationSummary, _write_animation_json,
                                                plan_animation)

    tasks = plan_animation(SCENE, tmp_path / "frames", 2, defines={"res": 4})
    assert tasks[0].params["time"] != 0.0015  # (the float32 value, as a float64)
    path = tmp_path / "animation.json"
    _write_animation_json(path, tasks, AnimationSummary(frames=2, skipped=0, done=2), 10.0,
                          None)
    text = path.read_text()
    assert '"exposure_s": 0.0015,' in text and "0.0015000000" not in text
    record = json.loads(text)
    assert record["frame_period_s"] == 0.0015 and record["params"]["time"] == 0.0015
    assert np.float32(record["exposure_s"]) == np.float32(tasks[0].params["time"])
