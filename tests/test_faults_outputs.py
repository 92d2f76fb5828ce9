"""Outputs under faults (issue 22, items 11 and 14): a multi-file output is all or
nothing (a failed capture leaves the previous one in its folder byte-identical, stale
files of an earlier run never survive beside a new summary.json, a killed run's
leftovers go at the next run), and a failed write names the file and the reason."""

import contextlib
import hashlib
import os
import resource
import shutil
import signal
import subprocess
import sys

import numpy as np
import pytest

import dopplertof
from dopplertof import file_formats, image_files, io
from dopplertof.cli import main
from dopplertof.demo import demo_scene_path

SCENE = demo_scene_path()
SRC = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "src")


def _capture(res, spp=8, **options):
    scene = dopplertof.load_file(SCENE, {"res": res, "spp": spp})
    return dopplertof.capture(scene, spp=spp, seed=0, progress=False, **options)


@pytest.fixture(scope="module")
def captures():
    """Three small captures: two resolutions, and one with Monte Carlo batches."""
    dopplertof.set_variant("llvm_ad_rgb")
    return {"small": _capture(8), "large": _capture(16), "batches": _capture(8, mc_batches=2)}


@pytest.fixture
def cheap_previews(monkeypatch):
    """The capture's previews replaced by raw bytes of what they show (4 copies, so that
    a 16x16 preview is 8 kB and an 8x8 one 2 kB), written through the same atomic
    writer: matplotlib's 20 figures would take most of a minute per capture here."""
    from dopplertof.tof import output

    def preview(path, *args, **kwargs):
        shown = [np.asarray(a, np.float64) for a in args if isinstance(a, np.ndarray)]
        with io.atomic_path(path) as tmp:
            with open(tmp, "wb") as f:
                f.write(b"".join(a.tobytes() for a in shown) * 4)

    for name in ("write_map", "write_log_map", "write_comparison", "write_radiance"):
        monkeypatch.setattr(output.figures, name, preview)
    monkeypatch.setattr(image_files, "write_png", preview)


def _snapshot(folder) -> dict:
    """Every entry under ``folder`` (hidden ones too) with its content's hash."""
    entries = {}
    for root, dirs, files in os.walk(folder):
        for name in dirs + files:
            path = os.path.join(root, name)
            rel = os.path.relpath(path, folder)
            entries[rel] = (None if os.path.isdir(path) else
                            hashlib.sha256(open(path, "rb").read()).hexdigest())
    return entries


def _staging_left(folder) -> list:
    return [n for n in os.listdir(folder) if ".staging-" in n or ".tmp" in n]


@contextlib.contextmanager
def file_size_limit(nbytes: int):
    """RLIMIT_FSIZE in this process: a write past ``nbytes`` fails with EFBIG ("File too
    large"; Python ignores SIGXFSZ)."""
    soft, hard = resource.getrlimit(resource.RLIMIT_FSIZE)
    previous = signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
    resource.setrlimit(resource.RLIMIT_FSIZE, (nbytes, hard))
    try:
        yield
    finally:
        resource.setrlimit(resource.RLIMIT_FSIZE, (soft, hard))
        signal.signal(signal.SIGXFSZ, previous)


def _count_files_written(monkeypatch, fail_after=None):
    """Count io.atomic_path's files; with ``fail_after``, the next one raises."""
    original, calls = io.atomic_path, {"n": 0}

    @contextlib.contextmanager
    def counting(path):
        if fail_after is not None and calls["n"] == fail_after:
            raise RuntimeError(f"injected failure at file {calls['n']}")
        with original(path) as tmp:
            yield tmp
        calls["n"] += 1

    monkeypatch.setattr(io, "atomic_path", counting)
    return calls


# ---- Item 11: a failed capture leaves the previous one complete -------------------------

