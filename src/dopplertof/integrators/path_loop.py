"""The path loop and its modalities.

One loop owns a path's state, from each lane's camera ray to its end: the ray, the
throughput, the path length so far, the depth, the previous vertex and BSDF sample (for
MIS), Russian roulette. At every surface hit it hands the vertex (what it hits and the
light sample it takes, each contribution with its full path length: path_steps.Vertex)
to a *modality*, which turns contributions into what a sensor measures: the D-ToF
camera's modulated correlations (dtof_path), the FMCW lidar's beat spectra
(fmcw/trace.py), or a transient's histogram of path lengths. A modality carries loop
state of its own (a tuple of Dr.Jit arrays) and may scatter into its own film.

A modality is a plain object (not a dataclass: Dr.Jit's loop transform would take a
dataclass read in the loop for loop state) with these hooks:

- ``label``: the loop's name in Dr.Jit's kernel history;
- ``dimensions``: the random numbers it reads of its own (:class:`..sampling.
  ModalityDimensions`: per lane and per bounce, in the slots the layout reserves);
- ``F``: the path length's type (the D-ToF full-waveform mode: float64);
- ``state()``: its loop state at the camera ray (no Bool: the loop's reverse-mode replay
  stores its state, and Dr.Jit 1.5 reads a stored Bool back as the wrong type);
- ``hit(mi, static, frames, ray, active, depth, fresh)``: the next surface interaction
  and whatever else the modality reads of the hit (``fresh``: the loop's first query);
- ``light(depth, max_depth, bsdf_ctx)``: ``shade``'s ``light`` (None: the scene's lights);
- ``vertex(state, si, hit, ray, v, beta, depth, numbers)``: its state after vertex ``v``.

:class:`Modality` gives the defaults of ``hit`` and ``light``.
"""

from __future__ import annotations

import drjit as dr

from ..sampling import ModalityDimensions
from ..scene.bodies import intersect
from .path_steps import (CameraSample, LoopSettings, PassLayout, advance, shade, survive,
                         vertex_numbers)


class Modality:
    """The hooks' defaults: the nearest hit at the lanes' times, the scene's lights."""

    label = "dopplertof_path"
    F = None  #: the path length's type (None: the variant's Float)
    dimensions = ModalityDimensions()  #: none of its own

    def state(self) -> tuple:
        return ()

    def hit(self, mi, static, frames, ray, active, depth, fresh):
        return intersect(mi, static, frames, ray, active, coherent=depth == 0), None

    def light(self, depth, max_depth, bsdf_ctx):
        return None

    def vertex(self, state, si, hit, ray, v, beta, depth, numbers):
        raise NotImplementedError


# The loop state holds no Bool besides the loop's condition: the loop's reverse-mode
# replay stores its state, and Dr.Jit 1.5 stores a Bool as i8 and reads it back as i1
# (an LLVM IR type error that aborted every dr.backward through the loop).
@dr.syntax
def trace_path_loop(mi, setup, layout: PassLayout, streams, start: CameraSample, modality):
    """Every lane's path from its camera ray (``start``), each surface hit handed to
    ``modality``; returns the modality's loop state at the paths' ends."""
    settings = LoopSettings(mi, setup, modality.F)  # (a plain object: not loop state)
    static, F = settings.static, settings.F
    ray, frames = start.ray, (start.frames, start.light_frames)

    # The first hit's light and BSDF samples from the pixel's low-discrepancy set
    u_em_first = streams.first_hit_2d(0, layout.group, layout.index, setup.groups_per_pixel)
    u_dir_first = streams.first_hit_2d(1, layout.group, layout.index, setup.groups_per_pixel)

    # ---- Loop state ----
    carried = modality.state()  # the modality's own (its measurement so far)
    beta = mi.Spectrum(start.ray_weight)  # path throughput
    length = F(start.camera_offset)  # path length, camera to ray origin (m)
    depth = mi.UInt32(0)  # surface hits so far
    going = mi.UInt32(dr.select(start.active, 1, 0))  # whether the path goes on (1) or not
    prev_si = dr.zeros(mi.Interaction3f)  # previous vertex, for emitter MIS
    prev_bsdf_pdf = mi.Float(1.0)  # solid-angle pdf of the last BSDF sample
    prev_bsdf_delta = mi.UInt32(1)  # whether that sample was a delta lobe (1) or not (0)
    eta = mi.Float(1.0)  # relative index of refraction along the path
    iteration = mi.UInt32(0)  # loop iterations so far (0: the camera ray's hit may be known)

    ray, attached = AttachedOrigin.split(mi, ray)  # (an attached origin: not loop state)

    # The path's state as the tuple path_steps' steps take (PATH_STATE) is built anew
    # in each iteration: the loop's own state holds no Bool (UInt32 flags instead).
    while dr.hint(going != 0, max_iterations=settings.max_iterations, label=modality.label):
        active, fresh = going != 0, iteration == 0
        if attached is not None:
            ray.o = dr.select(fresh, attached.origin, ray.o)
        si, hit = modality.hit(mi, static, frames[0], ray, active, depth, fresh)
        numbers = vertex_numbers(streams, depth, u_em_first, u_dir_first)
        path = (ray, beta, length, depth, active, prev_si, prev_bsdf_pdf,
                prev_bsdf_delta != 0, eta)
        v = shade(mi, settings, path, frames, si, numbers,
                  light=modality.light(depth, settings.max_depth, settings.bsdf_ctx))

        # ---- What the modality measures of this vertex ----
        carried = modality.vertex(carried, si, hit, ray, v, beta, depth, numbers)

        # ---- Continue the path ----
        ray, beta, length, depth, _, prev_si, prev_bsdf_pdf, delta, eta = advance(
            mi, path, si, v)
        prev_bsdf_delta = mi.UInt32(dr.select(delta, 1, 0))
        iteration += 1
        beta, going = survive(mi, v, beta, eta, depth, settings.rr_depth, numbers[3])
    return carried


class AttachedOrigin:
    """The camera rays' origins while they are attached to AD, held outside the path
    loop's state. Every Dr.Jit array the loop body reads directly (not through a plain
    object such as this one) is loop state, and Dr.Jit 1.5's reverse-mode replay of a
    loop runs once per attached state variable: the three components of an attached
    origin cost three replays (measured: 3 kernels of the replay's size), where inputs
    read through plain objects (the bodies' per-lane transforms, the modulation's
    variables) share one. The first iteration reads the origin from here."""

    def __init__(self, origin):
        self.origin = origin  #: the attached origins (Point3f)

    @classmethod
    def split(cls, mi, ray):
        """(ray, holder): where ``ray``'s origin is attached to AD, a copy of the ray with
        its origin detached (the loop's state) and the holder of the attached origin;
        else the ray and None."""
        if not dr.grad_enabled(ray.o):
            return ray, None
        holder = cls(ray.o)
        ray = mi.Ray3f(ray)
        ray.o = dr.detach(ray.o)
        return ray, holder
