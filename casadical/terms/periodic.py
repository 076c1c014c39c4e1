"""Periodic transmission (gear) error: A sin(h q_j + phi) on a joint."""

from __future__ import annotations

import math

import casadi as ca

from ..errors import ModelError
from ..model.parameters import Parameter
from ..robot import Robot
from .base import Context, ErrorTerm, register


@register
class JointPeriodic(ErrorTerm):
    """Harmonic ``h`` of joint ``j``: ``s sin(h q_j) + c cos(h q_j)``.

    Written linearly in ``s`` and ``c`` (amplitude ``hypot(s, c)``, phase
    ``atan2(c, s)``) so the fit has no local minima in the phase.

    Parameters
    ----------
    harmonics : list of (joint, harmonic)
        Pairs to model, e.g. ``[(2, 1), (2, 30)]``.
    """

    name = "joint_periodic"
    aliases = ("periodic",)
    revolute_only = True
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
            for kind in ("s", "c"):
                ps.append(Parameter(f"gear{j}_{kind}{h}", 0.0, "rad", 1e-4, self.name, j,
                                    lower=-math.radians(1.0), upper=math.radians(1.0)))
        return ps

    def joint_offsets(self, ctx: Context) -> dict:
        out: dict = {}
        for j, h in self.harmonics:
            qj = ctx.q[j - 1]
            term = ctx.p[f"gear{j}_s{h}"] * ca.sin(h * qj) + ctx.p[f"gear{j}_c{h}"] * ca.cos(h * qj)
            out[j] = out.get(j, 0) + term
        return out
