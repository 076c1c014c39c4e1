"""Read a URDF robot description as a casadical :class:`~casadical.robot.Robot`.

lxml parses the XML; this module reads what casadical uses of it (links
and their inertials, joints: type, parent, child, origin as a 4x4 matrix,
axis, limits, mimic tags) as yourdfpy reads them (the tests compare the
forward kinematics with yourdfpy's), without importing it: yourdfpy loads
trimesh and scipy, about a second and a half of every command's start on
a small machine, for meshes casadical never reads. It checks the tree, takes
the serial chain from the base link to the tip link, and converts the
joint axis lines (all joint angles zero) to modified DH parameters:

- frame i has its z axis on joint i's axis line, its x axis along the
  common normal to the next axis and its origin at the foot of that normal
  (Craig); frame 0 is the base link frame turned about and shifted along
  its z axis so that it fits this rule too (its pose is the robot's
  ``[base]``);
- where two consecutive axes are parallel or within ``PARALLEL_TOL_DEG``
  of it, the common normal is ill-conditioned: the link then carries
  Hayati's ``beta`` and its frame's x axis points to where the next axis
  pierces the frame's x-y plane (d = 0 on the previous frame);
- the last frame's origin is the tip link origin projected on the last
  axis, its x axis the tip's x (or y) axis projected on the normal plane.

Every frame is fixed by the axis lines, so the chain of link transforms
reproduces the URDF's forward kinematics exactly (to rounding).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import RobotFileError
from ..kinematics import matrix_to_rpy
from ..robot import GRAVITY, PRISMATIC, REVOLUTE, Joint, Robot

#: Consecutive axes closer to parallel than this (deg) get Hayati's beta. It
#: equals the geometric term's angle box, so an exported calibration of a
#: nominally parallel pair is read back with beta again.
PARALLEL_TOL_DEG = 5.0
_EPS = 1e-9  # m: parallel axes closer than this are coaxial (the x axis is kept from the frame before)
_REVOLUTE = ("revolute", "continuous")
#: the joints of the chain: revolute ones and linear axes (a prismatic joint: its reading a length along its axis)
_MOVABLE = _REVOLUTE + ("prismatic",)
_TYPES = ("revolute", "continuous", "prismatic", "fixed", "floating", "planar")
_PARSE_ERRORS = (KeyError, AttributeError, ValueError, TypeError, IndexError)


#: lengths (m) and masses (kg) beyond these are unit mistakes (as for a robot TOML's keys, casadical.robot)
MAX_LENGTH_M = 100.0
MAX_MASS_KG = 1e5


def robot_from_urdf(path: str | Path, tip: str | None = None, base: str | None = None,
                    tool: tuple[float, float, float] | None = None) -> Robot:
    """Read the serial chain of a URDF file as a robot (modified DH).

    Parameters
    ----------
    path : str or Path
    tip : str, optional
        Link whose origin is the measured point. Default: the one leaf below
        ``base`` reached through the most revolute/continuous joints.
    base : str, optional
        Link the robot stands on; positions are in its frame. Default: the
        root link.
    tool : sequence of 3 floats, optional
        Measured point in the tip link frame (m); default its origin.

    Returns
    -------
    Robot
        MDH, one joint per revolute, continuous or prismatic joint of the chain
        (fixed joints folded in; a prismatic joint is a linear axis, its reading
        added to d). Limits from ``<limit>`` (continuous: +-180 deg);
        each link's mass and centre of mass merged from every URDF link
        that moves with it; gravity along -z of the root link; a ``<mimic>``
        joint becomes a coupling row on the joint it follows.

    Raises
    ------
    RobotFileError
        Not XML, not a URDF, a loop, no revolute joint, an unknown or
        branching tip, a planar or floating joint on the chain, an axis of zero
        length, non-finite numbers, a mimic casadical cannot couple: one
        line naming the file, the line and the element.
    """
    path = str(path)
    doc = _Document.parse(path)
    tree = _Tree.build(doc)
    base = tree.root() if base is None else tree.link(base, "base")
    tip = tree.default_tip(base) if tip is None else tree.link(tip, "tip")
    chain = tree.chain(base, tip)
    movable = [j for j in chain if j.type in _MOVABLE]
    index = {j.name: i for i, j in enumerate(movable)}
    n = len(movable)

    poses = tree.zero_poses(base)   # every link below base, base frame, joint angles zero
    lines = []
    for j in movable:
        T = poses[j.child]
        lines.append((T[:3, 3], T[:3, :3] @ (j.axis / np.linalg.norm(j.axis))))
    T_tip = poses[tip]
    point = T_tip[:3, 3] if tool is None else T_tip[:3, :3] @ np.asarray(tool, dtype=float) + T_tip[:3, 3]
    frames, hayati = mdh_frames(lines, T_tip)
    links = [decompose(np.linalg.solve(frames[i], frames[i + 1]), hayati[i + 1]) for i in range(n)]

    mass, moment = np.zeros(n + 1), np.zeros((n + 1, 3))
    for name, group in tree.groups(base, {j.name for j in movable}).items():
        inertial = doc.links[name].inertial
        if group == 0 or inertial is None or not inertial.mass:
            continue
        com = poses[name] @ (inertial.origin if inertial.origin is not None else np.eye(4))
        mass[group] += inertial.mass
        moment[group] += inertial.mass * com[:3, 3]

    joints = []
    for i, j in enumerate(movable):
        alpha, a, beta, theta, d = links[i]
        lo, hi = doc.limits(j)
        com = np.zeros(3)
        if mass[i + 1] > 0:
            com = _transform(np.linalg.inv(frames[i + 1]), moment[i + 1] / mass[i + 1])
        coupling, offset = doc.coupling(j, index, n)
        joints.append(Joint(alpha=alpha, a=a, d=d, theta=theta, beta=beta, min=lo, max=hi,
                            mass=float(mass[i + 1]), com=com, coupling=coupling, coupling_offset=offset,
                            kind=PRISMATIC if j.type == "prismatic" else REVOLUTE))
    # gravity: -z of the URDF root, in frame 0
    root_to_base = tree.zero_poses(tree.top(base))[base][:3, :3]
    down = frames[0][:3, :3].T @ root_to_base.T @ np.array([0.0, 0.0, -1.0])
    return Robot(name=doc.name, joints=joints, convention="mdh", base_xyz=frames[0][:3, 3].copy(),
                 base_rpy=matrix_to_rpy(frames[0][:3, :3]),
                 tool=_transform(np.linalg.inv(frames[n]), point), gravity=GRAVITY * down, source=path)


# --- axis lines -> modified DH -------------------------------------------------------


def mdh_frames(lines: list[tuple[np.ndarray, np.ndarray]], tip: np.ndarray) -> tuple[list[np.ndarray], list[bool]]:
    """MDH frames 0..n (4x4, base frame) of joint axis lines (point, unit direction).

    Line 0 is the base z axis. ``hayati[i]`` is True where line i-1 and line
    i are within ``PARALLEL_TOL_DEG`` of parallel (link i then needs beta).
    """
    n = len(lines)
    points = [np.zeros(3)] + [p for p, _ in lines]
    dirs = [np.array([0.0, 0.0, 1.0])] + [z for _, z in lines]
    frames, hayati = [], [False] * (n + 1)
    arrival = np.zeros(3)            # where the previous x axis meets the current line
    x_prev = np.array([1.0, 0.0, 0.0])
    cos_tol = math.cos(math.radians(PARALLEL_TOL_DEG))
    for k in range(n):
        p, z, p2, z2 = points[k], dirs[k], points[k + 1], dirs[k + 1]
        if abs(z @ z2) >= cos_tol:
            # Hayati: x towards the point where the next axis pierces this frame's x-y plane
            origin = arrival
            arrival = p2 + ((origin - p2) @ z) / (z2 @ z) * z2
            x = arrival - origin if np.linalg.norm(arrival - origin) > _EPS else x_prev
            hayati[k + 1] = True
        else:
            # Craig: the common normal, from its foot on this axis
            w, b = p - p2, z @ z2
            s = (b * (z2 @ w) - z @ w) / (1 - b * b)
            t = ((z2 @ w) - b * (z @ w)) / (1 - b * b)
            origin, arrival = p + s * z, p2 + t * z2
            x = np.cross(z, z2)
            if x @ (arrival - origin) < 0:
                x = -x      # a >= 0
        frames.append(_frame(origin, z, x))
        x_prev = frames[-1][:3, 0]
    p, z = points[n], dirs[n]
    xt = tip[:3, 0] - (tip[:3, 0] @ z) * z
    frames.append(_frame(p + ((tip[:3, 3] - p) @ z) * z, z, xt if xt @ xt >= 0.5 else tip[:3, 1]))
    return frames, hayati


def decompose(T: np.ndarray, with_beta: bool) -> tuple[float, float, float | None, float, float]:
    """(alpha, a, beta, theta, d) with T = Rx(alpha) Tx(a) Ry(beta) Rz(theta) Tz(d); beta None if unused."""
    R, t = T[:3, :3], T[:3, 3]
    beta = math.asin(float(np.clip(R[0, 2], -1.0, 1.0)))
    alpha = math.atan2(-R[1, 2], R[2, 2])
    theta = math.atan2(-R[0, 1], R[0, 0])
    u = R[:, 2]
    d = (t[1] * u[1] + t[2] * u[2]) / (u[1] ** 2 + u[2] ** 2)
    a = t[0] - d * u[0]
    return alpha, float(a), (beta if with_beta else None), theta, float(d)


def _frame(origin: np.ndarray, z: np.ndarray, x: np.ndarray) -> np.ndarray:
    x = x - (x @ z) * z
    x = x / np.linalg.norm(x)
    T = np.eye(4)
    T[:3, 0], T[:3, 1], T[:3, 2], T[:3, 3] = x, np.cross(z, x), z, origin
    return T


def _transform(T: np.ndarray, point: np.ndarray) -> np.ndarray:
    return T[:3, :3] @ point + T[:3, 3]


# --- the document and its tree --------------------------------------------------------


@dataclass
class _Document:
    """A URDF's links and joints, with the source line of every element for error messages."""

    path: str
    name: str
    links: dict[str, "_Link"]
    joints: list["_Joint"]
    lines: dict[tuple[str, str], int] = field(default_factory=dict)

    @classmethod
    def parse(cls, path: str) -> "_Document":
        from lxml import etree

        try:
            data = Path(path).read_bytes()
        except OSError as e:
            raise RobotFileError(f"cannot read: {e.strerror}", file=path) from e
        try:
            root = etree.fromstring(data)
        except etree.XMLSyntaxError as e:
            raise RobotFileError(f"not valid XML: {e.msg}", file=path, row=e.lineno) from e
        if root.tag != "robot":
            raise RobotFileError(f"the top element is <{root.tag}>, a URDF's is <robot>", file=path,
                                 row=root.sourceline)

        elements = [el for el in root if isinstance(el.tag, str)]
        if "name" not in root.attrib:
            raise RobotFileError(f"<robot>: {_why(KeyError('name'))}", file=path, row=root.sourceline)
        links, joints = [], []
        for el in elements:
            try:
                if el.tag == "link":
                    links.append(_read_link(el))
                elif el.tag == "joint":
                    joints.append(_read_joint(el))
            except _PARSE_ERRORS as e:
                raise RobotFileError(f"<{el.tag} name={el.get('name')!r}>: {_why(e)}", file=path,
                                     row=el.sourceline) from e
        doc = cls(path, root.attrib["name"], {}, joints,
                  {(el.tag, el.get("name")): el.sourceline for el in elements})
        for link in links:
            if link.name in doc.links:
                raise doc.error("link", link.name, "is defined twice")
            doc.links[link.name] = link
            doc.check_inertial(link)
        for j in joints:
            doc.check_joint(j)
        return doc

    def error(self, kind: str, name: str, message: str) -> RobotFileError:
        return RobotFileError(f"{kind} {name!r}: {message}", file=self.path, row=self.lines.get((kind, name)))

    def check_inertial(self, link) -> None:
        inertial = link.inertial
        if inertial is None:
            return
        if inertial.mass is not None and not (math.isfinite(inertial.mass) and inertial.mass >= 0):
            raise self.error("link", link.name, f"<inertial> mass must be a finite number >= 0, got {inertial.mass}")
        if inertial.origin is not None and not np.isfinite(inertial.origin).all():
            raise self.error("link", link.name, "<inertial> <origin> has a non-finite number")
        if inertial.mass is not None and inertial.mass > MAX_MASS_KG:
            raise self.error("link", link.name, f"<inertial> mass {inertial.mass:g} kg is beyond {MAX_MASS_KG:g} kg: "
                                                "masses in a URDF are kg")
        if inertial.origin is not None:
            self._check_length(inertial.origin, "link", link.name, "<inertial> <origin>")

    def _check_length(self, T: np.ndarray, kind: str, name: str, what: str) -> None:
        far = float(np.abs(T[:3, 3]).max())
        if far > MAX_LENGTH_M:
            raise self.error(kind, name, f"{what} xyz has {far:g} m, beyond +-{MAX_LENGTH_M:g} m: lengths in a URDF "
                                         "are metres (a unit mistake?)")

    def check_joint(self, j) -> None:
        if j.type not in _TYPES:
            raise self.error("joint", j.name, f"unknown type {j.type!r} (URDF types: {', '.join(_TYPES)})")
        if j.origin is not None and not np.isfinite(j.origin).all():
            raise self.error("joint", j.name, "<origin> has a non-finite number")
        if j.origin is not None:
            self._check_length(j.origin, "joint", j.name, "<origin>")
        if j.type != "fixed":
            if not np.isfinite(j.axis).all():
                raise self.error("joint", j.name, f"<axis> has a non-finite number: {j.axis.tolist()}")
            if np.linalg.norm(j.axis) < 1e-12:
                raise self.error("joint", j.name, "<axis> has zero length")
        numbers = []
        if j.limit is not None:
            numbers += [x for x in (j.limit.lower, j.limit.upper) if x is not None]
        if j.mimic is not None:
            numbers += [j.mimic.multiplier, j.mimic.offset]
        if not all(math.isfinite(x) for x in numbers):
            raise self.error("joint", j.name, "<limit> or <mimic> has a non-finite number")

    def limits(self, j) -> tuple[float, float]:
        """Joint limits (rad); a continuous joint turns freely: +-180 deg covers every angle once."""
        if j.type == "continuous":
            return -math.pi, math.pi
        lim = j.limit
        if lim is None or lim.lower is None or lim.upper is None:
            raise self.error("joint", j.name, f"a {j.type} joint needs <limit lower=... upper=...> "
                             + ("(metres)" if j.type == "prismatic" else "(radians)"))
        if not lim.lower < lim.upper:
            raise self.error("joint", j.name, f"lower limit {lim.lower} must be below upper limit {lim.upper}")
        return float(lim.lower), float(lim.upper)

    def coupling(self, j, index: dict[str, int], n: int) -> tuple[np.ndarray | None, float]:
        """Coupling row and offset (rad) of a ``<mimic>`` joint: theta = multiplier * q_followed + offset."""
        if j.mimic is None:
            return None, 0.0
        followed = j.mimic.joint
        linear = [x for x in (j.name, followed) if any(k.name == x and k.type == "prismatic" for k in self.joints)]
        if linear:
            raise self.error("joint", j.name, f"<mimic> couples {linear[0]!r}, a prismatic joint; casadical couples "
                             "revolute joints only")
        if followed not in index:
            raise self.error("joint", j.name, f"<mimic> follows {followed!r}, which is not a revolute joint "
                             "of the chain; casadical couples joints of the chain only")
        if self.joint(followed).mimic is not None:
            raise self.error("joint", j.name, f"<mimic> follows {followed!r}, which follows another joint "
                             "itself; mimic joints must follow an actuated joint")
        row = np.zeros(n)
        row[index[followed]] = j.mimic.multiplier
        return row, float(j.mimic.offset)

    def joint(self, name: str):
        return next(j for j in self.joints if j.name == name)


