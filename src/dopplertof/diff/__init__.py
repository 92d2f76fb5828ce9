"""Differentiable D-ToF: derivatives of renders and velocities fitted to captures.

See docs/differentiable.md.
"""

from .gradient import Gradient, gradient
from .motion import VelocityMotion
from .render import (DerivativeError, Derivatives, DifferentiableScene,
                     render_derivatives)

__all__ = ["VelocityMotion", "DerivativeError", "Derivatives", "DifferentiableScene",
           "render_derivatives", "Gradient", "gradient"]
