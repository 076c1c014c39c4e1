"""Symbolic forward kinematics and gravity torques in CasADi.

Poses are pairs ``(R, t)`` of a 3x3 rotation and a 3-vector, cheaper than
4x4 matrices in the expression graph. Everything here accepts CasADi SX
expressions (or plain floats) for every geometric quantity, so the same code
gives the nominal model, the calibrated model and the identification
Jacobian by automatic differentiation.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, field
from typing import Any

import casadi as ca
import numpy as np

from .robot import Robot

Pose = tuple[Any, Any]  # (R: 3x3, t: 3x1)


def rotx(x) -> Pose:
    c, s = ca.cos(x), ca.sin(x)
    return ca.vertcat(ca.horzcat(1, 0, 0), ca.horzcat(0, c, -s), ca.horzcat(0, s, c)), ca.SX.zeros(3, 1)


def roty(x) -> Pose:
    c, s = ca.cos(x), ca.sin(x)
    return ca.vertcat(ca.horzcat(c, 0, s), ca.horzcat(0, 1, 0), ca.horzcat(-s, 0, c)), ca.SX.zeros(3, 1)


def rotz(x) -> Pose:
    c, s = ca.cos(x), ca.sin(x)
    return ca.vertcat(ca.horzcat(c, -s, 0), ca.horzcat(s, c, 0), ca.horzcat(0, 0, 1)), ca.SX.zeros(3, 1)


def trans(x=0, y=0, z=0) -> Pose:
    return ca.SX.eye(3), ca.vertcat(x, y, z)


def compose(*poses: Pose) -> Pose:
    R, t = poses[0]
    for R2, t2 in poses[1:]:
        t = t + ca.mtimes(R, t2)
        R = ca.mtimes(R, R2)
    return R, t


def rpy_pose(x, y, z, roll, pitch, yaw) -> Pose:
    """Translation then fixed-axis roll-pitch-yaw: Rz(yaw) Ry(pitch) Rx(roll)."""
    return compose(trans(x, y, z), rotz(yaw), roty(pitch), rotx(roll))


@dataclass
class Geometry:
    """Symbolic (or numeric) geometric quantities of a robot.

    One entry per joint in each list; ``beta``/``b`` entries are 0 where the
    robot does not model them.
    """

    alpha: list
    a: list
    beta: list
    b: list
    d: list
    theta: list
    tool: list
    base: list  # deviation of the base pose: x, y, z, roll, pitch, yaw
    loop: list = field(default_factory=list)  # crank, coupler, rocker
    #: a change of link frames after their link transforms, by 1-based joint: [dx, dy, dz, rx, ry, rz] applied as
    #: Tx Ty Tz Rz Ry Rx (a user term's ``frame`` effect, casadical.terms._user); none in the catalogue's models
    links: dict = field(default_factory=dict)
    #: a change of the robot base right after the estimated base pose, [dx, dy, dz, rx, ry, rz] as ``links``
    #: (a user term's ``base`` effect); empty: none
    mount: list = field(default_factory=list)
    #: a linear axis' carriage off its ideal travel, by 1-based joint: [dx, dy, dz, rx, ry, rz] applied as
    #: Tx Ty Tz Rz Ry Rx right after the joint's travel (``Rz(theta) Tz(d + q)``), in that frame: z along the
    #: travel (the straightness and the carriage's angles, casadical.terms._straightness, .carriage_angle)
    carriage: dict = field(default_factory=dict)

    @classmethod
    def nominal(cls, robot: Robot) -> "Geometry":
        J = robot.joints
        return cls(alpha=[j.alpha for j in J], a=[j.a for j in J],
                   beta=[j.beta or 0.0 for j in J], b=[j.b or 0.0 for j in J],
                   d=[j.d for j in J], theta=[j.theta for j in J],
                   tool=list(robot.tool), base=[0.0] * 6,
                   loop=[robot.loop.crank, robot.loop.coupler, robot.loop.rocker] if robot.loop else [])


def fourbar_rocker_angle(link_dir, crank_angle, ground, crank, coupler, rocker):
    """Absolute rocker angle of a four-bar whose ground is a link of length ``ground``.

    The crank turns about the first axis at absolute angle ``crank_angle``;
    the rocker turns about the second axis (``ground`` away along
    ``link_dir``). The assembly branch is the one that makes a parallelogram
    (crank == rocker, coupler == ground) return ``crank_angle`` exactly.
    """
    dx = ground * ca.cos(link_dir) - crank * ca.cos(crank_angle)
    dy = ground * ca.sin(link_dir) - crank * ca.sin(crank_angle)
    dist2 = dx * dx + dy * dy
    k = (coupler * coupler - dist2 - rocker * rocker) / (2 * rocker)
    phi_d = ca.atan2(dy, dx)
    # the branch sign is piecewise constant (zero derivative), so the
    # Jacobian stays that of the smooth branch
    branch = ca.sign(ca.sin(crank_angle - phi_d))
    return phi_d + branch * ca.acos(k / ca.sqrt(dist2))


def chain_angles(robot: Robot, q, geom: Geometry) -> list:
    """Joint angles used in the chain, before offsets: coupling and loop applied."""
    angles = []
    for i, j in enumerate(robot.joints):
        if j.coupling is not None:
            angles.append(sum(float(c) * q[k] for k, c in enumerate(j.coupling) if c != 0)
                          + j.coupling_offset)
        else:
            angles.append(q[i])
    if robot.loop is not None:
        i = robot.loop.joint - 1
        link_dir = q[i - 1] + geom.theta[i - 1]
        # distance between the two loop axes: MDH keeps it in row i, DH in row i-1
        ground = geom.a[i] if robot.convention == "mdh" else geom.a[i - 1]
        psi = fourbar_rocker_angle(link_dir, q[i], ground, *geom.loop)
        angles[i] = psi - link_dir + robot.joints[i].coupling_offset
    return angles


@dataclass
class Frames:
    """Per-joint frames of one configuration, robot base frame."""

    axis: list   # z axis of joint i (3x1)
    origin: list  # a point on joint i's axis
    link: list   # pose of link frame i
    tool: Pose   # pose of the tool frame (orientation of link n, origin at the tool point)


def forward(robot: Robot, angles: list, geom: Geometry) -> Frames:
    """Chain of link transforms for the given chain angles (theta offsets added here).

    The chain is built once per convention and joint count as a CasADi
    Function of the angles and the geometry (:func:`_chain_function`) and
    called on the given expressions: the same expression graph as building
    it term by term, three times faster to make (a model builds two chains).
    """
    n = robot.n
    carriage = tuple(sorted(geom.carriage))
    F = _chain_function(robot.convention, n, bool(geom.links), robot.prismatic if any(robot.prismatic) else (),
                        carriage)

    def column(values) -> ca.SX:
        return ca.vertcat(*[v if isinstance(v, ca.SX) else ca.SX(v) for v in values]) if len(values) else ca.SX(0, 1)

    args = [column(angles), *(column(getattr(geom, k)) for k in _CHAIN_GEOMETRY), column(geom.tool)]
    if geom.links:      # the link frames' changes, 6 numbers a joint (0 where none)
        args.append(column([v for i in range(1, n + 1) for v in geom.links.get(i, [0.0] * 6)]))
    if carriage:        # the carriages' changes, 6 numbers a joint that has one
        args.append(column([v for i in carriage for v in geom.carriage[i]]))
    out = F.call(args)[0]
    axes, origins, links = [], [], []
    for i in range(n):
        k = 18 * i
        axes.append(out[k:k + 3])
        origins.append(out[k + 3:k + 6])
        links.append((ca.reshape(out[k + 6:k + 15], 3, 3), out[k + 15:k + 18]))
    k = 18 * n
    return Frames(axes, origins, links, (ca.reshape(out[k:k + 9], 3, 3), out[k + 9:k + 12]))


_CHAIN_GEOMETRY = ("alpha", "a", "beta", "b", "d", "theta")


def small_pose(dx, dy, dz, rx, ry, rz) -> Pose:
    """Tx(dx) Ty(dy) Tz(dz) Rz(rz) Ry(ry) Rx(rx): a user term's change of a frame."""
    return compose(trans(dx, dy, dz), rotz(rz), roty(ry), rotx(rx))


