"""The error-term interface and its registry.

An error term is one physical cause of position error. It declares its
parameters and the per-pose covariates it needs, and adds its effect to the
symbolic model: as offsets of the joint angles (compliance, gear error,
encoder scale, backlash) or as a change of the geometry (thermal expansion).
A joint's angle offset is its drive's: it is added to the joint's reading
before couplings and loops make the chain angles, so on a coupled arm it
moves every chain angle made of that reading (a parallelogram's forearm
keeps its direction when joint 2's drive gives way).
Adding a term means writing one module in this folder that subclasses
:class:`ErrorTerm` and decorates it with :func:`register`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np

from ..errors import ModelError
from ..kinematics import Frames, Geometry, chain_angles, drive_torques, forward, gravity_torques, mount_moment
from ..parameters import Parameter
from ..robot import GRAVITY, Robot

REGISTRY: dict[str, type["ErrorTerm"]] = {}


def register(cls: type["ErrorTerm"]) -> type["ErrorTerm"]:
    """Class decorator: make a term available by its ``name`` and ``aliases``."""
    for key in (cls.name, *cls.aliases):
        REGISTRY[key] = cls
    return cls


@dataclass
class Context:
    """Symbols shared by the terms while a model is being built."""

    robot: Robot
    q: Any                       # joint readings, rad (SX n x 1)
    p: dict[str, Any]            # parameter symbols by name
    cov: dict[str, Any]          # covariate symbols by name
    geom: Geometry | None = None
    #: joint errors are the drives' (on the readings, before couplings and loops); False: on the chain angles
    #: (calibration files written before, :class:`~casadical.terms._geometric.Geometric` ``drive_errors``)
    drives: bool = True
    #: the model's point in the measurement frame before the terms' point offsets (set before
    #: :meth:`ErrorTerm.base_offset` is asked; a user term's ``point`` effect reads it)
    point: Any = None
    #: 1 at the poses where a term of one session acts, 0 elsewhere: a term whose geometry change
    #: :class:`~casadical.terms._local.SessionLocal` may make local (``gated``) multiplies its change by it
    gate: Any = None
    #: (term, key, expression) of the expressions to be checked finite at the data's poses (user terms')
    checks: list = field(default_factory=list)
    _frames: Frames | None = field(default=None, repr=False)
    _torques: list | None = field(default=None, repr=False)
    _moment: Any = field(default=None, repr=False)

    def frames(self) -> Frames:
        """Frames of the undeflected configuration (current geometry)."""
        if self._frames is None:
            self._frames = forward(self.robot, chain_angles(self.robot, self.q, self.geom), self.geom)
        return self._frames

    def torques(self) -> list:
        """Gravity torque each joint's drive carries, undeflected configuration, row payload
        (:func:`~casadical.kinematics.drive_torques`: the torque about the joint's axis unless joints are
        coupled)."""
        if self._torques is None:
            tau = gravity_torques(self.robot, self.frames(), self.cov["payload_kg"])
            self._torques = drive_torques(self.robot, self.q, self.geom, tau) if self.drives else tau
        return self._torques

    def moment(self):
        """Moment of the weights about the robot base frame's origin (3x1, N m), undeflected configuration, row
        payload (:func:`~casadical.kinematics.mount_moment`)."""
        if self._moment is None:
            self._moment = mount_moment(self.robot, self.frames(), self.cov["payload_kg"])
        return self._moment


class ErrorTerm:
    """Base class of the error terms.

    Parameters
    ----------
    joints : list of int, optional
        1-based joints the term applies to (terms that act per joint).
    """

    #: registry key, also used in model specifications ("kinematic+compliance")
    name: ClassVar[str] = ""
    aliases: ClassVar[tuple[str, ...]] = ()
    #: cause name of docs/formats.md section 4
    cause: ClassVar[str] = ""
    #: covariates read per pose (columns of the measurement file)
    covariates: ClassVar[tuple[str, ...]] = ()
    #: describes the measurement session, not the robot (like the base pose): a calibration taken
    #: to other data starts such a term from zero
    session: ClassVar[bool] = False
    #: an error of a revolute joint's angle (compliance, progressive stiffness, coupling): by default on the
    #: revolute joints only, and refused on a prismatic joint (a linear axis' own errors: encoder scale, periodic
    #: error and backlash along it, straightness, the carriage's angles)
    revolute_only: ClassVar[bool] = False
    #: its place in the superset every candidate model is a mask of (casadical.model._superset); None: not in it
    superset_order: ClassVar[int | None] = None
    #: the optional group of the superset it belongs to (None: always there): ``torques`` for the terms that
    #: deflect a joint by its gravity torque or tilt the mount by the moment of the weights (a model without such
    #: a term has the superset without them, whose Jacobian skips the torques: 3x cheaper); a model's superset
    #: holds the groups of its terms
    superset_group: ClassVar[str | None] = None
    #: a term of one session may be this term's in the superset: linear in its parameters (a joint offset or a
    #: translation), so that the shared and the session's parameters add up per pose
    session_local: ClassVar[bool] = False

    #: its parameters are tested in the notes on what is not significant (not the geometry's: a deviation of 0 is no
    #: fault)
    noted: ClassVar[bool] = True
    #: what its parameters that are not significant mean, and what to do: ("the stiffness of {joints} is",
    #: "measure poses that load {them}"); None: the general words
    weak_meaning: ClassVar[tuple[str, str] | None] = None

    #: what a parameter's value at or beyond a bound means, by its name without joint and session (``c``,
    #: ``escale``) and side: words added to the message
    bound_meaning: ClassVar[dict[str, dict[str, str]]] = {}
    #: a cause of position error the physics rules judge (not the geometry, the probe's mounting, the sessions'
    #: frames or a compensator)
    is_cause: ClassVar[bool] = True

    @classmethod
    def value_rules(cls, p: Parameter, params, tau, moves) -> list[tuple[tuple[str, ...], str]]:
        """The physics a parameter ``p`` of this term breaks by its value alone (beyond its bounds): (its names,
        what is wrong) each. ``params``: every parameter by name (a progressive spring's linear part ``c<j>``);
        ``tau()``: the poses' gravity torques (N, n); ``moves``: the sign of each joint's last move (N, n).
        None by default."""
        return []

    def fitted_causes(self, names: list[str], joint_of, where: str) -> list[tuple[int | None, list[str], str]]:
        """The term's parameters ``names`` split by cause as the physics rules judge them: (joint, names, words)
        each; ``joint_of(name)``: a parameter's joint, ``where``: `` in session B`` for a session's own. By default
        one per parameter."""
        return [(joint_of(n), [n], f"{self.name.replace('_', ' ')}"
                 + (f" of joint {joint_of(n)}" if joint_of(n) is not None else "") + where) for n in names]

    def group_key(self, p: Parameter):
        """What of the term a parameter ``p`` is dropped with when it is not significant: its joint."""
        return p.joint

    def weak_words(self, keys: list, joints: list[int]) -> tuple[str, str, str] | None:
        """What the parameters of the groups ``keys`` (:meth:`group_key`) that are not significant leave
        undetermined, what to measure, and what to drop (``joints``: theirs); None: the general words."""
        if not joints:
            return None
        what, do = self.weak_meaning or ("the effect of {joints} is", "measure poses that show it")
        one = len(joints) == 1
        return (what.format(joints=_joints(joints)), do.format(them="it" if one else "them",
                                                                their="its" if one else "their"),
                f"drop {'the joint' if one else 'those joints'} from the model")

    def without(self, kept: list[Parameter], dropped: list) -> str | None:
        """This term's specification without the groups ``dropped`` ('' if nothing is left; None: it cannot say)."""
        if self.joints is None or not self.spec().startswith(f"{self.name}["):
            return None
        joints = sorted({p.joint for p in kept if p.joint is not None})
        return f"{self.name}[{','.join(map(str, joints))}]" if joints else ""

    @classmethod
    def superset(cls, robot: Robot) -> list["ErrorTerm"]:
        """The terms of this kind the superset of ``robot`` holds; none by default."""
        return []

    def superset_member(self) -> bool:
        """This term (with its settings) is one the superset expresses."""
        return self.superset_order is not None

    def superset_parameters(self, robot: Robot) -> list[tuple[str, str | None]]:
        """For each of its parameters, the superset's parameter it is and the covariate whose value at a pose
        multiplies it there (None: none; a mount compliance's law: its polynomial of the column); by default
        itself."""
        return [(p.name, None) for p in self.parameters(robot)]

    def session_parameters(self, robot: Robot) -> list[Parameter]:
        """Its parameters as a term of one session (``NAME@S``, before their names take the session): its own by
        default (a mount's are bounded as a mount that differs between sessions)."""
        return self.parameters(robot)

    def refer(self, data) -> None:
        """Take from the calibration poses ``data`` what the term is written over (a law: its column's range);
        nothing by default (a :class:`ReferencedTerm` has its reference)."""

    def __init__(self, joints: list[int] | None = None):
        self.joints = None if joints is None else sorted({int(j) for j in joints})

    def bind(self, robot: Robot) -> None:
        """Check the term against the robot; resolve default joints."""
        if self.joints is None:
            self.joints = [j for j in range(1, robot.n + 1)
                           if not (self.revolute_only and robot.joints[j - 1].prismatic)]
        bad = [j for j in self.joints if not 1 <= j <= robot.n]
        if bad:
            raise ModelError(f"term {self.name}: joints {bad} do not exist on {robot.name} "
                             f"(joints 1..{robot.n})")
        if self.revolute_only:
            check_revolute(self.name, [j for j in self.joints], robot)

    def parameters(self, robot: Robot) -> list[Parameter]:
        """Parameters this term adds to the model."""
        return []

    def geometry(self, ctx: Context, geom: Geometry) -> Geometry:
        """Change the geometry (default: unchanged)."""
        return geom

    def joint_offsets(self, ctx: Context) -> dict[int, Any]:
        """Offsets added to chain angles, by 1-based joint (default: none)."""
        return {}

    def base_offset(self, ctx: Context):
        """Translation (3-vector, measurement frame) added to the measured point (default: none)."""
        return None

    def robot_frame_offset(self, ctx: Context):
        """Translation (3-vector, robot base frame) added to the tool point (default: none).

        Unlike :meth:`base_offset` it turns with the base pose, so it holds
        wherever the tracker stands.
        """
        return None

    def base_tilt(self, ctx: Context):
        """Rotation vector (3x1, rad, robot base frame) by which the robot base frame turns about its origin
        before joint 1: a tilt of the mount (default: none). The model turns the tool point and the flange's
        orientation by the rotation of the terms' vectors summed (:func:`~casadical.kinematics.small_rotation`).
        """
        return None

    def reference(self, ctx: Context, R0, t0):
        """The reference pose the base parameters deviate from, per pose (default: ``base0``, unchanged)."""
        return R0, t0

    def covariate_values(self, data) -> dict:
        """Values of covariates this term makes from the data itself rather than reads from a column
        (e.g. a pose's session), by name (default: none)."""
        return {}
    def tool_rotation(self, ctx: Context):
        """Rotation (3x3) of the measured probe in the last link frame (default: none).

        Only full-pose models have one (:mod:`casadical.terms._tool_orientation`);
        it turns the measured orientation, never the measured point.
        """
        return None

    def spec(self) -> str:
        """The text that re-creates this term in a model specification."""
        if self.joints is None:
            return self.name
        return f"{self.name}[{','.join(str(j) for j in self.joints)}]"

    def settings(self) -> dict:
        """Settings that must be saved with a calibration to rebuild the term."""
        return {"joints": self.joints}


class ReferencedTerm(ErrorTerm):
    """A term driven by one covariate relative to a reference value (temperature, time).

    ``calibrate`` sets ``t_ref`` to the mean of that covariate over its data,
    which keeps the other parameters at the data's mean conditions; at
    ``t_ref`` the term has no effect.
    """

    def __init__(self, joints=None, t_ref: float = 0.0):
        super().__init__(None)
        self.t_ref = float(t_ref)

    @property
    def reference_covariate(self) -> str:
        return self.covariates[0]

    def reference_value(self, values: np.ndarray) -> float:
        """The reference of the covariate's ``values`` over the data (default: their mean)."""
        return float(np.mean(values))

    def bind(self, robot: Robot) -> None:
        """Nothing per joint to resolve (its spec stays ``drift``, not ``drift[1,...,n]``)."""

    def settings(self) -> dict:
        return {"t_ref": self.t_ref}


def check_revolute(term: str, joints, robot: Robot) -> None:
    """Refuse a revolute joint's error on a prismatic joint (one line)."""
    linear = [j for j in joints if robot.joints[j - 1].prismatic]
    if linear:
        raise ModelError(f"term {term}: joint {linear[0]} of {robot.name} is prismatic (a linear axis); {term} is "
                         "an error of a revolute joint's angle (a linear axis' own errors: encoder_scale per metre, "
                         "joint_periodic per metre, backlash, straightness, carriage_angle, mount_compliance)")


def _joints(js: list[int]) -> str:
    """``joint 2``, ``joints 2, 3 and 5``."""
    js = sorted(set(js))
    if len(js) == 1:
        return f"joint {js[0]}"
    return "joints " + ", ".join(map(str, js[:-1])) + f" and {js[-1]}"


def revolute(robot: Robot) -> list[int]:
    """The revolute joints of ``robot`` (1-based)."""
    return [j for j in range(1, robot.n + 1) if not robot.joints[j - 1].prismatic]


def linear_axes(robot: Robot) -> list[int]:
    """The prismatic joints of ``robot``, its linear axes (1-based)."""
    return [j for j in range(1, robot.n + 1) if robot.joints[j - 1].prismatic]


def covariate_names(terms: list[ErrorTerm]) -> list[str]:
    """The covariates a model of ``terms`` reads per pose, in the order of its terms (the payload always)."""
    cov = list(dict.fromkeys(c for t in terms for c in t.covariates))
    return cov if "payload_kg" in cov else ["payload_kg"] + cov


def reach(robot: Robot, first: int = 1) -> float:
    """Upper bound of the distance from joint ``first`` to the tool point (m)."""
    links = sum(abs(j.a) + abs(j.d) + abs(j.b or 0.0) + (max(abs(j.min), abs(j.max)) if j.prismatic else 0.0)
                for j in robot.joints[first - 1:])
    loop = robot.loop.crank if robot.loop else 0.0
    return links + loop + float(sum(abs(robot.tool)))


def max_gravity_torque(robot: Robot, j: int) -> float:
    """Upper bound of the gravity torque at joint ``j`` (N m): every mass after it, payload included, at full reach."""
    load = sum(jt.mass for jt in robot.joints[j - 1:]) + robot.payload_mass
    return GRAVITY * load * reach(robot, j)


def check_linear(term: str, joints, robot: Robot) -> None:
    """Refuse a linear axis' error on a revolute joint (one line)."""
    turning = [j for j in joints if not robot.joints[j - 1].prismatic]
    if turning:
        raise ModelError(f"term {term}: joint {turning[0]} of {robot.name} is revolute; {term} is an error of a "
                         "linear axis (a prismatic joint: a track, a column, a gantry)")


def travel(robot: Robot, j: int, q):
    """The reading ``q`` (m) of linear axis ``j`` scaled by its limits to [-1, 1] (numpy or CasADi)."""
    lo, hi = robot.joints[j - 1].min, robot.joints[j - 1].max
    return (2 * q - (lo + hi)) / (hi - lo)


def legendre(k: int, u):
    """The Legendre polynomial of degree ``k`` (1 to 3) of ``u`` (numpy or CasADi)."""
    if k == 1:
        return u
    if k == 2:
        return (3 * u * u - 1) / 2
    if k == 3:
        return (5 * u * u * u - 3 * u) / 2
    raise ModelError(f"Legendre polynomials of degree 1 to 3 only, not {k}")
