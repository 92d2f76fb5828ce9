"""Files written atomically and output folders written whole (the formats: file_formats.py;
images and figures: image_files.py). Every writer writes a temporary file in the target
folder and renames it into place: a failed or interrupted write never
leaves a partial file nor replaces a good one. A missing output folder (and its parents)
is made when the first file is written into it; :func:`check_output_folder` refuses,
before any work, a path that cannot become one (a file in the way, no permission).
Multi-file outputs (a capture, a report, the figures...) are all or nothing
(:func:`output_folder`): written into a staging folder inside the output folder and moved
into place together, so that a failure (full disk, an exception, a kill) leaves the
previous output complete. A failed write raises :class:`WriteError`, one line naming the
file and the reason ("out/depth.npy: file too large (the file size limit)")."""

from __future__ import annotations

import contextlib
import errno
import fcntl
import glob
import json
import os
import re
import secrets
import shutil
import tempfile

from .backend import INTERRUPT_SEEN

FORMATS = (".exr", ".npy", ".png")


class OutputError(ValueError):
    """An output path that cannot be written (unknown extension, missing folder...)."""


class WriteError(OutputError):
    """A write that failed (full disk, file size limit, I/O error): ``path`` is the file
    the user asked for (never a temporary one), ``reason`` what the system said."""

    def __init__(self, path, reason: str):
        self.path, self.reason = os.fspath(path), reason
        super().__init__(f"{self.path}: {reason}")


#: the system's reasons that need a word of explanation
_WRITE_REASONS = {errno.EFBIG: "file too large (the file size limit)",
                  errno.ENOSPC: "No space left on device",
                  errno.EDQUOT: "disk quota exceeded"}


def write_error(path, exc: BaseException) -> WriteError:
    """The one-line :class:`WriteError` for ``exc`` (an OSError, or a library's message
    that ends in the system's reason) raised while writing ``path``."""
    if isinstance(exc, WriteError):
        return exc
    code = getattr(exc, "errno", None)
    text = getattr(exc, "strerror", None) or " ".join(str(exc).split()).rsplit(": ", 1)[-1]
    code = code or next((c for c in _WRITE_REASONS if os.strerror(c) == text), None)
    return WriteError(path, _WRITE_REASONS.get(code, text or type(exc).__name__))


def is_disk_full(exc: BaseException) -> bool:
    """Whether ``exc`` (an OSError or a :class:`WriteError`) says the disk or the quota
    is full."""
    if isinstance(exc, WriteError):
        return exc.reason in (_WRITE_REASONS[errno.ENOSPC], _WRITE_REASONS[errno.EDQUOT])
    return getattr(exc, "errno", None) in (errno.ENOSPC, errno.EDQUOT)


def check_output_folder(folder) -> str:
    """Before any work: ``folder`` is an existing writable folder, or a missing one that
    can be created (its nearest existing ancestor is a writable folder). Creates
    nothing; the writers create it. Returns the absolute path. An empty name (an
    unset variable: ``-o "$OUT"``) is refused, not read as the current folder ('.' names
    that)."""
    if isinstance(folder, bytes) or not isinstance(folder, (str, os.PathLike)) \
            or not isinstance(os.fspath(folder), str):
        raise TypeError(f"the output folder must be a path (str or os.PathLike), got "
                        f"{type(folder).__name__} {folder!r}")
    if not os.fspath(folder).strip():
        raise OutputError(f"output folder {os.fspath(folder)!r} is empty: name a folder "
                          "('.' for the current one; an empty name is often an unset "
                          "variable)")
    folder = os.path.abspath(os.fspath(folder))
    if os.path.exists(folder) and not os.path.isdir(folder):
        raise OutputError(f"output path exists and is not a folder: {folder}")
    existing = folder
    while not os.path.exists(existing):
        existing = os.path.dirname(existing)
    if not os.path.isdir(existing):
        raise OutputError(f"cannot create the output folder {folder}: {existing} is a file")
    if not os.access(existing, os.W_OK | os.X_OK):
        raise OutputError(f"output folder is not writable: {existing}")
    return folder


