"""dopplertof: a Doppler time-of-flight camera simulator on stock Mitsuba 3.

    import dopplertof
    dopplertof.set_variant("llvm_ad_rgb")     # optional: LLVM RGB is the default
    scene = dopplertof.load_file("scene.xml")
    img = dopplertof.render(scene, spp=1024, seed=0)   # float32 (H, W, C), signed
"""

from __future__ import annotations

from . import backend as _backend
from .lazy import lazy_exports

__version__ = "0.1.0"

# Point Dr.Jit at a usable libLLVM before anything starts its LLVM backend; a missing
# one is reported by set_variant() with what to install.
try:
    _backend.ensure_libllvm()
except _backend.BackendError:
    pass

from .backend import BackendError  # noqa: E402
from .render import render, render_result  # noqa: E402  (light: the pipeline on first use)

# ---- The rest on first use (NumPy and Mitsuba too): `import dopplertof` stays cheap ----
__getattr__, __dir__, _LAZY_NAMES = lazy_exports(__name__, {
    ".params": ("ParameterError", "RenderParams"),
    ".integrators.pipeline": ("RenderResult",),
    ".tof.capture": ("CaptureSettings",),
    ".scene": ("scene", "Animation", "DopplerScene", "SceneError"),
})


def _adopt_mitsuba(mi):
    """mitsuba.set_variant registers the plugins, mi.render takes a DopplerScene."""
    from . import interop

    interop.adopt(mi)


# from the moment mitsuba is imported, before or after dopplertof (interop.py)
_backend.when_imported("mitsuba", _adopt_mitsuba)


def set_variant(variant: str | None = None) -> str:
    """Choose the Mitsuba variant (LLVM RGB by default; checks libLLVM and the GPU) and
    register the D-ToF integrator plugins for it (``<integrator type="dopplertof">``)."""
    if variant is not None:
        from . import arguments

        arguments.check_text(variant, "variant")
    variant = _backend.set_variant(variant)
    from . import integrators

    integrators.register()
    return variant


def _ensure_variant():
    import mitsuba as mi

    if mi.variant() is None or not (mi.variant().startswith("llvm_")
                                    or mi.variant().startswith("cuda_")):
        set_variant()
    else:
        from . import integrators

        integrators.register()


def load_file(path, overrides=None, **kwargs):
    """Load a Mitsuba 3 XML scene (with <animation> keyframes); sets LLVM RGB if no
    JIT variant is set. ``overrides`` (or keyword arguments) set <default> values."""
    from . import arguments, scene

    path = arguments.check_path(path, "path")
    arguments.check_mapping(overrides, "overrides")
    _ensure_variant()
    return scene.load_file(path, {**(overrides or {}), **kwargs})


def load_string(text: str, overrides=None, **kwargs):
    """Load a scene from XML text; see load_file."""
    from . import arguments, scene

    arguments.check_text(text, "text")
    arguments.check_mapping(overrides, "overrides")
    _ensure_variant()
    return scene.load_string(text, {**(overrides or {}), **kwargs})


def load_dict(scene_dict: dict):
    """Load a dict scene (Mitsuba's load_dict format, with dopplertof.Animation)."""
    from . import arguments, scene

    arguments.check_mapping(scene_dict, "scene_dict", optional=False)
    _ensure_variant()
    return scene.load_dict(scene_dict)


def capture(scene, spp=None, seed=None, **kwargs):
    """One D-ToF camera frame: every capture, velocity and depth reconstruction and the
    exact truth (see :func:`dopplertof.tof.capture`). ``scene`` is a DopplerScene, a
    plain ``mi.Scene`` (static) or the path of an XML scene; ``settings=`` a
    :class:`CaptureSettings`, or its fields as keyword arguments (``seed`` None: the
    settings', by default 0). Returns a CaptureResult (``.velocity``, ``.velocity_gt``,
    ``.depth``, ``.depth_gt``, ``.captures``, ``.summary``, ``.write(folder)``)."""
    import os

    from . import arguments
    from .tof import capture as _capture

    if isinstance(scene, (str, os.PathLike)):
        scene = load_file(scene)
    else:
        scene = arguments.check_scene(scene, "scene")
        _ensure_variant()
    return _capture(scene, spp, seed, **kwargs)


__all__ = ["load_file", "load_string", "load_dict", "capture", "set_variant", "BackendError",
           "render", "render_result", *_LAZY_NAMES]
