"""Backlash: half the play of a joint, taken up on the side its load pushes."""

from __future__ import annotations

import math

import casadi as ca
import numpy as np

from .._format import relative
from ..errors import ModelError
from ..parameters import Parameter
from ..robot import Robot
from ._base import Context, ErrorTerm, register
from ._cause import Cause, register_cause

#: a linear axis' half play in metres read as radians by the arcsec conversion: divided by this, millimetres
ARCSEC_PER_MM = math.degrees(1.0) * 3600 / 1000.0
#: largest half play admitted on a linear axis (m)
MAX_PLAY_LINEAR = 1e-3


#: each sign of a backlash's sign source must hold at this many poses, and at this share of them
MIN_SIDE_POSES = 5
MIN_SIDE_SHARE = 0.02


def sign_changes(signs: np.ndarray, what: str) -> tuple[bool, str]:
    """Whether a sign source takes both signs at enough poses (:data:`MIN_SIDE_POSES`,
    :data:`MIN_SIDE_SHARE`); and the counts in words."""
    signs = np.asarray(signs)
    pos, neg = int(np.sum(signs > 0)), int(np.sum(signs < 0))
    need = max(MIN_SIDE_POSES, math.ceil(MIN_SIDE_SHARE * len(signs)))
    text = f"{what} is positive at {pos} and negative at {neg} of {len(signs)} poses"
    return min(pos, neg) >= need, text


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
    bound_meaning = {"backlash": {"lower": " (a play cannot be negative: the joint would stand against its load)"},
                     "backlash_m": {"lower": " (a play cannot be negative: the output would lead its motor, not trail "
                                             "it)"}}
    weak_meaning = ("the backlash of {joints} is", "measure poses whose gravity torque changes sign on {them}")
    superset_order = 4
    superset_group = "torques"
    session_local = True

    @classmethod
    def superset(cls, robot: Robot) -> list[ErrorTerm]:
        return [cls(joints=list(range(1, robot.n + 1)))]

    def superset_member(self) -> bool:
        """By the motion: the superset's has the trailing convention (``lag``); files older than it have not."""
        return self.source == "torque" or self.lag

    #: settings of a calibration file that lacks them: files older than the lag convention
    LEGACY = {"lag": False}

    def __init__(self, joints=None, source: str = "torque", lag: bool = True):
        if source not in ("torque", "motion"):
            raise ModelError(f"backlash source must be 'torque' or 'motion', got {source!r}")
        super().__init__(joints)
        self.source = source
        self.lag = bool(lag)
        if source == "motion":      # by the last move: no torque read (the superset's torques group need not be)
            self.superset_group = None

    @classmethod
    def value_rules(cls, p, params, tau, moves) -> list:
        """Play needs its sign source to change sign at the poses: otherwise it is a constant joint offset."""
        if p.term != Backlash.name:     # the load's play (a motion's is checked when it is screened)
            return []
        j, n = p.joint, p.name
        if n.startswith("backlash_m"):
            ok, text = sign_changes(moves[:, j - 1], f"the direction of joint {j}'s last move")
        else:
            ok, text = sign_changes(np.sign(tau()[:, j - 1]), f"the gravity torque of joint {j}")
        return [] if ok else [((n,), text + f": {n} acts as a constant offset of joint {j} (theta{j}), not as "
                                            "backlash")]

    def fitted_causes(self, names, joint_of, where) -> list:
        motion = " (direction of motion)" if self.source == "motion" else ""
        return [(joint_of(n), [n], f"backlash{motion}" + (f" of joint {joint_of(n)}" if joint_of(n) is not None
                                                          else "") + where) for n in names]

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
    weak_meaning = ("the backlash of {joints} is", "measure poses approached from both directions")
    superset_order = 8
    superset_group = None

    @classmethod
    def superset(cls, robot: Robot) -> list[ErrorTerm]:
        return [cls(joints=list(range(1, robot.n + 1)))]

    def __init__(self, joints=None, lag: bool = True):
        super().__init__(joints, source="motion", lag=lag)


