"""Parameter uncertainty from the least-squares Jacobian at the solution.

cov = sigma^2 (J^T J)^-1 with sigma^2 = SSR / (3N - p) estimated from the
residuals; standard errors, correlations, and warnings on strong
correlations and on parameters at a bound (where the linearised covariance
does not hold).
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np

from .errors import CorrelationWarning


@dataclass
class Uncertainty:
    """Covariance of the free parameters (SI units), in ``names`` order."""

    names: list[str]
    covariance: np.ndarray
    sigma: float
    dof: int

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
    m, p = J_scaled.shape
    dof = m - p
    sigma2 = float(residuals @ residuals) / dof if dof > 0 else float("nan")
    # pseudo-inverse through the SVD: robust when a direction is nearly flat
    U, s, Vt = np.linalg.svd(J_scaled, full_matrices=False)
    keep = s > s[0] * 1e-12 if len(s) else s > 0
    inv = (Vt[keep].T / s[keep] ** 2) @ Vt[keep]
    cov = sigma2 * inv * np.outer(scale, scale)
    return Uncertainty(names, cov, float(np.sqrt(sigma2)) if dof > 0 else float("nan"), dof)


def warn_problems(unc: Uncertainty, params, threshold: float = 0.95) -> list[str]:
    """Issue :class:`CorrelationWarning` for strongly correlated or bound-limited parameters."""
    notes = []
    pairs = unc.strong_pairs(threshold)
    if pairs:
        shown = ", ".join(f"{a}~{b} ({c:+.3f})" for a, b, c in pairs[:5])
        more = f" and {len(pairs) - 5} more" if len(pairs) > 5 else ""
        notes.append(f"strongly correlated parameters: {shown}{more}; their individual values are "
                     "uncertain (add poses that move them differently)")
    for name in unc.names:
        p = params[name]
        span = p.upper - p.lower
        tol = 1e-6 * (span if np.isfinite(span) else max(abs(p.value), p.scale))
        if p.value <= p.lower + tol or p.value >= p.upper - tol:
            side = "lower" if p.value <= p.lower + tol else "upper"
            notes.append(f"{name} is at or beyond its {side} bound ({p.to_display(p.value):.6g} {p.display_unit}); "
                         "its standard error is not meaningful, widen the bound if it is not physical")
    for n in notes:
        warnings.warn(n, CorrelationWarning, stacklevel=3)
    return notes
