"""False-failure rates of the statistical tests (docs/testing.md): bounds that give a
stated rate to a family of comparisons (Bonferroni: the family's rate is at most the sum
of its comparisons' rates)."""

import math

from scipy import stats


def student_bound(family_rate: float, comparisons: int, dof: int) -> float:
    """The |t| bound per comparison (two-sided Student quantile with ``dof`` degrees of
    freedom) under which ``comparisons`` comparisons together fail with probability at
    most ``family_rate`` when nothing is wrong."""
    return float(stats.t.ppf(1 - family_rate / (2 * comparisons), dof))


def normal_bound(family_rate: float, comparisons: int) -> float:
    """The same for |z| of normally distributed estimates."""
    return float(stats.norm.isf(family_rate / (2 * comparisons)))


# ---- Float32 rounding --------------------------------------------------------------

FLOAT32_UNIT = 2.0 ** -24  # u: the unit roundoff of float32 (round to nearest)


def rounding_bound(magnitude: float, terms: int, rate: float = 1e-6) -> float:
    """How far a float32 sum of ``terms`` terms, each computed with its own rounding,
    lies from the exact sum, given ``magnitude`` = sum |x_i| of its terms: Higham and
    Mary's probabilistic bound ("A New Approach to Probabilistic Rounding Error
    Analysis", SIAM J. Sci. Comput. 41(5), 2019, Theorems 2.4 and 3.1),
    gamma(lambda, n) * sum |x_i| with gamma = exp(lambda sqrt(n) u + n u^2 / (1 - u)) - 1,
    which holds in any summation order with probability at least
    1 - 2 n exp(-lambda^2 (1 - u)^2 / 2) for independent mean-zero rounding errors;
    lambda is chosen so that this failure probability is ``rate``.

    It depends on no machine: two computations of one sum in different orders (reverse
    and forward mode, two adjoint kernels, CPUs with other vector widths) differ by at
    most twice it. (The worst case, n u sum |x_i|, is sqrt(n) times larger and holds for
    any rounding.)"""
    u = FLOAT32_UNIT
    n = float(terms)
    lam = math.sqrt(2.0 * math.log(2.0 * n / rate)) / (1.0 - u)
    gamma = math.expm1(lam * math.sqrt(n) * u + n * u * u / (1.0 - u))
    return gamma * float(magnitude)


#: roundings counted per sample of a render: its value's own arithmetic (a BSDF, a light
#: sample, the modulation's cosine and their products; generous), as tests/test_gradient.py
#: counts a bounce's
OPS_PER_SAMPLE = 256


def mean_rounding_bound(amplitude: float, samples: int, rate: float = 1e-6) -> float:
    """How far a float32 render's pixel, the mean of ``samples`` samples each at most
    ``amplitude`` in size, lies from the exact mean of its samples by rounding alone:
    :func:`rounding_bound` of their sum (sum |x_i| <= samples x amplitude), each sample's
    own OPS_PER_SAMPLE roundings counted as terms too (sqrt(n) + sqrt(k) <= sqrt(2 (n +
    k))), over the count. The floor under a relative tolerance where the samples cancel
    (a heterodyne value near zero), in place of a fixed absolute one."""
    return rounding_bound(amplitude, 2 * (samples + OPS_PER_SAMPLE), rate)
