"""Scene loading: XML and dict scenes, keyframed motion, moving bodies."""

from .dicts import Animation, load_dict
from .scene import DopplerScene, SceneError
from .xml import load_file, load_string

__all__ = ["Animation", "DopplerScene", "SceneError", "load_dict", "load_file", "load_string"]
