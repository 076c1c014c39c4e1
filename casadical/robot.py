"""Robot descriptions: the TOML contract (docs/formats.md section 1) and built-ins.

A :class:`Robot` holds nominal values only, in SI units (m, rad, kg). The
symbolic model (:mod:`casadical.model._symbolic`) turns it into CasADi expressions.

This module imports no reader of another file type: the URDF reader
(:mod:`casadical.urdf`) builds on it, and loading a robot by file type
(built-in name, TOML, URDF) is :func:`casadical.loading.load_robot`, above
both (``tests/test_import_graph.py`` keeps it so).
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from .errors import InputError, ParallelAxesWarning, RobotFileError
from .runtime._files import read_toml

GRAVITY = 9.81
PROBLEMS = Path(__file__).resolve().parent.parent / "problems"
BUILTIN_DIR = PROBLEMS / "robots"
BUILTINS = ("ys100", "hh800", "ur10")


REVOLUTE, PRISMATIC = "revolute", "prismatic"
JOINT_TYPES = (REVOLUTE, PRISMATIC)


@dataclass
class Joint:
    """Nominal link and joint data of one joint (SI units).

    A revolute joint's reading (rad) adds to ``theta``; a prismatic joint's (a linear axis: track, lifting
    column, gantry; m) adds to ``d``, and its ``theta`` is constant. ``min``/``max`` are the reading's limits
    in the same units.
    """

    alpha: float
    a: float
    d: float
    theta: float = 0.0
    beta: float | None = None
    b: float | None = None
    min: float = -math.pi
    max: float = math.pi
    mass: float = 0.0
    com: np.ndarray = field(default_factory=lambda: np.zeros(3))
    coupling: np.ndarray | None = None
    coupling_offset: float = 0.0
    kind: str = REVOLUTE

    @property
    def prismatic(self) -> bool:
        """True for a linear axis (its reading a length along its z, added to ``d``)."""
        return self.kind == PRISMATIC

    @property
    def unit(self) -> str:
        """The unit of the reading in files and options: ``deg`` (revolute) or ``mm`` (prismatic)."""
        return "mm" if self.prismatic else "deg"


@dataclass
class Loop:
    """A four-bar (parallelogram) drive of one joint (casadical extension).

    The crank sits on the axis of the previous joint and is driven by the
    reading of ``joint`` as an absolute angle; the rocker is rigid with link
    ``joint``. With crank == rocker and coupler == the link length between
    the two axes the loop is a parallelogram and reduces to the linear
    coupling ``theta = q_joint - q_(joint-1) + coupling_offset``.
    """

    joint: int
    crank: float
    coupler: float
    rocker: float


@dataclass
class Robot:
    """Nominal description of a serial (or parallelogram-driven) arm."""

    name: str
    joints: list[Joint]
    convention: str = "mdh"
    base_xyz: np.ndarray = field(default_factory=lambda: np.zeros(3))
    base_rpy: np.ndarray = field(default_factory=lambda: np.zeros(3))
    tool: np.ndarray = field(default_factory=lambda: np.zeros(3))
    #: the nominal offsets of named tool points (``[tool.NAME]``, docs/formats.md section 11): a tool of several
    #: points (reflector nests, balls); a point not named here has ``tool``'s
    tools: dict = field(default_factory=dict)
    payload_mass: float = 0.0
    payload_com: np.ndarray = field(default_factory=lambda: np.zeros(3))
    gravity: np.ndarray = field(default_factory=lambda: np.array([0.0, 0.0, -GRAVITY]))
    loop: Loop | None = None
    source: str = ""

    @property
    def n(self) -> int:
        """Number of joints."""
        return len(self.joints)

    @property
    def limits(self) -> np.ndarray:
        """Joint limits of the readings, shape (n, 2), SI: radians (metres for a prismatic joint)."""
        return np.array([[j.min, j.max] for j in self.joints])

    @property
    def prismatic(self) -> tuple[bool, ...]:
        """Per joint: a linear axis (reading in m, ``qK_mm`` in files) or not (rad, ``qK_deg``)."""
        return tuple(j.prismatic for j in self.joints)

    @property
    def units(self) -> list[str]:
        """Per joint, the unit of its reading in files and options: ``deg`` or ``mm``."""
        return [j.unit for j in self.joints]

    @property
    def q_columns(self) -> list[str]:
        """The reading columns of a measurement file: ``q1_deg``, ... (``qK_mm`` for a prismatic joint K)."""
        return [f"q{i}_{j.unit}" for i, j in enumerate(self.joints, start=1)]

    def to_file_units(self, q) -> np.ndarray:
        """Readings (..., n) from SI (rad, m) to the files' units (deg, mm)."""
        return readings_to_file_units(q, self.prismatic)

    def from_file_units(self, q) -> np.ndarray:
        """Readings (..., n) from the files' units (deg, mm) to SI (rad, m)."""
        return readings_from_file_units(q, self.prismatic)

    @property
    def file_limits(self) -> np.ndarray:
        """Joint limits, shape (n, 2), in the files' units (deg, mm)."""
        return self.to_file_units(self.limits.T).T

    @classmethod
    def load(cls, spec: str | Path) -> "Robot":
        """Load a built-in robot by name (``ys100``, ``hh800``, ``ur10``) or a TOML file.

        Any robot file, URDF too: :func:`casadical.load_robot` (:mod:`casadical.loading`, the one
        ``load_robot``), which this module cannot import (the URDF reader builds on it).

        Raises
        ------
        RobotFileError
            Unknown name, unreadable file, a URDF file, or any invalid field.
        """
        path = robot_file(spec)
        if path.suffix.lower() == ".urdf":
            raise RobotFileError("Robot.load reads built-in robots and TOML files; read a URDF with "
                                 "casadical.load_robot", file=str(spec))
        return robot_from_toml(path)