def test_a_file_size_limit_mid_capture_leaves_the_previous_capture_untouched(
        captures, cheap_previews, tmp_path, monkeypatch):
    """A real "file too large" after 13 files (the radiance preview, 24 kB, is the first
    over 16 kB): the old capture is byte-identical, nothing staged is left."""
    folder = tmp_path / "cap"
    captures["small"].write(folder)
    before = _snapshot(folder)
    calls = _count_files_written(monkeypatch)
    with file_size_limit(16_000), pytest.raises((OSError, ValueError)) as failure:
        captures["large"].write(folder)
    assert calls["n"] == 13  # the failure came mid-way
    assert _snapshot(folder) == before
    assert str(failure.value) == f"{folder / 'radiance.png'}: file too large (the file size limit)"


@pytest.mark.parametrize("fail_after", [0, 1, 12, 26])
def test_an_exception_at_any_file_leaves_the_previous_capture_untouched(
        captures, cheap_previews, tmp_path, monkeypatch, fail_after):
    """26: the failing file is summary.json, the last of the 27."""
    folder = tmp_path / "cap"
    captures["small"].write(folder)
    summary = (folder / "summary.json").read_text()
    before = _snapshot(folder)
    _count_files_written(monkeypatch, fail_after)
    with pytest.raises(RuntimeError, match="injected"):
        captures["large"].write(folder)
    assert _snapshot(folder) == before
    assert (folder / "summary.json").read_text() == summary
    assert np.load(folder / "velocity.npy").shape == (8, 8)  # still the old resolution


def test_a_failed_fresh_capture_leaves_no_folder(captures, cheap_previews, tmp_path,
                                                 monkeypatch):
    _count_files_written(monkeypatch, fail_after=7)
    with pytest.raises(RuntimeError, match="injected"):
        captures["small"].write(tmp_path / "a" / "b")
    assert os.listdir(tmp_path) == []


def test_a_new_capture_removes_the_std_maps_of_one_with_mc_batches(captures, cheap_previews,
                                                                   tmp_path):
    folder, fresh = tmp_path / "cap", tmp_path / "fresh"
    captures["batches"].write(folder)
    assert list(folder.glob("*_std*.npy"))
    captures["small"].write(folder)
    captures["small"].write(fresh)
    assert not list(folder.glob("*_std*"))
    assert _snapshot(folder) == _snapshot(fresh)  # exactly the new capture's files


def test_files_that_are_not_the_captures_are_left_alone(captures, cheap_previews, tmp_path,
                                                        monkeypatch):
    """The user's files, a subfolder, another output set (a fit) beside a capture, and
    `-o .`: none is moved or deleted."""
    (tmp_path / "notes.txt").write_text("mine")
    (tmp_path / "data").mkdir()
    (tmp_path / "data" / "x.npy").write_bytes(b"x")
    with io.output_folder(tmp_path, "fit") as staged:
        file_formats.write_json(staged.path("fit.json"), {"fit": 1})
    monkeypatch.chdir(tmp_path)
    captures["batches"].write(".")
    captures["small"].write(".")
    assert (tmp_path / "notes.txt").read_text() == "mine"
    assert (tmp_path / "data" / "x.npy").read_bytes() == b"x"
    assert (tmp_path / "fit.json").is_file() and (tmp_path / ".dopplertof-fit.json").is_file()
    assert not list(tmp_path.glob("*_std*")) and not _staging_left(tmp_path)


# ---- issue 39 (C04, C14, C15): a camera capture is one output set too ------------------

@pytest.fixture(scope="module")
def camera_captures():
    """Two kinect-v2 frames of a plane (4x4 pixels, 4 spp), of two noise seeds."""
    from analytic import plane_scene
    from dopplertof.cameras.capture import capture_camera

    dopplertof.set_variant("llvm_ad_rgb")
    scene = dopplertof.load_dict(plane_scene(4.0, 0.0, exposure=0.02, spp=4, res=4))
    return [capture_camera(scene, "kinect-v2", spp=4, noise_seed=seed, progress=False)
            for seed in (0, 1)]


