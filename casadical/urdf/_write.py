"""Write a calibrated (or nominal) geometry as URDF.

The file has a root link ``world`` (gravity along its -z), the robot base
``base_link``, one link per joint, ``tool_point`` at the measured point and
``measurement_frame``, the frame the points were measured in (the
calibrated base pose). At joint readings q, the transform from
``measurement_frame`` to ``tool_point`` is casadical's geometric model of
the measured point (and, for a full-pose calibration, its axes are the
probe's: the mounting rotation is in ``tool_joint``); joint angles are the
readings themselves (the constant offsets theta sit in the joint origins).

The XML is built with the standard library's ElementTree: yourdfpy reads
URDF well but its writer drops ``<mimic>`` and comments.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from typing import TYPE_CHECKING

import numpy as np

from .. import __version__
from ..errors import ModelError
from ..kinematics import Geometry, base_pose_matrix, forward, matrix_to_rpy, pose_matrix
from ..robot import Robot
from ..terms import Context, make_term

if TYPE_CHECKING:
    from ..result import CalibrationResult

#: What a URDF cannot describe, and an exported file therefore does not contain.
NOT_IN_URDF = ("joint compliance (stiffness)", "periodic gear errors", "encoder scale errors", "backlash",
               "thermal expansion", "drift of the measurement frame", "the payload",
               "closed loops and couplings other than <mimic>")


def robot_to_urdf(source: "CalibrationResult | Robot", description: str | None = None) -> str:
    """URDF text of a calibration's geometric model (or of a robot's nominal one).

    Parameters
    ----------
    source : CalibrationResult or Robot
        A calibration: the identified link parameters, base pose and tool;
        a robot: its nominal values.
    description : str, optional
        What the geometry is, for the file's comment (default: the
        calibration's model and the terms the file leaves out); see
        :func:`casadical.apply._export_geometry.geometric_equivalent` for a model with
        terms a URDF cannot carry.

    Returns
    -------
    str
        URDF whose ``tool_point`` link, seen from ``measurement_frame`` at
        joint angles q, is where the geometric model puts the measured point
        (oriented as the probe, for a calibration with measured orientations).
        Link masses and centres of mass are written as inertials.

    Raises
    ------
    ModelError
        The robot has a four-bar loop, or a coupling that is not one joint
        following another (URDF's ``<mimic>``).
    """
    robot, geom, base, model = _geometry(source)
    model = description or model
    n = robot.n
    if robot.loop is not None:
        raise ModelError(f"{robot.name}: the four-bar loop driving joint {robot.loop.joint} cannot be written "
                         "as URDF (URDF describes trees; only a coupling of one joint to another becomes <mimic>)")
    mimics = [_mimic(robot, i) for i in range(n)]

    frames = forward(robot, [0.0] * n, geom)
    links = [pose_matrix(p) for p in frames.link]
    tool = pose_matrix(frames.tool)
    if not isinstance(source, Robot) and source.has_orientation:
        tool[:3, :3] = tool[:3, :3] @ source.tool_rotation()    # tool_point's axes are the probe's
    # the frame each joint turns (or, prismatic, slides along z): its link frame before the turn
    turn = []
    for i in range(n):
        if robot.convention == "mdh":
            turn.append(links[i] @ _tz(-geom.d[i]))
        else:
            turn.append((links[i - 1] if i else np.eye(4)) @ _rz(geom.theta[i]))

    root = ET.Element("robot", name=robot.name)
    sessions = [] if isinstance(source, Robot) else source.sessions
    root.append(ET.Comment(_comment(robot, model, sessions)))
    down = robot.gravity / np.linalg.norm(robot.gravity)
    _link(root, "world")
    _link(root, "base_link")
    _joint(root, "base_joint", "fixed", "world", "base_link", _upright(down))
    _link(root, "measurement_frame")
    _joint(root, "measurement_joint", "fixed", "base_link", "measurement_frame", np.linalg.inv(base))
    parent, parent_T = "base_link", np.eye(4)
    for i, j in enumerate(robot.joints):
        name = f"link_{i + 1}"
        com = np.linalg.solve(turn[i], links[i] @ np.append(j.com, 1.0))[:3]
        _link(root, name, j.mass, com)
        # a prismatic joint slides along the same z its MDH/DH row's d lies on: the same joint frame
        el = _joint(root, f"joint_{i + 1}", j.kind, parent, name, np.linalg.solve(parent_T, turn[i]),
                    axis=True)
        ET.SubElement(el, "limit", lower=_num(j.min), upper=_num(j.max), effort="0", velocity="0")
        if mimics[i] is not None:
            ET.SubElement(el, "mimic", joint=f"joint_{mimics[i][0] + 1}", multiplier=_num(mimics[i][1]),
                          offset=_num(j.coupling_offset))
        parent, parent_T = name, turn[i]
    _link(root, "tool_point")
    _joint(root, "tool_joint", "fixed", parent, "tool_point", np.linalg.solve(parent_T, tool))
    ET.indent(root)
    return ET.tostring(root, encoding="unicode", xml_declaration=True) + "\n"


def _geometry(source) -> tuple[Robot, Geometry, np.ndarray, str]:
    """Robot, numeric geometry, base pose (4x4, measurement frame) and a model description."""
    if isinstance(source, Robot):
        return (source, Geometry.nominal(source), base_pose_matrix(source.base_xyz, source.base_rpy),
                "nominal values of the robot file")
    robot = source.model.robot
    values = dict(zip(source.parameters.names, source.parameters.values.tolist()))
    geom = make_term("geometric").geometry(Context(robot, None, values, {}), Geometry.nominal(robot))
    base = source.base_matrix()
    left_out = ", ".join(t.spec() for t in source.model.terms[1:]) or "none"
    return robot, geom, base, f"calibration, model {source.model.spec}; terms left out: {left_out}"


def _mimic(robot: Robot, i: int) -> tuple[int, float] | None:
    """(followed joint index, multiplier) of a coupled joint; None if not coupled."""
    row = robot.joints[i].coupling
    if row is None:
        return None
    nz = np.flatnonzero(row)
    if len(nz) != 1 or nz[0] == i or robot.joints[nz[0]].coupling is not None:
        raise ModelError(f"{robot.name}: the coupling of joint {i + 1} ({[float(c) for c in row]}) cannot be "
                         "written as URDF: <mimic> makes a joint follow one other, uncoupled joint")
    return int(nz[0]), float(row[nz[0]])


def _comment(robot: Robot, model: str, sessions: list[str]) -> str:
    where = (f"  'measurement_frame' is the measurement frame of session {sessions[0]}, the calibration's first of "
             f"{', '.join(sessions)}\n  (every session's base pose is in the parameter table).\n" if sessions else "")
    return (f"\n  {robot.name}: geometric model written by casadical {__version__} ({model}).\n"
            + ("  At joint readings q (radians, metres for a prismatic joint; the constant offsets theta are in\n"
               "  the joint origins), link" if any(robot.prismatic) else
               "  At joint readings q (radians; the constant offsets theta are in the joint origins), link") + "\n"
            "  'tool_point' seen from 'measurement_frame' is the measured point (its axes the probe's, for a\n"
            "  full-pose calibration); 'world' has gravity along -z.\n" + where +
            "  A URDF cannot carry, so this file does not contain: " + ", ".join(NOT_IN_URDF) + ".\n"
            "  Inertia tensors, effort and velocity limits are unknown to casadical and written as 0.\n")


def _link(root: ET.Element, name: str, mass: float = 0.0, com: np.ndarray | None = None) -> None:
    el = ET.SubElement(root, "link", name=name)
    if mass > 0:
        inertial = ET.SubElement(el, "inertial")
        ET.SubElement(inertial, "origin", xyz=" ".join(_num(x) for x in com), rpy="0 0 0")
        ET.SubElement(inertial, "mass", value=_num(mass))
        ET.SubElement(inertial, "inertia", ixx="0", ixy="0", ixz="0", iyy="0", iyz="0", izz="0")


def _joint(root: ET.Element, name: str, kind: str, parent: str, child: str, T: np.ndarray,
           axis: bool = False) -> ET.Element:
    el = ET.SubElement(root, "joint", name=name, type=kind)
    ET.SubElement(el, "parent", link=parent)
    ET.SubElement(el, "child", link=child)
    ET.SubElement(el, "origin", xyz=" ".join(_num(x) for x in T[:3, 3]),
                  rpy=" ".join(_num(x) for x in matrix_to_rpy(T[:3, :3])))
    if axis:
        ET.SubElement(el, "axis", xyz="0 0 1")
    return el


def _upright(down: np.ndarray) -> np.ndarray:
    """Pose of the robot base in a frame whose -z is the gravity direction ``down`` (base frame)."""
    T = np.eye(4)
    if down @ np.array([0.0, 0.0, -1.0]) < 1.0 - 1e-15:
        from scipy.spatial.transform import Rotation
        T[:3, :3] = Rotation.align_vectors([[0.0, 0.0, -1.0]], [down])[0].as_matrix()
    return T


def _tz(d: float) -> np.ndarray:
    T = np.eye(4)
    T[2, 3] = d
    return T


def _rz(x: float) -> np.ndarray:
    T = np.eye(4)
    T[:2, :2] = [[math.cos(x), -math.sin(x)], [math.sin(x), math.cos(x)]]
    return T


def _num(x: float) -> str:
    """Every digit of a float (URDF numbers are read back exactly)."""
    return repr(float(x))
