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


def available_memory() -> int | None:
    """Bytes of memory available now (Linux MemAvailable), else the physical memory."""
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    try:
        return os.sysconf("SC_PHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (ValueError, OSError, AttributeError):
        return None


def check(est: Estimate, available: int | None = None) -> Estimate:
    """Refuse a render that cannot fit, naming the estimate and what to lower."""
    available = available_memory() if available is None else available
    too_big = available is not None and est.bytes > available
    too_long = est.largest_array > MAX_LANES
    if not (too_big or too_long):
        return est
    reasons = []
    if too_big:
        reasons.append(f"more than the {_gib(available)} available")
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


def _duration(seconds: float) -> str:
    if seconds < 90:
        return f"{seconds:.0f} s"
    if seconds < 5400:
        return f"{seconds / 60:.0f} min"
    return f"{seconds / 3600:.1f} h"
