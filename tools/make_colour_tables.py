"""Write the package's colour tables (src/dopplertof/data/colormaps.npz): Matplotlib's
colour maps that the previews use, at dopplertof.previews.TABLE_SIZE entries, as uint8
RGB. The previews read them instead of importing Matplotlib (half a second);
tests/test_previews.py checks them against the installed Matplotlib.

    .venv/bin/python tools/make_colour_tables.py
"""

import os
import sys

import matplotlib
import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "src"))

from dopplertof import previews  # noqa: E402

#: the maps of the capture, render and camera previews
NAMES = ("RdBu_r", "PuOr_r", "viridis", "gray", "magma")


def table(name: str) -> np.ndarray:
    colours = matplotlib.colormaps[name](np.linspace(0.0, 1.0, previews.TABLE_SIZE))[:, :3]
    return np.round(colours * 255).astype(np.uint8)


def main() -> None:
    tables = {name: table(name) for name in NAMES}
    np.savez_compressed(previews.COLOUR_TABLES, **tables)
    print(f"wrote {previews.COLOUR_TABLES}: {', '.join(NAMES)}")


if __name__ == "__main__":
    main()
