"""The method interface, its registry and the result every method returns.

A *method* is a complete calibration recipe of one of the seed papers (or a
casadical variant of one): which model, which solver or optimiser, and which
compensator of the residual. Each lives in its own module of this package,
subclasses :class:`Method` and is registered by name with :func:`register`,
like the error terms of :mod:`casadical.terms`.
"""

from __future__ import annotations

import time
import warnings
from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np

from ..data._measurements import Measurements
from ..errors import InputError
from ..result import CalibrationResult, ErrorStats, touch_stats
from ..robot import Robot

REGISTRY: dict[str, type["Method"]] = {}


def register(cls: type["Method"]) -> type["Method"]:
    """Class decorator: make a method available by its ``name`` (case-insensitive lookup)."""
    REGISTRY[cls.name] = cls
    return cls


def method_names() -> list[str]:
    """Registered method names in the order of the papers' tables."""
    return sorted(REGISTRY, key=lambda n: (REGISTRY[n].order, n))


def lookup(name: str) -> type["Method"]:
    """The method class called ``name`` (case-insensitive).

    Raises
    ------
    InputError
        Unknown name; the message lists the valid ones.
    """
    key = {n.lower(): n for n in REGISTRY}.get(str(name).strip().lower())
    if key is None:
        raise InputError(f"unknown method {name!r}; choose from {', '.join(method_names())}")
    return REGISTRY[key]


@dataclass
class Inputs:
    """What a method works on (the sets of the papers' protocols).

    Attributes
    ----------
    robot : Robot
    calibration : Measurements
        Poses the parameters are identified on (Q1).
    extra : Measurements or None
        A further measured set some methods train a compensator on (the
        TLBO paper's Q2); never the validation set.
    seed : int
        Seed of every random choice of the method.
    """

    robot: Robot
    calibration: Measurements
    extra: Measurements | None = None
    seed: int = 0


@dataclass
class MethodResult:
    """Outcome of one method on one data set.

    Attributes
    ----------
    name : str
        Method name.
    calibration : ErrorStats
        Position errors on the calibration poses (with the compensator).
    validation : ErrorStats or None
        The same on the validation poses, if given (never used for fitting).
    time_s : float
        Wall time of the identification and training (model building
        included, evaluation on validation excluded).
    result : CalibrationResult
        The model-based calibration underneath.
    compensator : Compensator or None
        Residual compensator (RBF, MLP), None if the method has none or the
        guard rejected it.
    frame : str
        Frame of the compensator's outputs: ``"measurement"`` or ``"joint1"``
        (see :func:`frame_rotations`).
    features : str
        What the compensator reads: ``"torques"`` (the six effective joint
        torques of the calibrated model) or ``"angles"`` (joint readings, rad).
    extra : ErrorStats or None
        Errors on the ``extra`` set (the network-training set), if given.
    info : dict
        Method-specific details: identified stiffness, optimiser evaluations,
        iterations, multi-start costs, compensator training, notes.
    """

    name: str
    calibration: ErrorStats
    validation: ErrorStats | None
    time_s: float
    result: CalibrationResult
    compensator: Any = None
    features: str = ""
    extra: ErrorStats | None = None
    info: dict = field(default_factory=dict)
    frame: str = "measurement"

    def features_of(self, data: Measurements) -> np.ndarray:
        """Compensator inputs for the poses of ``data``."""
        return compensator_features(self.result, data, self.features)

    def predict(self, data: Measurements) -> np.ndarray:
        """Predicted tool positions (m, (N, 3)): calibrated model plus compensator."""
        xyz = self.result.predict(data)
        if self.compensator is not None:
            y = self.compensator.predict(self.features_of(data))
            xyz = xyz + from_frame(self.result, data, self.frame, y)
        return xyz

    def errors(self, data: Measurements) -> np.ndarray:
        """Position error norm per pose (m): a touch row's, its distance from what it touched (fitted to the rows
        of its session that touch it, :meth:`CalibrationResult.errors`)."""
        if data.touches:
            return np.linalg.norm(data.layout.residuals(self.predict(data)), axis=1)
        return np.linalg.norm(self.predict(data) - data.xyz, axis=1)

    def stats(self, data: Measurements) -> ErrorStats:
        """The error statistics of ``data`` (of rows that touch, with their consistency and distance error)."""
        if data.touches:
            P = self.predict(data)
            return ErrorStats.of(np.linalg.norm(data.layout.residuals(P), axis=1), touch_stats(data.layout, P))
        return ErrorStats.of(self.errors(data))

    def stiffness(self) -> dict[int, float]:
        """Identified joint stiffness (N m/rad) by joint (empty for kinematic-only methods)."""
        return {j: k for j, (k, _) in self.result.stiffness().items()}

    def to_dict(self) -> dict:
        """The ``compare`` JSON entry of this method."""
        return {"name": self.name,
                "calibration": self.calibration.to_dict(n_poses=False),
                "validation": self.validation.to_dict(n_poses=False) if self.validation else None,
                "time_s": self.time_s,
                "extra": self.extra.to_dict(n_poses=False) if self.extra else None,
                "n_poses": {"calibration": self.calibration.n_poses,
                            "validation": self.validation.n_poses if self.validation else 0,
                            "extra": self.extra.n_poses if self.extra else 0},
                "stiffness_nm_per_rad": {str(j): k for j, k in self.stiffness().items()},
                "compensator": type(self.compensator).__name__ if self.compensator is not None else None,
                "details": _jsonable(self.info)}


