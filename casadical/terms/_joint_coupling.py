"""Joint coupling: a joint's angle error proportional to another joint's reading (the gear coupling of a wrist)."""

from __future__ import annotations

import numpy as np

from .._format import relative
from ..errors import ModelError
from ..parameters import Parameter
from ..robot import Robot
from ._base import Context, ErrorTerm, check_revolute, register
from ._cause import Cause, register_cause

#: largest coupling factor admitted (rad/rad): beyond 1 % the robot file's coupling ratio is wrong, which is
#: its ``coupling`` row's business, not a gear's error
MAX_COUPLING = 0.01


@register
class JointCoupling(ErrorTerm):
    """Joint ``j``'s drive stands ``c_jk q_k`` off its reading, ``q_k`` joint ``k``'s reading.

    In an industrial wrist the motors of axes 4 to 6 sit in the forearm and
    their shafts pass through the axes before them: turning axis 4 turns
    axis 5's and 6's gear trains, and the controller subtracts the nominal
    ratio. What is left of it (a ratio a little off, a gear not as the
    robot file says) is an angle error of joint ``j`` proportional to the
    reading of joint ``k``. Like the other joint errors it is added to the
    drive's reading (:mod:`casadical.terms._base`). The parameter
    ``cpl<j>_<k>`` (rad/rad, ``|c| <= 0.01``) is linear in the model. It is
    separable from the geometry only if ``q_k`` varies independently of
    ``q_j`` over the data (``c q_j`` would be an encoder scale, a constant
    a joint offset).

    Parameters
    ----------
    pairs : list of (joint, source joint)
        e.g. ``[(5, 4)]``: joint 5's error from joint 4's reading; in a model specification
        ``joint_coupling[5:4]``.
    """

    name = "joint_coupling"
    cause = "joint_coupling"
    bound_meaning = {"cpl": {side: " (a coupling beyond 1 % is a wrong coupling ratio in the robot file, not a gear's "
                                   "error)" for side in ("lower", "upper")}}
    session_local = True

    def superset_member(self) -> bool:
        """The superset expresses it (its chain offsets: the source joint's reading)."""
        return True
    revolute_only = True

    def __init__(self, joints=None, pairs=()):
        self.pairs = sorted({(int(j), int(k)) for j, k in pairs})
        if not self.pairs:
            raise ModelError("joint_coupling needs (joint, source joint) pairs, e.g. joint_coupling[5:4] (joint "
                             "5's error proportional to joint 4's reading)")
        same = [j for j, k in self.pairs if j == k]
        if same:
            raise ModelError(f"joint_coupling: joint {same[0]}'s error from its own reading is an encoder scale "
                             f"(encoder_scale[{same[0]}]), not a coupling")
        super().__init__(sorted({j for j, _ in self.pairs}))

    @classmethod
    def arguments(cls, args: str) -> dict:
        """``joint_coupling[5:4,6:4]``: (joint, source joint) pairs."""
        pairs = [tuple(int(x) for x in a.split(":")) for a in args.split(",")]
        if any(len(p) != 2 for p in pairs):
            raise ValueError("expected joint:source pairs, e.g. joint_coupling[5:4,6:5]")
        return {"pairs": pairs}

    def bind(self, robot: Robot) -> None:
        super().bind(robot)
        bad = sorted({k for _, k in self.pairs if not 1 <= k <= robot.n})
        if bad:
            raise ModelError(f"term {self.name}: source joints {bad} do not exist on {robot.name} "
                             f"(joints 1..{robot.n})")
        check_revolute(self.name, [k for _, k in self.pairs], robot)

    def spec(self) -> str:
        return f"{self.name}[{','.join(f'{j}:{k}' for j, k in self.pairs)}]"

    def settings(self) -> dict:
        return {"pairs": [list(p) for p in self.pairs]}

    def parameters(self, robot: Robot) -> list[Parameter]:
        return [Parameter(f"cpl{j}_{k}", 0.0, "rad/rad", 1e-4, self.name, j, lower=-MAX_COUPLING,
                          upper=MAX_COUPLING) for j, k in self.pairs]

    def joint_offsets(self, ctx: Context) -> dict:
        out: dict = {}
        for j, k in self.pairs:
            out[j] = out.get(j, 0) + ctx.p[f"cpl{j}_{k}"] * ctx.q[k - 1]
        return out


class Coupling(Cause):
    """A joint's angle error proportional to another joint's reading (:class:`JointCoupling`)."""

    name = "joint_coupling"
    analytic = True
    own_variable = "q"
    checks = ("reading_halves",)
    needs = {"linear_axis": "joint_coupling", "one_at_a_time": "joint_coupling", "still": "joint_coupling"}
    short = "coupling"
    tier = 5
    order = 100
    varies_text = "move joint {j} and its source joint independently over wider ranges"
    tell_apart = {
        "encoder_scale": "move joint {j} and the joint its error would follow independently (one still while the "
                         "other turns): a scale grows with joint {j}'s own reading, a coupling with the other's",
        "joint_coupling": "move each of the joints the error could follow while the others stand still",
    }

    def candidates(self, data) -> list:
        """Every pair of moving joints with the source before the joint (a drive train passes through the joints
        before its joint); none on poses that move one joint at a time (its ``one_at_a_time`` condition)."""
        return [data.make(self.name, j, source_joint=k) for j in data.moving for k in data.moving
                if k < j and data.couples]

    def place(self, cand) -> str:
        return f"joint {cand.joint}, from joint {cand.source_joint}'s reading"

    def size(self, cand, values, stds, params, linear) -> str:
        return f"{values[0] * 1e3:.3g} mrad per rad of joint {cand.source_joint}{relative(stds[0], values[0])}"

    def unexplained_item(self, cand, values, linear) -> dict:
        v = values[cand.parameter_names()[0]]
        return {"coupling": v, "what": f"a part that follows joint {cand.source_joint}'s reading "
                                       f"({v * 1e3:.3g} mrad per rad)"}

    def words(self, cand, params, robot, data, linear) -> str:
        p = params[0]
        return (f"joint {cand.joint}'s angle error, {p.value * 1e3:.3g} mrad per rad of joint {cand.source_joint} "
                f"(std {p.std * 1e3:.2g})")

    def figure(self, cand, data, model, params, linear) -> dict:
        k = cand.source_joint
        value = params[cand.parameter_names()[0]].value
        return {"x": np.degrees(data.q[:, k - 1]), "xlabel": f"joint {k} reading (deg)",
                "effect": value * data.q[:, k - 1]}

    def reading(self, cand) -> int | None:
        return cand.source_joint

    def analytic_term(self, cand):
        return JointCoupling(pairs=[(cand.joint, cand.source_joint)])

    def analytic_column(self, cand, k, data, JA, t0, robot):
        return JA[:, :, cand.joint - 1] * data.q[:, cand.source_joint - 1, None]

    def parameter_names(self, cand) -> list[str]:
        return [f"cpl{cand.joint}_{cand.source_joint}"]

    def terms(self, cands) -> list[ErrorTerm]:
        cpl = sorted({(c.joint, c.source_joint) for c in self.mine(cands)})
        return [JointCoupling(pairs=cpl)] if cpl else []


JOINT_COUPLING = register_cause(Coupling())
