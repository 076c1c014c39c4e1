"""Joint compliance: deflection = gravity torque x compliance."""

from __future__ import annotations

import math

import numpy as np

from .._format import g3, relative
from ..parameters import Parameter
from ..robot import Robot
from ._base import Context, ErrorTerm, max_gravity_torque, register, revolute
from ._cause import Cause, register_cause


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
    bound_meaning = {"c": {"lower": " (no positive compliance: the joint is stiffer than these poses and loads can "
                                    "tell, or the fit needs it to bend against its load)",
                           "upper": " (softer than the least stiffness admitted)"}}
    weak_meaning = ("the stiffness of {joints} is", "measure poses that load {them}")
    revolute_only = True
    covariates = ("payload_kg",)
    superset_order = 1
    superset_group = "torques"
    session_local = True

    @classmethod
    def superset(cls, robot: Robot) -> list[ErrorTerm]:
        return [cls(joints=revolute(robot))]

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


class Compliance(Cause):
    """A joint that deflects in proportion to its gravity torque (:class:`JointCompliance`)."""

    name = "joint_compliance"
    unchecked_by = "torque"
    explains_set_aside = ("load", "direction", "region")
    looks_like = ("encoder_scale", "joint_periodic", "backlash")
    own_variable = "tau"
    first_order = True
    needs = {"linear_axis": "joint_compliance", "masses": "joint_compliance", "idle": "joint_compliance"}
    short = "compliance"
    order = 10
    varies_text = "load joint {j} over a wider range of torques"
    tell_apart = {
        "backlash": "measure the same poses with two payloads: a compliant joint deflects in proportion to the load, "
                    "backlash does not",
        "encoder_scale": "measure the same poses with two payloads, or with joint {j} at mirrored angles",
        "thermal_expansion": "repeat poses at another temperature in random order",
    }

    def candidates(self, data) -> list:
        return [data.make(self.name, j) for j in data.revolute]

    def size(self, cand, values, stds, params, linear) -> str:
        if values[0] <= 0:
            return f"{params[0].name} = {g3(values[0])} rad/(N m), not positive"
        return f"k{cand.joint} = {g3(1 / values[0])} N m/rad{relative(stds[0], values[0])}"

    def words(self, cand, params, robot, data, linear) -> str:
        p = params[0]
        k = 1.0 / p.value if p.value > 0 else math.inf
        sk = p.std / p.value ** 2 if p.value > 0 and math.isfinite(p.std) else math.nan
        text = f"stiffness k{cand.joint} = {k:.4g} N m/rad (std {sk:.2g})"
        if data.get("payload_kg") is not None and np.ptp(data.get("payload_kg")) > 0:
            text += "; the rows' payloads vary and enter the torques"
        return text

    def figure(self, cand, data, model, params, linear) -> dict:
        x = model.torques(data.q, params.values, model.covariates(data))[:, cand.joint - 1]
        return {"x": x, "xlabel": f"gravity torque at joint {cand.joint} (N m)",
                "effect": params[cand.parameter_names()[0]].value * x}

    def parameter_names(self, cand) -> list[str]:
        return [f"c{cand.joint}"]

    def terms(self, cands) -> list[ErrorTerm]:
        # the joints of this cause and of those that need it (a progressive spring has a linear part)
        joints = sorted({c.joint for c in cands if c.kind is self or self.name in c.kind.requires})
        return [JointCompliance(joints=joints)] if joints else []


COMPLIANCE = register_cause(Compliance())
