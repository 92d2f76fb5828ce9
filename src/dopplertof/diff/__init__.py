"""Differentiable D-ToF: derivatives of renders and velocities fitted to captures.

See docs/differentiable.md.
"""

from ..lazy import lazy_exports

# imported on first use (with NumPy and the renderer): `dopplertof --help` stays cheap
__getattr__, __dir__, __all__ = lazy_exports(__name__, {
    ".motion": ("VelocityMotion",),
    ".render": ("DerivativeError", "Derivatives", "DifferentiableScene", "render_derivatives",
                "differentiable_names", "parameter_names"),
    ".adjoint": ("Gradient", "gradient"),
    ".loss": ("cross_loss", "cross_seed_gradient"),
})
