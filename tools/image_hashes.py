"""Hash the images of a fixed set of renders: a refactor must leave every one bitwise
unchanged (same machine, same Dr.Jit and Mitsuba).

    .venv/bin/python tools/image_hashes.py -o before.json
    ... change the code ...
    .venv/bin/python tools/image_hashes.py --compare before.json

``-P name=value`` adds a render parameter to every configuration (e.g.
``-P film_sampling=importance``: tests/fixtures/images_importance_film.json holds those
hashes, which tests/test_film.py compares on the machine that recorded them). The set
covers every time-sampling method (the analytic and control-variate modes among them), the
waveforms and the full-waveform mode, the variant families (RGB, spectral, mono), body,
camera and light motion, the three filters, adaptive counts, a crop window, the motion
mapping; and the captures: a D-ToF frame (with error
bars, through a checkpoint), two camera presets' frames, an FMCW spectrum and two dataset
samples. About a minute on 2 cores.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import sys

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
PUBLISHED = os.path.join(ROOT, "tests", "fixtures", "cornell_box_moving.xml")
sys.path.insert(0, os.path.join(ROOT, "tests"))  # analytic.plane_scene


def _digest(*arrays) -> str:
    h = hashlib.sha256()
    for a in arrays:
        a = np.ascontiguousarray(a)
        h.update(str((a.dtype, a.shape)).encode())
        h.update(a.tobytes())
    return h.hexdigest()[:16]


#: the captures hashed after the renders of configurations(), by name
CAPTURES = ("capture", "capture-error-bars", "capture-checkpoint", "camera-azure-kinect",
            "camera-kinect-v2", "fmcw", "fmcw-collimated-speckle", "dataset-sample0",
            "dataset-sample1")


def names() -> list:
    """Every hash's name, in the order they are computed (docs/testing.md lists them)."""
    return [c[0] for c in configurations()] + list(CAPTURES)


def configurations():
    """(name, variant, scene factory, render keyword arguments)."""
    import dopplertof

    def published(**defines):
        return lambda: dopplertof.load_file(PUBLISHED, resx="12", resy="10", **defines)

    def plane(**kw):
        from analytic import plane_scene

        def make():
            d = plane_scene(2.0, 30.0, res=3, **kw)
            return dopplertof.load_dict(d)
        return make

    def with_filter(kind, crop=False):
        def make():
            from analytic import plane_scene

            d = plane_scene(2.0, 30.0, res=6)
            d["sensor"]["film"]["rfilter"] = {"type": kind}
            if crop:
                d["sensor"]["film"].update(crop_offset_x=1, crop_offset_y=2, crop_width=4,
                                           crop_height=3)
            return dopplertof.load_dict(d)
        return make

    rgb = "llvm_ad_rgb"
    yield "published-scene", rgb, published(), {"spp": 32}
    for method in ("auto", "uniform", "stratified", "antithetic", "antithetic_mirror"):
        yield f"published-{method}", rgb, published(), {
            "spp": 32, "params": {"time_sampling_method": method}}
    yield "published-depth1", rgb, published(), {
        "spp": 32, "params": {"time_sampling_method": "antithetic", "path_correlation_depth": 1}}
    yield "published-K4", rgb, published(), {
        "spp": 32, "params": {"time_sampling_method": "antithetic", "time_correlate_number": 4}}
    yield "published-homodyne", rgb, published(), {
        "spp": 32, "params": {"hetero_frequency": 0, "hetero_offset": 0.25}}
    yield "published-motion-map", rgb, published(), {
        "spp": 32, "params": {"time_sampling_method": "antithetic",
                              "antithetic_mapping": "motion"}}
    yield "published-analytic", rgb, published(), {
        "spp": 32, "params": {"time_sampling_method": "analytic"}}
    yield "published-control-variate", rgb, published(), {
        "spp": 32, "params": {"time_sampling_method": "control_variate"}}
    yield "published-adaptive", rgb, published(), {
        "spp": 128, "params": {"adaptive_sampling": True}}
    for wave in ("rectangular", "triangular", "trapezoidal"):
        yield f"plane-{wave}", rgb, plane(), {
            "spp": 64, "params": {"wave_function_type": wave, "hetero_frequency": 1}}
    yield "plane-full-waveform", rgb, plane(), {
        "spp": 64, "params": {"low_frequency_component_only": False}}
    yield "plane-camera-motion", rgb, plane(camera_velocity=5.0), {"spp": 64}
    yield "plane-light-motion", rgb, plane(light_velocity=-8.0), {"spp": 64}
    for kind in ("box", "tent", "gaussian"):
        yield f"filter-{kind}", rgb, with_filter(kind), {"spp": 32}
    yield "filter-tent-crop", rgb, with_filter("tent", crop=True), {"spp": 32}
    yield "spectral", "llvm_ad_spectral", plane(), {"spp": 32}
    yield "mono", "llvm_ad_mono", plane(), {"spp": 32}


