"""Joint compliance: deflection = gravity torque x compliance."""

from __future__ import annotations

from ..model.parameters import Parameter
from ..robot import Robot
from .base import Context, ErrorTerm, max_gravity_torque, register


@register
class JointCompliance(ErrorTerm):
    """Joint ``j`` deflects by ``c_j * tau_j`` (``c_j = 1 / k_j``).

    The model is linear in the compliance ``c_j`` (rad/(N m)), which keeps
    the least-squares problem well conditioned; stiffness ``k_j = 1 / c_j``
    is reported beside it.

    Parameters
    ----------
    joints : list of int, optional
        Compliant joints (default all; joints without gravity torque are
        found non-identifiable and fixed).
    k_min : float
        Smallest admissible stiffness (N m/rad); bounds ``c_j <= 1 / k_min``.
    """

    name = "joint_compliance"
    aliases = ("compliance",)
    cause = "joint_compliance"
    revolute_only = True
    covariates = ("payload_kg",)

    def __init__(self, joints=None, k_min: float = 1e3):
        super().__init__(joints)
        self.k_min = k_min

    def settings(self) -> dict:
        return {"joints": self.joints, "k_min": self.k_min}

    def parameters(self, robot: Robot) -> list[Parameter]:
        ps = []
        for j in self.joints:
            tau_max = max_gravity_torque(robot, j)
            # a unit step of the scaled variable deflects the joint 0.1 mrad at full load
            scale = 1e-4 / tau_max if tau_max > 0 else 1e-6
            ps.append(Parameter(f"c{j}", 0.0, "rad/(N*m)", scale, self.name, j,
                                lower=0.0, upper=1.0 / self.k_min))
        return ps

    def joint_offsets(self, ctx: Context) -> dict:
        tau = ctx.torques()
        return {j: ctx.p[f"c{j}"] * tau[j - 1] for j in self.joints}
