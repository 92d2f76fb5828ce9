"""The D-ToF integrator, registered with Mitsuba.

The path tracer is the class :mod:`.dtof_path` makes per variant (``DopplerToFPath``,
a ``mi.SamplingIntegrator``); :func:`register` makes it loadable by Mitsuba as
``<integrator type="dopplertof">`` (alias ``dopplertofpath``) for the current variant
(see the bottom of :mod:`.dtof_path`).
"""

_registered: set = set()


def register() -> None:
    """Register the plugins for the current Mitsuba variant (idempotent)."""
    import mitsuba as mi

    if mi.variant() in _registered:
        return
    from .dtof_path import register_plugin

    register_plugin(mi)
    _registered.add(mi.variant())


def register_refusal(problem: str) -> None:
    """In a variant dopplertof cannot run in: plugins that raise ``problem`` (why) when a
    scene names them (idempotent)."""
    import mitsuba as mi

    from ..backend import BackendError
    from ..scene.scene import DTOF_INTEGRATORS

    if mi.variant() in _registered:
        return

    def refuse(props):
        raise BackendError(f"<integrator type=\"dopplertof\">: {problem}")

    for name in DTOF_INTEGRATORS:
        mi.register_integrator(name, refuse)
    _registered.add(mi.variant())