@dataclass
class _Tree:
    """Links and joints as a tree: parent joint of each link, child joints of each link."""

    doc: _Document
    parent: dict[str, "_Joint"]
    children: dict[str, list]

    @classmethod
    def build(cls, doc: _Document) -> "_Tree":
        parent: dict[str, _Joint] = {}
        children: dict[str, list] = {name: [] for name in doc.links}
        seen = set()
        for j in doc.joints:
            if j.name in seen:
                raise doc.error("joint", j.name, "is defined twice")
            seen.add(j.name)
            for role, link in (("parent", j.parent), ("child", j.child)):
                if link not in doc.links:
                    raise doc.error("joint", j.name, f"its {role} link {link!r} is not defined")
            if j.child in parent:
                raise doc.error("joint", j.name, f"link {j.child!r} is already the child of joint "
                                f"{parent[j.child].name!r}: a closed loop (casadical reads serial chains)")
            parent[j.child] = j
            children[j.parent].append(j)
        if not doc.links:
            raise RobotFileError("has no <link>", file=doc.path)
        tree = cls(doc, parent, children)
        for name in doc.links:
            tree.top(name)      # raises on a loop
        return tree

    def link(self, name: str, role: str) -> str:
        if name not in self.doc.links:
            raise RobotFileError(f"no link named {name!r} (the {role} link); links: "
                                 f"{', '.join(sorted(self.doc.links))}", file=self.doc.path)
        return name

    def top(self, link: str) -> str:
        """The root above ``link``."""
        path = [link]
        while link in self.parent:
            link = self.parent[link].parent
            if link in path:
                loop = path[path.index(link):]
                raise self.doc.error("joint", self.parent[loop[0]].name, "its links form a closed loop: "
                                     + " -> ".join(reversed(loop)))
            path.append(link)
        return link

    def root(self) -> str:
        roots = sorted(name for name in self.doc.links if name not in self.parent)
        if len(roots) > 1:
            raise RobotFileError(f"links {', '.join(roots)} have no parent joint: not one tree (name the "
                                 "base link)", file=self.doc.path)
        return roots[0]

    def default_tip(self, base: str) -> str:
        """The one leaf below ``base`` reached through the most revolute joints."""
        leaves, stack = [], [(base, 0)]
        while stack:
            link, k = stack.pop()
            if not self.children[link]:
                leaves.append((link, k))
            stack += [(j.child, k + (j.type in _REVOLUTE)) for j in self.children[link]]
        most = max(k for _, k in leaves)
        if most == 0:
            raise RobotFileError(f"no revolute or continuous joint below link {base!r}", file=self.doc.path)
        tips = sorted(link for link, k in leaves if k == most)
        if len(tips) > 1:
            raise RobotFileError(f"the chain branches: leaves {', '.join(tips)} all follow {most} revolute "
                                 "joints; name the tip link", file=self.doc.path)
        return tips[0]

    def chain(self, base: str, tip: str) -> list:
        """Joints from ``base`` down to ``tip``, each revolute, continuous, prismatic or fixed."""
        chain, link = [], tip
        while link != base:
            if link not in self.parent:
                raise RobotFileError(f"link {tip!r} is not below link {base!r}", file=self.doc.path)
            chain.append(self.parent[link])
            link = self.parent[link].parent
        chain.reverse()
        for j in chain:
            if j.type not in _MOVABLE + ("fixed",):
                raise self.doc.error("joint", j.name, f"is {j.type}, on the chain from {base!r} to {tip!r}: "
                                     "casadical models revolute and prismatic joints only")
        if not any(j.type in _MOVABLE for j in chain):
            raise RobotFileError(f"no revolute or continuous joint between links {base!r} and {tip!r}",
                                 file=self.doc.path)
        return chain

    def zero_poses(self, base: str) -> dict[str, np.ndarray]:
        """Pose of every link below ``base`` in its frame, all joint angles zero."""
        poses, stack = {}, [(base, np.eye(4))]
        while stack:
            link, T = stack.pop()
            poses[link] = T
            stack += [(j.child, T if j.origin is None else T @ j.origin) for j in self.children[link]]
        return poses

    def groups(self, base: str, movable: set[str]) -> dict[str, int]:
        """Link -> number of chain joints above it (0: does not move; i: moves with joint i)."""
        groups, stack = {}, [(base, 0)]
        while stack:
            link, g = stack.pop()
            groups[link] = g
            stack += [(j.child, g + (j.name in movable)) for j in self.children[link]]
        return groups


