"""Bearing compliance: a joint's axis tilts under the moment of the weights it carries across its axis."""

from __future__ import annotations

from dataclasses import replace

import casadi as ca
import numpy as np

from .._format import g3, relative
from ..errors import ModelError
from ..kinematics import Geometry, chain_angles, forward, rotx, roty
from ..parameters import Parameter
from ..robot import Robot
from ._base import Context, ErrorTerm, max_gravity_torque, register, revolute
from ._cause import Cause, register_cause
from ._straightness import axis_pairs

#: largest tilt admitted at the largest moment the joint can carry (rad): more is a loose bearing, not a compliance
MAX_TILT = 5e-3
#: a component's moment must change by this share of the largest the joint can carry for its tilt to show (a
#: constant tilt is the geometry's)
MOMENT_CHANGE = 1e-3


def carried_moment(robot: Robot, frames, payload_mass, j: int):
    """The moment of the weights joint ``j`` carries (links j..n and the payload, at their centres) about the
    origin of its axis (N m, 3x1, robot base frame)."""
    g = ca.DM(robot.gravity)
    o = frames.origin[j - 1]
    total = ca.SX.zeros(3, 1)
    for i in range(j - 1, robot.n):
        R, t = frames.link[i]
        total = total + ca.cross(t + ca.mtimes(R, ca.DM(robot.joints[i].com)) - o, robot.joints[i].mass * g)
    R, t = frames.tool
    return total + ca.cross(t + ca.mtimes(R, ca.DM(robot.payload_com)) - o, payload_mass * g)


def axis_frame(robot: Robot, frames, geom: Geometry, j: int):
    """Joint ``j``'s axis frame (z its axis, before it turns) in the frame before its row: its rotation and its
    origin (mdh ``Rx(alpha) Tx(a) Ry(beta) Ty(b)``; dh the frame itself), and the rotation of the frame before
    the row in the robot base frame."""
    R_pre, p = ca.SX.eye(3), ca.SX.zeros(3, 1)
    if robot.convention == "mdh":
        Rx = rotx(geom.alpha[j - 1])[0]
        R_pre = ca.mtimes(Rx, roty(geom.beta[j - 1])[0])
        p = ca.mtimes(Rx, ca.vertcat(geom.a[j - 1], 0, 0)) + ca.mtimes(R_pre, ca.vertcat(0, geom.b[j - 1], 0))
    return R_pre, p, frames.link[j - 2][0] if j > 1 else ca.SX.eye(3)


def parallel_to_earlier(robot: Robot, q: np.ndarray, j: int) -> dict[str, int | None]:
    """For each component (``x``, ``y``) of joint ``j``'s tilt, the earlier revolute joint whose axis it is at every
    pose of ``q`` (nominal geometry; None: none): a tilt about that axis is that joint's compliance, to first
    order, where the moments about the two origins agree (a 7-axis arm's joint 3 about its y: joint 2's)."""
    q = np.atleast_2d(np.asarray(q, float))
    qs = ca.SX.sym("q", robot.n)
    geom = Geometry.nominal(robot)
    frames = forward(robot, chain_angles(robot, qs, geom), geom)
    R_pre, _, R_before = axis_frame(robot, frames, geom, j)
    R = ca.mtimes(R_before, R_pre)
    earlier = [k for k in revolute(robot) if k < j]
    if not earlier:
        return {"x": None, "y": None}
    f = ca.Function("bearing_axes", [qs], [ca.mtimes(R[:, :2].T, ca.horzcat(*[frames.axis[k - 1] for k in earlier]))])
    cos = np.abs(np.array(f.map(len(q))(q.T)).reshape(2, len(q), len(earlier)))     # pose by pose
    out: dict[str, int | None] = {}
    for i, key in enumerate("xy"):
        same = [k for m, k in enumerate(earlier) if np.all(cos[i, :, m] > 1 - 1e-9)]
        out[key] = same[-1] if same else None
    return out


def bearing_moments(robot: Robot, q: np.ndarray, payload_kg: np.ndarray | None, j: int) -> np.ndarray:
    """The moment joint ``j`` carries about its origin, in its axis frame (N, 3; N m; nominal geometry): its z the
    torque about the axis, its x and y what loads the bearing."""
    q = np.atleast_2d(np.asarray(q, float))
    qs, m = ca.SX.sym("q", robot.n), ca.SX.sym("m")
    geom = Geometry.nominal(robot)
    frames = forward(robot, chain_angles(robot, qs, geom), geom)
    R_pre, _, R_before = axis_frame(robot, frames, geom, j)
    f = ca.Function("bearing_moment", [qs, m], [ca.mtimes(ca.mtimes(R_before, R_pre).T,
                                                          carried_moment(robot, frames, m, j))])
    pay = np.full(len(q), robot.payload_mass) if payload_kg is None else np.asarray(payload_kg, float)
    return np.array(f.map(len(q))(q.T, pay[None, :])).T


