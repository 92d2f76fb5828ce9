"""FMCW lidar on the D-ToF scenes: the up and down chirps' beat spectra of
every pixel, range and radial velocity from their peaks, against the exact truth.

    import dopplertof
    from dopplertof.fmcw import Chirp, fmcw
    scene = dopplertof.load_file("scene.xml")
    result = fmcw(scene, Chirp(bandwidth=1e9, chirp_time=10e-6, bins=256), spp=64)
    result.spectrum, result.range, result.velocity, result.summary
    result.write("out/")

See docs/fmcw.md for the model, the conventions and the cost.
"""

from ..lazy import lazy_exports

__getattr__, __dir__, __all__ = lazy_exports(__name__, {
    ".chirp": ("Chirp", "FMCWError"),
    ".capture": ("fmcw", "FMCWResult", "spectrum_peaks"),
})
