"""Mitsuba's own calls with dopplertof (design.md section 6): once mitsuba is imported
(before or after dopplertof), ``mitsuba.set_variant`` registers the D-ToF plugins for
the variant it sets, so that ``mi.load_file`` finds ``<integrator type="dopplertof">``,
and ``mi.render`` renders a DopplerScene (moving bodies included) with
:func:`dopplertof.render`."""

from __future__ import annotations


def adopt(mi) -> None:
    """Hook dopplertof into the mitsuba module ``mi`` (once per process)."""
    from .backend import after_set_variant

    after_set_variant(mi, register_plugins)
    if not getattr(mi.render, "dopplertof_render", False):
        mi.render = _render_accepting_doppler_scenes(mi, mi.render)


def register_plugins(mi) -> None:
    """The D-ToF plugins for the variant Mitsuba has now: the integrator where dopplertof
    can run (a JIT variant without polarization), else one that says why not when a
    scene asks for it (not Mitsuba's "Plugin not found")."""
    from . import integrators
    from .backend import variant_problem

    problem = variant_problem(mi.variant() or "")
    if problem is None:
        integrators.register()
    else:
        integrators.register_refusal(problem)


def _render_accepting_doppler_scenes(mi, original):
    """``mi.render`` that also takes a DopplerScene (with ``seed`` and ``spp``, as
    Mitsuba's; the other arguments belong to Mitsuba's integrators)."""
    def render(scene, *args, **kwargs):
        from .scene import DopplerScene

        if not isinstance(scene, DopplerScene):
            return original(scene, *args, **kwargs)
        if args or set(kwargs) - {"seed", "spp"}:
            raise TypeError(
                "mi.render(DopplerScene) renders it with dopplertof.render: it takes seed= "
                "and spp= only; for derivatives use dopplertof.diff.render_derivatives, for "
                "another integrator mi.render(scene.static, ...) (the static part only, "
                "without the moving bodies)")
        from .render import render as render_doppler

        spp = int(kwargs.get("spp", 0))
        image = render_doppler(scene, spp=spp or None, seed=int(kwargs.get("seed", 0)),
                               progress=False)
        return mi.TensorXf(image)

    render.__doc__ = getattr(original, "__doc__", None)
    render.dopplertof_render = True
    return render
