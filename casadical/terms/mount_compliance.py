"""Mount compliance: the robot's base tilts under the moment of its weights about the mount."""

from __future__ import annotations

import casadi as ca
import numpy as np

from .._format import relative
from ..errors import ModelError
from ..model.kinematics import Geometry, chain_angles, forward, mount_moment
from ..model.parameters import Parameter
from ..robot import GRAVITY, Robot
from .base import Context, ErrorTerm, reach, register
from .cause import Cause, register_cause

#: largest tilt admitted at the largest moment the robot can put on its mount (rad): half a degree is a mount
#: coming loose, not a compliance
MAX_TILT = 0.01


def max_mount_moment(robot: Robot) -> float:
    """Upper bound of the moment of the weights about the base frame's origin (N m): every mass at full reach."""
    return GRAVITY * (sum(j.mass for j in robot.joints) + robot.payload_mass) * reach(robot, 1)


def mount_moments(robot: Robot, q: np.ndarray, payload_kg: np.ndarray | None = None) -> np.ndarray:
    """The moment of the weights about the base frame's origin at the readings ``q`` (N, 3; N m, base frame,
    nominal geometry, as :class:`MountCompliance` computes it): each row's payload if given, else the robot
    file's; zeros without masses."""
    q = np.atleast_2d(np.asarray(q, float))
    if max_mount_moment(robot) <= 0:
        return np.zeros((len(q), 3))
    qs, m = ca.SX.sym("q", robot.n), ca.SX.sym("m")
    geom = Geometry.nominal(robot)
    f = ca.Function("mount_moment", [qs, m], [mount_moment(robot, forward(robot, chain_angles(robot, qs, geom),
                                                                             geom), m)])
    pay = np.full(len(q), robot.payload_mass) if payload_kg is None else np.asarray(payload_kg, float)
    return np.array(f.map(len(q))(q.T, pay[None, :])).T


@register
class MountCompliance(ErrorTerm):
    """The robot's base frame turns about its origin by ``C M`` (rad), ``M`` the moment of the weights.

    A pedestal, a column or a track's carriage gives way under the moment
    the arm's weights put on it: ``M = sum_j c_j x (m_j g)`` about the base
    frame's origin (the mount point; every link's weight at its centre of
    mass, the row's payload at its centre in the tool frame, the robot
    file's gravity; the undeflected configuration, as the joints' torques).
    The base tilts by the rotation vector ``theta = C M`` (``C`` >= 0,
    rad/(N m)): towards the weights. The rotation is applied before joint
    1, about the base frame's origin: the tool point and the flange's
    orientation turn with it.

    A constant tilt is a rotation of the base pose, which the calibration
    fits anyway: only the part of the tilt that varies with the moment is
    identifiable, from poses that swing the weights about (joint 1 turning
    the arm's moment around, joints 2 and 3 stretching it, payloads).

    Parameters
    ----------
    axes : {"", "xy"}
        ``""`` (``mount_compliance``): one compliance ``cmount``, the same
        about every horizontal axis (a round column). ``"xy"``
        (``mount_compliance[xy]``): ``cmount_x`` and ``cmount_y`` about the
        base frame's x and y axes, ``theta = (Cx M_x, Cy M_y, 0)`` (a track's
        carriage, stiffer along the track); for a robot standing on (or
        hanging from) its base, gravity along its z axis.

    Raises
    ------
    ModelError
        The robot file gives no masses (the moment cannot be computed).
    """

    name = "mount_compliance"
    cause = "mount_compliance"
    bound_meaning = {k: {"lower": " (no positive compliance: the mount is stiffer than these poses can tell, or the "
                              "fit needs the base to tilt away from its weights)",
                     "upper": " (a tilt of 0.01 rad at the largest moment: a mount coming loose, not a "
                              "compliance)"}
                     for k in ("cmount", "cmount_x", "cmount_y")}
    covariates = ("payload_kg",)
    superset_order = 5
    superset_group = "torques"
    session_local = True

    @classmethod
    def superset(cls, robot: Robot) -> list[ErrorTerm]:
        """The base's tilt under the moment of the weights (it needs the masses)."""
        return [cls()] if max_mount_moment(robot) > 0 else []

    def __init__(self, joints=None, axes: str = ""):
        super().__init__(None)
        self.axes = str(axes)
        if self.axes not in ("", "xy"):
            raise ModelError(f"mount_compliance: axes must be '' (one compliance) or 'xy' (one about x, one about "
                             f"y), got {axes!r}")

    @classmethod
    def arguments(cls, args: str) -> dict:
        """``mount_compliance[xy]``: a compliance about x and one about y."""
        if args.strip() != "xy":
            raise ValueError("mount_compliance takes [xy] (a compliance about the base's x axis and one about its "
                             "y axis) or nothing (one compliance)")
        return {"axes": "xy"}

    def bind(self, robot: Robot) -> None:
        if max_mount_moment(robot) <= 0:
            raise ModelError(f"mount_compliance: {robot.name} has no masses (mass_kg and com_m of its joints, or a "
                             "payload, in the robot file): the moment of its weights about the mount cannot be "
                             "computed")
        g = np.asarray(robot.gravity, float)
        if self.axes == "xy" and np.hypot(g[0], g[1]) > 1e-9 * np.linalg.norm(g):
            raise ModelError(f"mount_compliance[xy]: {robot.name}'s gravity is not along its base's z axis; "
                             "use mount_compliance (one compliance)")

    def spec(self) -> str:
        return f"{self.name}[{self.axes}]" if self.axes else self.name

    def settings(self) -> dict:
        return {"axes": self.axes}

    def names(self) -> list[str]:
        return ["cmount_x", "cmount_y"] if self.axes else ["cmount"]

    def parameters(self, robot: Robot) -> list[Parameter]:
        top = max_mount_moment(robot)
        # a unit step of the scaled variable tilts the base 0.1 mrad at the largest moment
        return [Parameter(n, 0.0, "rad/(N*m)", 1e-4 / top, self.name, lower=0.0, upper=MAX_TILT / top)
                for n in self.names()]

    def base_tilt(self, ctx: Context):
        M = ctx.moment()
        if self.axes:
            return ca.vertcat(ctx.p["cmount_x"] * M[0], ctx.p["cmount_y"] * M[1], 0)
        return ctx.p["cmount"] * M


