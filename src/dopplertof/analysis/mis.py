"""Antithetic sampling combined with multiple importance sampling (supplementary Sec. 4).

An antithetic map T is an involution (T(T(x)) = x) with Jacobian J_T(x) = |dT/dx|; the
antithetic sample T(x) of a primal x ~ p has density p_T(T(x)) = p(x) / J_T(x) (Eq. 29).

* Sec. 4.1: MIS between the primal and the antithetic strategy.  The balance weights of
  Eqs. (32)-(33) agree, w(x) = w_T(T(x)), and w(x) + w(T(x)) = 1, so the weighted pair
  w(x) (f(x) + f(T(x)) J_T(x)) / p(x) stays unbiased and keeps the cancellation.
* Sec. 4.2: MIS between two antithetic maps T_1, T_2.  The weights alpha, beta of Eq. (35)
  need not sum to one, and then Eq. (36) loses the cancellation; the counterexample
  f(y, z) = sin y sin z with T_1 = (y, -z), T_2 = (-y, z) shows it for any p with
  p(y, z) != p(-y, -z).

Functions take callables for p, T and J_T that work on NumPy arrays (a point is an array
whose last axis holds its coordinates, or a plain array in 1-D).
"""

from __future__ import annotations

import math

import numpy as np


# --------------------------------------------------------------------------- Sec. 4.1

def antithetic_pdf(pdf, involution, jacobian, y):
    """p_T(y): density of antithetic samples at y.  From Eq. (29) with x = T(y)."""
    x = involution(y)
    return pdf(x) / jacobian(x)


def primal_weight(pdf, involution, jacobian, x):
    """w(x) = p(x) / (p(x) + J_T(x) p(T(x))), Eq. (32): balance weight of the primal x."""
    return pdf(x) / (pdf(x) + jacobian(x) * pdf(involution(x)))


def antithetic_weight(pdf, involution, jacobian, x):
    """w_T(T(x)) = p_T(T(x)) / (p(T(x)) + p_T(T(x))), Eq. (33), from the definition."""
    y = involution(x)
    p_anti = antithetic_pdf(pdf, involution, jacobian, y)
    return p_anti / (pdf(y) + p_anti)


def mis_antithetic_estimate(f, pdf, involution, jacobian, x):
    """Eq. (31) with 0.5 replaced by the MIS weight: w(x) (f(x) + f(T(x)) J_T(x)) / p(x)."""
    return (primal_weight(pdf, involution, jacobian, x)
            * (f(x) + f(involution(x)) * jacobian(x)) / pdf(x))


# --------------------------------------------------------------------------- Sec. 4.2

def two_strategy_weights(pdf, map1, jacobian1, map2, jacobian2, x):
    """(alpha, beta) = (w_T1(T1(x)), w_T2(T2(x))) of Eqs. (34)-(35), balance heuristic.

    p_T2(T1(x)) = p(T2(T1(x))) / J_T2(T2(T1(x))): the primal that T2 would have sent to
    T1(x) is T2(T1(x)).
    """
    def pdf_of_map_at(mapping, jac, y):  # p_T(y) = p(T(y)) / J_T(T(y))
        return pdf(mapping(y)) / jac(mapping(y))

    y1, y2 = map1(x), map2(x)
    own1 = pdf(x) / jacobian1(x)              # p_T1(T1(x)), Eq. (29)
    own2 = pdf(x) / jacobian2(x)              # p_T2(T2(x))
    alpha = own1 / (own1 + pdf_of_map_at(map2, jacobian2, y1))
    beta = own2 / (own2 + pdf_of_map_at(map1, jacobian1, y2))
    return alpha, beta


def two_strategy_estimate(f, pdf, map1, jacobian1, map2, jacobian2, x):
    """Eq. (36): 0.5 (f(x) + alpha f(T1(x)) J_T1(x) + beta f(T2(x)) J_T2(x)) / p(x)."""
    alpha, beta = two_strategy_weights(pdf, map1, jacobian1, map2, jacobian2, x)
    return 0.5 * (f(x) + alpha * f(map1(x)) * jacobian1(x)
                  + beta * f(map2(x)) * jacobian2(x)) / pdf(x)


# --------------------------------------------------------------------------- examples

def reciprocal_involution(x):
    """T(x) = (1 - x) / (1 + x): an involution of [0, 1] with a non-constant Jacobian."""
    return (1.0 - x) / (1.0 + x)