def machine() -> str:
    """What bitwise results depend on: CPU, Dr.Jit, Mitsuba and libLLVM."""
    import platform

    import drjit as dr
    import mitsuba as mi

    cpu = platform.machine()
    try:
        with open("/proc/cpuinfo") as f:
            flags = {}
            for line in f:
                key, _, value = line.partition(":")
                flags.setdefault(key.strip(), value.strip())
        cpu = f"{flags.get('model name', cpu)} [{hashlib.sha256(flags.get('flags', '').encode()).hexdigest()[:8]}]"
    except OSError:
        pass
    from dopplertof.backend import ensure_libllvm

    llvm = os.path.basename(os.path.realpath(ensure_libllvm()))
    return f"{cpu}; drjit {dr.__version__}; mitsuba {mi.__version__}; {llvm}"


def hashes(extra_params: dict, only=None) -> dict:
    import dopplertof

    out = {}
    for name, variant, make, kwargs in configurations():
        if only and name not in only:
            continue
        dopplertof.set_variant(variant)
        scene = make()
        kwargs = dict(kwargs)
        params = {**kwargs.pop("params", {}), **extra_params}
        result = dopplertof.render_result(scene, seed=7, params=params, **kwargs)
        out[name] = _digest(result.image)
    dopplertof.set_variant("llvm_ad_rgb")
    scene = dopplertof.load_file(PUBLISHED, resx="8", resy="8")
    frame = dopplertof.capture(scene, spp=16, seed=3, params=extra_params or None)
    out["capture"] = _digest(*(frame.captures[k] for k in sorted(frame.captures)),
                             frame.velocity, frame.depth)
    out.update(capture_hashes(extra_params))
    if only is None:
        assert sorted(out) == sorted(names()), "CAPTURES is not what capture_hashes hashes"
    return out