@functools.lru_cache(maxsize=None)
def _chain_function(convention: str, n: int, links: bool = False, prismatic: tuple = (), carriage: tuple = ()
                    ) -> ca.Function:
    """The chain of :func:`forward` as a Function of (angles, alpha, a, beta, b, d, theta, tool) (and, with
    ``links``, of each link frame's change, 6 numbers a joint, after the tool; with ``carriage``, the 1-based
    joints whose carriage is off its travel, 6 numbers each, last).

    ``prismatic``: per joint, a linear axis (empty: none); its "angle" is its reading (m), added to ``d``, and
    its ``theta`` is the constant turn about z.

    Output: one column holding, per joint, its axis, a point on it and its
    link pose (R column-major, t), then the tool pose.
    """
    angles = ca.SX.sym("angles", n)
    geo = {k: ca.SX.sym(k, n) for k in _CHAIN_GEOMETRY}
    tool = ca.SX.sym("tool", 3)
    change = ca.SX.sym("links", 6 * n) if links else None
    off = ca.SX.sym("carriage", 6 * len(carriage)) if carriage else None
    slide = {j: small_pose(*(off[6 * k + i] for i in range(6))) for k, j in enumerate(carriage)}
    pose: Pose = (ca.SX.eye(3), ca.SX.zeros(3, 1))
    out = []
    for i in range(n):
        alpha, a, beta, b, d = (geo[k][i] for k in ("alpha", "a", "beta", "b", "d"))
        if prismatic and prismatic[i]:
            th, d = geo["theta"][i], d + angles[i]
        else:
            th = angles[i] + geo["theta"][i]
        if convention == "mdh":
            pre = compose(pose, rotx(alpha), trans(a), roty(beta), trans(0, b))
            axis, origin = pre[0][:, 2], pre[1]
            pose = compose(pre, rotz(th), trans(0, 0, d))
            if i + 1 in slide:
                pose = compose(pose, slide[i + 1])
        else:
            axis, origin = pose[0][:, 2], pose[1]
            pose = compose(pose, rotz(th), trans(0, 0, d))
            if i + 1 in slide:
                pose = compose(pose, slide[i + 1])
            pose = compose(pose, trans(a), rotx(alpha), roty(beta), trans(0, b))
        if links:
            pose = compose(pose, small_pose(*(change[6 * i + k] for k in range(6))))
        out += [axis, origin, ca.vec(pose[0]), pose[1]]
    end = compose(pose, trans(tool[0], tool[1], tool[2]))
    out += [ca.vec(end[0]), end[1]]
    kinds = "_" + "".join("P" if p else "R" for p in prismatic) if prismatic else ""
    slides = "_carriage" + "_".join(map(str, carriage)) if carriage else ""
    return ca.Function(f"chain_{convention}_{n}" + ("_links" if links else "") + kinds + slides,
                       [angles, *geo.values(), tool] + ([change] if links else []) + ([off] if carriage else []),
                       [ca.vertcat(*out)])


