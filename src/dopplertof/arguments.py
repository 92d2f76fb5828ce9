"""The arguments of the public entry points, checked one way everywhere.

One function per kind of argument (a seed, a sample count, render parameters, a scene,
a path, a mapping, a text), shared by render, render_result, capture, the loaders and
the commands: a TypeError when a value has the wrong type, a ValueError (or the
caller's subclass of it, ``error``) when it is out of range, each one line naming the
argument and what it expects. Nothing is converted silently: ``spp=16.7``, ``spp="16"``
and ``seed=True`` are refused, not read as 16 and 1.
"""

from __future__ import annotations

import os
from collections.abc import Mapping

import numpy as np

from .params import RenderParams
from .sampling import SEED_LIMIT


def _wrong_type(name: str, expected: str, value) -> TypeError:
    return TypeError(f"{name} must be {expected}, got {type(value).__name__} {value!r}")


def is_integer(value) -> bool:
    """A Python or NumPy integer, not a boolean (True is not seed 1)."""
    return isinstance(value, (int, np.integer)) and not isinstance(value, bool)


def is_number(value) -> bool:
    """A Python or NumPy real number (an integer or a float), not a boolean."""
    return isinstance(value, (int, float, np.integer, np.floating)) \
        and not isinstance(value, (bool, np.bool_))


def check_seed(value, name: str = "seed", error=ValueError) -> int:
    """A seed: an integer in [0, 2^64) (all 64 bits key the random streams)."""
    if not is_integer(value):
        raise _wrong_type(name, "an integer in [0, 2^64)", value)
    if not 0 <= int(value) < SEED_LIMIT:
        raise error(f"{name} must be an integer in [0, 2^64), got {int(value)}")
    return int(value)


def check_spp(value, name: str = "spp", error=ValueError):
    """A sample count per pixel: a positive integer, or None (the scene's)."""
    if value is None:
        return None
    if not is_integer(value):
        raise _wrong_type(name, "a positive integer (None: the scene's sample count)", value)
    if value < 1:
        raise error(f"{name} must be >= 1, got {int(value)}")
    return int(value)


def check_params(value, name: str = "params"):
    """Render parameter overrides: None, a mapping {name: value} or a RenderParams."""
    if value is None or isinstance(value, (Mapping, RenderParams)):
        return value
    raise _wrong_type(name, "a dict {name: value} of render parameters or a RenderParams "
                            "(None: the scene's)", value)


def check_scene(value, name: str = "scene"):
    """A loaded scene: a DopplerScene, or a plain ``mi.Scene`` made one (static,
    :func:`dopplertof.scene.scene.as_doppler_scene`)."""
    from .scene.scene import DopplerScene, as_doppler_scene

    value = as_doppler_scene(value)
    if isinstance(value, DopplerScene):
        return value
    hint = (": load it first with dopplertof.load_file(path)"
            if isinstance(value, (str, os.PathLike)) else "")
    raise _wrong_type(name, f"a DopplerScene (from dopplertof.load_file) or an mi.Scene{hint}", value)


def check_path(value, name: str = "path") -> str:
    """A file path: a str or an os.PathLike."""
    if isinstance(value, (str, os.PathLike)) and not isinstance(value, bytes):
        path = os.fspath(value)
        if isinstance(path, str):
            return path
    raise _wrong_type(name, "a file path (str or os.PathLike)", value)


def check_mapping(value, name: str, optional: bool = True):
    """A dict (``optional``: or None)."""
    if (value is None and optional) or isinstance(value, Mapping):
        return value
    raise _wrong_type(name, "a dict" + (" or None" if optional else ""), value)


def check_text(value, name: str = "text") -> str:
    """A text (str)."""
    if isinstance(value, str):
        return value
    raise _wrong_type(name, "a str", value)


def check_choice(value, choices, name: str, error=ValueError) -> str:
    """One of the names ``choices`` (a str)."""
    if not isinstance(value, str):
        raise _wrong_type(name, "one of " + ", ".join(map(repr, choices)), value)
    if value not in choices:
        raise error(f"unknown {name} {value!r}: one of {', '.join(choices)}")
    return value


def check_flag(value, name: str) -> bool:
    """True or False (a NumPy bool too); ``'no'``, 0 or None are refused, not read as
    a truth value (``noise='no'`` turned the noise on)."""
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    raise _wrong_type(name, "True or False", value)


def check_index(value, length: int, name: str = "index") -> int:
    """An item of a sequence of ``length``: an integer in [-length, length)."""
    if not is_integer(value):
        raise _wrong_type(name, "an integer (one item; a range of items: a loop or a "
                                "torch Subset)", value)
    if not -length <= int(value) < length:
        raise IndexError(f"{name} {int(value)} out of range: {length} item(s)")
    return int(value) % length


def check_callable(value, name: str, optional: bool = True):
    """A function (``optional``: or None)."""
    if (value is None and optional) or callable(value):
        return value
    raise _wrong_type(name, "a function" + (" or None" if optional else ""), value)


def check_camera_capture(scene, camera, spp, seed, params, noise, noise_seed, on_frame,
                         checkpoint, preset_type):
    """The arguments of ``capture_camera`` (cameras/capture.py), each named when wrong
    (``noise='no'`` turned the noise on, ``noise_seed=1.5`` was seed 1, a path
    or None for the camera an os.fspath TypeError); returns the scene as a DopplerScene.
    ``preset_type``: the camera preset class (cameras/ is above this module)."""
    if not isinstance(camera, (str, os.PathLike, preset_type)) or isinstance(camera, bytes):
        raise _wrong_type("camera", "a preset name, a .toml path or a CameraPreset", camera)
    check_spp(spp)
    check_seed(seed)
    check_params(params)
    check_flag(noise, "noise")
    check_seed(noise_seed, "noise_seed")
    check_callable(on_frame, "on_frame")
    if checkpoint is not None:
        check_path(checkpoint, "checkpoint")
    if isinstance(scene, (str, os.PathLike)) and not isinstance(scene, bytes):
        return check_path(scene, "scene")  # a scene file, loaded for the camera
    return check_scene(scene)
