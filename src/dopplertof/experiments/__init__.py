"""Experiments at scale: sweeps, animations and reports on Dask distributed.

    from dopplertof.experiments import load_config, run_sweep, write_report
    config = load_config("sweep.toml")
    summary = run_sweep(config, "results/")          # LocalCluster; scheduler="tcp://..."
    write_report("results/", "report/")

See docs/experiments.md.
"""

from ..lazy import lazy_exports

# imported on first use (with NumPy and Dask): `dopplertof --help` stays cheap
__getattr__, __dir__, __all__ = lazy_exports(__name__, {
    ".animate": ("AnimationSummary", "run_animation"),
    ".cluster": ("ClusterError",),
    ".config": ("ConfigError", "ReferenceConfig", "SweepConfig", "config_from_mapping",
                "load_config"),
    ".presets": ("PRESETS", "preset_config"),
    ".report": ("ReportError", "write_report"),
    ".sweep": ("SweepSummary", "plan_sweep", "run_sweep"),
})
