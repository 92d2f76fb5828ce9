"""The dataset rows of the fault campaign of issue 53 (docs/reliability.md, *Campaign
2026-12-07*): an edited dataset.json (SH15, SH16, SH19), exports of a dataset with a
failed sample (EX01), into a folder written meanwhile (CC05), onto a full disk (FD05),
after a killed export (EI02-EI06), and the arguments verify is called with (OU24, PA39)."""

import contextlib
import errno
import fcntl
import json
import os
import shutil

import numpy as np
import pytest

pytest.importorskip("h5py")

from dopplertof.dataset import Dataset, DatasetError  # noqa: E402
from test_dataset import TINY, _shard_bytes, _write_toml, in_process_client, tiny  # noqa: E402,F401


def _edited_copy(tiny, tmp_path, edit, keep_digest=True):
    """A copy of the tiny dataset whose dataset.json ``edit(info)`` changed."""
    out = tmp_path / "out"
    shutil.copytree(tiny[1], out)
    info = json.loads((out / "dataset.json").read_text())
    edit(info)
    if not keep_digest:
        info.pop("sha256")
    (out / "dataset.json").write_text(json.dumps(info, indent=2))
    return str(out)


def _drop_shard(info):
    del info["shards"][1]


def _units_mm(info):
    info["units"]["depth"] = "mm"


def _other_hash(info):
    info["config_hash"] = "0" * 64


def _failed_listed(info):
    info["failed_samples"] = [{"index": 2, "error": "made up"}]


EDITS = [  # (id, edit, the words naming what is wrong, checksum kept)
    ("SH15", _drop_shard, "'shards' lists 2 shard(s) where 'samples' 3 at "
     "'samples_per_shard' 1 plan 3 (shard_00001.h5 left out)", True),
    ("SH15-no-checksum", _drop_shard, "(shard_00001.h5 left out)", False),
    ("SH16", _units_mm, "'units.depth' is 'mm' where the shards store 'm'", True),
    ("SH16-no-checksum", _units_mm, "'units.depth' is 'mm'", False),
    ("SH19", _other_hash, "'config_hash' 000000000000 is not the one its shards were "
     "written with", True),
    ("edited", _failed_listed, "does not match its checksum 'sha256'", True),
]


