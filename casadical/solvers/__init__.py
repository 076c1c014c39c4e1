"""Local solvers of the calibration least squares, by name."""

import typing as _typing

from .._lazy import lazy
from ..errors import SolverError
from ._base import Solver, SolverResult
from ._ipopt import Ipopt
from ._lm import GaussNewton, LevenbergMarquardt

SOLVERS = {"lm": LevenbergMarquardt, "gn": GaussNewton, "ipopt": Ipopt}


def make_solver(name: str, **settings) -> Solver:
    """A solver by name: ``lm`` (Levenberg-Marquardt), ``gn`` (Gauss-Newton), ``ipopt``."""
    try:
        return SOLVERS[name](**settings)
    except KeyError:
        raise SolverError(f"unknown solver {name!r}; choose one of {', '.join(SOLVERS)}") from None


__all__ = ["GaussNewton", "HANDOVER", "Ipopt", "LevenbergMarquardt", "SOLVERS", "Solver", "SolverResult", "make_solver"]

#: public name -> its private module, imported on first use (PEP 562)
_EXPORTS = {"HANDOVER": "_ipopt"}

if _typing.TYPE_CHECKING:
    from ._ipopt import HANDOVER
else:
    __getattr__, __dir__ = lazy(__name__, globals(), _EXPORTS)