def reciprocal_involution_jacobian(x):
    """|dT/dx| = 2 / (1 + x)^2 for ``reciprocal_involution``."""
    return 2.0 / (1.0 + x) ** 2


def linear_pdf(slope: float):
    """p(x) = 1 + slope (x - 1/2) on [0, 1]; a valid density for |slope| < 2."""
    return lambda x: 1.0 + slope * (np.asarray(x) - 0.5)


def antisymmetrize(h, involution, jacobian):
    """f(x) = h(x) - h(T(x)) J_T(x): then f(x) + f(T(x)) J_T(x) = 0 exactly, and I = 0."""
    return lambda x: h(x) - h(involution(x)) * jacobian(x)


# The Sec. 4.2 counterexample on the square [-pi, pi]^2 (points: last axis = (y, z)).

def sine_product(x):
    """f(y, z) = sin(y) sin(z); its integral over [-pi, pi]^2 is 0."""
    return np.sin(x[..., 0]) * np.sin(x[..., 1])


def flip_z(x):
    """T1(y, z) = (y, -z)."""
    return x * np.array([1.0, -1.0])


def flip_y(x):
    """T2(y, z) = (-y, z)."""
    return x * np.array([-1.0, 1.0])


def unit_jacobian(x):
    return np.ones(np.shape(x)[:-1])


def tilted_pdf(tilt: float):
    """p(y, z) = (1 + tilt y)(1 + tilt z) / (4 pi^2) on [-pi, pi]^2, |tilt| < 1/pi.

    tilt = 0 is uniform (p(y, z) = p(-y, -z)); any other tilt breaks that symmetry.
    """
    if abs(tilt) * math.pi >= 1.0:
        raise ValueError("tilt must satisfy |tilt| < 1/pi for a positive density")
    return lambda x: (1.0 + tilt * x[..., 0]) * (1.0 + tilt * x[..., 1]) / (4.0 * math.pi**2)


def sample_tilted(tilt: float, count: int, rng):
    """Samples of ``tilted_pdf(tilt)`` by inverting each coordinate's CDF (a quadratic)."""
    u = rng.random((count, 2))
    if tilt == 0.0:
        return math.pi * (2.0 * u - 1.0)
    # CDF(y) = (y + pi + tilt (y^2 - pi^2) / 2) / (2 pi) = u
    a, b = 0.5 * tilt, 1.0
    c = math.pi - 0.5 * tilt * math.pi**2 - 2.0 * math.pi * u
    return (-b + np.sqrt(b * b - 4.0 * a * c)) / (2.0 * a)


def square_quadrature(nodes_per_axis: int = 48):
    """Tensor Gauss-Legendre points (n, 2) and weights (n,) on [-pi, pi]^2."""
    t, w = np.polynomial.legendre.leggauss(nodes_per_axis)
    y, z = np.meshgrid(math.pi * t, math.pi * t, indexing="ij")
    weights = np.outer(math.pi * w, math.pi * w).reshape(-1)
    return np.stack([y.reshape(-1), z.reshape(-1)], axis=-1), weights


def counterexample_variances(tilt: float, nodes_per_axis: int = 48):
    """Mean and variance (by quadrature) of three estimators of the integral of sin y sin z.

    Returns a dict with, for x ~ tilted_pdf(tilt):
      'single_antithetic': 0.5 (f(x) + f(T1 x)) / p(x)       (cancels exactly)
      'two_strategy_mis':  Eq. (36) with alpha, beta of Eq. (35)
      'independent':       mean of f/p over 3 independent samples (same evaluation count)
    each as (mean, variance), and 'alpha_plus_beta' as (min, max) over the square.
    """
    pdf = tilted_pdf(tilt)
    points, weights = square_quadrature(nodes_per_axis)
    density = pdf(points)

    def moments(values):
        mean = np.sum(weights * density * values)
        return float(mean), float(np.sum(weights * density * (values - mean) ** 2))

    single = 0.5 * (sine_product(points) + sine_product(flip_z(points))) / density
    mis = two_strategy_estimate(sine_product, pdf, flip_z, unit_jacobian, flip_y, unit_jacobian,
                                points)
    plain_mean, plain_var = moments(sine_product(points) / density)
    alpha, beta = two_strategy_weights(pdf, flip_z, unit_jacobian, flip_y, unit_jacobian, points)
    return {
        "single_antithetic": moments(single),
        "two_strategy_mis": moments(mis),
        "independent": (plain_mean, plain_var / 3.0),
        "alpha_plus_beta": (float(np.min(alpha + beta)), float(np.max(alpha + beta))),
    }
