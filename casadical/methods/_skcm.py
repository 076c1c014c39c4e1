"""``SKCM``: simultaneous kinematic and compliance calibration (GA and TLBO papers' baseline)."""

from __future__ import annotations

from ..calibration import calibrate
from ._base import Inputs, Method, MethodResult, compliance_model, compliant_joints, new_result, register


@register
class SKCM(Method):
    """Geometric parameters and joint compliances in one bounded least squares (IPOPT).

    Zhou, Nguyen and Kang (2014), the baseline of the GA and TLBO papers. The
    compliances ``c_j = 1/k_j`` enter linearly and are bounded to
    ``0 <= c_j <= 1/k_min``, so IPOPT needs no start near the truth.

    Settings
    --------
    joints : sequence of int
        Compliant joints (default 2-5 on a six-axis arm, as in the papers; 2..n-1 on others).
    solver : str
        ``"ipopt"`` (default), ``"lm"``, ``"gn"`` or ``"auto"``.
    """

    name = "SKCM"
    paper = "GA and TLBO papers (Zhou, Nguyen & Kang 2014)"
    summary = "kinematics + joint compliance, simultaneous (IPOPT, bounded)"
    order = 20
    joints = None
    solver = "ipopt"

    def fit(self, inputs: Inputs) -> MethodResult:
        joints = compliant_joints(inputs.robot, self.joints)
        res = calibrate(inputs.robot, inputs.calibration, compliance_model(joints), self.solver, warn=False,
                        position_only=True)
        return new_result(res, info={"solver": res.solver_name, "iterations": res.solver.iterations,
                                     "status": res.solver.status, "joints": joints})
