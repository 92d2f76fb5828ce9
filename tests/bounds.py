"""False-failure rates of the statistical tests (docs/testing.md): bounds that give a
stated rate to a family of comparisons (Bonferroni: the family's rate is at most the sum
of its comparisons' rates)."""

from scipy import stats


def student_bound(family_rate: float, comparisons: int, dof: int) -> float:
    """The |t| bound per comparison (two-sided Student quantile with ``dof`` degrees of
    freedom) under which ``comparisons`` comparisons together fail with probability at
    most ``family_rate`` when nothing is wrong."""
    return float(stats.t.ppf(1 - family_rate / (2 * comparisons), dof))


def normal_bound(family_rate: float, comparisons: int) -> float:
    """The same for |z| of normally distributed estimates."""
    return float(stats.norm.isf(family_rate / (2 * comparisons)))