class Play(Cause):
    """Half the play of a joint, on the side its load (``source`` torque) or its last move (motion) takes it."""

    name = "backlash"
    own_variable = "tau"
    needs = {"masses": "backlash by the load", "level": "backlash by the load", "idle": "backlash by the load",
             "one_sign": "backlash by the load", "one_way": "backlash by the motion"}
    order = 50
    varies_text = "load joint {j} with torques of both signs"
    tell_apart = {
        "backlash": "approach the same poses from both directions of joint {j}: play that follows the motion changes "
                    "sign, play that follows gravity does not",
    }

    def candidates(self, data) -> list:
        # a linear axis: by the motion, and by the load where gravity pushes along it (a column's weight)
        return ([data.make(self.name, j, source=s) for j in data.revolute for s in ("torque", "motion")]
                + [data.make(self.name, j, source=s) for j in data.moving_axes for s in ("torque", "motion")
                   if s == "motion" or data.loaded(j)])

    def screenable(self, cand, data) -> bool:
        """Play needs its sign source to change sign in the data: otherwise it is a joint offset."""
        return data.sign_changes(cand)

    def place(self, cand) -> str:
        return f"joint {cand.joint}" + (", by the last move" if cand.source == "motion" else ", by the load")

    def size(self, cand, values, stds, params, linear) -> str:
        if linear:
            return f"half play {values[0] * 1e3:.3g} mm{relative(stds[0], values[0])}"
        return f"half play {math.degrees(values[0]) * 3600:.1f} arcsec{relative(stds[0], values[0])}"

    def unexplained_item(self, cand, values, linear) -> dict:
        v = math.degrees(values[cand.parameter_names()[0]]) * 3600
        motion = cand.source == "motion"
        if v >= 0:
            what = f"a step with the sign of the joint's {'motion' if motion else 'load'} ({v:.1f} arcsec)"
        elif motion:
            what = f"a lead of {-v:.1f} arcsec in the direction of the joint's last move (play would trail)"
        else:
            what = f"a step of {-v:.1f} arcsec against the sign of the joint's load"
        if linear:      # the parameter is in metres: in arcsec times this, mm
            mm = v / ARCSEC_PER_MM
            return {"half_play_mm": mm, "what": f"a step with the sign of the axis' {'motion' if motion else 'load'} "
                                                f"({mm:.3g} mm)"}
        return {"half_play_arcsec": v, "what": what}

    def words(self, cand, params, robot, data, linear) -> str:
        p = params[0]
        if linear:
            return (f"half play {p.value * 1e3:.3g} mm along axis {cand.joint} (std {p.std * 1e3:.2g}), sign from the "
                    f"{'force of gravity along it' if cand.source != 'motion' else 'last move'}")
        return (f"half play {math.degrees(p.value) * 3600:.2f} arcsec, sign from the "
                f"{'gravity torque' if cand.source != 'motion' else 'last move'}")

    def figure(self, cand, data, model, params, linear) -> dict:
        j = cand.joint
        value = params[cand.parameter_names()[0]].value
        if cand.source == "motion":
            x = data.moves[:, j - 1]
            # a linear axis' carriage trails its drive (the term's sign); the joint's figure as it always was
            return {"x": x, "xlabel": f"direction of the last move of {'axis' if linear else 'joint'} {j}",
                    "effect": -value * x if linear else value * x}
        x = model.torques(data.q, params.values, model.covariates(data))[:, j - 1]
        return {"x": x, "xlabel": f"force of gravity along axis {j} (N)" if linear else
                f"gravity torque at joint {j} (N m)", "effect": value * np.sign(x)}

    def parameter_names(self, cand) -> list[str]:
        return [f"backlash{cand.joint}" if cand.source != "motion" else f"backlash_m{cand.joint}"]

    def terms(self, cands) -> list[ErrorTerm]:
        mine = self.mine(cands)
        out = []
        for kind, motion in ((Backlash, False), (BacklashMotion, True)):
            joints = sorted({c.joint for c in mine if (c.source == "motion") == motion})
            if joints:
                out.append(kind(joints=joints))
        return out

    def varies(self, cand) -> str:
        return "approach joint {j} from both directions" if cand.source == "motion" else self.varies_text


BACKLASH = register_cause(Play())
