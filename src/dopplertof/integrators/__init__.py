"""Integrator plugins registered with Mitsuba.

The D-ToF path tracer itself lives in :mod:`.dtof_path`; :func:`register` makes
``<integrator type="dopplertof">`` (alias ``dopplertofpath``) loadable by Mitsuba
for the current variant (see the bottom of :mod:`.dopplertof`).
"""

_registered: set = set()


def register() -> None:
    """Register the plugins for the current Mitsuba variant (idempotent)."""
    import mitsuba as mi

    if mi.variant() in _registered:
        return
    from .dopplertof import register_plugin

    register_plugin()
    _registered.add(mi.variant())
