"""A modality written against the path loop's hooks in one file: a transient camera,
per pixel a histogram of its light over path length, checked against the closed form
of a plane lit from the camera (integrators/path_loop.py)."""

import math

import drjit as dr
import numpy as np

import dopplertof
from analytic import INTENSITY, RHO, plane_scene
from dopplertof.integrators.path_loop import Modality, trace_path_loop


# ---- The modality: under 80 lines --------------------------------------------------------

class Transient(Modality):
    """Each contribution, unmodulated (its colour's mean), added to its pixel's histogram
    at the bin of its full path length (``bins`` bins of ``width`` metres from ``first``)."""

    label = "transient"

    def __init__(self, mi, histogram, pixel, bins: int, first: float, width: float):
        self.mi, self.histogram, self.pixel = mi, histogram, pixel
        self.bins, self.first, self.width = bins, first, width

    def vertex(self, state, si, hit, ray, v, beta, depth, numbers):
        for value, length, on in ((v.emitted * v.mis_hit, v.length_hit, v.hit_emitter),
                                  (v.em_value * v.mis_em, v.length_em, v.active_em)):
            grey = sum(value[c] for c in range(len(value))) * (1.0 / len(value))
            offset = (self.mi.Float(length) - self.first) / self.width
            slot = self.mi.UInt32(dr.floor(dr.maximum(offset, 0.0)))
            dr.scatter_reduce(dr.ReduceOp.Add, self.histogram, grey, self.pixel * self.bins
                              + slot, on & (offset >= 0.0) & (slot < self.bins))
        return state


def render_transient(scene, spp: int, bins: int, first: float, width: float, seed: int = 0):
    """(H, W, bins): each pixel's mean light per path-length bin over ``spp`` samples."""
    import mitsuba as mi

    from dopplertof.integrators.dtof_path import integrator_class
    from dopplertof.integrators.path_steps import PassLayout, lane_streams

    w, h = (int(v) for v in scene.sensor.film().crop_size())
    setup = integrator_class(mi)().prepared(scene, scene.params.resolved(scene.shutter_interval),
                                            spp, seed)
    histogram = dr.zeros(mi.Float, w * h * bins)
    layout = PassLayout(mi, w * h, spp, dr.opaque(mi.UInt32, 0), setup.group_size)
    streams = lane_streams(mi, setup, layout)
    trace_path_loop(mi, setup, layout, streams, setup.sample_camera(layout, streams),
                    Transient(mi, histogram, layout.pixel, bins, first, width))
    return histogram.numpy().reshape(h, w, bins) / spp


# ---- The check: a plane at z0 lit by a point light at the camera -------------------------

def test_a_transient_of_a_plane_holds_each_pixels_path_lengths_and_light():
    """Direct light only: a sample's point at image-plane (x, y) (unit depth) is at range
    r = z0 sqrt(1 + x^2 + y^2), its path 2 r long, its light rho I z0 / (pi r^3) (the
    diffuse BSDF, the cosine z0 / r, the inverse square). So each pixel's histogram is
    zero outside the bins of [2 r_min, 2 r_max] over its footprint, and its total (the
    samples' mean light) lies between the footprint's extremes of the light (float32
    rounding aside: a relative 1e-5)."""
    z0, res, bins, first, width = 2.0, 3, 64, 3.995, 2e-4  # (paths 4 to 4.0025 m long)
    dopplertof.set_variant("llvm_ad_rgb")
    scene = dopplertof.load_dict(plane_scene(z0, 0.0, spp=64, res=res))
    transient = render_transient(scene, 64, bins, first, width)
    half = math.tan(math.radians(4.0) / 2)  # (analytic.FOV)
    edges = np.linspace(-half, half, res + 1)
    for i in range(res):
        for j in range(res):
            xs, ys = edges[j:j + 2], edges[i:i + 2]
            near = sum(0.0 if e[0] < 0 < e[1] else min(e ** 2) for e in (xs, ys))
            far = sum(max(e ** 2) for e in (xs, ys))
            r_min, r_max = z0 * math.sqrt(1 + near), z0 * math.sqrt(1 + far)
            lit = np.flatnonzero(transient[i, j])
            assert lit.size, (i, j)
            assert lit.min() >= math.floor((2 * r_min - first) / width) - 1, (i, j, lit)
            assert lit.max() <= math.floor((2 * r_max - first) / width) + 1, (i, j, lit)
            light = [RHO * INTENSITY * z0 / (math.pi * r ** 3) for r in (r_max, r_min)]
            total = transient[i, j].sum()
            assert light[0] * (1 - 1e-5) <= total <= light[1] * (1 + 1e-5), (i, j, total, light)
