"""Residual kinds: which components of a head's pixel error the calibration compares.

The person model (:mod:`.model`) predicts each head pixel; its error ``e = (e_u, e_v)`` (predicted
minus observed, px) is what a residual kind turns into numbers:

- ``pixel_axes``: the image axes (0 = u, 1 = v) whose squared errors the *unweighted* cost sums:
  the paper grid and its fast kernel, the refinement's robust seeding grid, the reported rmse.
  Keep the kind linear in ``e``, so the grid's closed form (:mod:`.grid`) holds;
- :meth:`ResidualKind.along`: the component along the person's image axis (the one the stature
  moves; for the head row, the row itself), used to profile each track's stature;
- :meth:`ResidualKind.whitened`: the refinement's components per pair, whitened by the pair's error
  covariance (:class:`PairCovariance`: the pixel noise of the head, the foot's noise carried
  through the model, the stature spread along the person); ``dof`` of them, the first along the person;
- ``test_against``: a kind using a subset of these components (the head rows alone) against
  which the head-column (Hausman) test checks the fit, or None.

The registry holds every kind by name; the config's ``calibrate.residual`` choices, the CLI's
help and :func:`residual_kind` read it. Adding a kind is one class here (decorated with
:func:`register`), its test, and a row in docs/calibration.md.

>>> RESIDUALS
('full', 'vertical')
>>> residual_kind("vertical").dof, residual_kind("full").test_against
(1, 'vertical')
"""

from __future__ import annotations

import functools
import operator
from collections.abc import Callable

import numpy as np

from .chi_square import chi2_99, chi2_median

__all__ = ["PairCovariance", "ResidualKind", "component_sum", "RESIDUAL_KINDS", "RESIDUALS", "register", "residual_kind"]


