"""A scene's integrator parameters, each to its owner: the D-ToF camera's
(:class:`..params.RenderParams`) and every other modality's settings, whose names carry
the modality's prefix (the FMCW lidar's ``fmcw_*``: :class:`..fmcw_settings.FMCWSettings`).
One parser for the XML and dict loaders, Mitsuba's own plugin and ``-P``: a name that
is no one's is an error naming the nearest known ones, whoever's they are.
"""

from __future__ import annotations

from ..fmcw_settings import FMCWSettings
from ..hints import unknown_name
from ..params import ParameterError, RenderParams

#: the settings of the modalities other than the D-ToF camera, by modality: each a
#: frozen dataclass with PREFIX, WHOSE, names(), coerced() and from_mapping(), as
#: FMCWSettings
MODALITY_SETTINGS = {"fmcw": FMCWSettings}


def default_settings() -> dict:
    """Every modality's settings at their defaults, ``{modality: settings}``."""
    return {name: cls() for name, cls in MODALITY_SETTINGS.items()}


def known_names() -> tuple:
    """Every parameter name an integrator may carry: the D-ToF ones, then each
    modality's."""
    return RenderParams.names() + tuple(n for cls in MODALITY_SETTINGS.values()
                                        for n in cls.names())


def split(values: dict, where: str = "parameters") -> tuple[dict, dict]:
    """``values`` ({name: value}) as (the D-ToF ones, {modality: its ones}); a
    ParameterError for a name no one knows."""
    own, others = {}, {}
    for name, value in values.items():
        if name in RenderParams.names():
            own[name] = value
            continue
        modality = next((m for m, cls in MODALITY_SETTINGS.items() if name in cls.names()),
                        None)
        if modality is None:
            raise ParameterError(f"{where}: {unknown_name('parameter', name, known_names())}")
        others.setdefault(modality, {})[name] = value
    return own, others


def coerced(values: dict, where: str = "parameters") -> None:
    """Check ``values``' names and types (no ranges, no scene: the command line's -P
    values before Mitsuba loads); a ParameterError at the first problem."""
    own, others = split(values, where)
    RenderParams.coerced(own, where)
    for modality, given in others.items():
        MODALITY_SETTINGS[modality].coerced(given, where)


def render_values(values: dict, where: str = "render parameters") -> dict:
    """``values`` checked as a D-ToF render's (-P of ``render``, ``capture``,
    ``precision``): names and types, and a ParameterError for another modality's name,
    which such a render would ignore."""
    own, others = split(values, where)
    for modality, given in others.items():
        name, whose = next(iter(given)), MODALITY_SETTINGS[modality].WHOSE
        raise ParameterError(f"{where}: {name} is {whose}, not a D-ToF render's: it would "
                             "be ignored; leave it out")
    return RenderParams.coerced(own, where)


def parsed(values: dict, where: str, params: RenderParams,
           settings: dict | None = None) -> tuple[RenderParams, dict]:
    """``values`` parsed on top of ``params`` and ``settings`` ({modality: settings},
    None: the defaults), each checked (the D-ToF parameters first):
    (RenderParams, {modality: settings})."""
    own, others = split(values, where)
    params = RenderParams.from_mapping(own, where=where, base=params)
    settings = dict(settings or default_settings())
    for modality, given in others.items():
        settings[modality] = MODALITY_SETTINGS[modality].from_mapping(
            given, where=where, base=settings[modality])
    return params, settings