def make_output_folder(folder) -> str:
    """Check ``folder`` (:func:`check_output_folder`) and create it; returns its path."""
    folder = check_output_folder(folder)
    os.makedirs(folder, exist_ok=True)
    return folder


def check_output_path(path) -> str:
    """Validate an output file path before any work is done; returns its extension.
    A missing folder is created when the file is written."""
    path = os.fspath(path)
    ext = os.path.splitext(path)[1].lower()
    if ext not in FORMATS:
        raise OutputError(f"unknown output extension {ext or '(none)'!r} in {path}: "
                          f"use one of {', '.join(FORMATS)}")
    if os.path.isdir(path):
        raise OutputError(f"output path is a folder: {path}")
    check_output_folder(os.path.dirname(os.path.abspath(path)))
    return ext


@contextlib.contextmanager
def atomic_path(path):
    """Yield a temporary path beside ``path`` (same extension); rename on success, unless
    the command was interrupted meanwhile (its KeyboardInterrupt may have been lost: a
    file is not committed after a Ctrl-C, as :func:`output_folder`'s are not). A missing
    folder is created first."""
    path = os.fspath(path)
    base, ext = os.path.splitext(os.path.basename(path))
    try:
        folder = make_output_folder(os.path.dirname(os.path.abspath(path)))
    except OSError as exc:
        raise write_error(path, exc) from exc
    # named before it exists: an interrupt right after its creation still removes it
    tmp = os.path.join(folder, f".{base}.{secrets.token_hex(8)}.tmp{ext}")
    try:
        os.close(os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600))
        yield tmp
        if INTERRUPT_SEEN.is_set():  # interrupted, even if the KeyboardInterrupt was lost
            raise KeyboardInterrupt
        os.chmod(tmp, 0o666 & ~_umask())  # made 0600: follow the umask instead
        os.replace(tmp, path)
    except BaseException as exc:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        if isinstance(exc, OSError):  # full disk, file size limit: name the file
            raise write_error(path, exc) from exc
        raise


def remove_temporaries(path) -> list:
    """Delete the temporary files that interrupted writes of ``path`` (atomic_path's,
    ``.NAME.XXXX.tmpEXT`` beside it) left, e.g. by a killed process; returns them.
    Another file's temporaries (``.NAME.more.XXXX.tmpEXT``) are left alone."""
    path = os.path.abspath(os.fspath(path))
    base, ext = os.path.splitext(os.path.basename(path))
    pattern = os.path.join(glob.escape(os.path.dirname(path)),
                           f".{glob.escape(base)}.*.tmp{glob.escape(ext)}")
    # the random part: 16 hex digits (8 letters and digits in older versions)
    ours = re.compile(rf"\.{re.escape(base)}\.\w{{8,16}}\.tmp{re.escape(ext)}")
    removed = []
    for leftover in glob.glob(pattern):
        if not ours.fullmatch(os.path.basename(leftover)):
            continue
        with contextlib.suppress(OSError):
            os.unlink(leftover)
            removed.append(leftover)
    return removed


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


# ---- Output folders: a set of files, all or nothing ---------------------------------------
#
# Inside the output folder, an output set NAME (capture, report...) has
#   .dopplertof-NAME.json             its manifest: the files the last complete run wrote
#   .dopplertof-NAME.staging-XXXXXXXX a run in progress, locked (flock) by its process
# Committing a set: the staging folder gets the new manifest (from then on the new output
# wins), the files of the old manifest that the new run did not write are deleted, the new
# files are renamed into place (same folder, same filesystem: each rename is atomic, none
# needs space) and the manifest last. Files the set did not write are never touched.


