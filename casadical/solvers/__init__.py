"""Local solvers of the calibration least squares, by name."""

from ..errors import SolverError
from .base import Solver, SolverResult
from .ipopt import Ipopt
from .lm import GaussNewton, LevenbergMarquardt

SOLVERS = {"lm": LevenbergMarquardt, "gn": GaussNewton, "ipopt": Ipopt}


def make_solver(name: str, **settings) -> Solver:
    """A solver by name: ``lm`` (Levenberg-Marquardt), ``gn`` (Gauss-Newton), ``ipopt``."""
    try:
        return SOLVERS[name](**settings)
    except KeyError:
        raise SolverError(f"unknown solver {name!r}; choose one of {', '.join(SOLVERS)}") from None


__all__ = ["GaussNewton", "Ipopt", "LevenbergMarquardt", "SOLVERS", "Solver", "SolverResult", "make_solver"]
