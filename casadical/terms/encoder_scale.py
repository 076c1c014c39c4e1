"""Encoder (gear ratio) scale error: offset proportional to the reading."""

from __future__ import annotations

from ..model.parameters import Parameter
from ..robot import Robot
from .base import Context, ErrorTerm, register


@register
class EncoderScale(ErrorTerm):
    """Joint ``j`` turns by ``(1 + s_j) q_j`` instead of ``q_j``.

    On a linear axis (a prismatic joint) the carriage travels ``(1 + s_j) q_j``: the scale error of ISO 230-1,
    ``s_j`` metres per metre of travel (reports say mm per m); its zero is the reading's zero, whose offset the
    geometry's ``d`` takes.
    """

    name = "encoder_scale"
    cause = "encoder_scale"

    def parameters(self, robot: Robot) -> list[Parameter]:
        return [Parameter(f"escale{j}", 0.0, "1", 1e-4, self.name, j, lower=-0.01, upper=0.01)
                for j in self.joints]

    def joint_offsets(self, ctx: Context) -> dict:
        return {j: ctx.p[f"escale{j}"] * ctx.q[j - 1] for j in self.joints}