def manifest_name(name: str) -> str:
    """The file name of output set ``name``'s manifest (hidden, in its folder)."""
    return f".dopplertof-{name}.json"


def _staging_prefix(name: str) -> str:
    return f".dopplertof-{name}.staging-"


class StagedFolder:
    """The staging side of :func:`output_folder`: write file NAME at ``path(NAME)`` (or
    anywhere in ``staging``); after the block, ``written`` lists the final paths, those
    asked for through ``path`` first, in that order."""

    def __init__(self, target: str, staging: str):
        self.target, self.staging, self.names = target, staging, []
        self.written = []

    def path(self, name: str) -> str:
        if not _plain_name(name):
            raise ValueError(f"not a plain file name for an output set: {name!r}")
        if name not in self.names:
            self.names.append(name)
        return os.path.join(self.staging, name)

    def staged_files(self) -> list:
        """The set's files: those asked for, then any other file written in ``staging``."""
        present = [n for n in os.listdir(self.staging) if _plain_name(n)
                   and os.path.isfile(os.path.join(self.staging, n))]
        return ([n for n in self.names if n in present]
                + sorted(n for n in present if n not in self.names))


def _plain_name(name) -> bool:
    return (isinstance(name, str) and name not in ("", ".", "..") and not name.startswith(".")
            and os.sep not in name and (os.altsep is None or os.altsep not in name))


@contextlib.contextmanager
def output_folder(folder, name: str):
    """Write a set of files into ``folder`` all or nothing: yields a
    :class:`StagedFolder`, whose files replace the set's previous ones when the block
    ends without an exception. On a failure (an exception, a full disk, a kill) the
    previous files are left complete and untouched, the staging folder is removed (a
    killed run's at the next run into the folder) and folders this call created are
    removed again. Files of the previous run of the set that this one did not write are
    deleted; any other file in ``folder`` (the user's, another set's) is left alone."""
    target = check_output_folder(folder)
    created = _missing_folders(target)
    try:
        os.makedirs(target, exist_ok=True)
        with _locked(target):
            _recover_leftovers(target)
            staging = tempfile.mkdtemp(prefix=_staging_prefix(name), dir=target)
            owner = _hold_lock(staging)
    except OSError as exc:
        _remove_created(created)
        raise write_error(target, exc) from exc
    try:
        staged = StagedFolder(target, staging)
        yield staged
        if INTERRUPT_SEEN.is_set():  # interrupted, even if the KeyboardInterrupt was lost
            raise KeyboardInterrupt
        with _locked(target):
            _commit(staged, name)
    except BaseException as exc:
        if not os.path.exists(os.path.join(staging, manifest_name(name))):
            shutil.rmtree(staging, ignore_errors=True)  # not committed: drop the new files
            _remove_created(created)
        _raise_in_target(exc, staging, target)
    finally:
        os.close(owner)


@contextlib.contextmanager
def new_folder(folder):
    """A folder written whole, subfolders and all (dataset exports): yields a
    staging folder (a hidden sibling of ``folder``, locked by this process) that becomes
    ``folder`` in one rename when the block ends without an exception; on any failure it
    is removed and nothing is left (a killed run's staging folder is removed by the next
    call for ``folder``). A ``folder`` that exists and is not empty is refused (an
    OutputError before anything is written, or at the rename where another process
    wrote it meanwhile: nothing is overwritten). A write error names the file in
    ``folder``."""
    target = check_output_folder(folder)
    if os.path.isdir(target) and os.listdir(target):
        raise _not_empty(target)
    parent = os.path.dirname(target)
    created = _missing_folders(parent)
    prefix = f".{os.path.basename(target)}.staging-"
    try:
        os.makedirs(parent, exist_ok=True)
        for dead in _dead_stagings(parent, lambda entry: entry.startswith(prefix)):
            shutil.rmtree(dead, ignore_errors=True)
        staging = tempfile.mkdtemp(prefix=prefix, dir=parent)
        owner = _hold_lock(staging)
    except OSError as exc:
        _remove_created(created)
        raise write_error(target, exc) from exc
    try:
        yield staging
        if INTERRUPT_SEEN.is_set():
            raise KeyboardInterrupt
        try:
            if os.path.isdir(target):
                os.rmdir(target)  # (empty)
            os.rename(staging, target)
        except OSError:
            if os.path.isdir(target) and os.listdir(target):
                raise _not_empty(target, " (written meanwhile by another process)") from None
            raise
    except BaseException as exc:
        shutil.rmtree(staging, ignore_errors=True)
        _remove_created(created)
        _raise_in_target(exc, staging, target)
    finally:
        os.close(owner)