def gravity_torques(robot: Robot, frames: Frames, payload_mass) -> list:
    """Torque of gravity about each joint axis (N m), robot base frame.

    tau_i = z_i . sum_{j >= i} (c_j - o_i) x (m_j g), with the payload at the
    tool frame counted with every joint. A prismatic joint's is the force of
    gravity along its axis (N): z_i . sum_{j >= i} m_j g.
    """
    g = ca.DM(robot.gravity)
    weights = []  # (centre of mass, force)
    for i, j in enumerate(robot.joints):
        R, t = frames.link[i]
        weights.append((t + ca.mtimes(R, ca.DM(j.com)), j.mass * g))
    R, t = frames.tool
    weights.append((t + ca.mtimes(R, ca.DM(robot.payload_com)), payload_mass * g))
    taus = []
    for i in range(robot.n):
        moment = ca.SX.zeros(3, 1)
        for k in range(i, robot.n + 1):
            c, f = weights[k]
            moment = moment + (f if robot.joints[i].prismatic else ca.cross(c - frames.origin[i], f))
        taus.append(ca.dot(frames.axis[i], moment))
    return taus


def mount_moment(robot: Robot, frames: Frames, payload_mass):
    """Moment of the weights of every link and the payload about the robot base frame's origin (N m, 3x1, robot
    base frame): ``sum_j c_j x (m_j g)``, the payload at the tool frame (what tilts a compliant mount)."""
    g = ca.DM(robot.gravity)
    moment = ca.SX.zeros(3, 1)
    for i, j in enumerate(robot.joints):
        R, t = frames.link[i]
        moment = moment + ca.cross(t + ca.mtimes(R, ca.DM(j.com)), j.mass * g)
    R, t = frames.tool
    return moment + ca.cross(t + ca.mtimes(R, ca.DM(robot.payload_com)), payload_mass * g)