@register
class BearingCompliance(ErrorTerm):
    """Joint ``j``'s axis tips about its origin by the rotation vector ``(cx_j M_x, cy_j M_y, 0)`` of its own frame.

    ``M`` is the moment of the weights the joint carries (every link after it, its own included, and the
    row's payload, at their centres of mass; the undeflected configuration, as the joints' torques) about the
    origin of its axis, in the axis' frame (z the axis, before the joint turns: mdh after ``Rx(alpha) Tx(a)
    Ry(beta) Ty(b)``, dh the frame before the row). Its component along the axis is the torque the drive carries
    (a joint compliance's); the two across it load the bearing, which gives way: the joint and everything after
    it turn about the axis' origin. ``cx``, ``cy`` >= 0 (rad/(N m)): towards the weights, as a mount gives way.

    Parameters
    ----------
    joints : list of int, optional
        The joints whose bearings tilt about both axes across theirs (default: every revolute joint).
    pairs : list of (joint, "x" | "y")
        Each a component of one joint's tilt (``bearing_compliance[3:y]``; ``bearing_compliance[3]``: both).
    """

    name = "bearing_compliance"
    aliases = ("bearing",)
    cause = "bearing_compliance"
    revolute_only = True
    covariates = ("payload_kg",)
    superset_order = 13
    superset_group = "bearing"
    KEYS = ("x", "y")

    def __init__(self, joints=None, pairs=()):
        self.pairs = sorted({(int(j), str(k)) for j, k in pairs}) if pairs else None
        if self.pairs is not None and any(k not in self.KEYS for _, k in self.pairs):
            raise ModelError(f"bearing_compliance: components are x and y, got {self.pairs}")
        super().__init__(sorted({j for j, _ in self.pairs}) if self.pairs else joints)

    @classmethod
    def arguments(cls, args: str) -> dict:
        """``bearing_compliance[3]`` (both components) or ``[2:x,3:y]``."""
        return {"pairs": axis_pairs(args, cls.KEYS, "component")}

    @classmethod
    def superset(cls, robot: Robot) -> list[ErrorTerm]:
        joints = [j for j in revolute(robot) if max_gravity_torque(robot, j) > 0]
        return [cls(joints=joints)] if joints else []

    def bind(self, robot: Robot) -> None:
        super().bind(robot)
        if self.pairs is None:
            self.pairs = [(j, k) for j in self.joints for k in self.KEYS]

    def resolved(self, robot: Robot) -> list[tuple[int, str]]:
        """The (joint, component) pairs (before :meth:`bind` too: the superset's terms are not bound)."""
        if self.pairs is not None:
            return self.pairs
        return [(j, k) for j in self.joints or revolute(robot) for k in self.KEYS]

    def spec(self) -> str:
        if self.pairs is None or self.pairs == [(j, k) for j in self.joints for k in self.KEYS]:
            return super().spec()
        return f"{self.name}[{','.join(f'{j}:{k}' for j, k in self.pairs)}]"

    def settings(self) -> dict:
        return {"pairs": [list(p) for p in self.pairs]} if self.pairs else {"joints": self.joints}

    def parameters(self, robot: Robot) -> list[Parameter]:
        out = []
        for j, k in self.resolved(robot):
            top = max_gravity_torque(robot, j)       # the largest moment joint j can carry
            # a unit step of the scaled variable tilts the axis 0.1 mrad at the largest moment
            scale, upper = (1e-4 / top, MAX_TILT / top) if top > 0 else (1e-6, 1e-3)
            out.append(Parameter(f"cbear{j}_{k}", 0.0, "rad/(N*m)", scale, self.name, j, lower=0.0, upper=upper))
        return out

    def geometry(self, ctx: Context, geom: Geometry) -> Geometry:
        # the undeflected configuration of the geometry so far (as the joints' torques)
        frames = (ctx if ctx.geom is not None else replace(ctx, geom=geom, _frames=None, _torques=None)).frames()
        robot = ctx.robot
        links, mount = dict(geom.links), list(geom.mount or [0.0] * 6)
        pairs = self.resolved(robot)
        for j in dict.fromkeys(j for j, _ in pairs):
            R_pre, p, R_before = axis_frame(robot, frames, geom, j)
            M = ca.mtimes(ca.mtimes(R_before, R_pre).T, carried_moment(robot, frames, ctx.cov["payload_kg"], j))
            c = [ctx.p[f"cbear{j}_{k}"] if (j, k) in pairs else 0 for k in self.KEYS]
            w = ca.mtimes(R_pre, ca.vertcat(c[0] * M[0], c[1] * M[1], 0))
            # the turn about the axis' origin as a change of the frame before the row (Tx Ty Tz, then the small
            # rotation: first order, as the compliance)
            change = [*(ca.cross(p, w)[k] for k in range(3)), w[0], w[1], w[2]]
            if j > 1:
                links[j - 1] = [a + v for a, v in zip(links.get(j - 1, [0.0] * 6), change)]
            else:
                mount = [a + v for a, v in zip(mount, change)]
        return replace(geom, links=links, mount=mount)


