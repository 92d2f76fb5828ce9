"""Mitsuba variant choice and the libLLVM check (design.md section 6).

The Mitsuba wheel's LLVM variants load the system's libLLVM at run time. Dr.Jit 1.5
aborts the whole process inside LLVM 14 or 15 ("Cannot select ... fminimum"), so we
must never let it load one of those: before Dr.Jit starts its LLVM backend we find a
usable libLLVM and point ``DRJIT_LIBLLVM_PATH`` at it, or stop with a clear message.
"""

from __future__ import annotations

import contextlib
import glob
import importlib.util
import os
import re
import signal
import sys
import threading

#: oldest libLLVM major version that Dr.Jit 1.5 runs on (14 and 15 abort; 19 is tested)
MIN_LLVM_MAJOR = 16

DEFAULT_VARIANT = "llvm_ad_rgb"

_SEARCH_GLOBS = (
    "/usr/lib/x86_64-linux-gnu/libLLVM*.so*",
    "/usr/lib/aarch64-linux-gnu/libLLVM*.so*",
    "/usr/lib/llvm-*/lib/libLLVM*.so*",
    "/usr/lib64/libLLVM*.so*",
    "/usr/lib/libLLVM*.so*",
    "/usr/local/lib/libLLVM*.so*",
    "/opt/homebrew/opt/llvm/lib/libLLVM*.dylib",
    "/usr/local/opt/llvm/lib/libLLVM*.dylib",
)

INSTALL_HINT = (
    "install LLVM >= {min} (Debian/Ubuntu: 'apt-get install libllvm19'), "
    "or set DRJIT_LIBLLVM_PATH to a libLLVM.so of version >= {min}"
)


class BackendError(RuntimeError):
    """No usable JIT backend: the message says what to install."""


