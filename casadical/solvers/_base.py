"""Solver interface and result (pymoo style: problem, algorithm and result kept apart)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..problem import CalibrationProblem


@dataclass
class SolverResult:
    """What a solver returns.

    Attributes
    ----------
    x : ndarray
        Scaled free variables at the solution.
    cost : float
        Half the sum of squared residuals (m^2).
    success : bool
    status : str
        The solver's own status word.
    iterations : int
    solve_time_s : float
        Wall time of the solve (construction excluded).
    setup_time_s : float
        Time to build the solver (IPOPT's NLP; 0 for LM).
    message : str
    history : list of float
        Cost per iteration.
    """

    x: np.ndarray
    cost: float
    success: bool
    status: str
    iterations: int
    solve_time_s: float
    setup_time_s: float = 0.0
    message: str = ""
    history: list[float] = field(default_factory=list)


class Solver:
    """Base class: ``solve(problem, x0) -> SolverResult``."""

    name = ""

    def solve(self, problem: CalibrationProblem, x0: np.ndarray | None = None) -> SolverResult:
        raise NotImplementedError