def _jsonable(o):
    if isinstance(o, dict):
        return {str(k): _jsonable(v) for k, v in o.items()}
    if isinstance(o, (list, tuple)):
        return [_jsonable(v) for v in o]
    if isinstance(o, np.ndarray):
        return _jsonable(o.tolist())
    if isinstance(o, (np.floating, np.integer)):
        return o.item()
    if isinstance(o, float) and not np.isfinite(o):
        return None
    if o is None or isinstance(o, (str, int, float, bool)):
        return o
    return str(o)


def compensator_features(result: CalibrationResult, data: Measurements, features: str) -> np.ndarray:
    """Inputs of a residual compensator for the poses of ``data``.

    ``"torques"``: the gravity ("effective") torques of every joint from the
    calibrated model and each row's payload (GA paper, eq. 13);
    ``"angles"``: the joint readings in radians (TLBO paper).
    """
    if features == "torques":
        m = result.model
        return m.torques(data.q, result.parameters.values, m.covariates(data))
    if features == "angles":
        return data.q
    raise InputError(f"unknown compensator features {features!r}; use 'torques' or 'angles'")


def frame_rotations(result: CalibrationResult, data: Measurements, frame: str) -> np.ndarray:
    """Rotations (N, 3, 3) from ``frame`` coordinates to the measurement frame, per pose.

    ``"measurement"``: identity. ``"joint1"``: the frame that turns with
    joint 1 (the robot base rotated about the first joint axis by the
    reading q1). Gravity torques and every effect of joints 2..n are the
    same whatever q1 is, but their position error seen in the measurement
    frame turns with q1; in this frame it does not, so a compensator of
    the other joints' angles or torques can learn it.
    """
    N = len(data)
    if frame == "measurement":
        return np.broadcast_to(np.eye(3), (N, 3, 3))
    if frame != "joint1":
        raise InputError(f"unknown compensator frame {frame!r}; use 'measurement' or 'joint1'")
    from ..kinematics import base_pose_matrix
    xyz, rpy = result.base_pose()
    Rb = base_pose_matrix(xyz, rpy)[:3, :3]
    p = result.parameters
    robot = result.model.robot
    if robot.convention == "mdh":   # link 1 turns its axis by alpha1 (and Hayati's beta1, if modelled)
        a = p["alpha1"].value
        b = p["beta1"].value if "beta1" in p else 0.0
        ca_, sa, cb, sb = np.cos(a), np.sin(a), np.cos(b), np.sin(b)
        Rx = np.array([[1, 0, 0], [0, ca_, -sa], [0, sa, ca_]])
        Ry = np.array([[cb, 0, sb], [0, 1, 0], [-sb, 0, cb]])
        Rb = Rb @ Rx @ Ry
    j1 = robot.joints[0]
    q1 = data.q[:, 0] if j1.coupling is None else data.q @ j1.coupling + j1.coupling_offset
    th = q1 + p["theta1"].value
    c, s = np.cos(th), np.sin(th)
    Rz = np.zeros((N, 3, 3))
    Rz[:, 0, 0], Rz[:, 0, 1], Rz[:, 1, 0], Rz[:, 1, 1], Rz[:, 2, 2] = c, -s, s, c, 1.0
    return Rb @ Rz


