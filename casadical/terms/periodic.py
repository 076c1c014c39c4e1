"""Periodic transmission (gear) error: A sin(h q_j + phi) on a joint."""

from __future__ import annotations

import math

import casadi as ca

from ..errors import ModelError
from ..model.parameters import Parameter
from ..robot import Robot
from .base import Context, ErrorTerm, register

#: largest amplitude admitted of a linear axis' periodic error (m, each of its two parts)
MAX_PITCH_ERROR = 1e-3


def phase(robot: Robot, j: int, q):
    """What joint ``j``'s harmonics are multiples of: its reading (rad), or ``2 pi`` times a linear axis' reading
    (m): cycles per metre (numpy or CasADi)."""
    return 2 * math.pi * q if robot.joints[j - 1].prismatic else q


@register
class JointPeriodic(ErrorTerm):
    """Harmonic ``h`` of joint ``j``: ``s sin(h q_j) + c cos(h q_j)``.

    On a linear axis (a prismatic joint) harmonic ``h`` is ``h`` cycles per metre of travel (a screw's or a
    rack's pitch error: a 10 mm pitch is harmonic 100): ``s sin(2 pi h q_j) + c cos(2 pi h q_j)``, ``s`` and
    ``c`` in metres along the axis (at most 1 mm each), as a revolute joint's are per turn in rad.

    Written linearly in ``s`` and ``c`` (amplitude ``hypot(s, c)``, phase
    ``atan2(c, s)``) so the fit has no local minima in the phase.

    Parameters
    ----------
    harmonics : list of (joint, harmonic)
        Pairs to model, e.g. ``[(2, 1), (2, 30)]``.
    """

    name = "joint_periodic"
    aliases = ("periodic",)
    cause = "joint_periodic"

    def __init__(self, harmonics: list[tuple[int, int]]):
        if not harmonics:
            raise ModelError("joint_periodic needs (joint, harmonic) pairs, e.g. periodic[2:1]")
        self.harmonics = sorted({(int(j), int(h)) for j, h in harmonics})
        if any(h < 1 for _, h in self.harmonics):
            raise ModelError("joint_periodic harmonics must be whole numbers >= 1")
        super().__init__(sorted({j for j, _ in self.harmonics}))

    def spec(self) -> str:
        return f"{self.name}[{','.join(f'{j}:{h}' for j, h in self.harmonics)}]"

    def settings(self) -> dict:
        return {"harmonics": [list(p) for p in self.harmonics]}

    def parameters(self, robot: Robot) -> list[Parameter]:
        ps = []
        for j, h in self.harmonics:
            linear = robot.joints[j - 1].prismatic if 1 <= j <= robot.n else False
            for kind in ("s", "c"):
                if linear:
                    ps.append(Parameter(f"gear{j}_{kind}{h}", 0.0, "m", 1e-5, self.name, j,
                                        lower=-MAX_PITCH_ERROR, upper=MAX_PITCH_ERROR))
                else:
                    ps.append(Parameter(f"gear{j}_{kind}{h}", 0.0, "rad", 1e-4, self.name, j,
                                        lower=-math.radians(1.0), upper=math.radians(1.0)))
        return ps

    def joint_offsets(self, ctx: Context) -> dict:
        out: dict = {}
        for j, h in self.harmonics:
            qj = phase(ctx.robot, j, ctx.q[j - 1])
            term = ctx.p[f"gear{j}_s{h}"] * ca.sin(h * qj) + ctx.p[f"gear{j}_c{h}"] * ca.cos(h * qj)
            out[j] = out.get(j, 0) + term
        return out