def capture_hashes(extra_params: dict) -> dict:
    """The captures' frame loop and outputs: a frame with error-bar batches, one
    through a checkpoint folder, a camera preset's frame and an FMCW spectrum."""
    import tempfile

    import dopplertof
    from dopplertof.cameras.capture import capture_through
    from dopplertof.fmcw import fmcw

    out = {}
    params = extra_params or None
    scene = dopplertof.load_file(PUBLISHED, resx="6", resy="6")
    frame = dopplertof.capture(scene, spp=8, seed=3, params=params, mc_batches=2)
    out["capture-error-bars"] = _digest(*(frame.captures[k] for k in sorted(frame.captures)),
                                        frame.velocity, frame.depth)
    with tempfile.TemporaryDirectory() as folder:
        frame = dopplertof.capture(scene, spp=8, seed=3, params=params,
                                   checkpoint=os.path.join(folder, "ckpt"))
        out["capture-checkpoint"] = _digest(
            *(frame.captures[k] for k in sorted(frame.captures)), frame.velocity, frame.depth)
    for camera in ("azure-kinect", "kinect-v2"):
        result, = capture_through(os.path.join(ROOT, "examples", "translating_sphere.xml"),
                                  [camera], resolution=(8, 6), spp=8, seed=2, params=params)
        out[f"camera-{camera}"] = _digest(result.rendered, result.raw, result.depth,
                                          *(np.asarray(v) for _, v in sorted(
                                              vars(result.reconstruction).items())
                                            if isinstance(v, np.ndarray)))
    street = dopplertof.load_file(os.path.join(ROOT, "examples", "fmcw_street.xml"),
                                  {"res": "6", "spp": "8"})
    spectra = fmcw(street, seed=1, params=params)
    out["fmcw"] = _digest(spectra.spectrum, spectra.range, spectra.velocity)
    spectra = fmcw(street, seed=1, params=params, beam="collimated", beam_intensity=2.0,
                   speckle=True)
    out["fmcw-collimated-speckle"] = _digest(spectra.spectrum, spectra.speckle)
    out.update(dataset_hashes())
    return out


#: a dataset sample's keys (with their split suffixes) added after its hashes were first
#: recorded (layout 4's unlit mask: all False through this dataset's paper-dtof, whose light
#: holds the view; tests/test_dataset_unlit.py tests it)
ADDED = ("camera_mask_unlit",)


def dataset_hashes() -> dict:
    """Two samples of a tiny dataset (12x10, 4 spp, two objects of every shape and
    material kind), every array each holds (the camera's outputs and the truth)."""
    import tempfile

    from dopplertof.dataset.config import config_from_mapping
    from dopplertof.dataset.sample import render_sample
    from dopplertof.outputs import CAMERA_SPLITS, RENAMED

    config = config_from_mapping({
        "samples": 2, "samples_per_shard": 1, "seed": 7,
        "render": {"resolution": [12, 10], "spp": 4, "max_depth": 4},
        "objects": {"count": [2, 2], "shapes": ["sphere", "cube", "rectangle"],
                    "materials": ["diffuse", "plastic", "conductor"]}}, "<image_hashes>")
    # (the arrays in the order of their names before a rename: a rename alone keeps the
    # hash; and without the keys added since, ADDED: an addition alone keeps it too)
    former = {new + suffix: old + suffix for (where, old), new in RENAMED.items()
              if where == "dataset" for suffix in CAMERA_SPLITS.values()}
    added = {key + suffix for key in ADDED for suffix in CAMERA_SPLITS.values()}
    out = {}
    with tempfile.TemporaryDirectory() as folder:
        for index in range(2):
            arrays, _ = render_sample(config, index, folder)
            out[f"dataset-sample{index}"] = _digest(*(
                np.asarray(arrays[k]) for k in sorted(set(arrays) - added,
                                                      key=lambda k: former.get(k, k))))
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("-o", "--output", help="write the hashes (JSON)")
    ap.add_argument("--compare", help="compare with hashes written before")
    ap.add_argument("-P", action="append", default=[], metavar="NAME=VALUE")
    args = ap.parse_args(argv)
    extra = dict(item.split("=", 1) for item in args.P)
    found = hashes(extra)
    if args.output:
        with open(args.output, "w") as f:
            json.dump({"machine": machine(), "images": found}, f, indent=1, sort_keys=True)
    if args.compare:
        with open(args.compare) as f:
            before = json.load(f)["images"]
        changed = sorted(k for k in before if found.get(k) != before[k])
        new = sorted(set(found) - set(before))
        if new:
            print(f"not recorded before (not compared): {', '.join(new)}")
        for k in changed:
            print(f"changed: {k}")
        print(f"{len(before) - len(changed)} of {len(before)} images bitwise unchanged")
        return 1 if changed else 0
    print(json.dumps(found, indent=1, sort_keys=True))
    return 0


if __name__ == "__main__":
    sys.exit(main())