class PairCovariance:
    """Each pair's head-error covariance in the image's (u, v) basis: ``uu``, ``uv``, ``vv`` (px^2), each
    broadcasting to (Q, N).

    ``project(a, b)`` is ``a^T C b`` for unit vectors ``a``, ``b`` (N, 2): a kind reads the covariance in
    its own basis (along and across the person, or the head row).
    """

    __slots__ = ("uu", "uv", "vv")

    def __init__(self, uu: np.ndarray, uv: np.ndarray, vv: np.ndarray) -> None:
        self.uu, self.uv, self.vv = uu, uv, vv

    def project(self, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        """``a^T C b`` (Q, N) for vectors a, b (N, 2)."""
        return (a[:, 0] * b[:, 0]) * self.uu + (a[:, 0] * b[:, 1] + a[:, 1] * b[:, 0]) * self.uv \
            + (a[:, 1] * b[:, 1]) * self.vv



def component_sum(values: np.ndarray) -> np.ndarray:
    """``values`` (..., K) summed over their last axis (a pair's residual components): for K = 1 or 2 the first
    component plus the second, bit for bit ``np.sum(values, axis=-1)`` without its reduction machinery (40x faster
    on (Q, N, 2) arrays, where that reduction was a tenth of a 20,000-pair refinement); other K: ``np.sum``.

    >>> x = np.array([[0.1, 0.2], [1e16, 1.0], [-3.0, 3.0]])
    >>> component_sum(x).tolist() == np.sum(x, axis=-1).tolist()
    True
    """
    if values.shape[-1] == 2:
        return values[..., 0] + values[..., 1]
    if values.shape[-1] == 1:
        return values[..., 0].copy()
    return np.sum(values, axis=-1)


class ResidualKind:
    """One way of comparing predicted and observed heads (subclass, set the attributes, register)."""

    name: str  # config and CLI value
    summary: str  # a few words for --help and the docs
    pixel_axes: tuple[int, ...]  # image axes of the head error in the unweighted cost (0 = u, 1 = v)
    test_against: str | None = None  # kind holding a subset of the components: the head-column test

    @property
    def dof(self) -> int:
        """Residual components per pair."""
        return len(self.pixel_axes)

    @property
    def chi2_99(self) -> float:
        """99% quantile of a pair's squared whitened residual norm (outlier rejection)."""
        return chi2_99(self.dof)

    @property
    def chi2_median(self) -> float:
        """Median of a pair's squared whitened residual norm (robust scale)."""
        return chi2_median(self.dof)

    def squared_px(self, e: tuple[np.ndarray, np.ndarray]) -> np.ndarray:
        """Unweighted squared error (...) px^2 of head errors ``e = (e_u, e_v)``, each (...)."""
        return functools.reduce(operator.add, (e[axis] ** 2 for axis in self.pixel_axes))

    def along(self, e: tuple[np.ndarray, np.ndarray], axis: np.ndarray) -> np.ndarray:
        """Component (Q, N) of pixel vectors ``e`` ((Q, N) each) along the person; ``axis`` (N, 2) unit foot->head."""
        raise NotImplementedError

    def along_variance(self, cov: PairCovariance, axis: np.ndarray) -> np.ndarray:
        """Variance (Q, N) px^2 of the :meth:`along` component under the pairs' covariance."""
        raise NotImplementedError

    def whitened(self, e: tuple[np.ndarray, np.ndarray], axis: np.ndarray, cov: PairCovariance) -> np.ndarray:
        """Whitened components (Q, N, dof) of head errors ``e`` under each pair's error covariance ``cov``:
        the first is the component along the person over its sd, the others what remains of the error
        once that is accounted for (a Cholesky factor of the covariance in the kind's own basis)."""
        return self.whitener(axis, cov)(e)

    def whitener(self, axis: np.ndarray, cov: PairCovariance) -> Callable[[tuple[np.ndarray, np.ndarray]], np.ndarray]:
        """:meth:`whitened` as a function of ``e`` alone, its factors computed once for ``axis`` and ``cov`` (the
        refinement whitens the head errors and their derivatives under one covariance)."""
        raise NotImplementedError

    def __repr__(self) -> str:
        return f"<residual {self.name!r}>"


RESIDUAL_KINDS: dict[str, ResidualKind] = {}


def register(cls: type[ResidualKind]) -> type[ResidualKind]:
    """Class decorator: add one instance of the kind to the registry under its name."""
    if cls.name in RESIDUAL_KINDS:
        raise ValueError(f"residual kind {cls.name!r} is registered twice")
    RESIDUAL_KINDS[cls.name] = cls()
    return cls


def residual_kind(name: str) -> ResidualKind:
    """The registered kind called ``name``; ValueError listing the kinds otherwise.

    >>> residual_kind("sideways")
    Traceback (most recent call last):
    ...
    ValueError: residual must be one of ('full', 'vertical'), got 'sideways'
    """
    try:
        return RESIDUAL_KINDS[name]
    except (KeyError, TypeError):
        raise ValueError(f"residual must be one of {tuple(RESIDUAL_KINDS)}, got {name!r}") from None


# ---- the kinds ------------------------------------------------------------------------------------------
@register
class Full(ResidualKind):
    """Head u and v: along the person (its stature) and across it (how verticals converge)."""

    name = "full"
    summary = "head u and v"
    pixel_axes = (0, 1)
    test_against = "vertical"

    def along(self, e, axis):
        return e[0] * axis[:, 0] + e[1] * axis[:, 1]

    def along_variance(self, cov, axis):
        return cov.project(axis, axis)

    def whitener(self, axis, cov):
        normal = np.stack([-axis[:, 1], axis[:, 0]], axis=1)  # across the person: (e_v a_u - e_u a_v)
        c_an, c_nn = cov.project(axis, normal), cov.project(normal, normal)
        sd_a = np.sqrt(self.along_variance(cov, axis))
        link = c_an / sd_a  # the across error explained by the along one (Cholesky, along first)
        sd_across = np.sqrt(np.maximum(c_nn - link**2, 1e-300))

        def whiten(e):
            along = self.along(e, axis) / sd_a
            across = (e[1] * axis[:, 0] - e[0] * axis[:, 1] - link * along) / sd_across
            return np.stack([along, across], axis=-1)

        return whiten


@register
class Vertical(ResidualKind):
    """The head row only (robust to head columns that do not follow the person's vertical)."""

    name = "vertical"
    summary = "head row only"
    pixel_axes = (1,)

    def along(self, e, axis):
        return e[1]

    def along_variance(self, cov, axis):
        return cov.vv

    def whitener(self, axis, cov):
        sd = np.sqrt(self.along_variance(cov, axis))
        return lambda e: (self.along(e, axis) / sd)[..., None]


RESIDUALS = tuple(RESIDUAL_KINDS)  # the names, in registration order (config choices)