def to_frame(result: CalibrationResult, data: Measurements, frame: str, r: np.ndarray) -> np.ndarray:
    """Measurement-frame vectors ``r`` (N, 3) in ``frame`` coordinates."""
    R = frame_rotations(result, data, frame)
    return np.einsum("nji,nj->ni", R, r)


def from_frame(result: CalibrationResult, data: Measurements, frame: str, y: np.ndarray) -> np.ndarray:
    """``frame`` vectors ``y`` (N, 3) in measurement-frame coordinates."""
    R = frame_rotations(result, data, frame)
    return np.einsum("nij,nj->ni", R, y)


class Method:
    """Base class of the calibration methods.

    Subclasses set ``name`` (the registry key), ``paper`` and ``summary``,
    accept their settings as keyword arguments, and implement :meth:`fit`.
    """

    #: registry key, as used by ``compare --methods``
    name: ClassVar[str] = ""
    #: where the method comes from
    paper: ClassVar[str] = ""
    #: one line for tables and ``--help``
    summary: ClassVar[str] = ""
    #: position in tables (the papers' order: nominal, KM, SKCM, variants)
    order: ClassVar[int] = 100

    def __init__(self, **settings):
        meta = ("name", "paper", "summary", "order", "fit", "run")
        unknown = [k for k in settings if not hasattr(self, k) or k.startswith("_") or k in meta]
        if unknown:
            raise InputError(f"method {self.name}: unknown setting(s) {', '.join(sorted(unknown))}")
        for k, v in settings.items():
            setattr(self, k, v)

    def fit(self, inputs: Inputs) -> MethodResult:
        """Identify (and train) on ``inputs``; return a result without validation stats."""
        raise NotImplementedError

    def run(self, inputs: Inputs, validation: Measurements | None = None) -> MethodResult:
        """Time :meth:`fit`, then evaluate on calibration, extra and validation poses."""
        t0 = time.perf_counter()
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            res = self.fit(inputs)
        res.time_s = time.perf_counter() - t0
        res.name = self.name
        res.calibration = res.stats(inputs.calibration)
        if inputs.extra is not None:
            res.extra = res.stats(inputs.extra)
        if validation is not None:
            res.validation = res.stats(validation)
        return res


def new_result(result: CalibrationResult, **kwargs) -> MethodResult:
    """A MethodResult whose statistics are filled in by :meth:`Method.run`."""
    empty = ErrorStats(0, float("nan"), float("nan"), float("nan"), float("nan"))
    return MethodResult(name="", calibration=empty, validation=None, time_s=0.0, result=result, **kwargs)


def compliant_joints(robot: Robot, joints=None) -> list[int]:
    """The compliant joints of a method: the given ones, else every joint but the first and the last.

    On a six-axis arm the default is the papers' joints 2-5 (joint 1 turns
    about the vertical, the last joint carries little torque); on other arms
    the same rule gives 2..n-1 (joint 2 alone on a three-axis arm).
    """
    js = tuple(range(2, max(robot.n, 3))) if joints is None else tuple(int(j) for j in joints)
    out = [j for j in js if 1 <= j <= robot.n]
    if not out:
        raise InputError(f"no compliant joint among {list(js)} on {robot.name} ({robot.n} joints)")
    return out


def compliance_model(joints: list[int]) -> str:
    """Model specification ``kinematic+compliance[j,...]``."""
    return "kinematic+compliance[" + ",".join(str(j) for j in joints) + "]"
