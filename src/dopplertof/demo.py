"""The built-in demo: one D-ToF camera frame of a moving Cornell box, against the truth.

The scene ships with the package (data/cornell_demo.xml): the short box approaches
the camera and the tall box recedes, at 10 m/s each, under a point light at the
camera. The demo runs the capture pipeline (dopplertof.tof): homodyne and
heterodyne captures, velocity and depth reconstruction, ground truth, previews and
summary.json, and prints the summary.
"""

from __future__ import annotations


#: default settings: about a minute on 2 cores
DEMO_SPP = 512
DEMO_RES = 128


def demo_scene_path() -> str:
    """The packaged demo scene's XML file."""
    from importlib import resources  # (not at import: the command line's --help)

    return str(resources.files("dopplertof") / "data" / "cornell_demo.xml")


def run_demo(outdir: str, spp: int = DEMO_SPP, res: int = DEMO_RES, variant=None,
             progress=None, noise=None, quiet: bool = False) -> dict:
    """Capture one frame of the demo scene into ``outdir``; returns the summary."""
    import dopplertof
    from .tof import format_summary, prepare_folder

    if isinstance(res, bool) or not isinstance(res, int) or res < 1:
        raise ValueError(f"res must be a positive integer, got {res!r}")
    prepare_folder(outdir)
    dopplertof.set_variant(variant)
    scene = dopplertof.load_file(demo_scene_path(), {"res": res, "spp": spp})

    def report(spec, seconds):
        if not quiet:
            print(f"  {spec.name:<16} {seconds:6.1f} s", flush=True)

    result = dopplertof.capture(scene, spp=spp, seed=0, noise=noise, progress=progress,
                                on_capture=report)
    result.write(outdir)
    print(format_summary(result.summary, outdir))
    return result.summary
