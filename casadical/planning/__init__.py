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

__all__ = [
    "DOptimalDesign", "DesignProblem", "ExactDesign", "METHODS", "Observability", "PlanResult",
    "PlanSettings", "Relaxation", "RelaxationSettings", "d_efficiency", "d_optimal_design",
    "design_problem", "exchange", "indices_from_singular_values", "log_det_information", "o1_batch",
    "observability", "random_o1", "relax_cvxpy", "relax_multiplicative", "round_and_exchange",
    "select_poses", "upper_bound",
]