def aligned_host_array(values, dtype):
    """``values`` as a NumPy array of ``dtype`` in a 64-byte-aligned buffer, to become a
    Dr.Jit array. Dr.Jit maps a NumPy array of its own dtype without copying and compiles
    the loads of the kernels that read it for the buffer's alignment: an array placed
    wherever the allocator puts it compiles those kernels anew (``align 1`` against
    ``align 32``) from one call to the next (tests/test_startup.py)."""
    import numpy as np

    values = np.asarray(values, dtype=dtype).ravel()
    raw = np.empty(values.size + 64 // values.itemsize, dtype=dtype)
    start = (-raw.ctypes.data % 64) // values.itemsize
    out = raw[start:start + values.size]
    out[:] = values
    return out


def llvm_major_version(path: str) -> int | None:
    """Major LLVM version of a libLLVM file, read from its name (libLLVM-19.so, libLLVM.so.19.1)."""
    name = os.path.basename(os.path.realpath(path))
    for candidate in (name, os.path.basename(path)):
        m = re.search(r"libLLVM[-.]?(?:so\.)?(\d+)", candidate)
        if m:
            return int(m.group(1))
    return None


def find_libllvm() -> str | None:
    """Path of the newest usable libLLVM on this machine, or None."""
    found: dict[str, int] = {}
    for pattern in _SEARCH_GLOBS:
        for path in glob.glob(pattern):
            major = llvm_major_version(path)
            if major is not None and major >= MIN_LLVM_MAJOR and os.path.isfile(path):
                found.setdefault(os.path.realpath(path), major)
    if not found:
        return None
    return max(found.items(), key=lambda kv: (kv[1], kv[0]))[0]


def ensure_libllvm() -> str:
    """Point Dr.Jit at a usable libLLVM; return its path or raise BackendError.

    A user-set DRJIT_LIBLLVM_PATH is respected when it names an existing file of a
    usable version, and rejected with the reason otherwise.
    """
    hint = INSTALL_HINT.format(min=MIN_LLVM_MAJOR)
    user = os.environ.get("DRJIT_LIBLLVM_PATH")
    if user:
        if not os.path.isfile(user):
            raise BackendError(f"DRJIT_LIBLLVM_PATH={user} does not exist; {hint}")
        major = llvm_major_version(user)
        if major is not None and major < MIN_LLVM_MAJOR:
            raise BackendError(
                f"DRJIT_LIBLLVM_PATH={user} is LLVM {major}, which crashes Dr.Jit 1.5; {hint}"
            )
        return user
    path = find_libllvm()
    if path is None:
        raise BackendError(f"no usable libLLVM found for Mitsuba's LLVM variants; {hint}")
    os.environ["DRJIT_LIBLLVM_PATH"] = path
    return path


def variant_problem(variant: str) -> str | None:
    """Why dopplertof cannot run in Mitsuba variant ``variant`` (None: it can)."""
    if variant.startswith("scalar_"):
        return (f"variant {variant!r} runs Python per sample and is not supported; "
                "use an llvm_* (CPU) or cuda_* (GPU) variant")
    if not (variant.startswith("llvm_") or variant.startswith("cuda_")):
        return f"unknown variant {variant!r}: expected llvm_* or cuda_*"
    if "polarized" in variant:
        return (f"variant {variant!r}: polarized light transport is not supported; use an "
                "rgb, spectral or mono variant")
    return None


def set_variant(variant: str | None = None) -> str:
    """Select a Mitsuba JIT variant (LLVM RGB by default) after the libLLVM check.

    :func:`dopplertof.set_variant` also registers the D-ToF integrator plugins for it
    (this module knows nothing of the integrators).
    """
    variant = variant or DEFAULT_VARIANT
    problem = variant_problem(variant)
    if problem:
        raise BackendError(problem)
    if variant.startswith("llvm_"):
        ensure_libllvm()
        if "drjit" not in sys.modules:  # ---- before Dr.Jit starts: can it, in this limit?
            from .budget import check_address_space_to_start

            check_address_space_to_start()
    with interrupts_deferred():
        return _set_mitsuba_variant(variant)


def _set_mitsuba_variant(variant: str) -> str:
    """Import Mitsuba and select ``variant`` (checked by :func:`set_variant`)."""
    import mitsuba as mi

    if variant not in mi.variants():
        raise BackendError(f"variant {variant!r} is not in this Mitsuba build: {mi.variants()}")
    problem = cuda_problem(mi, variant)
    if problem:
        raise BackendError(problem)
    try:
        mi.set_variant(variant)
    except Exception as exc:
        if variant.startswith("cuda_"):
            raise BackendError(f"variant {variant!r}: the CUDA backend did not start ({exc}); "
                               f"the variants that work here: {working_variants(mi)}") from None
        raise BackendError(f"cannot use variant {variant!r}: {exc}") from None
    _log_to_stderr(mi)
    return variant


# A Ctrl-C that Python dropped: a KeyboardInterrupt raised inside a weakref callback or a
# __del__ (matplotlib's transforms have such callbacks) is printed and ignored, and the
# command goes on. The CLI's SIGINT handler sets this; no output set commits after it
# (io.output_folder).
INTERRUPT_SEEN = threading.Event()


@contextlib.contextmanager
def interrupts_deferred():
    """Hold a Ctrl-C (SIGINT) back until the block ends, then deliver it to the handler
    that was there: a KeyboardInterrupt raised while Mitsuba's and Dr.Jit's C++ modules
    initialise comes back as an unrelated error or aborts the process (SIGABRT). Only in
    the main thread, where Python runs signal handlers."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    held = []
    previous = signal.signal(signal.SIGINT, lambda signum, frame: held.append(frame))
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)
    if held and callable(previous):
        previous(signal.SIGINT, held[0])  # the default handler raises KeyboardInterrupt
    elif held and previous == signal.SIG_DFL:
        signal.raise_signal(signal.SIGINT)


def cuda_problem(mi, variant: str) -> str | None:
    """Why a CUDA ``variant`` cannot run on this machine (None: it is no CUDA variant, or
    a CUDA device and driver are there)."""
    if variant.startswith("cuda_") and not _has_cuda():
        return (f"variant {variant!r}: no CUDA device or driver was found on this machine; "
                f"the variants that work here: {working_variants(mi)}")
    return None


def _has_cuda() -> bool:
    """Whether Dr.Jit finds a CUDA driver and device (without raising)."""
    import drjit as dr

    try:
        return bool(dr.has_backend(dr.JitBackend.CUDA))
    except Exception:
        return False


def working_variants(mi) -> str:
    """The variants of this Mitsuba build that dopplertof can use on this machine."""
    usable = [v for v in mi.variants() if v.startswith("llvm_") and "polarized" not in v]
    return ", ".join(usable) if usable else "none (" + INSTALL_HINT.format(min=MIN_LLVM_MAJOR) + ")"


_STDERR_APPENDER = []  # the one appender we installed (kept alive here)


def _log_to_stderr(mi) -> None:
    """Mitsuba's log messages (its WARN lines) go to stderr: stdout is for results."""
    import sys

    logger = mi.logger() if hasattr(mi, "logger") else mi.Thread.thread().logger()
    if logger is None:
        return
    if _STDERR_APPENDER and logger.appender_count() == 1 \
            and logger.appender(0) is _STDERR_APPENDER[0]:
        return

    class StderrAppender(mi.Appender):
        def append(self, level, text):
            sys.stderr.write(text.rstrip("\n") + "\n")

        def log_progress(self, *args):
            pass

    appender = StderrAppender()
    logger.clear_appenders()
    logger.add_appender(appender)
    _STDERR_APPENDER[:] = [appender]


# ---- Mitsuba's own calls: a hook after every mitsuba.set_variant ----

def when_imported(name: str, callback) -> None:
    """Run ``callback(module)`` once module ``name`` is imported: now if it is, else
    right after its first import (a one-shot import hook; nothing is imported here)."""
    if name in sys.modules:
        callback(sys.modules[name])
        return
    sys.meta_path.insert(0, _ImportHook(name, callback))


class _ImportHook:
    """A meta path finder (importlib's protocol; no base class, whose module costs an
    import of importlib.resources at start-up): finds ``name`` with the other finders and runs ``callback`` after it loads."""

    def __init__(self, name: str, callback):
        self.name, self.callback = name, callback

    def find_spec(self, fullname, path=None, target=None):
        if fullname != self.name:
            return None
        sys.meta_path.remove(self)  # once: the real finders find it from here on
        spec = importlib.util.find_spec(fullname)
        if spec is not None and spec.loader is not None:
            spec.loader = _ThenCall(spec.loader, self.callback)
        return spec


class _ThenCall:
    """A loader (importlib's protocol): a module's own loader, then ``callback`` on what sys.modules holds (Mitsuba puts
    its variant-dispatching alias module there)."""

    def __init__(self, loader, callback):
        self.loader, self.callback = loader, callback

    def create_module(self, spec):
        return self.loader.create_module(spec)

    def exec_module(self, module):
        self.loader.exec_module(module)
        self.callback(sys.modules.get(module.__name__, module))

    def __getattr__(self, name):  # resources and the rest: the module's own loader
        return getattr(self.loader, name)


def after_set_variant(mi, callback) -> None:
    """Run ``callback(mi)`` for the variant set now (if one is) and after every later
    ``mitsuba.set_variant`` (``mitsuba.variant_context`` calls it too). Mitsuba has no
    such hook, so its set_variant is replaced, once, by one that calls the original and
    then the callbacks."""
    original = mi.set_variant
    callbacks = getattr(original, "dopplertof_callbacks", None)
    if callbacks is None:
        def set_variant(*args, **kwargs):
            original(*args, **kwargs)
            for after in callbacks:
                after(mi)

        callbacks = set_variant.dopplertof_callbacks = []
        set_variant.__doc__ = getattr(original, "__doc__", None)
        mi.set_variant = set_variant
    callbacks.append(callback)
    if mi.variant() is not None:
        callback(mi)


def require_variant():
    """The mitsuba module with a JIT variant set, or a clear error."""
    import mitsuba as mi

    v = mi.variant()
    if v is None or not (v.startswith("llvm_") or v.startswith("cuda_")):
        raise BackendError(
            "no Mitsuba JIT variant is set: call dopplertof.set_variant() "
            "(or mitsuba.set_variant('llvm_ad_rgb')) first"
        )
    return mi
