"""Backlash: half the play of a joint, taken up on the side its load pushes."""

from __future__ import annotations

import math

import casadi as ca

from ..errors import ModelError
from ..parameters import Parameter
from ..robot import Robot
from .base import Context, ErrorTerm, register


@register
class Backlash(ErrorTerm):
    """Joint ``j`` is off by ``+-b_j``, the sign following its load.

    Parameters
    ----------
    source : {"torque", "motion"}
        ``torque``: the sign of the joint's gravity torque (a gravity-loaded
        joint rests on one flank of the gear); ``motion``: the sign of the
        last move of the joint, from the row order (covariate ``move<j>``).
    """

    name = "backlash"
    cause = "backlash"

    def __init__(self, joints=None, source: str = "torque"):
        if source not in ("torque", "motion"):
            raise ModelError(f"backlash source must be 'torque' or 'motion', got {source!r}")
        super().__init__(joints)
        self.source = source

    @property
    def covariates(self) -> tuple[str, ...]:  # type: ignore[override]
        if self.source == "motion":
            return tuple(f"move{j}" for j in self.joints)
        return ("payload_kg",)

    def spec(self) -> str:
        base = super().spec()
        return base if self.source == "torque" else base.replace(self.name, "backlash_motion", 1)

    def settings(self) -> dict:
        return {"joints": self.joints, "source": self.source}

    @property
    def prefix(self) -> str:
        """Parameter name prefix: both kinds can sit in one model."""
        return "backlash" if self.source == "torque" else "backlash_m"

    def parameters(self, robot: Robot) -> list[Parameter]:
        return [Parameter(f"{self.prefix}{j}", 0.0, "rad", 1e-4, self.name, j,
                          lower=0.0, upper=math.radians(1.0)) for j in self.joints]

    def joint_offsets(self, ctx: Context) -> dict:
        if self.source == "torque":
            tau = ctx.torques()
            return {j: ctx.p[f"backlash{j}"] * ca.sign(tau[j - 1]) for j in self.joints}
        return {j: ctx.p[f"backlash_m{j}"] * ctx.cov[f"move{j}"] for j in self.joints}


@register
class BacklashMotion(Backlash):
    """Backlash whose sign follows the direction of the joint's last move."""

    name = "backlash_motion"
    aliases = ()
    cause = "backlash"

    def __init__(self, joints=None):
        super().__init__(joints, source="motion")
