"""``KM``: conventional kinematic calibration (iterative least squares, all three papers)."""

from __future__ import annotations

from ..calibration import calibrate
from ._base import Inputs, Method, MethodResult, new_result, register


@register
class KM(Method):
    """Every identifiable geometric parameter by iterative least squares.

    Settings
    --------
    solver : str
        ``"lm"`` (default; Levenberg-Marquardt, the papers' iterated
        ``(J^T J)^-1 J^T dP`` with damping), ``"gn"`` or ``"ipopt"``.
    """

    name = "KM"
    paper = "all three (baseline)"
    summary = "kinematic calibration, least squares"
    order = 10
    solver = "lm"

    def fit(self, inputs: Inputs) -> MethodResult:
        res = calibrate(inputs.robot, inputs.calibration, "kinematic", self.solver, warn=False, position_only=True)
        return new_result(res, info={"solver": res.solver_name, "iterations": res.solver.iterations,
                                     "status": res.solver.status})
