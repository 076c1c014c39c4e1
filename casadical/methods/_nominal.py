"""``Nominal``: the robot's nominal model, only the base pose fitted (the papers' first row)."""

from __future__ import annotations

from ..calibration import calibrate
from ._base import Inputs, Method, MethodResult, new_result, register


@register
class Nominal(Method):
    """Nominal geometry; the base pose (measurement frame) is fitted, nothing else.

    The seed papers' "Nominal parameters" rows: a laser tracker's frame is
    never known in advance, so the base pose is always estimated.
    """

    name = "Nominal"
    paper = "all three (baseline)"
    summary = "nominal geometry, base pose fitted"
    order = 0
    solver = "lm"

    def fit(self, inputs: Inputs) -> MethodResult:
        res = calibrate(inputs.robot, inputs.calibration, "nominal", self.solver, warn=False, position_only=True)
        return new_result(res, info={"solver": res.solver_name, "iterations": res.solver.iterations})
