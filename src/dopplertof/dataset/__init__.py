"""Training data: randomized dynamic scenes rendered on Dask into HDF5 shards
(``dopplertof dataset CONFIG.toml -o DIR``), and their reader :class:`Dataset`.
docs/dataset.md describes the configuration, the layout and every convention."""

from ..lazy import lazy_exports

# imported on first use (with NumPy, h5py and Dask): `dopplertof --help` stays cheap
__getattr__, __dir__, __all__ = lazy_exports(__name__, {
    ".config": ("DatasetConfig", "DatasetError", "load_config"),
    ".reader": ("Dataset",),
})
