"""Backlash: half the play of a joint, taken up on the side its load pushes."""

from __future__ import annotations

import math

import casadi as ca

from ..errors import ModelError
from ..model.parameters import Parameter
from ..robot import Robot
from .base import Context, ErrorTerm, register

#: largest half play admitted on a linear axis (m)
MAX_PLAY_LINEAR = 1e-3


@register
class Backlash(ErrorTerm):
    """Joint ``j`` is off by the half play ``b_j >= 0``, on the side its load takes it.

    Sign convention (docs/diagnosis.md): with the gravity torque as sign
    source the joint deflects *with* its torque, as a compliant joint does:
    ``+b sign(tau_j)``. With the last move as sign source the output trails
    its motor: after a move in the positive direction the joint stands
    ``b`` short of its reading, ``-b sign(move_j)``. Either way a negative
    ``b`` (the joint standing against its load, or leading its motor) is
    not play.

    On a linear axis (a prismatic joint; ISO 230-1's reversal error) ``b_j`` is in metres along the axis, at
    most 1 mm: by the motion the carriage trails its drive, by the load (the force of gravity along the axis: a
    column) it rests on the side the weight pushes it.

    Parameters
    ----------
    source : {"torque", "motion"}
        ``torque``: the sign of the joint's gravity torque (a gravity-loaded
        joint rests on one flank of the gear); ``motion``: the sign of the
        last move of the joint, from the row order (covariate ``move<j>``).
    lag : bool
        Motion source only: the convention above (True). Calibration files
        written before it was fixed hold ``+b sign(move_j)`` and are read
        with ``lag=False`` (:data:`LEGACY`), so they predict as before.
    """

    name = "backlash"
    cause = "backlash"

    #: settings of a calibration file that lacks them: files older than the lag convention
    LEGACY = {"lag": False}

    def __init__(self, joints=None, source: str = "torque", lag: bool = True):
        if source not in ("torque", "motion"):
            raise ModelError(f"backlash source must be 'torque' or 'motion', got {source!r}")
        super().__init__(joints)
        self.source = source
        self.lag = bool(lag)

    @property
    def covariates(self) -> tuple[str, ...]:  # type: ignore[override]
        if self.source == "motion":
            return tuple(f"move{j}" for j in self.joints)
        return ("payload_kg",)

    def spec(self) -> str:
        base = super().spec()
        return base if self.source == "torque" else base.replace(self.name, "backlash_motion", 1)

    def settings(self) -> dict:
        return {"joints": self.joints, "source": self.source, "lag": self.lag}

    @property
    def prefix(self) -> str:
        """Parameter name prefix: both kinds can sit in one model."""
        return "backlash" if self.source == "torque" else "backlash_m"

    def parameters(self, robot: Robot) -> list[Parameter]:
        return [Parameter(f"{self.prefix}{j}", 0.0, "m", 1e-5, self.name, j, lower=0.0, upper=MAX_PLAY_LINEAR)
                if robot.joints[j - 1].prismatic else
                Parameter(f"{self.prefix}{j}", 0.0, "rad", 1e-4, self.name, j, lower=0.0, upper=math.radians(1.0))
                for j in self.joints]

    def joint_offsets(self, ctx: Context) -> dict:
        if self.source == "torque":
            tau = ctx.torques()
            return {j: ctx.p[f"backlash{j}"] * ca.sign(tau[j - 1]) for j in self.joints}
        sign = -1.0 if self.lag else 1.0
        return {j: sign * ctx.p[f"backlash_m{j}"] * ctx.cov[f"move{j}"] for j in self.joints}


@register
class BacklashMotion(Backlash):
    """Backlash whose sign follows the direction of the joint's last move."""

    name = "backlash_motion"
    aliases = ()
    cause = "backlash"

    def __init__(self, joints=None, lag: bool = True):
        super().__init__(joints, source="motion", lag=lag)