@pytest.mark.parametrize("fail_after", [0, 5, 12])
def test_a_failed_camera_capture_leaves_the_previous_one_untouched(
        camera_captures, tmp_path, monkeypatch, fail_after):
    """A camera capture failing (an interrupt, a kill, a full disk) at its 1st, 6th or
    13th file into the folder of a complete one leaves that one byte-identical (the
    arrays were written file by file: the new raw.npy beside the old summary.json)."""
    first, second = camera_captures
    folder = tmp_path / "cap"
    first.write(folder)
    before = _snapshot(folder)
    _count_files_written(monkeypatch, fail_after)
    with pytest.raises(RuntimeError, match="injected"):
        second.write(folder)
    assert _snapshot(folder) == before and not _staging_left(folder)


def test_a_camera_capture_replaces_the_previous_one_whole_or_leaves_no_folder(
        camera_captures, tmp_path, monkeypatch):
    first, second = camera_captures
    folder, fresh = tmp_path / "cap", tmp_path / "fresh"
    first.write(folder)
    paths = second.write(folder)
    second.write(fresh)
    assert _snapshot(folder) == _snapshot(fresh)
    assert sorted(os.path.basename(p) for p in paths) == sorted(
        n for n in os.listdir(folder) if n != io.manifest_name("capture"))
    _count_files_written(monkeypatch, fail_after=3)
    with pytest.raises(RuntimeError, match="injected"):
        first.write(tmp_path / "a" / "b")
    assert not (tmp_path / "a").exists()


# ---- Item 11: the other commands' output sets -----------------------------------------

def test_a_failed_fit_leaves_the_previous_fit_json_and_plot(tmp_path, monkeypatch):
    from dopplertof.diff import fit, fit_output

    result = fit.FitResult(bodies=[{"name": "box"}], iterations=1, loss=1.0,
                           history=[{"iteration": 0, "loss": 1.0, "radial_velocity_m_s": [2.0]}])
    fit.write_fit(result, tmp_path)
    before = _snapshot(tmp_path)

    def plot_fails(result, path):
        raise RuntimeError("injected failure in the plot")

    monkeypatch.setattr(fit_output, "write_convergence_plot", plot_fails)
    with pytest.raises(RuntimeError, match="injected"):
        fit.write_fit(fit.FitResult(bodies=[], iterations=2, loss=0.5), tmp_path)
    assert _snapshot(tmp_path) == before  # fit.json is still the first fit's


def _report_runs(folder, errors: bool) -> list:
    """Two sweep runs (8x8 images in their folders), with errors against a reference or
    without."""
    from dopplertof.experiments.report import RunRecord

    runs = []
    for k, method in enumerate(("uniform", "antithetic")):
        run_folder = folder / method
        run_folder.mkdir(parents=True, exist_ok=True)
        np.save(run_folder / "image.npy", np.full((8, 8, 3), 0.1 * (k + 1), np.float32))
        runs.append(RunRecord(name=f"time_sampling_method={method}",
                              point={"time_sampling_method": method}, spp=8, seed=0,
                              seconds=1.0, folder=str(run_folder), reference=None,
                              mse=1e-3 * (k + 1) if errors else None,
                              relative_mse=0.1 * (k + 1) if errors else None))
    return runs


def test_a_report_replaces_the_previous_one_all_or_nothing(tmp_path, monkeypatch):
    """A report without errors removes the error figures of one with them; a report
    that fails half-way leaves the previous one as it was."""
    from dopplertof.experiments import report

    sweep = {"config": {"name": "t", "grid": {"time_sampling_method": ["uniform", "antithetic"]},
                        "grid_axes": ["time_sampling_method"]}}
    (tmp_path / "results").mkdir()
    out = tmp_path / "report"
    for errors in (True, False):
        runs = _report_runs(tmp_path / "results", errors)
        monkeypatch.setattr(report, "read_results", lambda results: (sweep, runs, {}, [], []))
        written = report.write_report(tmp_path / "results", out)
        assert written.files and all(os.path.isfile(f) for f in written.files)
        assert any("mse" in os.path.basename(f) for f in written.files) == errors
    assert not list(out.glob("*mse*.png"))  # the first report's error figures are gone
    before = _snapshot(out)
    monkeypatch.setattr(report, "_metrics_csv", lambda *args: 1 / 0)
    with pytest.raises(ZeroDivisionError):
        report.write_report(tmp_path / "results", out)
    assert _snapshot(out) == before