def readings_to_file_units(q, prismatic) -> np.ndarray:
    """Readings (..., n) from SI (rad; m where ``prismatic``) to the files' units (deg; mm)."""
    q = np.asarray(q, dtype=float)
    if not any(prismatic):
        return np.degrees(q)
    return np.where(np.asarray(prismatic, bool), q * 1000.0, np.degrees(q))


def readings_from_file_units(q, prismatic) -> np.ndarray:
    """Readings (..., n) from the files' units (deg; mm where ``prismatic``) to SI (rad; m)."""
    q = np.asarray(q, dtype=float)
    if not any(prismatic):
        return np.radians(q)
    return np.where(np.asarray(prismatic, bool), q / 1000.0, np.radians(q))


# --- TOML loading -----------------------------------------------------------------

_TOP_KEYS = {"name", "convention", "base", "joint", "tool", "payload", "gravity", "loop"}
_JOINT_KEYS = {"alpha_deg", "a_m", "beta_deg", "b_m", "d_m", "theta_deg", "min_deg", "max_deg",
               "mass_kg", "com_m", "coupling", "coupling_offset_deg", "type", "min_mm", "max_mm"}
_TABLE_KEYS = {
    "base": {"xyz_m", "rpy_deg"},
    "tool": {"a_m", "b_m", "d_m"},
    "payload": {"mass_kg", "com_m"},
    "gravity": {"direction"},
    "loop": {"joint", "crank_m", "coupler_m", "rocker_m"},
}


def robot_file(spec: str | Path) -> Path:
    """The file of a robot: a built-in name (``ys100``, ``hh800``, ``ur10``) or a path that exists.

    Raises
    ------
    RobotFileError
        Neither a built-in name nor an existing file.
    """
    text_spec = str(spec)
    if text_spec.lower() in BUILTINS and not Path(text_spec).exists():
        return BUILTIN_DIR / f"{text_spec.lower()}.toml"
    path = Path(text_spec)
    if not path.exists():
        raise RobotFileError(f"no such robot file, and not a built-in robot (built-ins: {', '.join(BUILTINS)})",
                             file=text_spec)
    return path


def robot_from_toml(path: str | Path) -> Robot:
    """Read a robot TOML file (docs/formats.md section 1); a :class:`~casadical.errors.ParallelAxesWarning`
    names each link with parallel consecutive axes and no ``beta_deg``.

    Raises
    ------
    RobotFileError
        Unreadable file or any invalid field (the message names the file,
        the table and the key).
    """
    robot = robot_from_dict(read_toml(path, RobotFileError), str(path))
    warn_parallel_axes(robot.joints, robot.convention, str(path))
    return robot


def check_not_urdf_options(spec: str | Path, tip, base, tool) -> None:
    """Refuse the chain options of a URDF file for a robot that is not one (one line)."""
    if (tip, base, tool) != (None, None, None):
        raise InputError(f"{spec}: a tip link, base link or tool point chooses the chain of a URDF file; "
                         "this robot is not one (give a .urdf file, or drop those options)")