@pytest.mark.parametrize("case, edit, words, keep", EDITS, ids=[e[0] for e in EDITS])
def test_an_edited_dataset_json_is_refused_by_the_reader_verify_and_export(
        tiny, tmp_path, capsys, case, edit, words, keep):
    """SH15, SH16: a shard taken out of dataset.json's list, or its units edited to mm,
    was served (len 2; Dataset.units['depth'] == 'mm' over values in metres) and verify
    said nothing; SH19: verify blamed the intact shards. Now the reader, verify (exit 1)
    and export (exit 2, nothing written) name dataset.json and the key."""
    from dopplertof.cli import main

    out = _edited_copy(tiny, tmp_path, edit, keep)
    with pytest.raises(DatasetError) as raised:
        Dataset(out)
    message = str(raised.value)
    assert len(message.splitlines()) == 1 and words in message
    assert message.startswith(os.path.join(out, "dataset.json"))
    assert main(["dataset", "verify", out]) == 1
    lines = capsys.readouterr().out.strip().splitlines()
    assert len(lines) == 2 and words in lines[0] and "shard of another" not in lines[0]
    exported = tmp_path / "exported"
    assert main(["dataset", "export", out, "--format", "torf", "-o", str(exported)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and words in err
    assert not exported.exists()


@pytest.mark.parametrize("edit", [_drop_shard, _other_hash], ids=["SH15", "SH19"])
def test_a_rerun_writes_an_edited_dataset_json_again(tiny, tmp_path, capsys, edit):
    """SH19: the rerun refused the folder ('another configuration') where verify blamed
    the shards; now a rerun with the configuration whose shards the folder holds writes
    dataset.json again, renders nothing and leaves the shards bitwise."""
    from dopplertof.cli import main

    out = _edited_copy(tiny, tmp_path, edit)
    before = _shard_bytes(out)
    assert main(["dataset", tiny[0], "-o", out, "--quiet"]) == 0
    assert _shard_bytes(out) == before == _shard_bytes(tiny[1])
    assert len(Dataset(out)) == 3 and main(["dataset", "verify", out]) == 0
    capsys.readouterr()


def test_an_edited_dataset_json_with_other_shards_is_still_refused(tiny, tmp_path, capsys):
    """An edited dataset.json does not let a rerun of another configuration claim the
    folder: its shards decide, and they are of another configuration."""
    from dopplertof.cli import main

    out = _edited_copy(tiny, tmp_path, _failed_listed)
    other = _write_toml(tmp_path / "other.toml", {**TINY, "seed": 8})
    before = _shard_bytes(out)
    assert main(["dataset", other, "-o", out, "--quiet"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "dataset.json was edited" in err
    assert _shard_bytes(out) == before


def test_verify_without_a_folder_names_the_folder(capsys):
    """OU24: `dopplertof dataset verify` read 'verify' as a configuration file; PA39:
    verify_dataset(None) raised os.fspath's TypeError."""
    from dopplertof.cli import main
    from dopplertof.dataset.driver import verify_dataset

    for words in (["verify"], ["export", "--format", "torf", "-o", "x"]):
        assert main(["dataset", *words]) == 2
        err = capsys.readouterr().err.strip()
        assert len(err.splitlines()) == 1
        assert f"dataset {words[0]} needs the dataset FOLDER" in err
    with pytest.raises(TypeError, match="folder must be a file path"):
        verify_dataset(None)


@pytest.fixture(scope="module")
def with_failed(tmp_path_factory, in_process_client):
    """Two samples in one shard, sample 1 failed."""
    from dopplertof.dataset import load_config, sample
    from dopplertof.dataset.driver import run_dataset

    folder = tmp_path_factory.mktemp("failed")
    real = sample.render_sample

    def failing(config, index, where):
        if index == 1:
            raise RuntimeError("out of luck")
        return real(config, index, where)

    sample.render_sample = failing
    try:
        config = load_config(_write_toml(folder / "two.toml",
                                         {**TINY, "samples": 2, "samples_per_shard": 2}))
        summary = run_dataset(config, folder / "out", client=in_process_client, retries=0,
                              progress=False)
    finally:
        sample.render_sample = real
    assert [f["index"] for f in summary.failed] == [1]
    return str(folder / "out")


def test_an_export_of_a_dataset_with_a_failed_sample_names_it(with_failed, tmp_path, capsys):
    """EX01: 'exported 3 samples' with exit 0 and nothing of the failed sample. Now the
    export is refused naming the sample (exit 2, nothing written); --skip-missing exports
    the others, says which is missing, and export.json lists it."""
    from dopplertof.cli import main

    out = tmp_path / "exp"
    assert main(["dataset", "export", with_failed, "--format", "torf", "-o", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "sample(s) 1 of 2 failed" in err
    assert "--skip-missing" in err and not out.exists()
    assert main(["dataset", "export", with_failed, "--format", "torf", "-o", str(out),
                 "--skip-missing"]) == 0
    captured = capsys.readouterr()
    assert "exported 1 samples" in captured.out and "sample(s) 1 missing" in captured.err
    info = json.loads((out / "export.json").read_text())
    assert info["samples"] == 1 and info["missing_samples"] == [1]
    assert sorted(os.listdir(out)) == ["export.json", "sample_00000000"]


def test_an_export_writes_the_bytes_np_save_writes(tiny, tmp_path):
    """The export's .npy files go through file_formats.write_npy now (FD05): the same
    bytes as np.save."""
    from dopplertof.cli import main

    out = tmp_path / "torf"
    assert main(["dataset", "export", tiny[1], "--format", "torf", "-o", str(out)]) == 0
    scan = out / "sample_00000000"
    for name in ("tof/0000.npy", "depth/0000.npy", "cams/depth_range.npy",
                 "cams/tof_extrinsics.npy"):
        array = np.load(scan / name)
        np.save(tmp_path / "ref.npy", array)
        assert (scan / name).read_bytes() == (tmp_path / "ref.npy").read_bytes()


class _FullFile:
    """A file whose writes fail as on a full disk."""

    def __init__(self, path, mode="r", *args, **kwargs):
        self.inner = open(path, mode, *args, **kwargs)

    def write(self, data):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    def __getattr__(self, name):
        return getattr(self.inner, name)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.inner.close()


@pytest.mark.parametrize("module", ["dopplertof.file_formats", "dopplertof.dataset.export"])
def test_an_export_onto_a_full_disk_names_the_file(tiny, tmp_path, capsys, monkeypatch,
                                                    module):
    """FD05: 'dopplertof: error: 3072 requested and 992 written' (np.save's and tofile's
    short-write message): no file, no reason. Now one line naming the file in OUT and
    'No space left on device'; nothing left."""
    import importlib

    from dopplertof.cli import main

    monkeypatch.setattr(importlib.import_module(module), "open", _FullFile, raising=False)
    out = tmp_path / "exp"
    if module == "dopplertof.file_formats":  # (TöRF's .npy files)
        assert main(["dataset", "export", tiny[1], "--format", "torf", "-o", str(out)]) == 2
        expected = os.path.join(str(out), "sample_00000000", "tof", "0000.npy")
    else:  # FLAT's raw files (the export needs a Kinect dataset: the writer alone)
        from dopplertof import io
        from dopplertof.dataset import export

        with pytest.raises(io.WriteError) as raised:
            export._write_raw(str(tmp_path / "raw"), np.zeros(4, np.int32))
        assert str(raised.value) == f"{tmp_path / 'raw'}: No space left on device"
        return
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and expected in err and "No space left on device" in err
    assert os.listdir(tmp_path) == []


def test_a_killed_exports_staging_folder_is_removed_by_the_next(tiny, tmp_path):
    """EI02, EI03, EI05, EI06: a TERM or KILL left a hidden .OUT.staging-* sibling that no
    later export removed. Now the next export into OUT removes a killed one (its lock
    free), and leaves a live one (locked) alone."""
    from dopplertof.cli import main

    dead, live = tmp_path / ".exp.staging-dead1234", tmp_path / ".exp.staging-live1234"
    for folder in (dead, live):
        (folder / "sample_00000000").mkdir(parents=True)
        (folder / "sample_00000000" / "partial.npy").write_bytes(b"x" * 100)
    fd = os.open(live, os.O_RDONLY | os.O_DIRECTORY)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        assert main(["dataset", "export", tiny[1], "--format", "torf", "-o",
                     str(tmp_path / "exp")]) == 0
        assert sorted(os.listdir(tmp_path)) == [live.name, "exp"]
    finally:
        os.close(fd)


def test_sigterm_during_an_export_says_so_in_one_line(tiny, tmp_path, capsys, monkeypatch):
    """SIGTERM during `dataset export` (EI02, EI05) ended the process without a word,
    its staging sibling left. Now one line says the export was interrupted, OUT was not
    written and the dataset and earlier outputs are intact; exit 143; no staging left;
    a rerun exports."""
    import signal

    from dopplertof import file_formats
    from dopplertof.cli import main

    real = file_formats.write_npy

    def terminated_while_writing(path, array):
        real(path, array)
        os.kill(os.getpid(), signal.SIGTERM)  # (handled at the next bytecode)

    monkeypatch.setattr(file_formats, "write_npy", terminated_while_writing)
    out = tmp_path / "exp"
    assert main(["dataset", "export", tiny[1], "--format", "torf", "-o", str(out)]) == 143
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err
    assert err.startswith(f"dopplertof: dataset export interrupted (SIGTERM): {out} was not "
                          "written; the dataset") and "earlier output are intact" in err
    assert os.listdir(tmp_path) == []
    assert signal.getsignal(signal.SIGTERM) is signal.SIG_DFL  # (the handler given back)
    monkeypatch.setattr(file_formats, "write_npy", real)
    assert main(["dataset", "export", tiny[1], "--format", "torf", "-o", str(out)]) == 0
    assert (out / "export.json").exists()


def test_a_folder_written_meanwhile_is_refused_in_one_line(tmp_path):
    """CC05: two exports into one new OUT at once: the second's rename failed with
    '[Errno 39] Directory not empty: 'cc05''. Now the usual 'exists and is not empty'
    line, its staging folder removed, the other's files untouched."""
    from dopplertof import io

    target = tmp_path / "cc05"
    with pytest.raises(io.OutputError) as raised:
        with io.new_folder(target) as staging:
            with open(os.path.join(staging, "mine"), "w") as f:
                f.write("mine")
            target.mkdir()
            (target / "theirs").write_text("theirs")
    assert str(raised.value) == (f"{target} exists and is not empty (written meanwhile by "
                                 "another process): nothing there is overwritten; choose "
                                 "a new folder")
    assert sorted(os.listdir(tmp_path)) == ["cc05"] and os.listdir(target) == ["theirs"]
    with contextlib.suppress(FileNotFoundError):
        assert not os.listdir(staging)


# ---- DK04, DK06, DK06b: a run's tasks on a scheduler that outlives the client -------------

def _one_shard_task(tmp_path, samples=2):
    from dopplertof.dataset import load_config
    from dopplertof.dataset.driver import plan_shards

    config = load_config(_write_toml(tmp_path / "two.toml",
                                     {**TINY, "samples": samples, "samples_per_shard": samples}))
    os.makedirs(tmp_path / "out")
    (task,) = plan_shards(config, str(tmp_path / "out"), "llvm_ad_rgb")
    return task


#: what the cancelled task's test and the functions it submits share (module level: a
#: submitted function is pickled, by reference when it is a module's)
_SHARED = {}


def _held_render(config, index, folder):
    _SHARED["started"].set()
    _SHARED["release"].wait(30)
    return _SHARED["real"](config, index, folder)


def _watched(task):
    from dopplertof.dataset.driver import run_shard_task

    try:
        return run_shard_task(task)
    finally:
        _SHARED["done"].set()


def test_a_cancelled_shard_task_writes_nothing(tmp_path, monkeypatch, in_process_client):
    """DK06: after a Ctrl-C the client cancelled its futures, but a task already running
    went on and wrote its shard (2 shards at exit, 4 shards 25 s later). Now a task asks
    before each sample and before the write whether its key was released, and stops."""
    import threading
    import time

    from dopplertof.dataset import sample

    task = _one_shard_task(tmp_path)
    _SHARED.update(started=threading.Event(), release=threading.Event(),
                   done=threading.Event(), real=sample.render_sample)
    monkeypatch.setattr(sample, "render_sample", _held_render)
    future = in_process_client.submit(_watched, task, key="dk06-test", pure=False)
    assert _SHARED["started"].wait(60)
    future.cancel()
    worker = next(iter(in_process_client.cluster.workers.values()))
    for _ in range(200):  # (until the scheduler has told the worker)
        state = worker.state.tasks.get("dk06-test")
        if state is None or state.state != "executing":
            break
        time.sleep(0.05)
    _SHARED["release"].set()
    assert _SHARED["done"].wait(60)
    assert os.listdir(tmp_path / "out") == []


def test_a_shard_task_whose_folder_was_deleted_does_not_make_it_again(tmp_path,
                                                                      monkeypatch):
    """DK06b: Ctrl-C, then rm -rf of the output folder: 30 s later the folder was back,
    holding a shard the still-running task wrote (atomic_path makes missing folders).
    Now a task whose output folder is gone writes nothing."""
    from dopplertof.dataset import sample
    from dopplertof.dataset.driver import run_shard_task

    task = _one_shard_task(tmp_path)
    real = sample.render_sample

    def deleting(config, index, folder):
        result = real(config, index, folder)
        shutil.rmtree(folder)
        return result

    monkeypatch.setattr(sample, "render_sample", deleting)
    assert run_shard_task(task)["given_up"] and not (tmp_path / "out").exists()


class _FakeFuture:
    """A future whose statuses are given in turn, each time as_completed yields it."""

    def __init__(self, statuses, result):
        self.statuses, self.value, self.key = list(statuses), result, "k"

    @property
    def status(self):
        return self.statuses[0]

    def result(self):
        return self.value

    def exception(self):
        return None

    def release(self):
        pass

    def cancel(self):
        pass


class _FakeCompleted:
    def __init__(self, futures):
        self.queue = list(futures)

    def next_batch(self, block=False):
        batch, self.queue = self.queue, []
        return batch

    def add(self, future):
        future.statuses.pop(0)  # (computed again: its next status)
        self.queue.append(future)


def test_a_result_lost_with_its_worker_is_waited_for_not_failed(monkeypatch):
    """DK04: a worker SIGKILLed after it finished a shard (its nanny restarted it):
    'shard failed: shard_00001: task ended as finished', exit 1, though the scheduler
    computed the lost result again and every shard was complete. Now a future yielded
    in another state than finished, error or cancelled is waited for again."""
    import distributed
    from types import SimpleNamespace

    from dopplertof.experiments import cluster

    future = _FakeFuture(["lost", "finished"], {"shard": "shard_00001"})
    client = SimpleNamespace(submit=lambda *a, **k: future,
                             scheduler_info=lambda: {"workers": {"w": {}}})
    monkeypatch.setattr(distributed, "as_completed", _FakeCompleted)
    monkeypatch.setattr(cluster, "_lost", lambda client: False)
    monkeypatch.setattr(cluster, "_check_scheduler", lambda client, batch: None)
    outcome = cluster.run_tasks(client, None, [SimpleNamespace(name="shard_00001",
                                                               hash="h")], run="r")
    assert outcome.failed == [] and outcome.done == [{"shard": "shard_00001"}]