class MountGive(Cause):
    """The base tilting under the moment of the weights about the mount (:class:`MountCompliance`)."""

    name = "mount_compliance"
    own_variable = "moment"
    needs = {"mount_masses": "mount_compliance", "mount_moment": "mount_compliance"}
    short = "mount compliance"
    tier = 2
    order = 110
    session_part = "the mount"
    varies_text = "swing the arm's weight about the base (joint 1 turning, the arm stretched and folded)"
    tell_apart = {
        "joint_compliance": "turn joint 1 with the arm stretched: the base's tilt follows the moment about the mount, "
                            "a joint's deflection its own torque",
        "thermal_expansion": "repeat poses at another temperature with the arm stretched and folded",
    }

    def candidates(self, data) -> list:
        """The robot's and each session's, where the moment of the weights changes over their poses."""
        return [data.make(self.name, session=s) for s in data.mount]

    def place(self, cand) -> str:
        return "the base's mount"

    def size(self, cand, values, stds, params, linear) -> str:
        return f"tilt {values[0] * 1e6:.3g} mrad per kN m of moment{relative(stds[0], values[0])}"

    def words(self, cand, params, robot, data, linear) -> str:
        p = params[0]
        M = np.linalg.norm(mount_moments(robot, data.q, data.get("payload_kg")), axis=1).max(initial=0.0)
        return (f"the base tilts {p.value * M * 1e3:.3g} mrad at the largest moment of these poses ({M:.4g} N m; "
                f"compliance {p.value:.3g} rad/(N m), std {p.std:.2g})")

    def figure(self, cand, data, model, params, linear) -> dict:
        return {"x": np.linalg.norm(mount_moments(model.robot, data.q, data.get("payload_kg"))[:, :2], axis=1),
                "xlabel": "moment of the weights about the base, horizontal (N m)", "along": None}

    def own_shape(self, cand) -> tuple[str, str, int | None]:
        return "moment", "tilt", None

    def parameter_names(self, cand) -> list[str]:
        return ["cmount"]

    def specs(self, cands) -> list[str]:
        return ["mount_compliance"] if self.mine(cands) else []


MOUNT_COMPLIANCE = register_cause(MountGive())
