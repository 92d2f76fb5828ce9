"""Memory and time of a render, estimated before it starts.

A pass traces a whole number of chunks (``min(spp, 8 K)`` samples) of *every* pixel, so
its lanes are at least ``pixels * chunk`` whatever the pass size; the host keeps float64
sums per pixel. A render that cannot fit is refused before anything is allocated, with
the estimate and what to lower; a long one says what it will take.

The constants were measured on the development machine (LLVM, the demo Cornell box,
``max_depth`` 4): about 30 bytes of JIT memory per lane in flight and about 4 million
samples per second per core (docs/benchmarks.md); the estimate uses a margin on the
memory and is a rough guide to the time (deeper paths and more bodies are slower).
"""

from __future__ import annotations

import os
from dataclasses import dataclass

#: JIT memory per lane of a pass (measured about 30; with a margin)
BYTES_PER_LANE = 48
#: host memory per pixel and channel besides the sums: the pass's chunk sums, the image
BYTES_PER_PIXEL_CHANNEL = 8 + 4
#: host memory per pixel for index arrays (int64)
BYTES_PER_PIXEL = 4 * 8
#: Dr.Jit arrays hold fewer than 2^32 entries
MAX_LANES = (1 << 32) - 1
#: samples per second per core, a rough guide (demo scene, max_depth 4)
SAMPLES_PER_CORE_SECOND = 4e6
#: renders estimated longer than this say so on stderr before they start
LONG_RENDER_SECONDS = 30.0


class ResourceError(ValueError):
    """A render that cannot fit in this machine's memory or Dr.Jit's array sizes."""


@dataclass(frozen=True)
class Estimate:
    width: int
    height: int
    spp: int
    chunk: int  #: samples of every pixel in the smallest pass
    lanes_per_pass: int
    passes: int
    host_bytes: int
    pass_bytes: int  #: in Dr.Jit: a pass's lanes and the sums kept there
    seconds: float  #: rough
    largest_array: int = 0  #: entries of the largest Dr.Jit array (a pass, the splat sums)

    @property
    def bytes(self) -> int:
        return self.host_bytes + self.pass_bytes

    def describe(self) -> str:
        return (f"{self.width}x{self.height} pixels at {self.spp} spp: about "
                f"{_gib(self.bytes)} of memory ({self.passes} pass(es) of "
                f"{self.lanes_per_pass:.3g} samples) and roughly {_duration(self.seconds)} "
                f"on {os.cpu_count() or 1} core(s)")