# --- the elements casadical reads (as yourdfpy reads them) ---------------------------------


@dataclass
class _Inertial:
    mass: float | None
    origin: np.ndarray | None


@dataclass
class _Link:
    name: str
    inertial: _Inertial | None


@dataclass
class _Limit:
    lower: float | None
    upper: float | None


@dataclass
class _Mimic:
    joint: str | None
    multiplier: float
    offset: float


@dataclass
class _Joint:
    name: str
    type: str | None
    parent: str
    child: str
    origin: np.ndarray | None
    axis: np.ndarray
    limit: _Limit | None
    mimic: _Mimic | None


def _numbers(text: str, n: int, what: str) -> np.ndarray:
    values = np.array([float(v) for v in text.split()])
    if len(values) != n:
        raise ValueError(f"{what} needs {n} numbers, got {text!r}")
    return values


def _origin(el) -> np.ndarray | None:
    """``<origin xyz rpy>`` as a 4x4 matrix (rpy: fixed axes x, y, z in turn, R = Rz(y) Ry(p) Rx(r)); None if
    absent."""
    if el is None:
        return None
    r, p, y = _numbers(el.get("rpy", "0 0 0"), 3, "rpy")
    cr, sr, cp, sp, cy, sy = math.cos(r), math.sin(r), math.cos(p), math.sin(p), math.cos(y), math.sin(y)
    T = np.eye(4)
    T[:3, :3] = [[cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
                 [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
                 [-sp, cp * sr, cp * cr]]
    T[:3, 3] = _numbers(el.get("xyz", "0 0 0"), 3, "xyz")
    return T


def _float(text: str | None) -> float | None:
    return None if text is None else float(text)


def _read_link(el) -> _Link:
    inertial = el.find("inertial")
    if inertial is not None:
        mass = inertial.find("mass")
        inertial = _Inertial(None if mass is None else float(mass.get("value", 0.0)), _origin(inertial.find("origin")))
    return _Link(el.attrib["name"], inertial)


def _read_joint(el) -> _Joint:
    axis, limit, mimic = el.find("axis"), el.find("limit"), el.find("mimic")
    return _Joint(
        name=el.attrib["name"], type=el.get("type"),
        parent=el.find("parent").get("link"), child=el.find("child").get("link"),
        origin=_origin(el.find("origin")),
        axis=np.array([1.0, 0.0, 0.0]) if axis is None else _numbers(axis.get("xyz", "1 0 0"), 3, "axis"),
        limit=None if limit is None else _Limit(_float(limit.get("lower")), _float(limit.get("upper"))),
        mimic=None if mimic is None else _Mimic(mimic.get("joint"), float(mimic.get("multiplier", 1.0)),
                                                float(mimic.get("offset", 0.0))))


def _why(e: Exception) -> str:
    if isinstance(e, KeyError):
        return f"missing attribute {e.args[0]!r}"
    if isinstance(e, AttributeError):
        return f"missing a required element or attribute ({e})"
    return f"cannot read it: {e}"