def robot_from_dict(data: dict[str, Any], file: str = "<dict>") -> Robot:
    """Validate a parsed TOML document and build a :class:`Robot`."""
    v = _Validator(file)
    if not isinstance(data, dict):
        raise RobotFileError(f"must be a table of keys (name, convention, joint, ...), got {type(data).__name__}",
                             file=file)
    v.keys(data, _TOP_KEYS, "")
    name = v.string(data, "name", "", required=True)
    convention = v.string(data, "convention", "", default="mdh")
    if convention not in ("mdh", "dh"):
        raise RobotFileError(f"convention must be \"mdh\" or \"dh\", got {convention!r}",
                             file=file, column="convention")
    joints_raw = data.get("joint")
    if not isinstance(joints_raw, list) or not joints_raw:
        raise RobotFileError("needs at least one [[joint]] table", file=file, column="joint")
    n = len(joints_raw)
    joints = []
    for i, jt in enumerate(joints_raw, start=1):
        t = f"joint[{i}]"
        if not isinstance(jt, dict):
            raise RobotFileError("must be a table", file=file, column=t)
        v.keys(jt, _JOINT_KEYS, t)
        kind = v.string(jt, "type", t, default=REVOLUTE)
        if kind not in JOINT_TYPES:
            raise RobotFileError(f"type must be \"revolute\" or \"prismatic\", got {kind!r}", file=file,
                                 column=f"{t}.type")
        if kind == PRISMATIC:
            for k in ("min_deg", "max_deg", "coupling", "coupling_offset_deg"):
                if k in jt:
                    raise RobotFileError("a prismatic joint (a linear axis) " + (
                        "takes its limits in millimetres: min_mm / max_mm" if k in ("min_deg", "max_deg")
                        else "cannot be coupled: couplings combine revolute readings only"), file=file,
                        column=f"{t}.{k}")
            lo = v.number(jt, "min_mm", t, required=True)
            hi = v.number(jt, "max_mm", t, required=True)
            if not lo < hi:
                raise RobotFileError(f"min_mm ({lo}) must be below max_mm ({hi})", file=file,
                                     column=f"{t}.min_mm")
            lo, hi = lo / 1000.0, hi / 1000.0
        else:
            for k in ("min_mm", "max_mm"):
                if k in jt:
                    raise RobotFileError("a revolute joint takes its limits in degrees: min_deg / max_deg (min_mm "
                                         "/ max_mm are a prismatic joint's, type = \"prismatic\")", file=file,
                                         column=f"{t}.{k}")
            lo = v.number(jt, "min_deg", t, default=-180.0)
            hi = v.number(jt, "max_deg", t, default=180.0)
            if not lo < hi:
                raise RobotFileError(f"min_deg ({lo}) must be below max_deg ({hi})", file=file,
                                     column=f"{t}.min_deg")
            lo, hi = math.radians(lo), math.radians(hi)
        mass = v.number(jt, "mass_kg", t, default=0.0)
        if mass < 0:
            raise RobotFileError(f"mass must not be negative, got {mass}", file=file,
                                 column=f"{t}.mass_kg")
        coupling = None
        if "coupling" in jt:
            coupling = v.vector(jt, "coupling", t, n)
        beta = v.number(jt, "beta_deg", t, default=None)
        joints.append(Joint(
            alpha=math.radians(v.number(jt, "alpha_deg", t, required=True)),
            a=v.number(jt, "a_m", t, required=True),
            d=v.number(jt, "d_m", t, required=True),
            theta=math.radians(v.number(jt, "theta_deg", t, default=0.0)),
            beta=None if beta is None else math.radians(beta),
            b=v.number(jt, "b_m", t, default=None),
            min=lo, max=hi, mass=mass,
            com=v.vector(jt, "com_m", t, 3, default=np.zeros(3)),
            coupling=coupling,
            coupling_offset=math.radians(v.number(jt, "coupling_offset_deg", t, default=0.0)),
            kind=kind,
        ))
    for i, jt in enumerate(joints, start=1):     # couplings combine revolute readings only
        if jt.coupling is not None:
            named = [k for k, c in enumerate(jt.coupling, start=1) if c != 0 and joints[k - 1].prismatic]
            if named:
                raise RobotFileError(f"couples joint {named[0]}, a prismatic joint (a linear axis): couplings "
                                     "combine revolute readings only", file=file, column=f"joint[{i}].coupling")
    tables = {}
    for tname, allowed in _TABLE_KEYS.items():
        tab = data.get(tname, {})
        if not isinstance(tab, dict):
            raise RobotFileError("must be a table", file=file, column=tname)
        # [tool.NAME] tables are named tool points (read below), not keys of the tool
        v.keys({k: x for k, x in tab.items() if not (tname == "tool" and isinstance(x, dict))}, allowed, tname)
        tables[tname] = tab
    base, tool, payload, grav = (tables[k] for k in ("base", "tool", "payload", "gravity"))
    tools = {}
    for k, sub in tool.items():     # [tool.NAME]: a named tool point's own nominal offset
        if isinstance(sub, dict):
            where = f"tool.{k}"
            if not re.fullmatch(r"[A-Za-z0-9_.-]+", k):
                raise RobotFileError(f"a tool point's name is letters, digits, _ . -, got {k!r}", file=file,
                                     column=where)
            v.keys(sub, _TABLE_KEYS["tool"], where)
            tools[k] = np.array([v.number(sub, c, where, default=float(v.number(tool, c, "tool", default=0.0)))
                                 for c in ("a_m", "b_m", "d_m")])
    direction = v.vector(grav, "direction", "gravity", 3, default=np.array([0.0, 0.0, -1.0]))
    if not np.any(direction):
        raise RobotFileError("gravity direction must not be zero", file=file,
                             column="gravity.direction")
    direction = direction / np.max(np.abs(direction))  # any finite size: no overflow or underflow
    norm = float(np.linalg.norm(direction))
    pmass = v.number(payload, "mass_kg", "payload", default=0.0)
    if pmass < 0:
        raise RobotFileError(f"mass must not be negative, got {pmass}", file=file,
                             column="payload.mass_kg")
    loop = None
    if tables["loop"]:
        lt = tables["loop"]
        j = v.number(lt, "joint", "loop", required=True)
        if j != int(j) or not 2 <= j <= n:
            raise RobotFileError(f"loop joint must be a joint number from 2 to {n}, got {j}",
                                 file=file, column="loop.joint")
        lengths = [v.number(lt, k, "loop", required=True) for k in ("crank_m", "coupler_m", "rocker_m")]
        for k, x in zip(("crank_m", "coupler_m", "rocker_m"), lengths):
            if x <= 0:
                raise RobotFileError(f"length must be positive, got {x}", file=file, column=f"loop.{k}")
        if joints[int(j) - 1].prismatic or joints[int(j) - 2].prismatic:
            raise RobotFileError(f"the loop drives joint {int(j)} from joint {int(j) - 1}: both must be revolute",
                                 file=file, column="loop.joint")
        loop = Loop(int(j), *lengths)
    return Robot(
        name=name, joints=joints, convention=convention,
        base_xyz=v.vector(base, "xyz_m", "base", 3, default=np.zeros(3)),
        base_rpy=np.radians(v.vector(base, "rpy_deg", "base", 3, default=np.zeros(3))),
        tool=np.array([v.number(tool, k, "tool", default=0.0) for k in ("a_m", "b_m", "d_m")]), tools=tools,
        payload_mass=pmass,
        payload_com=v.vector(payload, "com_m", "payload", 3, default=np.zeros(3)),
        gravity=GRAVITY * direction / norm, loop=loop, source=file)


