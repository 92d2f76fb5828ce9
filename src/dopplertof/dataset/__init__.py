"""Training data: randomized dynamic scenes rendered on Dask into HDF5 shards
(``dopplertof dataset CONFIG.toml -o DIR``), and their reader :class:`Dataset`.
docs/dataset.md describes the configuration, the layout and every convention."""

from .config import DatasetConfig, DatasetError, load_config
from .reader import Dataset

__all__ = ["Dataset", "DatasetConfig", "DatasetError", "load_config"]