def _not_empty(target: str, why: str = "") -> OutputError:
    return OutputError(f"{target} exists and is not empty{why}: nothing there is "
                       "overwritten; choose a new folder")


def _raise_in_target(exc: BaseException, staging: str, target: str):
    """Raise ``exc`` again (called in its handler), or where its message names a path in
    the staging folder, the error naming the output's own path instead (from ``exc``)."""
    if isinstance(exc, WriteError) and exc.path.startswith(staging + os.sep):
        raise WriteError(os.path.join(target, os.path.relpath(exc.path, staging)),
                         exc.reason) from exc
    if isinstance(exc, OSError):
        raise write_error(target, exc) from exc
    raise exc


def other_sets_files(folder, name: str) -> dict:
    """{file: set} of the files that the other output sets in ``folder`` (their
    manifests) wrote there and still hold: those ``name``'s set must not replace."""
    owned = {}
    with contextlib.suppress(OSError):
        for entry in sorted(os.listdir(folder)):
            if not (entry.startswith(".dopplertof-") and entry.endswith(".json")):
                continue
            other = entry[len(".dopplertof-"):-len(".json")]
            if other == name or ".staging-" in other:
                continue
            for file in _manifest_files(os.path.join(folder, entry)):
                if os.path.isfile(os.path.join(folder, file)):
                    owned.setdefault(file, other)
    return owned


def check_output_set(folder, name: str, files) -> str:
    """Before any work, and again at the commit: ``folder`` can receive the files
    ``files`` of output set ``name`` (:func:`check_output_folder`) without replacing a
    file another set wrote there (a capture's summary.json under an FMCW frame's): an
    OutputError naming them otherwise, so that one kind of output never overwrites
    another; the user's consent is to choose another folder or remove those files.
    Returns the absolute path."""
    folder = check_output_folder(folder)
    owned = other_sets_files(folder, name)
    clash = [f for f in files if f in owned]
    if clash:
        kinds = sorted({owned[f] for f in clash})
        raise OutputError(
            f"{folder} holds the {' and '.join(kinds)} output that wrote "
            f"{', '.join(clash)}: the {name} output would overwrite "
            f"{'it' if len(clash) == 1 else 'them'}; write into another folder (or remove "
            f"{'that file' if len(clash) == 1 else 'those files'} first)")
    return folder


def _commit(staged: StagedFolder, name: str) -> None:
    """The commit point (the staging folder's manifest), then the moves; refused when a
    file would replace another output set's (:func:`check_output_set`)."""
    files = staged.staged_files()
    check_output_set(staged.target, name, files)
    with atomic_path(os.path.join(staged.staging, manifest_name(name))) as tmp:
        with open(tmp, "w", encoding="utf-8") as f:  # names only: plain JSON
            json.dump({"files": files}, f, indent=2, sort_keys=True)
            f.write("\n")
    _finish_commit(staged.target, staged.staging, name)
    staged.written = [os.path.join(staged.target, n) for n in files]


