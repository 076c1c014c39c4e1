"""Parameter uncertainty from the least-squares Jacobian at the solution.

cov = sigma^2 A^-1 with sigma^2 = sum w_i |r_i|^2 / (3N - p) estimated from
the residuals. ``A`` is the Gauss-Newton matrix of the loss at the solution:
``J^T J`` for plain least squares; for the robust loss
``sum J_i^T (w_i I - delta w_i^3 r_i r_i^T) J_i`` (w_i: the pose weights),
i.e. ``J^T W J`` less the loss's flattening along each large residual, so a
pose the loss sets aside informs the estimate even less than its weight
says (:class:`casadical.problem.Linearization`). Standard errors,
correlations, and warnings on strong correlations and on parameters at a
bound (where the linearised covariance does not hold).
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np

from ..errors import CorrelationWarning, listing
from ..terms._geometric import Geometric


@dataclass
class Uncertainty:
    """Covariance of the free parameters (SI units), in ``names`` order."""

    names: list[str]
    covariance: np.ndarray
    sigma: float
    dof: int
    #: the factor of the 95 % interval of a measured point where no GP compensator applies, calibrated on the
    #: calibration poses' folds (:func:`casadical.prediction.fold_interval_k`); None: chi_3's
    interval_k: float | None = None

    @property
    def std(self) -> np.ndarray:
        return np.sqrt(np.clip(np.diag(self.covariance), 0, None))

    @property
    def correlation(self) -> np.ndarray:
        s = self.std
        with np.errstate(invalid="ignore", divide="ignore"):
            c = self.covariance / np.outer(s, s)
        return np.nan_to_num(c)

    def strong_pairs(self, threshold: float = 0.95) -> list[tuple[str, str, float]]:
        c = self.correlation
        i, j = np.triu_indices(len(c), 1)
        k = np.abs(c[i, j]) > threshold
        return [(self.names[a], self.names[b], float(c[a, b])) for a, b in zip(i[k], j[k])]


def estimate(residuals: np.ndarray, J_scaled: np.ndarray, scale: np.ndarray,
             names: list[str]) -> Uncertainty:
    """Covariance from residuals (3N,) and the Jacobian in scaled variables (3N, p)."""
    return from_normal(J_scaled.T @ J_scaled, float(residuals @ residuals), J_scaled.shape[0], scale, names)


def from_normal(A: np.ndarray, ssr: float, m: int, scale: np.ndarray, names: list[str]) -> Uncertainty:
    """Covariance from the Gauss-Newton matrix of the scaled variables.

    Parameters
    ----------
    A : ndarray, shape (p, p)
        The loss's Gauss-Newton matrix in scaled variables (``J^T J`` for
        plain least squares; see the module's docstring for the robust loss).
    ssr : float
        Weighted sum of squared residuals ``sum w_i |r_i|^2`` (m^2).
    m : int
        Number of equations (3 per pose).
    scale, names
        Scales and names of the free parameters.
    """
    p = A.shape[0]
    dof = m - p
    sigma2 = ssr / dof if dof > 0 else float("nan")
    # pseudo-inverse through the eigenvalues (the squared singular values of J): robust when a
    # direction is nearly flat
    lam, V = np.linalg.eigh((A + A.T) / 2)
    keep = lam > (lam[-1] * 1e-24 if len(lam) else 0.0)
    inv = (V[:, keep] / lam[keep]) @ V[:, keep].T
    cov = sigma2 * inv * np.outer(scale, scale)
    return Uncertainty(names, cov, float(np.sqrt(sigma2)) if dof > 0 else float("nan"), dof)


def bound_note(p, side: str) -> str:
    """Words for parameter ``p`` at or beyond its ``side`` bound: its value, the bound and where that comes from (a
    bound of the geometry: the robot file's nominal plus or minus the geometry's box), and what to do."""
    bound = p.lower if side == "lower" else p.upper
    unit = p.display_unit
    show = lambda v: f"{p.to_display(v):.6g} {unit}"     # noqa: E731
    text = f"{p.name} = {show(p.value)} is at or beyond its {side} bound {show(bound)}"
    if p.term == Geometric.name and p.group != "base":
        box = abs(p.to_display(bound) - p.to_display(p.nominal))
        return (text + f" (its nominal {show(p.nominal)} {'-' if side == 'lower' else '+'} {box:.6g} {unit}, the "
                "geometry's bound: docs/formats.md); its standard error is not meaningful: if the value is real, "
                "the robot file's nominal is that far off (correct it there)")
    return text + "; its standard error is not meaningful, widen the bound if it is not physical"


def warn_problems(unc: Uncertainty, params, threshold: float = 0.95,
                  expected: frozenset = frozenset()) -> list[str]:
    """Issue :class:`CorrelationWarning` for strongly correlated or bound-limited parameters.

    ``expected``: pairs (frozensets of two names) whose correlation is known
    and said elsewhere (a combination that only a fitted term tells apart).
    """
    notes = []
    pairs = [pr for pr in unc.strong_pairs(threshold) if frozenset(pr[:2]) not in expected]
    if pairs:
        shown = listing([f"{a}~{b} ({c:+.3f})" for a, b, c in pairs], 5)
        notes.append(f"strongly correlated parameters: {shown}; their individual values are "
                     "uncertain (add poses that move them differently)")
    for name in unc.names:
        p = params[name]
        span = p.upper - p.lower
        tol = 1e-6 * (span if np.isfinite(span) else max(abs(p.value), p.scale))
        if p.value <= p.lower + tol or p.value >= p.upper - tol:
            side = "lower" if p.value <= p.lower + tol else "upper"
            if (p.lower if side == "lower" else p.upper) == 0:    # a sign its physics sets (a compliance >= 0)
                notes.append(f"{name} is at its {side} bound 0 ({p.to_display(p.value):.6g} {p.display_unit}), a limit "
                             "of its physics that cannot be widened: it is not determined by these poses (they "
                             "cannot tell it from 0), and its standard error is not meaningful")
            else:
                notes.append(bound_note(p, side))
    for n in notes:
        warnings.warn(n, CorrelationWarning, stacklevel=3)
    return notes