#: consecutive axes closer to parallel than this (deg) need Hayati's beta (as the URDF reader gives them)
PARALLEL_DEG = 5.0


def parallel_without_beta(joints: list[Joint], convention: str) -> list[tuple[int, int]]:
    """``(link, next joint)`` of every pair of consecutive parallel axes whose link has no ``beta``: in ``dh`` the
    angle between axes i and i+1 is link i's alpha (its beta is link i's), in ``mdh`` the angle between axes i-1
    and i is link i's (so is its beta)."""
    tol = math.sin(math.radians(PARALLEL_DEG))
    out = []
    for i, j in enumerate(joints, start=1):
        pair = (i, i + 1) if convention == "dh" else (i - 1, i)
        if 1 <= pair[0] and pair[1] <= len(joints) and abs(math.sin(j.alpha)) < tol and j.beta is None:
            out.append((i, pair[0] if convention == "mdh" else pair[1]))
    return out


def warn_parallel_axes(joints: list[Joint], convention: str, file: str) -> None:
    """A :class:`~casadical.errors.ParallelAxesWarning` naming each link with parallel consecutive axes and no
    ``beta_deg``."""
    import warnings

    for link, other in parallel_without_beta(joints, convention):
        warnings.warn(f"{file}: joint[{link}]: the axes of joints {min(link, other)} and {max(link, other)} are "
                      f"parallel (alpha_deg {math.degrees(joints[link - 1].alpha):g}) and joint[{link}] has no "
                      "beta_deg: a small tilt between them (Hayati's beta) cannot be calibrated, and its d_m is "
                      f"ill-conditioned; add beta_deg = 0.0 to joint[{link}]", ParallelAxesWarning, stacklevel=4)