def _finish_commit(target: str, staging: str, name: str) -> None:
    """Delete the old run's files that the new one lacks, move the new ones (the new
    manifest last), remove the staging folder. Also completes a killed commit: files
    already moved are skipped."""
    new = _manifest_files(os.path.join(staging, manifest_name(name)))
    old = _manifest_files(os.path.join(target, manifest_name(name)))
    for stale in old:
        path = os.path.join(target, stale)
        if stale not in new and (os.path.isfile(path) or os.path.islink(path)):
            os.unlink(path)
    for file in [*new, manifest_name(name)]:
        if os.path.exists(os.path.join(staging, file)):
            os.replace(os.path.join(staging, file), os.path.join(target, file))
    shutil.rmtree(staging, ignore_errors=True)


def _manifest_files(path: str) -> list:
    """The plain file names a manifest lists; none when it is missing or unreadable."""
    try:
        with open(path, encoding="utf-8") as f:
            files = json.load(f).get("files", [])
    except (OSError, ValueError, AttributeError):
        return []
    return [n for n in files if _plain_name(n)] if isinstance(files, list) else []


def _recover_leftovers(target: str) -> None:
    """The staging folders of killed runs (their lock is free): a committed one is
    completed, any other removed. Live runs' folders are left alone."""
    def ours(entry: str) -> bool:
        return entry.startswith(".dopplertof-") and ".staging-" in entry

    for staging in _dead_stagings(target, ours):
        entry = os.path.basename(staging)
        name = entry[len(".dopplertof-"):entry.rindex(".staging-")]
        if os.path.exists(os.path.join(staging, manifest_name(name))):
            _finish_commit(target, staging, name)
        else:
            shutil.rmtree(staging, ignore_errors=True)


def _dead_stagings(folder: str, matches):
    """The staging folders in ``folder`` whose name ``matches`` and whose lock is free
    (their run was killed), each yielded while this process holds its lock. Live runs'
    folders (and, where locks are unsupported, every folder) are left alone."""
    for entry in sorted(os.listdir(folder)):
        if not matches(entry):
            continue
        staging = os.path.join(folder, entry)
        try:
            fd = os.open(staging, os.O_RDONLY | os.O_DIRECTORY)
        except OSError:
            continue
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:  # held: a run in progress (or locks unsupported: keep it)
            os.close(fd)
            continue
        try:
            yield staging
        finally:
            os.close(fd)


def _hold_lock(folder: str) -> int:
    """An open descriptor of ``folder`` holding its lock until closed (or the process
    dies); where the filesystem has no locks, the descriptor alone."""
    fd = os.open(folder, os.O_RDONLY | os.O_DIRECTORY)
    with contextlib.suppress(OSError):
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    return fd


@contextlib.contextmanager
def _locked(folder: str):
    """The output folder locked against other runs' recoveries and commits."""
    fd = os.open(folder, os.O_RDONLY | os.O_DIRECTORY)
    try:
        with contextlib.suppress(OSError):
            fcntl.flock(fd, fcntl.LOCK_EX)
        yield
    finally:
        os.close(fd)  # releases the lock


# ---- A run's hold on its output folder -----------------------------------------------------
#
# A command that fills a folder piece by piece over a long run and resumes into it (a
# sweep, an animation, a dataset, a capture's checkpoint folder) holds the folder for its
# whole run: it locks (flock)
#   .dopplertof-run.lock    the lock file, and writes who holds it in
#   .dopplertof-run.holder  {"pid", "host", "command", "started"}
# both removed when the run ends; a killed run's lock is free again (the system releases
# it with the process), so the next run takes the folder and resumes.

RUN_LOCK = ".dopplertof-run.lock"
RUN_HOLDER = ".dopplertof-run.holder"


