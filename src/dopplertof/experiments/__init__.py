"""Experiments at scale: sweeps, animations and reports on Dask distributed.

    from dopplertof.experiments import load_config, run_sweep, write_report
    config = load_config("sweep.toml")
    summary = run_sweep(config, "results/")          # LocalCluster; scheduler="tcp://..."
    write_report("results/", "report/")

See docs/experiments.md.
"""

from .animate import AnimationSummary, run_animation
from .cluster import ClusterError
from .config import ConfigError, ReferenceConfig, SweepConfig, config_from_mapping, load_config
from .presets import PRESETS, preset_config
from .report import ReportError, write_report
from .sweep import SweepSummary, plan_sweep, run_sweep

__all__ = [
    "AnimationSummary", "ClusterError", "ConfigError", "PRESETS", "ReferenceConfig",
    "ReportError", "SweepConfig", "SweepSummary", "config_from_mapping", "load_config",
    "plan_sweep", "preset_config", "run_animation", "run_sweep", "write_report",
]
