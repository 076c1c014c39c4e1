"""Progressive (nonlinear) joint stiffness: a deflection cubic in the gravity torque."""

from __future__ import annotations

import math

import numpy as np

from .._format import g3, relative
from ..parameters import Parameter
from ..robot import Robot
from ._base import Context, ErrorTerm, max_gravity_torque, register, revolute
from ._cause import Cause, load_item, register_cause


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
    weak_meaning = ("the progressive part of the spring of {joints} is", "measure poses that load {them} more")
    covariates = ("payload_kg",)
    superset_order = 2
    superset_group = "torques"
    session_local = True

    @classmethod
    def superset(cls, robot: Robot) -> list[ErrorTerm]:
        return [cls(joints=revolute(robot))]

    @classmethod
    def value_rules(cls, p, params, tau, moves) -> list:
        """A spring that stiffens must not turn back (its deflection fall with load) within the poses' torques."""
        j, n = p.joint, p.name
        c = params[f"c{j}"].value if f"c{j}" in params else 0.0
        top = float(np.max(np.abs(tau()[:, j - 1]))) if len(tau()) else 0.0
        if p.value < 0 and c + 3 * p.value * top ** 2 <= 0:
            turn = math.sqrt(max(c, 0.0) / (-3 * p.value))
            return [((n,), f"the fitted spring of joint {j} turns back above {turn:.3g} N m (its deflection c{j} tau "
                           f"+ {n} tau^3 falls with load there) while the poses load it up to {top:.3g} N m: not a "
                           "stiffness")]
        return []

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


class ProgressiveStiffness(Cause):
    """A joint's spring that stiffens or softens with load (:class:`NonlinearStiffness`, beside its compliance)."""

    name = "nonlinear_stiffness"
    unchecked_by = "torque"
    own_variable = "tau"
    first_order = True
    checks = ("versus_harmonics",)
    needs = {"linear_axis": "nonlinear_stiffness", "masses": "nonlinear_stiffness", "idle": "nonlinear_stiffness"}
    short = "progressive stiffness"
    order = 20
    requires = ("joint_compliance",)
    varies_text = "load joint {j} over a wider range of torques"
    tell_apart = {
        "backlash": "measure the same poses with two payloads: a progressive spring's deflection grows smoothly with "
                    "the load, backlash jumps at zero torque and stays",
        "joint_compliance": "measure poses that load joint {j} over a wider range of torques (and with two payloads)",
    }

    def candidates(self, data) -> list:
        """Where the joint's compliance is named (the robot's or the session's)."""
        return [data.make(self.name, a.joint, session=a.session) for a in data.accepted
                if a.cause in self.requires]

    def size(self, cand, values, stds, params, linear) -> str:
        how = "stiffens" if values[1] < 0 else "softens"
        return f"cubic term {g3(values[1])} rad/(N m)^3{relative(stds[1], values[1])}: {how} with load"

    def unexplained_item(self, cand, values, linear) -> dict:
        return load_item(cand, values, progressive=True)

    def words(self, cand, params, robot, data, linear) -> str:
        p = params[1]
        return (f"progressive term {p.value:.3g} rad/(N m)^3 (std {p.std:.2g}): the joint "
                f"{'stiffens' if p.value < 0 else 'softens'} with load")

    def figure(self, cand, data, model, params, linear) -> dict:
        x = model.torques(data.q, params.values, model.covariates(data))[:, cand.joint - 1]
        # the figure's curve: the first parameter's value (the linear compliance's) times the torque cubed
        return {"x": x, "xlabel": f"gravity torque at joint {cand.joint} (N m)",
                "effect": params[cand.parameter_names()[0]].value * x ** 3}

    def parameter_names(self, cand) -> list[str]:
        return [f"c{cand.joint}", f"cubic{cand.joint}"]     # a progressive spring has a linear part too

    def terms(self, cands) -> list[ErrorTerm]:
        joints = sorted({c.joint for c in self.mine(cands)})
        return [NonlinearStiffness(joints=joints)] if joints else []


PROGRESSIVE_STIFFNESS = register_cause(ProgressiveStiffness())
