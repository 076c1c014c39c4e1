"""Geometric (kinematic) parameters: links, base pose and tool offset."""

from __future__ import annotations

import math

from ..kinematics import Geometry
from ..parameters import Parameter
from ..robot import Robot
from ._base import Context, ErrorTerm, register
from ._cause import Cause, register_cause

LENGTH_SCALE = 1e-3   # 1 mm
ANGLE_SCALE = 1e-3    # 1 mrad
#: the bounds of the geometry: every length (a link's, the tool's) within this of its nominal (m), every angle within
#: :data:`ANGLE_BOX` (rad); docs/formats.md ("Bounds of the geometry")
LENGTH_BOX = 0.05
ANGLE_BOX = math.radians(5.0)


@register
class Geometric(ErrorTerm):
    """Every link parameter, the base pose deviation and the tool offset.

    This term is part of every model. In the ``nominal`` model only the base
    pose is free (the measurement frame is never known in advance).

    Parameters
    ----------
    length_box : float
        Bound on the deviation of a link length from nominal (m).
    angle_box : float
        Bound on the deviation of a link angle from nominal (rad).
    drive_errors : bool
        Joint errors (compliance, gear error, encoder scale, backlash) are the drives': added to the readings
        before couplings and loops, with the torques the drives carry (True). Calibration files written
        before this was so hold ``False`` (:data:`LEGACY`: the errors on the chain angles, the torques about
        the joint axes), so they predict as before; it matters only for robots with a coupling or a loop.
    """

    #: settings of a calibration file that lacks them: files older than the drive convention
    LEGACY = {"drive_errors": False}

    name = "geometric"
    aliases = ("kinematic",)
    cause = "geometric"
    is_cause = False
    noted = False

    def superset_member(self) -> bool:
        """The superset expresses it (its geometry and sessions come first) with the drives' convention; files
        older than it (``drive_errors=False``) run on their model's own graph."""
        return self.drive_errors

    def __init__(self, joints=None, length_box: float = LENGTH_BOX, angle_box: float = ANGLE_BOX,
                 drive_errors: bool = True):
        super().__init__(joints)
        self.length_box = length_box
        self.angle_box = angle_box
        self.drive_errors = bool(drive_errors)

    def spec(self) -> str:
        return "kinematic"

    def settings(self) -> dict:
        return {"length_box": self.length_box, "angle_box": self.angle_box, "drive_errors": self.drive_errors}

    def parameters(self, robot: Robot) -> list[Parameter]:
        L, A = self.length_box, self.angle_box

        def length(name, nominal, joint=None, group="link"):
            return Parameter(name, nominal, "m", LENGTH_SCALE, "geometric", joint, group,
                             lower=nominal - L, upper=nominal + L)

        def angle(name, nominal, joint=None, group="link"):
            return Parameter(name, nominal, "rad", ANGLE_SCALE, "geometric", joint, group,
                             lower=nominal - A, upper=nominal + A)

        ps = [Parameter(f"base_{k}", 0.0, "m", LENGTH_SCALE, "geometric", group="base") for k in "xyz"]
        ps += [Parameter(f"base_{k}", 0.0, "rad", ANGLE_SCALE, "geometric", group="base")
               for k in ("roll", "pitch", "yaw")]
        for i, j in enumerate(robot.joints, start=1):
            ps.append(angle(f"alpha{i}", j.alpha, i))
            ps.append(length(f"a{i}", j.a, i))
            if j.beta is not None:
                ps.append(angle(f"beta{i}", j.beta, i))
            if j.b is not None:
                ps.append(length(f"b{i}", j.b, i))
            ps.append(length(f"d{i}", j.d, i))
            ps.append(angle(f"theta{i}", j.theta, i))
        ps += [length(f"tool_{k}", v, None, "tool") for k, v in zip("xyz", robot.tool)]
        if robot.loop is not None:
            lp = robot.loop
            # crank last: to first order only rocker - crank is seen, and the
            # identifiability analysis keeps the earlier of confounded parameters
            ps += [length(f"loop_{k}", v, lp.joint, "loop")
                   for k, v in (("coupler", lp.coupler), ("rocker", lp.rocker), ("crank", lp.crank))]
        return ps

    def geometry(self, ctx: Context, geom: Geometry) -> Geometry:
        p, robot = ctx.p, ctx.robot
        rng = range(1, robot.n + 1)
        return Geometry(
            alpha=[p[f"alpha{i}"] for i in rng],
            a=[p[f"a{i}"] for i in rng],
            beta=[p.get(f"beta{i}", 0.0) for i in rng],
            b=[p.get(f"b{i}", 0.0) for i in rng],
            d=[p[f"d{i}"] for i in rng],
            theta=[p[f"theta{i}"] for i in rng],
            tool=[p[f"tool_{k}"] for k in "xyz"],
            base=[p[f"base_{k}"] for k in ("x", "y", "z", "roll", "pitch", "yaw")],
            loop=[p[f"loop_{k}"] for k in ("crank", "coupler", "rocker")] if robot.loop else [],
        )


class Kinematic(Cause):
    """Kinematic parameter errors: the links, the base and the tool (:class:`Geometric`)."""

    name = "geometric"
    geometry = True
    short = "kinematic"
    scope_word = "robot"
    #: the links and the tool are the robot's; each session has its own base pose
    session_part = "the instrument's set-up"

    def step_label(self, cand) -> str:
        return "kinematic"

    def finding_label(self, finding) -> str:
        return "geometry"

    def where(self, cand, finding) -> str:
        return "links, base and tool"

    def finding_size(self, finding, final) -> str:
        n = sum(1 for p in final.parameters if p.term == self.name and not p.fixed and not p.name.startswith("base_"))
        return f"{n} link and tool parameters"

    def action(self, finding) -> str:
        return ("use the calibrated geometry: export writes it as URDF and a DH table (compensate uses the full "
                "model)")


GEOMETRIC = register_cause(Kinematic())