def small_rotation(theta):
    """The rotation by the rotation vector ``theta`` (3x1, rad) for angles well below 0.1 rad: Rodrigues'
    ``I + a K + b K^2`` with ``a = sin|t| / |t|``, ``b = (1 - cos|t|) / |t|^2`` by their series (``1 - t^2 / 6``,
    ``1/2 - t^2 / 24``: 1e-14 off at 0.01 rad), smooth at zero where the closed form is not."""
    K = ca.skew(theta)
    t2 = ca.dot(theta, theta)
    return ca.SX.eye(3) + (1 - t2 / 6) * K + (0.5 - t2 / 24) * ca.mtimes(K, K)


def coupled(robot: Robot) -> bool:
    """True if a chain angle is made of other joints' readings too (a coupling or a loop)."""
    return robot.loop is not None or any(j.coupling is not None for j in robot.joints)


def drive_torques(robot: Robot, q, geom: Geometry, taus: list) -> list:
    """The torque each joint's drive carries: ``J^T tau`` with ``J`` = d chain angles / d readings (virtual work).

    Without couplings and loops ``J`` is the identity and the drives carry the torques about the joint axes.
    A parallelogram's drives share them: the crank's (joint 3 of the HH800) carries joint 3's torque,
    joint 2's drive ``tau2 - tau3``. ``q`` must be the readings' symbol.
    """
    if not coupled(robot):
        return taus
    J = ca.jacobian(ca.vertcat(*chain_angles(robot, q, geom)), q)
    out = ca.densify(ca.mtimes(J.T, ca.vertcat(*taus)))   # a reading that drives nothing carries an explicit 0
    return [out[i] for i in range(robot.n)]


def base_pose_matrix(xyz, rpy) -> np.ndarray:
    """Numeric 4x4 pose from translation and fixed-axis roll-pitch-yaw (radians)."""
    return pose_matrix(rpy_pose(*xyz, *rpy))


def pose_matrix(pose) -> np.ndarray:
    """Numeric 4x4 matrix of a pose ``(R, t)`` whose entries are constant CasADi expressions."""
    R, t = pose
    T = np.eye(4)
    T[:3, :3] = np.array(ca.evalf(ca.SX(R)))
    T[:3, 3] = np.array(ca.evalf(ca.SX(t))).ravel()
    return T


def matrix_to_rpy(R: np.ndarray) -> np.ndarray:
    """Fixed-axis roll-pitch-yaw (radians) of a rotation matrix, R = Rz Ry Rx.

    Yaw is taken from what roll and pitch leave, so the angles rebuild R to
    rounding error also at and near pitch = +-90 deg (gimbal lock), where
    roll and yaw alone are ill-determined.
    """
    R = np.asarray(R, dtype=float)
    pitch = np.arctan2(-R[2, 0], np.hypot(R[2, 1], R[2, 2]))
    roll = np.arctan2(R[2, 1], R[2, 2])
    cr, sr, cp, sp = np.cos(roll), np.sin(roll), np.cos(pitch), np.sin(pitch)
    # Rz(yaw) = R Rx(roll)^T Ry(pitch)^T: first column of that product
    m00 = R[0, 0] * cp + (R[0, 1] * sr + R[0, 2] * cr) * sp
    m10 = R[1, 0] * cp + (R[1, 1] * sr + R[1, 2] * cr) * sp
    yaw = np.arctan2(m10, m00)
    return np.array([roll, pitch, yaw])