@contextlib.contextmanager
def held_folder(folder, remove_empty: bool = False):
    """Hold output folder ``folder`` (created if missing) for this run: yields its
    absolute path. While another live run holds it, an OutputError naming the folder and
    that run (its pid and command), before anything in the folder changes. Where the
    filesystem has no locks the run goes on unheld. Writes inside the folder (this run's,
    its Dask workers') are never refused: only another run's ``held_folder`` is. At the
    end a folder this call created and the run left empty is removed again (with
    ``remove_empty``, one that existed too: a checkpoint folder that has served)."""
    target = check_output_folder(folder)
    created, fd = _missing_folders(target), None
    try:
        os.makedirs(target, exist_ok=True)
        fd = _take_run_lock(target)
        if fd is not None:
            _write_holder(target)
    except BaseException as exc:
        _release_run_lock(target, fd, created, False)
        if isinstance(exc, OSError):
            raise write_error(target, exc) from exc
        raise
    try:
        yield target
    finally:
        _release_run_lock(target, fd, created, remove_empty)


def _release_run_lock(target: str, fd, created: list, remove_empty: bool) -> None:
    if fd is not None:  # (removed while still locked: the next run makes them anew)
        for name in (RUN_HOLDER, RUN_LOCK):
            with contextlib.suppress(OSError):
                os.unlink(os.path.join(target, name))
        os.close(fd)
    if remove_empty:
        with contextlib.suppress(OSError):
            os.rmdir(target)  # (only when empty)
    _remove_created(created)


def _take_run_lock(target: str):
    """The descriptor of ``target``'s lock file, locked; None where locks are
    unsupported. Refused (OutputError) while another run holds it."""
    path = os.path.join(target, RUN_LOCK)
    while True:
        try:
            fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o666)
        except OSError as exc:  # (a folder or a dangling link in its place: named)
            raise write_error(path, exc) from exc
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            os.close(fd)
            raise OutputError(f"{target} is in use by another run ({_holder(target)}): "
                              "wait for it to end (or stop it), or write into another "
                              "folder; nothing was changed") from None
        except OSError:  # no locks on this filesystem: go on unheld
            os.close(fd)
            return None
        try:
            mine = os.path.samestat(os.stat(path), os.fstat(fd))
        except FileNotFoundError:
            mine = False
        if mine:
            return fd
        os.close(fd)  # the holder removed it as it ended: take the new one


def _write_holder(target: str) -> None:
    import shlex
    import socket
    import sys
    import time

    argv = sys.argv or [""]
    ours = argv[0] in ("", "-c") or os.path.dirname(os.path.abspath(argv[0])) == \
        os.path.dirname(os.path.abspath(__file__))  # (python -m dopplertof.cli)
    prog = "dopplertof" if ours else os.path.basename(argv[0])
    with atomic_path(os.path.join(target, RUN_HOLDER)) as tmp:
        with open(tmp, "w", encoding="utf-8") as f:
            json.dump({"pid": os.getpid(), "host": socket.gethostname(),
                       "command": shlex.join([prog, *sys.argv[1:]]),
                       "started": time.strftime("%Y-%m-%d %H:%M:%S %Z")}, f)


def _holder(target: str) -> str:
    """Who holds ``target`` (its holder file), in words on one line."""
    def words(value) -> str:
        return " ".join(str(value).split())

    try:
        with open(os.path.join(target, RUN_HOLDER), encoding="utf-8") as f:
            info = json.load(f)
        return (f"pid {int(info['pid'])} on {words(info['host'])}, started "
                f"{words(info['started'])}: {words(info['command'])}")
    except FileNotFoundError:
        return "its pid not written yet"
    except (OSError, ValueError, TypeError, KeyError, OverflowError):
        return f"its holder file {RUN_HOLDER} unreadable"


def _missing_folders(folder: str) -> list:
    """``folder`` and its ancestors that do not exist yet, deepest first."""
    missing = []
    while not os.path.exists(folder):
        missing.append(folder)
        folder = os.path.dirname(folder)
    return missing


def _remove_created(created: list) -> None:
    """Remove again the folders an output set created, where they stayed empty."""
    for folder in created:
        try:
            os.rmdir(folder)
        except OSError:
            return