def test_a_new_sweep_plan_never_sits_beside_the_last_runs_summary(tmp_path):
    from types import SimpleNamespace

    from dopplertof.experiments.sweep import write_sweep_files

    def config(name):
        return SimpleNamespace(to_json=lambda: {"name": name})

    summary = SimpleNamespace(to_json=lambda: {"done": 5})
    write_sweep_files(config("first"), [], str(tmp_path), summary)
    assert (tmp_path / "summary.json").is_file()
    write_sweep_files(config("second"), [], str(tmp_path))  # a new run starts
    assert not (tmp_path / "summary.json").exists()
    assert '"second"' in (tmp_path / "sweep.json").read_text()


# ---- Item 11: kills, and leftovers cleaned at the next run ------------------------------

_KILLED_WRITER = """
import os, signal, sys
from dopplertof import io
folder, moves_before_kill = sys.argv[1], int(sys.argv[2])
original, moved = os.replace, []
def replace_then_die(src, dst):
    original(src, dst)
    if ".staging-" in src and ".staging-" not in dst:
        moved.append(dst)
        if len(moved) == moves_before_kill:
            os.kill(os.getpid(), signal.SIGKILL)
os.replace = replace_then_die
with io.output_folder(folder, "set") as staged:
    for name in ("a.txt", "b.txt"):
        with open(staged.path(name), "w") as f:
            f.write("new " + name)
    if moves_before_kill == 0:
        os.kill(os.getpid(), signal.SIGKILL)
"""


def _old_set(folder):
    with io.output_folder(folder, "set") as staged:
        for name in ("a.txt", "stale.txt"):
            with open(staged.path(name), "w") as f:
                f.write("old " + name)


def _run_killed(folder, moves_before_kill):
    done = subprocess.run([sys.executable, "-c", _KILLED_WRITER, str(folder),
                           str(moves_before_kill)], env={**os.environ, "PYTHONPATH": SRC},
                          capture_output=True, text=True, timeout=60)
    assert done.returncode == -signal.SIGKILL, done.stderr


def test_a_run_killed_while_writing_leaves_the_old_set_and_its_leftovers_go(tmp_path):
    _old_set(tmp_path)
    before = _snapshot(tmp_path)
    _run_killed(tmp_path, 0)
    assert len(_staging_left(tmp_path)) == 1  # what a SIGKILL leaves
    assert {k: v for k, v in _snapshot(tmp_path).items() if ".staging-" not in k} == before
    _old_set(tmp_path)  # the next run
    assert _snapshot(tmp_path) == before


def test_a_run_killed_inside_its_commit_is_completed_by_the_next_run(tmp_path):
    _old_set(tmp_path)
    _run_killed(tmp_path, 1)  # killed after the first of its files was moved into place
    with io.output_folder(tmp_path, "other"):
        pass  # any next run into the folder completes the commit
    assert (tmp_path / "a.txt").read_text() == "new a.txt"
    assert (tmp_path / "b.txt").read_text() == "new b.txt"
    assert not (tmp_path / "stale.txt").exists() and not _staging_left(tmp_path)


def test_the_staging_folder_of_a_run_in_progress_is_left_alone(tmp_path):
    with io.output_folder(tmp_path, "set") as running:
        open(running.path("a.txt"), "w").write("running")
        _old_set(tmp_path)  # another run into the same folder meanwhile
        assert os.path.isfile(running.path("a.txt"))
    assert (tmp_path / "a.txt").read_text() == "running"  # the last to commit wins


