"""The paper's experiments as sweep configurations, on any scene.

- ``reference``: high-spp homodyne and heterodyne captures at sensor offsets 0 and 1/4
  (what velocity reconstruction needs), rendered with the scene's own sampling.
- ``time-sampling``: every time sampling method x path correlation depth
  (0 independent paths, 1 shared camera ray, 2 also the first hit's decisions, full
  path) over an 11 x 11 grid of heterodyne frequencies (0 to 2 beat periods per
  exposure) and sensor offsets (0 to 1 period), against a reference per grid cell.
- ``no-further-stratification``: every method with and without the stratification of
  the primal time numbers across a pixel's groups
  (``use_stratified_sampling_for_each_interval``), whole-path correlation, same grid.
- ``antithetic-shift``: shifted antithetic sampling with the shift a from 0 to 1 in
  steps of 0.1, at heterodyne frequencies 0.5, 1, 1.5 and 2, offset 0 (the analysis of
  the supplementary, Sec. 3, predicts the optimum a = 0.5 below one beat period).

``quick=True`` cuts each axis to a few values for a first look.
"""

from __future__ import annotations

import os

from typing import TYPE_CHECKING

from ..sampling import FULL_CORRELATION, METHODS

if TYPE_CHECKING:  # (the annotations' names; the config, NumPy with it, on first use)
    from .config import SweepConfig

PRESETS = ("reference", "time-sampling", "no-further-stratification", "antithetic-shift")

#: samples per pixel of the compared images and of their references, unless given
DEFAULT_SPP = {"reference": 4096, "time-sampling": 64, "no-further-stratification": 64,
               "antithetic-shift": 64}
DEFAULT_REFERENCE_SPP = 4096

CORRELATION_DEPTHS = (0, 1, 2, "full")


def _steps(start: float, stop: float, count: int) -> tuple[float, ...]:
    return tuple(round(start + (stop - start) * i / (count - 1), 10) for i in range(count))


def frequency_offset_grid(quick: bool) -> dict:
    if quick:
        return {"hetero_frequency": (0.0, 1.0, 2.0), "hetero_offset": (0.0, 0.25)}
    return {"hetero_frequency": _steps(0.0, 2.0, 11), "hetero_offset": _steps(0.0, 1.0, 11)}


def preset_config(preset: str, scene, *, spp: int | None = None,
                  reference_spp: int | None = None, defines: dict | None = None,
                  seeds=(0,), quick: bool = False, variant: str | None = None) -> SweepConfig:
    """The sweep configuration of a named preset on ``scene`` (a scene file path)."""
    from .config import ConfigError, ReferenceConfig, SweepConfig, typed_value

    if preset not in PRESETS:
        raise ConfigError(f"unknown preset {preset!r}: expected one of {', '.join(PRESETS)}")
    if scene is None:
        raise ConfigError(f"--preset {preset} needs --scene SCENE.xml")
    scene = os.path.abspath(os.fspath(scene))
    if not os.path.isfile(scene):
        raise ConfigError(f"scene file not found: {scene}")
    where = f"preset {preset}"
    spp = typed_value("spp", spp if spp is not None else DEFAULT_SPP[preset], f"{where}: spp")
    seeds = tuple(typed_value("seed", s, f"{where}: seed") for s in seeds)
    if not seeds or len(set(seeds)) != len(seeds):
        raise ConfigError(f"{where}: seeds must be distinct and at least one, got {seeds}")
    fixed = {"spp": spp}
    grid: dict = {}
    if preset == "reference":
        grid = {"hetero_frequency": (0.0, 1.0), "hetero_offset": (0.0, 0.25)}
        reference = None
    else:
        ref_spp = typed_value("spp", reference_spp or DEFAULT_REFERENCE_SPP,
                              f"{where}: reference spp")
        reference = ReferenceConfig(spp=ref_spp, params={
            "time_sampling_method": "antithetic", "path_correlation_depth": FULL_CORRELATION})
        if reference.seed in seeds:
            raise ConfigError(f"{where}: seed {reference.seed} is the reference's seed")
        methods = ("uniform", "antithetic") if quick else METHODS
        if preset == "time-sampling":
            depths = (0, 1, "full") if quick else CORRELATION_DEPTHS
            grid = {"time_sampling_method": methods,
                    "path_correlation_depth": tuple(
                        typed_value("path_correlation_depth", d, where) for d in depths),
                    **frequency_offset_grid(quick)}
        elif preset == "no-further-stratification":
            fixed["path_correlation_depth"] = FULL_CORRELATION
            grid = {"time_sampling_method": methods,
                    "use_stratified_sampling_for_each_interval": (True, False),
                    **frequency_offset_grid(quick)}
        else:  # antithetic-shift
            fixed["time_sampling_method"] = "antithetic"
            fixed["hetero_offset"] = 0.0
            shifts = _steps(0.0, 1.0, 5) if quick else _steps(0.0, 1.0, 11)
            grid = {"antithetic_shift": shifts,
                    "hetero_frequency": (1.0, 2.0) if quick else (0.5, 1.0, 1.5, 2.0)}
    if len(seeds) > 1:
        grid["seed"] = seeds
    else:
        fixed["seed"] = seeds[0]
    name = f"{preset} ({os.path.basename(scene)})"
    return SweepConfig(scene=scene, grid=grid, fixed=fixed, defines=dict(defines or {}),
                       reference=reference, variant=variant, name=name, source=where)
