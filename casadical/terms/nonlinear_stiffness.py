"""Progressive (nonlinear) joint stiffness: a deflection cubic in the gravity torque."""

from __future__ import annotations

from ..model.parameters import Parameter
from ..robot import Robot
from .base import Context, ErrorTerm, max_gravity_torque, register


@register
class NonlinearStiffness(ErrorTerm):
    """Joint ``j`` deflects by a further ``k3_j * tau_j^3`` beyond the linear compliance.

    A spring that stiffens with load (a harmonic drive's flexspline, a gear
    mesh taking up) deflects less than linearly at high torque: ``k3 < 0``
    with ``c > 0``; ``k3 > 0`` is a softening spring. Used next to
    ``joint_compliance`` on the same joint.
    """

    name = "nonlinear_stiffness"
    aliases = ("cubic_stiffness",)
    revolute_only = True
    cause = "nonlinear_stiffness"
    covariates = ("payload_kg",)

    def parameters(self, robot: Robot) -> list[Parameter]:
        ps = []
        for j in self.joints:
            tau_max = max_gravity_torque(robot, j)
            # a unit step of the scaled variable deflects the joint 0.1 mrad at full load
            scale = 1e-4 / tau_max ** 3 if tau_max > 0 else 1e-12
            ps.append(Parameter(f"cubic{j}", 0.0, "rad/(N*m)^3", scale, self.name, j))
        return ps

    def joint_offsets(self, ctx: Context) -> dict:
        tau = ctx.torques()
        return {j: ctx.p[f"cubic{j}"] * tau[j - 1] ** 3 for j in self.joints}