class BearingGive(Cause):
    """A joint's bearing that lets its axis tilt under the moment of the weights it carries
    (:class:`BearingCompliance`)."""

    name = "bearing_compliance"
    short = "bearing compliance"
    tier = 2
    order = 115
    needs = {"linear_axis": "bearing_compliance", "masses": "bearing_compliance"}
    varies_text = "swing the weights joint {j} carries across its axis (the arm stretched sideways, then folded)"
    tell_apart = {
        "joint_compliance": "load joint {j} across its axis (the arm reaching sideways of it) and along it: its "
                            "bearing tilts under the moment across the axis, a joint's drive gives way under the "
                            "torque about it",
        "mount_compliance": "turn joint {j} with the arm stretched: the bearing's tilt turns with the joint, the "
                            "mount's stays with the base",
    }

    def candidates(self, data) -> list:
        """Each component of joints 2 onwards (joint 1's axis tilting about its origin is the mount's give) whose
        moment changes over the poses (a constant tilt is the geometry's) and whose axis is no earlier joint's
        (:meth:`untested`)."""
        out = []
        for j in (j for j in data.revolute if j > 1 and max_gravity_torque(data.robot, j) > 0):
            M = data.memo(("bearing moments", j), lambda j=j: bearing_moments(data.robot, data.cal.q,
                                                                                data.cal.get("payload_kg"), j))
            parallel = data.memo(("bearing axes", j), lambda j=j: parallel_to_earlier(data.robot, data.cal.q, j))
            top = max_gravity_torque(data.robot, j)
            out += [data.make(self.name, j, direction=k) for i, k in enumerate("xy")
                    if parallel[k] is None and np.ptp(M[:, i]) > MOMENT_CHANGE * top]
        return out

    def untested(self, data) -> list:
        """The components whose axis is an earlier joint's (at every pose): that joint's compliance takes their tilt
        (one entry for every such joint)."""
        found = {}
        for j in (j for j in data.revolute if j > 1 and max_gravity_torque(data.robot, j) > 0):
            for k, earlier in parallel_to_earlier(data.robot, data.cal.q, j).items():
                if earlier is not None:
                    found.setdefault(k, []).append((j, earlier))
        return [([j for j, _ in pairs], f"each bearing's tilt about its {k} is a turn about the joint before "
                 f"({', '.join(f'joint {e} for {j}' for j, e in pairs)}), whose compliance takes it",
                 "no poses could tell them apart") for k, pairs in found.items()]

    def parameter_names(self, cand) -> list[str]:
        return [f"cbear{cand.joint}_{cand.direction}"]

    def terms(self, cands) -> list[ErrorTerm]:
        pairs = sorted({(c.joint, c.direction) for c in self.mine(cands)})
        return [BearingCompliance(pairs=pairs)] if pairs else []

    def place(self, cand) -> str:
        return f"joint {cand.joint}'s bearing, about its {cand.direction}"

    def size(self, cand, values, stds, params, linear) -> str:
        return f"tilt {g3(values[0] * 1e6)} mrad per kN m{relative(stds[0], values[0])}"

    def words(self, cand, params, robot, data, linear) -> str:
        p = params[0]
        M = np.abs(bearing_moments(robot, data.q, data.get("payload_kg"), cand.joint)[:, "xy".index(cand.direction)])
        return (f"the axis tilts {p.value * M.max() * 1e3:.3g} mrad about its {cand.direction} at the largest moment "
                f"across it of these poses ({M.max():.4g} N m; compliance {p.value:.3g} rad/(N m), std {p.std:.2g})")

    def unexplained_item(self, cand, values, linear) -> dict:
        v = values.get(cand.parameter_names()[0], 0.0)
        return {"bearing_compliance": v, "what": f"a tilt of the joint's axis about its {cand.direction} with the "
                                                 f"moment it carries across it ({v:.3g} rad/(N m))"}

    def figure(self, cand, data, model, params, linear) -> dict:
        M = bearing_moments(model.robot, data.q, data.get("payload_kg"), cand.joint)
        return {"x": M[:, "xy".index(cand.direction)], "along": None,
                "xlabel": f"moment of the weights about joint {cand.joint}'s {cand.direction} axis (N m)"}


BEARING_COMPLIANCE = register_cause(BearingGive())
