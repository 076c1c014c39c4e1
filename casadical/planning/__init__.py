"""Pose planning: which poses to measure before going to the robot.

- :mod:`~casadical.planning.observability` -- O1..O5 of a pose set from the
  scaled identification Jacobian of the identifiable parameters;
- :mod:`~casadical.planning.doptimal` -- certified D-optimal design: the
  continuous relaxation (first-order multiplicative algorithm, or cvxpy),
  its upper bound, rounding and Fedorov exchange;
- :mod:`~casadical.planning.selectors` -- :func:`select_poses` with the
  ``d-optimal``, ``ga`` (the GA paper's selector) and ``random`` methods.

The ``plan-poses`` and ``candidates`` commands are in :mod:`casadical.cli.planning`.
"""

import typing as _typing

from .._lazy import lazy

#: public name -> its module, imported on first use (PEP 562): importing one module of the package
#: imports no other
_EXPORTS = {"DOptimalDesign": "doptimal", "ExactDesign": "doptimal", "Relaxation": "doptimal",
            "RelaxationSettings": "doptimal", "d_efficiency": "doptimal", "d_optimal_design": "doptimal",
            "exchange": "doptimal", "relax_cvxpy": "doptimal", "relax_multiplicative": "doptimal",
            "round_and_exchange": "doptimal", "upper_bound": "doptimal", "DesignProblem": "observability",
            "Observability": "observability", "design_problem": "observability",
            "indices_from_singular_values": "observability", "log_det_information": "observability",
            "o1_batch": "observability", "observability": "observability", "METHODS": "selectors",
            "PlanResult": "selectors", "PlanSettings": "selectors", "random_o1": "selectors",
            "select_poses": "selectors"}

__all__ = [
    "DOptimalDesign", "DesignProblem", "ExactDesign", "METHODS", "Observability", "PlanResult",
    "PlanSettings", "Relaxation", "RelaxationSettings", "d_efficiency", "d_optimal_design",
    "design_problem", "exchange", "indices_from_singular_values", "log_det_information", "o1_batch",
    "observability", "random_o1", "relax_cvxpy", "relax_multiplicative", "round_and_exchange",
    "select_poses", "upper_bound",
]

if _typing.TYPE_CHECKING:
    from .doptimal import (
        DOptimalDesign,
        ExactDesign,
        Relaxation,
        RelaxationSettings,
        d_efficiency,
        d_optimal_design,
        exchange,
        relax_cvxpy,
        relax_multiplicative,
        round_and_exchange,
        upper_bound,
    )
    from .observability import (
        DesignProblem,
        Observability,
        design_problem,
        indices_from_singular_values,
        log_det_information,
        o1_batch,
        observability,
    )
    from .selectors import METHODS, PlanResult, PlanSettings, random_o1, select_poses
else:
    __getattr__, __dir__ = lazy(__name__, globals(), _EXPORTS)
