"""The built-in demo: a moving Cornell box, homodyne and heterodyne captures."""

from __future__ import annotations

import os
from importlib import resources

import numpy as np


def demo_scene_path() -> str:
    return str(resources.files("dopplertof") / "data" / "cornell_demo.xml")


def run_demo(outdir: str, spp: int = 64, res: int = 128, variant=None, progress=None) -> dict:
    """Render homodyne and heterodyne images of the demo scene; write NPY and PNG."""
    import dopplertof
    from . import io

    os.makedirs(outdir, exist_ok=True)
    dopplertof.set_variant(variant)
    scene = dopplertof.load_file(demo_scene_path(), {"res": res, "spp": spp})
    summary = {}
    for name, h in (("homodyne", 0.0), ("heterodyne", 1.0)):
        result = dopplertof.render_result(scene, spp=spp, seed=0,
                                          params={"hetero_frequency": h}, progress=progress)
        img = result.image
        io.write_npy(os.path.join(outdir, f"{name}.npy"), img)
        io.write_png(os.path.join(outdir, f"{name}.png"), img,
                     title=f"{name} (hetero_frequency={h:g}), {spp} spp",
                     metadata=result.metadata)
        summary[name] = {"mean": float(np.mean(img)), "abs_max": float(np.abs(img).max()),
                         "seconds": round(result.metadata["render_seconds"], 2)}
        print(f"{name:>10}: {img.shape[1]}x{img.shape[0]}, {spp} spp, "
              f"{result.metadata['render_seconds']:.1f} s, mean {np.mean(img):+.3e}, "
              f"|max| {np.abs(img).max():.3e} -> {os.path.join(outdir, name + '.png')}")
    return summary