# ---- Item 11: a real full disk ----------------------------------------------------------

@pytest.fixture
def tiny_disk(tmp_path):
    """Mount a tmpfs of a given size in kB (root and mount -t tmpfs needed; skipped
    otherwise); unmounted at the end."""
    if os.geteuid() != 0 or not shutil.which("mount"):
        pytest.skip("a tmpfs mount needs root and mount(8)")
    mount = tmp_path / "disk"
    mount.mkdir()
    mounted = []

    def make(size_kb: int):
        done = subprocess.run(["mount", "-t", "tmpfs", "-o", f"size={size_kb}k", "tmpfs",
                               str(mount)], capture_output=True, text=True)
        if done.returncode:
            pytest.skip(f"mount -t tmpfs is not allowed here: {done.stderr.strip()}")
        mounted.append(mount)
        return mount

    yield make
    for path in mounted:
        subprocess.run(["umount", str(path)], check=True)


def _kilobytes_used(folder) -> int:
    return sum(os.stat(os.path.join(root, n)).st_blocks // 2
               for root, _, files in os.walk(folder) for n in files)


def test_a_full_disk_mid_capture_leaves_the_previous_capture_untouched(
        captures, cheap_previews, tiny_disk, tmp_path):
    """A disk with room for the old capture and half the new one beside it."""
    measure = tmp_path / "measure"
    captures["small"].write(measure / "small")
    captures["large"].write(measure / "large")
    size = _kilobytes_used(measure / "small") + _kilobytes_used(measure / "large") // 2
    folder = tiny_disk(size + 16) / "cap"
    captures["small"].write(folder)
    before = _snapshot(folder)
    with pytest.raises((OSError, ValueError), match="No space left on device"):
        captures["large"].write(folder)
    assert _snapshot(folder) == before


# ---- Item 14: a failed write names the file and the reason ------------------------------

@pytest.mark.parametrize("ext", [".npy", ".exr", ".png"])
def test_a_failed_write_names_the_file_and_the_reason(tmp_path, ext):
    path = tmp_path / f"depth{ext}"
    image = np.random.default_rng(0).random((64, 64, 3)).astype(np.float32)
    with file_size_limit(4096), pytest.raises(io.OutputError) as failure:
        image_files.write_image(path, image)
    assert str(failure.value) == f"{path}: file too large (the file size limit)"
    assert os.listdir(tmp_path) == []


def test_the_cli_says_it_in_one_line_with_exit_2(tmp_path, monkeypatch, capsys):
    out = tmp_path / "out" / "depth.npy"
    original = image_files.write_image

    def limited(*args, **kwargs):
        with file_size_limit(256):
            return original(*args, **kwargs)

    monkeypatch.setattr(image_files, "write_image", limited)
    code = main(["render", SCENE, "-D", "res=8", "--spp", "2", "--quiet", "-o", str(out)])
    err = capsys.readouterr().err
    assert code == 2
    assert err == f"dopplertof: error: {out}: file too large (the file size limit)\n"


def test_json_floats_are_written_to_fifteen_significant_digits(tmp_path):
    """issue 42: a sum's rounding (0.1 * 0.1 = 0.010000000000000002, 0.03 - 0.02 =
    0.009999999999999998) read as noise in summary.json; float32 values keep their
    shortest decimal; integers, infinities and NaN pass as they are."""
    import json

    from dopplertof import file_formats

    path = tmp_path / "a.json"
    file_formats.write_json(path, {"a": 0.03 - 0.02, "b": [0.1 * 0.1, np.float64(1 / 3)],
                         "c": np.float32(0.0015), "d": 7, "e": float("inf"), "f": 123456.789})
    text = path.read_text()
    assert "0.0099999" not in text and "0.0100000" not in text
    got = json.loads(text)
    assert got["a"] == 0.01 and got["b"] == [0.01, 0.333333333333333] and got["c"] == 0.0015
    assert got["d"] == 7 and got["e"] == float("inf") and got["f"] == 123456.789
