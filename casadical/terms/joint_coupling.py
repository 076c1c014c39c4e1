"""Joint coupling: a joint's angle error proportional to another joint's reading (the gear coupling of a wrist)."""

from __future__ import annotations

from ..errors import ModelError
from ..model.parameters import Parameter
from ..robot import Robot
from .base import Context, ErrorTerm, check_revolute, register

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
    drive's reading (:mod:`casadical.terms.base`). The parameter
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
