"""Pose planning: which poses to measure before going to the robot.

- :mod:`~casadical.planning._observability` -- O1..O5 of a pose set from the
  scaled identification Jacobian of the identifiable parameters;
- :mod:`~casadical.planning._doptimal` -- certified D-optimal design: the
  continuous relaxation (first-order multiplicative algorithm, or cvxpy),
  its upper bound, rounding and Fedorov exchange;
- :mod:`~casadical.planning._selectors` -- :func:`select_poses` with the
  ``d-optimal``, ``ga`` (the GA paper's selector) and ``random`` methods.

The ``plan-poses`` and ``candidates`` commands are in :mod:`casadical.cli._planning`.
"""

import typing as _typing

from .._lazy import lazy

#: public name -> its module, imported on first use (PEP 562): importing one module of the package
#: imports no other
_EXPORTS = {"DOptimalDesign": "_doptimal", "ExactDesign": "_doptimal", "Relaxation": "_doptimal",
            "RelaxationSettings": "_doptimal", "d_efficiency": "_doptimal", "d_optimal_design": "_doptimal",
            "exchange": "_doptimal", "relax_cvxpy": "_doptimal", "relax_multiplicative": "_doptimal",
            "round_and_exchange": "_doptimal", "upper_bound": "_doptimal", "DesignProblem": "_observability",
            "Observability": "_observability", "design_problem": "_observability",
            "indices_from_singular_values": "_observability", "log_det_information": "_observability",
            "o1_batch": "_observability", "observability": "_observability", "METHODS": "_selectors",
            "PlanResult": "_selectors", "PlanSettings": "_selectors", "random_o1": "_selectors",
            "select_poses": "_selectors", "Criterion": "_augment", "JIT_MIN_CANDIDATES": "_observability",
            "criterion_value": "_augment", "ds_design": "_augment", "measurement_order": "_order",
            "open_questions": "_questions", "parametric_spec": "_next_poses", "path_length": "_order",
            "plan_next": "_next_poses", "pool_jacobian": "_observability", "random_rows": "_touches",
            "relax_ds_cvxpy": "_augment", "schur_log_det": "_touches", "select_touches": "_touches",
            "short_sets": "_touches", "touch_problem": "_touches"}

__all__ = [
    "Criterion", "DOptimalDesign", "DesignProblem", "ExactDesign", "JIT_MIN_CANDIDATES", "METHODS", "Observability",
    "PlanResult", "PlanSettings", "Relaxation", "RelaxationSettings", "criterion_value", "d_efficiency",
    "d_optimal_design", "design_problem", "ds_design", "exchange", "indices_from_singular_values",
    "log_det_information", "measurement_order", "o1_batch", "observability", "open_questions", "parametric_spec",
    "path_length", "plan_next", "pool_jacobian", "random_o1", "random_rows", "relax_cvxpy", "relax_ds_cvxpy",
    "relax_multiplicative", "round_and_exchange", "schur_log_det", "select_poses", "select_touches", "short_sets",
    "touch_problem", "upper_bound",
]

if _typing.TYPE_CHECKING:
    from ._augment import Criterion, criterion_value, ds_design, relax_ds_cvxpy
    from ._doptimal import (
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
    from ._next_poses import parametric_spec, plan_next
    from ._observability import (
        JIT_MIN_CANDIDATES,
        DesignProblem,
        Observability,
        design_problem,
        indices_from_singular_values,
        log_det_information,
        o1_batch,
        observability,
        pool_jacobian,
    )
    from ._order import measurement_order, path_length
    from ._questions import open_questions
    from ._selectors import METHODS, PlanResult, PlanSettings, random_o1, select_poses
    from ._touches import random_rows, schur_log_det, select_touches, short_sets, touch_problem
else:
    __getattr__, __dir__ = lazy(__name__, globals(), _EXPORTS)