def estimate(width: int, height: int, channels: int, spp: int, chunk: int,
             pass_chunks: int, adaptive: bool = False, columns: int | None = None,
             device_columns: int = 0) -> Estimate:
    """``columns``: float64 sums per pixel on the host (default ``channels``; the splat
    film keeps one set per film offset); ``device_columns``: those kept in Dr.Jit too."""
    pixels = width * height
    n_chunks = -(-spp // chunk)
    lanes = pixels * chunk * pass_chunks
    columns = channels if columns is None else columns
    host = pixels * (8 * columns + 8 * 2 * channels * adaptive
                     + channels * BYTES_PER_PIXEL_CHANNEL + BYTES_PER_PIXEL)
    seconds = pixels * spp / (SAMPLES_PER_CORE_SECOND * (os.cpu_count() or 1))
    return Estimate(width, height, spp, chunk, lanes, -(-n_chunks // pass_chunks), host,
                    lanes * BYTES_PER_LANE + 8 * pixels * device_columns, seconds,
                    max(lanes, pixels * device_columns))


#: address space a render takes beyond its estimate: LLVM compiling its kernels, thread
#: stacks (VmPeak of a 16x16 render 140 MiB above its VmSize before)
RENDER_ADDRESS_SPACE = 192 << 20
#: address space Mitsuba and Dr.Jit take to start, load a scene and pass the budget of a
#: tiny render, measured on the development machine: VmSize 482 MiB once the variant is
#: set, 670 MiB after loading with 2 threads (916 MiB with 8), plus RENDER_ADDRESS_SPACE.
#: Below about 680 MiB (2 threads) Dr.Jit hangs in an allocator (620 MiB), aborts
#: (450 MiB) or reports a missing libLLVM (300 MiB). A base and a part per thread:
START_ADDRESS_SPACE = 800 << 20
ADDRESS_SPACE_PER_THREAD = 32 << 20
#: where cgroup file systems are mounted (v2: one hierarchy; v1: memory/)
CGROUP_ROOT = "/sys/fs/cgroup"


@dataclass(frozen=True)
class MemoryLimit:
    """The memory a render may use now, and which limit sets it (for the message)."""

    available: int  #: bytes
    source: str  #: e.g. "MemAvailable", "the address-space limit (ulimit -v) of 3 GiB"


def available_memory() -> int | None:
    """Bytes a render may allocate now: the smallest of :func:`memory_limits`."""
    limit = tightest_memory_limit()
    return None if limit is None else limit.available


def tightest_memory_limit() -> MemoryLimit | None:
    limits = memory_limits()
    return min(limits, key=lambda limit: limit.available) if limits else None


def memory_limits() -> list[MemoryLimit]:
    """Every limit found: the system's MemAvailable (else its physical memory), the
    cgroup's memory limit less its usage, the address-space limit (RLIMIT_AS, ``ulimit
    -v``) less the address space in use and what a render needs beside its arrays."""
    limits = [limit for limit in (_system_memory(), cgroup_memory(), _address_space_left())
              if limit is not None]
    return limits


def _system_memory() -> MemoryLimit | None:
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return MemoryLimit(int(line.split()[1]) * 1024, "MemAvailable")
    except (OSError, ValueError, IndexError):
        pass
    try:
        return MemoryLimit(os.sysconf("SC_PHYS_PAGES") * os.sysconf("SC_PAGE_SIZE"),
                           "the physical memory")
    except (ValueError, OSError, AttributeError):
        return None


def address_space_limit() -> int | None:
    """The soft RLIMIT_AS in bytes (``ulimit -v``), None when unlimited."""
    import resource

    soft, _ = resource.getrlimit(resource.RLIMIT_AS)
    return None if soft == resource.RLIM_INFINITY else soft


def _address_space_in_use() -> int:
    """This process's virtual size (VmSize), 0 where /proc does not say."""
    try:
        with open("/proc/self/status") as f:
            for line in f:
                if line.startswith("VmSize:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    return 0


def _address_space_left() -> MemoryLimit | None:
    limit = address_space_limit()
    if limit is None:
        return None
    left = max(0, limit - _address_space_in_use() - RENDER_ADDRESS_SPACE)
    return MemoryLimit(left, f"the address-space limit (ulimit -v) of {_mib(limit)}, less "
                       f"the {_mib(limit - left)} this process and a render's kernels take")


def cgroup_memory(root: str | None = None) -> MemoryLimit | None:
    """The cgroup's memory limit less its usage (v2 ``memory.max`` - ``memory.current``,
    v1 ``memory.limit_in_bytes`` - ``memory.usage_in_bytes``; page cache it may drop,
    ``inactive_file``, counts as free), None without a limit."""
    root = CGROUP_ROOT if root is None else root
    for folder in _cgroup_folders(root):
        for limit_file, usage_file, cache_key in (
                ("memory.max", "memory.current", "inactive_file"),
                ("memory.limit_in_bytes", "memory.usage_in_bytes", "total_inactive_file")):
            limit = _read_int(os.path.join(folder, limit_file))
            if limit is None or limit >= 1 << 60:  # "max", or v1's "no limit"
                continue
            usage = _read_int(os.path.join(folder, usage_file)) or 0
            usage -= _memory_stat(os.path.join(folder, "memory.stat"), cache_key)
            return MemoryLimit(max(0, limit - max(0, usage)),
                               f"the cgroup memory limit of {_mib(limit)} ({limit_file}) "
                               f"less the {_mib(max(0, usage))} in use")
    return None


def _cgroup_folders(root: str) -> list[str]:
    """The folders that may hold this process's cgroup memory files: its own cgroup
    (from /proc/self/cgroup) under the v2 root and v1's memory/, then those roots (a
    container sees its own cgroup as the root)."""
    paths = []
    try:
        with open("/proc/self/cgroup") as f:
            for line in f:
                _, controllers, path = line.rstrip("\n").split(":", 2)
                if controllers in ("", "memory") or "memory" in controllers.split(","):
                    paths.append(os.path.join(root, "" if controllers == "" else "memory",
                                              path.lstrip("/")))
    except (OSError, ValueError):
        pass
    return [p for p in paths + [root, os.path.join(root, "memory")] if os.path.isdir(p)]


def _read_int(path: str) -> int | None:
    try:
        with open(path) as f:
            return int(f.read().split()[0])
    except (OSError, ValueError, IndexError):
        return None


def _memory_stat(path: str, key: str) -> int:
    try:
        with open(path) as f:
            for line in f:
                name, _, value = line.partition(" ")
                if name == key:
                    return int(value)
    except (OSError, ValueError):
        pass
    return 0


def address_space_to_start(threads: int) -> int:
    """Bytes of address space Mitsuba and Dr.Jit need to start with ``threads`` threads
    and render a tiny image."""
    return START_ADDRESS_SPACE + ADDRESS_SPACE_PER_THREAD * max(1, threads)


def check_address_space_to_start(threads: int | None = None) -> None:
    """Refuse, before Mitsuba starts, an address-space limit below what it needs to start
    (below it, Dr.Jit reports a missing libLLVM, aborts, or hangs in an allocator)."""
    limit = address_space_limit()
    if limit is None:
        return
    threads = threads or _cpus()
    needed = address_space_to_start(threads)
    if limit < needed:
        raise ResourceError(
            f"the address-space limit (ulimit -v) of {_mib(limit)} is below the ~"
            f"{_mib(needed)} that Mitsuba and Dr.Jit need to start with {threads} "
            "thread(s): memory is the cause; raise the limit (ulimit -v), or run on fewer "
            "CPUs (taskset)")


def _cpus() -> int:
    try:
        return len(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        return os.cpu_count() or 1


def check(est: Estimate, available: int | None = None) -> Estimate:
    """Refuse a render that cannot fit, naming the estimate, the limit that refuses it
    and what to lower."""
    limit = tightest_memory_limit() if available is None else MemoryLimit(available, "")
    available = None if limit is None else limit.available
    too_big = available is not None and est.bytes > available
    too_long = est.largest_array > MAX_LANES
    if not (too_big or too_long):
        return est
    reasons = []
    if too_big:
        reasons.append(f"more than the {_gib(available)} of memory available"
                       + (f" ({limit.source})" if limit.source else ""))
    if too_long:
        reasons.append(f"an array of {est.largest_array:.3g} entries (a pass of "
                       f"{est.lanes_per_pass:.3g} samples), more than Dr.Jit's "
                       f"{MAX_LANES + 1:.3g} per array")
    lower_spp = (f"--spp below {est.chunk} (a pass holds min(spp, {est.chunk}) samples of "
                 "every pixel) or " if est.chunk > 2 and not
                 (too_big and est.host_bytes > available) else "")
    raise ResourceError(
        f"this render needs about {_gib(est.bytes)} of memory ({est.width}x{est.height} "
        f"pixels: {_gib(est.host_bytes)} of sums, {_gib(est.pass_bytes)} per pass): "
        f"{' and '.join(reasons)}; lower {lower_spp}the resolution (-D res, or the film's "
        "width and height)")


def _gib(n: float) -> str:
    for unit, size in (("TiB", 2**40), ("GiB", 2**30)):
        if n >= size:
            return f"{n / size:.3g} {unit}"
    return f"{n / 2**20:.3g} MiB"


def _mib(n: float) -> str:
    return f"{n / 2**20:.0f} MiB"


def duration(seconds: float) -> str:
    """``seconds`` in words: s, min or h."""
    return _duration(seconds)


def _duration(seconds: float) -> str:
    if seconds < 90:
        return f"{seconds:.0f} s"
    if seconds < 5400:
        return f"{seconds / 60:.0f} min"
    return f"{seconds / 3600:.1f} h"