class _Validator:
    """Typed look-ups that raise :class:`RobotFileError` naming table and key."""

    def __init__(self, file: str):
        self.file = file

    def _err(self, msg: str, table: str, key: str) -> RobotFileError:
        return RobotFileError(msg, file=self.file, column=f"{table}.{key}" if table else key)

    def keys(self, tab: dict, allowed: set[str], table: str) -> None:
        for k in tab:
            if k not in allowed:
                raise self._err(f"unknown key (allowed: {', '.join(sorted(allowed))})", table, k)

    def string(self, tab, key, table, required=False, default=None):
        if key not in tab:
            if required:
                raise self._err("missing required key", table, key)
            return default
        if not isinstance(tab[key], str):
            raise self._err(f"must be a string, got {tab[key]!r}", table, key)
        return tab[key]

    def number(self, tab, key, table, required=False, default=None):
        if key not in tab:
            if required:
                raise self._err("missing required key", table, key)
            return default
        return self._value(tab[key], table, key)

    def vector(self, tab, key, table, length, default=None):
        if key not in tab:
            return default
        x = tab[key]
        if not isinstance(x, list) or len(x) != length:
            raise self._err(f"must be a list of {length} finite numbers, got {x!r}", table, key)
        return np.array([self._value(e, table, key) for e in x], dtype=float)

    def _value(self, x, table, key) -> float:
        """A finite number within the plausible range of its unit (the key's suffix)."""
        if isinstance(x, bool) or not isinstance(x, (int, float)):
            raise self._err(f"must be a number, got {x!r}", table, key)
        try:
            v = float(x)
        except OverflowError:
            v = math.inf
        if not math.isfinite(v):
            text = repr(x)
            raise self._err(f"must be finite, got {text if len(text) < 40 else text[:30] + '...'}", table, key)
        for suffix, (top, what) in _RANGES.items():
            if key.endswith(suffix) and abs(v) > top:
                raise self._err(f"{what} must lie within +-{top:g}, got {v:g}", table, key)
        return v


#: plausible ranges by key suffix: beyond them a value is a unit mistake, and would overflow the model
_RANGES = {
    "_m": (100.0, "lengths are in metres and"),
    "_deg": (36000.0, "angles are in degrees and"),
    "_mm": (100000.0, "lengths are in millimetres and"),
    "_kg": (1e5, "masses are in kg and"),
    "coupling": (100.0, "coupling factors"),
}


def robot_to_dict(robot: Robot) -> dict[str, Any]:
    """The TOML document (as a dict) that :func:`robot_from_dict` reads back to ``robot``."""
    joints = []
    for j in robot.joints:
        d: dict[str, Any] = {"alpha_deg": math.degrees(j.alpha), "a_m": j.a}
        if j.beta is not None:
            d["beta_deg"] = math.degrees(j.beta)
        if j.b is not None:
            d["b_m"] = j.b
        d.update(d_m=j.d, theta_deg=math.degrees(j.theta))
        if j.prismatic:
            d.update(type=PRISMATIC, min_mm=j.min * 1000.0, max_mm=j.max * 1000.0)
        else:
            d.update(min_deg=math.degrees(j.min), max_deg=math.degrees(j.max))
        d.update(mass_kg=j.mass, com_m=[float(x) for x in j.com])
        if j.coupling is not None:
            d["coupling"] = [float(x) for x in j.coupling]
            d["coupling_offset_deg"] = math.degrees(j.coupling_offset)
        joints.append(d)
    g = float(np.linalg.norm(robot.gravity))
    doc: dict[str, Any] = {
        "name": robot.name, "convention": robot.convention,
        "base": {"xyz_m": [float(x) for x in robot.base_xyz],
                 "rpy_deg": [math.degrees(x) for x in robot.base_rpy]},
        "joint": joints,
        "tool": {"a_m": float(robot.tool[0]), "b_m": float(robot.tool[1]), "d_m": float(robot.tool[2]),
                 **{k: {"a_m": float(x[0]), "b_m": float(x[1]), "d_m": float(x[2])} for k, x in robot.tools.items()}},
        "payload": {"mass_kg": robot.payload_mass, "com_m": [float(x) for x in robot.payload_com]},
        "gravity": {"direction": [float(x) / g for x in robot.gravity]},
    }
    if robot.loop is not None:
        doc["loop"] = {"joint": robot.loop.joint, "crank_m": robot.loop.crank,
                       "coupler_m": robot.loop.coupler, "rocker_m": robot.loop.rocker}
    return doc
