"""``<integrator type="dopplertof">`` for Mitsuba's own loader and ``mi.render``.

Scenes loaded with :func:`dopplertof.load_file` carry their moving bodies and use
:func:`dopplertof.render`; this plugin lets plain ``mitsuba.load_file`` +
``mitsuba.render`` produce the same D-ToF image for static scenes.
"""

from __future__ import annotations

from ..params import RenderParams


def _make_class(mi):
    class DopplerToFIntegrator(mi.SamplingIntegrator):
        """Mitsuba plugin wrapper around the D-ToF render pipeline."""

        def __init__(self, props):
            super().__init__(props)
            values = {name: props[name] for name in props.keys()}
            self.params = RenderParams.from_mapping(values, where="integrator dopplertof")

        def render(self, scene, sensor=0, seed=0, spp=0, develop=True, evaluate=True):
            from ..scene.scene import build
            from .pipeline import render_result

            if not isinstance(sensor, int) and sensor is not scene.sensors()[0]:
                raise ValueError("dopplertof renders the scene's first sensor only")
            dscene = build(mi, scene, (), self.params, "<mitsuba scene>")
            result = render_result(dscene, spp=spp or None, seed=int(seed), progress=False)
            return mi.TensorXf(result.image)

        def sample(self, *args, **kwargs):
            raise NotImplementedError("dopplertof renders whole images: use render()")

        def to_string(self):
            return f"DopplerToFIntegrator[{self.params}]"

    return DopplerToFIntegrator


def register_plugin() -> None:
    import mitsuba as mi

    cls = _make_class(mi)
    for name in ("dopplertof", "dopplertofpath"):
        mi.register_integrator(name, lambda props, cls=cls: cls(props))
