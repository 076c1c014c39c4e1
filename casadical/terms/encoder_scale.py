"""Encoder (gear ratio) scale error: offset proportional to the reading."""

from __future__ import annotations

from ..model.parameters import Parameter
from ..robot import Robot
from .base import Context, ErrorTerm, register


@register
class EncoderScale(ErrorTerm):
    """Joint ``j`` turns by ``(1 + s_j) q_j`` instead of ``q_j``."""

    name = "encoder_scale"
    cause = "encoder_scale"
    revolute_only = True

    def parameters(self, robot: Robot) -> list[Parameter]:
        return [Parameter(f"escale{j}", 0.0, "1", 1e-4, self.name, j, lower=-0.01, upper=0.01)
                for j in self.joints]

    def joint_offsets(self, ctx: Context) -> dict:
        return {j: ctx.p[f"escale{j}"] * ctx.q[j - 1] for j in self.joints}
