"""Chi-square quantiles the calibration tests residuals against, for 1 to 6 degrees of freedom (a
pair's residual components; a fit's free parameters).

A table rather than ``scipy.stats.chi2`` or ``scipy.special.chdtri``: importing either costs a
command 0.3 to 1.9 s for twelve numbers. ``tests/test_calibrate.py`` checks every entry against
``scipy.stats.chi2`` to its four decimals.

>>> chi2_99(2), chi2_median(1)
(9.2103, 0.4549)
"""

from __future__ import annotations

__all__ = ["CHI2_99", "CHI2_MEDIAN", "chi2_99", "chi2_median"]

CHI2_99 = {1: 6.6349, 2: 9.2103, 3: 11.3449, 4: 13.2767, 5: 15.0863, 6: 16.8119}  # 99% quantile by dof
CHI2_MEDIAN = {1: 0.4549, 2: 1.3863, 3: 2.3660, 4: 3.3567, 5: 4.3515, 6: 5.3481}  # 50% quantile by dof


def chi2_99(dof: int) -> float:
    """The chi-square distribution's 99% quantile for ``dof`` (1..6) degrees of freedom."""
    return CHI2_99[int(dof)]


def chi2_median(dof: int) -> float:
    """The chi-square distribution's median for ``dof`` (1..6) degrees of freedom."""
    return CHI2_MEDIAN[int(dof)]
