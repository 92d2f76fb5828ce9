"""Real AMCW ToF cameras on top of the D-ToF camera (:mod:`dopplertof.tof`).

    from dopplertof import cameras
    cameras.preset_names()                       # the packaged presets
    preset = cameras.load_preset("kinect-v2")    # or a path to your own .toml
    result = cameras.capture_camera("scene.xml", preset, spp=64)
    result.raw, result.depth, result.summary
    result.write("out/")
    mine = cameras.calibrate("azure-kinect", "walls.csv")  # fitted to measured wall noise
    cameras.write_preset(mine, "mine.toml")

Each raw frame is rendered in its own time window (real cameras read their frames one
after the other, so a moving object is elsewhere in each), then the camera's sensor
(:mod:`.sensor`) and its own reconstruction (:mod:`.demodulate`, :mod:`.unwrap`) run.
See docs/cameras.md. Nothing below this package imports it.
"""

from ..lazy import lazy_exports

# imported on first use: `dopplertof --help` builds this package's command cheaply
__getattr__, __dir__, __all__ = lazy_exports(__name__, {
    ".preset": ("CameraPreset", "PresetError", "RawFrame", "format_preset", "load_preset",
                "preset_names"),
    ".preset_file": ("write_preset",),
    ".calibration": ("calibrate", "fit_table", "CalibrationError"),
    ".capture": ("capture_camera",),
    ".scene_view": ("load_scene_for_camera",),
})
