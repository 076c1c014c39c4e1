"""Gauss-Newton / Levenberg-Marquardt on the model's CasADi residuals and Jacobians.

The iterative least squares of the seed papers, with Marquardt damping so it
also converges from far starts. With a robust loss the same iteration is
iteratively reweighted least squares: the Gauss-Newton matrix and gradient
carry each pose's weight, and steps are accepted on the loss itself. Bounds
are not enforced; the calibration hands over to IPOPT when the solution
leaves them.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from ..errors import SolverError
from ..problem import CalibrationProblem
from ..runtime._interrupts import checkpoint
from ._base import Solver, SolverResult


@dataclass
class LevenbergMarquardt(Solver):
    """Levenberg-Marquardt (``damping=True``) or Gauss-Newton with step halving.

    Parameters
    ----------
    max_iter : int
    ftol : float
        Stop when the relative cost decrease of an accepted step is below this.
    xtol : float
        Stop when the step (scaled variables) is below ``xtol * (xtol + |x|)``.
    lam0 : float
        Initial damping, relative to the diagonal of J^T J.
    damping : bool
        False gives plain Gauss-Newton with backtracking.
    std_tol : float or None
        Also stop, converged, when the next step is below this share of
        every parameter's standard error (``sigma^2 A^-1`` at the current
        point, ``sigma`` from the weighted residuals), before evaluating
        it: the solution is then within about that share of a standard
        error of the optimum. None (the default): the tests above alone.
        Near the optimum a Gauss-Newton step is the distance to it, and
        the cost's rounding can hide its decrease (rejected trials, each a
        linearisation); a calibration of many poses uses 0.01
        (:mod:`casadical.calibration._solve`).
    """

    max_iter: int = 100
    ftol: float = 1e-10
    xtol: float = 1e-10
    lam0: float = 1e-5
    damping: bool = True
    std_tol: float | None = None

    def __post_init__(self) -> None:
        if not (isinstance(self.max_iter, int) and self.max_iter >= 1):
            raise SolverError(f"max_iter must be a whole number >= 1, got {self.max_iter!r}")

    @property
    def name(self) -> str:  # type: ignore[override]
        return "levenberg-marquardt" if self.damping else "gauss-newton"

    def solve(self, problem: CalibrationProblem, x0: np.ndarray | None = None) -> SolverResult:
        t0 = time.perf_counter()
        x = problem.x_from_values(problem.params.values) if x0 is None else np.array(x0, float)
        lin = problem.linearize(problem.values_from_x(x))
        cost = lin.cost
        history = [cost]
        lam = self.lam0 if self.damping else 0.0
        status, success = "max_iter", False
        it = 0
        for it in range(1, self.max_iter + 1):
            checkpoint("solver")
            A, g = lin.A, lin.g
            d = np.diag(A).copy()
            d[d <= 0] = 1.0
            accepted = False
            gn_step = None if self.damping else _solve(A, -g)
            if self.std_tol is not None and _within_std(problem, lin, _solve(A, -g), self.std_tol):
                status, success = "converged", True
                break
            for k in range(30):
                step = _solve(A + lam * np.diag(d), -g) if self.damping else gn_step * 0.5 ** k
                x_new = x + step
                # residuals and Jacobian together: an accepted step (the usual case) needs no
                # second evaluation, a rejected one costs a little more
                new = problem.linearize(problem.values_from_x(x_new))
                if new.cost <= cost:
                    accepted = True
                    break
                if self.damping:
                    lam = max(lam * 4.0, 1e-9)
            if not accepted:
                status, success = "no_decrease", cost < history[0] or it > 1
                break
            small_f = (cost - new.cost) <= self.ftol * max(cost, 1e-300)
            small_x = np.linalg.norm(step) <= self.xtol * (self.xtol + np.linalg.norm(x))
            x, cost, lin = x_new, new.cost, new
            history.append(cost)
            if self.damping:
                lam = max(lam / 3.0, 1e-12)
            if small_f or small_x:
                status, success = "converged", True
                break
        return SolverResult(x=x, cost=cost, success=success, status=status, iterations=it,
                            solve_time_s=time.perf_counter() - t0, history=history)


def _within_std(problem: CalibrationProblem, lin, step: np.ndarray, tol: float) -> bool:
    """True when ``step`` (scaled variables) is below ``tol`` standard errors of every free parameter at ``lin``
    (``sigma^2 diag(A^-1)``, ``sigma^2`` the weighted squared residuals per degree of freedom, as the
    calibration's uncertainty has them)."""
    dof = problem.equations_per_pose * problem.n_poses - len(step)
    if dof <= 0:
        return False
    u2 = lin.u2 if lin.u2 is not None else np.einsum("ij,ij->i", lin.r, lin.r)
    s2 = float(lin.weights @ u2) / dof
    try:
        var = s2 * np.diag(np.linalg.inv(lin.A))
    except np.linalg.LinAlgError:
        return False
    return bool(np.all(var > 0) and np.all(np.abs(step) <= tol * np.sqrt(var)))


def _solve(A: np.ndarray, b: np.ndarray) -> np.ndarray:
    try:
        return np.linalg.solve(A, b)
    except np.linalg.LinAlgError:
        return np.linalg.lstsq(A, b, rcond=None)[0]


def GaussNewton(**kwargs) -> LevenbergMarquardt:
    """Plain Gauss-Newton with step halving (the seed papers' iterative least squares)."""
    return LevenbergMarquardt(damping=False, **kwargs)
