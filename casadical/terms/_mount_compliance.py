"""Mount compliance: the robot's base tilts under the moment of its weights about the mount."""

from __future__ import annotations

import math
import re
from dataclasses import replace

import casadi as ca
import numpy as np

from .._format import relative
from ..errors import DataFileError, ModelError
from ..kinematics import Geometry, chain_angles, forward, mount_moment
from ..parameters import Parameter
from ..robot import GRAVITY, Robot
from ._base import Context, ErrorTerm, reach, register
from ._cause import Cause, register_cause

#: largest tilt admitted at the largest moment the robot can put on its mount (rad; every mass at full reach, well
#: beyond any pose's), for a mount that is the same in every session (a pedestal, a table, a track's carriage): half
#: a degree is a mount coming loose, not a compliance
MAX_TILT = 0.01
#: the same for a mount that differs between sessions (one compliance per session, or a law over a session column):
#: a lifting column or a mast, which bends by design and more the further it is out. Trailblazer's column, 3.87 m
#: out, tilts 29.6 urad/(N m) between its own accelerometers at its base and tip (8.6 mrad over the poses), and its
#: tracked chassis with it: the arm's base, per session, 40 to 87 urad/(N m) (benchmarks/studies/study_column.py),
#: 0.057 rad at the 658 N m of the arm's masses at full reach; bounded at MAX_TILT (15.2 urad/(N m)) the column's
#: give was named joint compliances "of one session" (issue 49). A tenth of a radian (5.7 deg) at that moment is a
#: mount falling over, not a compliance
MAX_COLUMN_TILT = 0.1


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

    A **law over a session covariate** (``mount_compliance[height_m]``):
    the compliance follows a numeric column of the data that is constant
    within each session (a lifting column's height, a track position, a
    payload), ``C(v) = sum_k c_k b_k(t)``, ``b_k`` the Bernstein polynomials
    of degree ``degree`` (1: a straight line; ``[height_m:2]``: a parabola)
    of ``t = (v - lo) / (hi - lo)``, ``lo`` and ``hi`` the column's range
    over the calibration poses (kept with the calibration: a session beyond
    it is extrapolated). Degree 1: ``c_0`` and ``c_1`` are the compliances at
    ``lo`` and at ``hi``. Each ``c_k`` is bounded as one compliance is, so the
    law stays within the bounds over the range (a Bernstein polynomial lies
    within its coefficients). Parameters ``cmount_0`` ... (``cmount_x_0``,
    ``cmount_y_0`` ... with ``xy``).

    Parameters
    ----------
    axes : {"", "xy"}
        ``""`` (``mount_compliance``): one compliance ``cmount``, the same
        about every horizontal axis (a round column). ``"xy"``
        (``mount_compliance[xy]``): ``cmount_x`` and ``cmount_y`` about the
        base frame's x and y axes, ``theta = (Cx M_x, Cy M_y, 0)`` (a track's
        carriage, stiffer along the track); for a robot standing on (or
        hanging from) its base, gravity along its z axis.
    law : str
        The column the compliance follows ("": none, one value).
    degree : int
        The law's degree (1 or 2).
    law_lo, law_hi : float
        The column's range the law is written over (set from the calibration poses).

    Raises
    ------
    ModelError
        The robot file gives no masses (the moment cannot be computed).
    """

    name = "mount_compliance"
    cause = "mount_compliance"
    bound_meaning = {k: {"lower": " (no positive compliance: the mount is stiffer than these poses can tell, or the "
                              "fit needs the base to tilt away from its weights)",
                     "upper": " (a tilt of 0.01 rad at the largest moment, 0.1 rad for a mount that differs "
                              "between sessions: a mount coming loose, not a compliance)"}
                     for k in ("cmount", "cmount_x", "cmount_y", "cmount_", "cmount_x_", "cmount_y_")}
    superset_order = 5
    superset_group = "torques"
    session_local = True

    @classmethod
    def superset(cls, robot: Robot) -> list[ErrorTerm]:
        """The base's tilt under the moment of the weights (it needs the masses)."""
        return [cls()] if max_mount_moment(robot) > 0 else []

    def __init__(self, joints=None, axes: str = "", law: str = "", degree: int = 1, law_lo: float = 0.0,
                 law_hi: float = 1.0):
        super().__init__(None)
        self.axes, self.law, self.degree = str(axes), str(law), int(degree)
        self.law_lo, self.law_hi = float(law_lo), float(law_hi)
        if self.axes not in ("", "xy"):
            raise ModelError(f"mount_compliance: axes must be '' (one compliance) or 'xy' (one about x, one about "
                             f"y), got {axes!r}")
        if self.law and not (_COLUMN.fullmatch(self.law) and self.degree in LAW_DEGREES):
            raise ModelError(f"mount_compliance: a law is a column's name and a degree of {LAW_DEGREES}, got "
                             f"{self.law!r} of degree {degree!r}")
        # a law is a sum of the superset's compliance at per-pose weights: a term of the robot's, never one session's
        self.session_local = not self.law

    @classmethod
    def arguments(cls, args: str) -> dict:
        """``mount_compliance[xy]``: a compliance about x and one about y; ``[height_m]``, ``[height_m:2]``,
        ``[xy,height_m]``: a law over a session covariate, of degree 1 or 2."""
        out: dict = {}
        for part in (a.strip() for a in args.split(",")):
            if part == "xy" and "axes" not in out:
                out["axes"] = "xy"
            elif "law" not in out and (m := _LAW.fullmatch(part)):
                out["law"], out["degree"] = m.group(1), int(m.group(2) or 1)
            else:
                raise ValueError("mount_compliance takes [xy] (a compliance about the base's x axis and one about "
                                 "its y axis), a law over a session column ([height_m], [height_m:2]: of degree 1 or "
                                 "2), both ([xy,height_m]) or nothing (one compliance)")
        return out

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
        args = [a for a in (self.axes, self.law + (f":{self.degree}" if self.law and self.degree > 1 else "")) if a]
        return f"{self.name}[{','.join(args)}]" if args else self.name

    def settings(self) -> dict:
        if not self.law:
            return {"axes": self.axes}
        return {"axes": self.axes, "law": self.law, "degree": self.degree, "law_lo": self.law_lo,
                "law_hi": self.law_hi}

    def axis_names(self) -> list[str]:
        """The compliances about the axes (the superset's parameters a law's coefficients are of)."""
        return ["cmount_x", "cmount_y"] if self.axes else ["cmount"]

    def names(self) -> list[str]:
        if not self.law:
            return self.axis_names()
        return [f"{a}_{k}" for a in self.axis_names() for k in range(self.degree + 1)]

    @property
    def weights(self) -> list[str]:
        """The covariates of a law: each Bernstein polynomial of the column at a pose (``height_m:b0``, ...)."""
        return [f"{self.law}:b{k}" for k in range(self.degree + 1)] if self.law else []

    @property
    def covariates(self) -> tuple[str, ...]:  # type: ignore[override]
        return ("payload_kg", *self.weights)

    def refer(self, data) -> None:
        """A law is written over its column's range on the calibration poses."""
        if self.law:
            v = self._column(data)
            self.law_lo, self.law_hi = float(np.min(v)), float(np.max(v))
            if not self.law_hi > self.law_lo:
                raise ModelError(f"{self.spec()}: {self.law} takes one value ({self.law_lo:g}) over the "
                                 "calibration poses: a law over it needs sessions at two values or more")

    def _column(self, data) -> np.ndarray:
        """The law's column at the poses of ``data``; poses casadical made in memory without it (an accuracy map,
        an export's target poses) take the middle of its range; a file without it is an error naming it."""
        v = data.get(self.law)
        if v is None and data.path == "<memory>":
            return np.full(len(data), (self.law_lo + self.law_hi) / 2)
        if v is None:
            raise DataFileError(f"has no numeric {self.law} column, which the {self.spec()} term reads (its mount "
                                "compliance follows it)", file=data.path, column=self.law)
        return np.asarray(v, float)

    def covariate_values(self, data) -> dict:
        if not self.law:
            return {}
        return dict(zip(self.weights, bernstein(self.degree, self._column(data), self.law_lo, self.law_hi).T))

    def superset_parameters(self, robot: Robot) -> list[tuple[str, str | None]]:
        """A law's coefficient is the superset's compliance about its axis at the weight of its polynomial."""
        if not self.law:
            return super().superset_parameters(robot)
        return [(a, w) for a in self.axis_names() for w in self.weights]

    def parameters(self, robot: Robot) -> list[Parameter]:
        top = max_mount_moment(robot)
        tilt = MAX_COLUMN_TILT if self.law else MAX_TILT     # a law: the mount differs between sessions
        # a unit step of the scaled variable tilts the base 0.1 mrad at the largest moment
        return [Parameter(n, 0.0, "rad/(N*m)", 1e-4 / top, self.name, lower=0.0, upper=tilt / top)
                for n in self.names()]

    def session_parameters(self, robot: Robot) -> list[Parameter]:
        """One session's own mount differs between sessions: bounded by :data:`MAX_COLUMN_TILT`."""
        return [replace(p, upper=p.upper * MAX_COLUMN_TILT / MAX_TILT) if not self.law else p
                for p in self.parameters(robot)]

    def compliance(self, ctx: Context, axis: str):
        """The compliance about ``axis`` at the pose: its parameter, or its law's value."""
        if not self.law:
            return ctx.p[axis]
        return sum(ctx.p[f"{axis}_{k}"] * ctx.cov[w] for k, w in enumerate(self.weights))

    def base_tilt(self, ctx: Context):
        M = ctx.moment()
        if self.axes:
            return ca.vertcat(self.compliance(ctx, "cmount_x") * M[0], self.compliance(ctx, "cmount_y") * M[1], 0)
        return self.compliance(ctx, "cmount") * M


#: a law's column: a name of the measurement file, and its degree (``height_m``, ``height_m:2``)
_COLUMN = re.compile(r"[A-Za-z_][A-Za-z0-9_.]*")
_LAW = re.compile(r"([A-Za-z_][A-Za-z0-9_.]*)(?::([0-9]+))?")
#: the degrees of a law over a session covariate: a straight line, a parabola
LAW_DEGREES = (1, 2)


def bernstein(degree: int, v: np.ndarray, lo: float, hi: float) -> np.ndarray:
    """The Bernstein polynomials of ``degree`` of ``v`` scaled by the range (``lo``, ``hi``) to [0, 1], (N, degree +
    1): within the range each is >= 0 and they sum to 1."""
    t = (np.asarray(v, float) - lo) / (hi - lo)
    return np.column_stack([math.comb(degree, k) * t ** k * (1 - t) ** (degree - k) for k in range(degree + 1)])


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
        """The robot's and each session's, where the moment of the weights changes over their poses; where the
        robot's does and the sessions differ by a column (a session covariate: a column's height), the laws over
        it of each degree its values can tell (a straight line from two values, a parabola from three)."""
        out = [data.make(self.name, session=s) for s in data.mount]
        if None in data.mount:
            out += [data.make(self.name, law=column + (f":{d}" if d > 1 else ""))
                    for column, values in data.session_covariates.items() for d in LAW_DEGREES
                    if len(set(values.values())) > d]
        return out

    def place(self, cand) -> str:
        return "the base's mount"

    def size(self, cand, values, stds, params, linear) -> str:
        return f"tilt {values[0] * 1e6:.3g} mrad per kN m of moment{relative(stds[0], values[0])}"

    def finding_size(self, finding, final) -> str | None:
        """A law: the compliance at the ends (and the middle) of its column's range."""
        cand = finding.candidate
        term = law_term(final.model, cand)
        if term is None:
            return None
        P = final.parameters
        along = [term.law_lo + (term.law_hi - term.law_lo) * k / term.degree for k in range(term.degree + 1)]
        parts = []
        for axis in term.axis_names():
            c = [P[f"{axis}_{k}"].value for k in range(term.degree + 1)]
            at = bernstein(term.degree, np.array(along), term.law_lo, term.law_hi) @ np.array(c)
            parts.append((f"{axis[-1]}: " if term.axes else "") + ", ".join(f"{x * 1e6:.3g}" for x in at))
        return (f"tilt {'; '.join(parts)} mrad per kN m of moment at {term.law} "
                + ", ".join(f"{v:.4g}" for v in along))

    def words(self, cand, params, robot, data, linear) -> str:
        M = np.linalg.norm(mount_moments(robot, data.q, data.get("payload_kg")), axis=1).max(initial=0.0)
        if cand.law is not None:
            column, degree = law_parts(cand.law)
            v = data.get(column)
            if v is None:
                return ""
            lo, hi = float(np.min(v)), float(np.max(v))
            per = degree + 1
            ends = [(params[k].value, params[k + per - 1].value) for k in range(0, len(params), per)]
            return (f"the mount's compliance follows {column} (a {'straight line' if per == 2 else 'parabola'} over "
                    f"its sessions' values): " + "; ".join(f"{a:.3g} rad/(N m) at {lo:.4g}, {b:.3g} at {hi:.4g}"
                                                           for a, b in ends)
                    + f"; the base tilts up to {max(b for _, b in ends) * M * 1e3:.3g} mrad at the largest moment "
                    f"of these poses ({M:.4g} N m)")
        p = params[0]
        return (f"the base tilts {p.value * M * 1e3:.3g} mrad at the largest moment of these poses ({M:.4g} N m; "
                f"compliance {p.value:.3g} rad/(N m), std {p.std:.2g})")

    def figure(self, cand, data, model, params, linear) -> dict:
        return {"x": np.linalg.norm(mount_moments(model.robot, data.q, data.get("payload_kg"))[:, :2], axis=1),
                "xlabel": "moment of the weights about the base, horizontal (N m)", "along": None}

    def own_shape(self, cand) -> tuple[str, str, int | None]:
        return "moment", "tilt", None

    def open_question(self, cand) -> str | None:
        """A law is told by the sessions' values of its column, not by the poses of one: a session at another value
        asks whether it holds there."""
        if cand.law is None:
            return None
        column, degree = law_parts(cand.law)
        return (f"the mount's compliance over {column}: does the {'straight line' if degree == 1 else 'parabola'} "
                f"hold between and beyond the sessions' values? Measure a session at another {column} (candidate "
                f"poses with that {column})")

    def parameter_names(self, cand) -> list[str]:
        if cand.law is None:
            return ["cmount"]
        return [f"cmount_{k}" for k in range(law_parts(cand.law)[1] + 1)]

    def carried(self, cand, params: list) -> list:
        """A session's own mount or a law differs between sessions: bounded by :data:`MAX_COLUMN_TILT`, not the
        robot's one compliance's :data:`MAX_TILT`."""
        if cand.session is None and cand.law is None:
            return params
        return [replace(p, upper=p.upper * MAX_COLUMN_TILT / MAX_TILT) for p in params]

    def factors(self, cand, data, cal) -> np.ndarray | None:
        """A law's columns are the robot's compliance's at its polynomials of the column (its range over the
        calibration poses ``cal``), (N, degree + 1) at the poses of ``data``."""
        if cand.law is None:
            return None
        column, degree = law_parts(cand.law)
        ref = cal.get(column)
        return bernstein(degree, data.get(column), float(np.min(ref)), float(np.max(ref)))

    def terms(self, cands) -> list[ErrorTerm]:
        mine = self.mine(cands)
        laws = [law_parts(law) for law in dict.fromkeys(c.law for c in mine if c.law is not None)]
        return ([MountCompliance()] if any(c.law is None for c in mine) else []) + [
            MountCompliance(law=column, degree=degree) for column, degree in laws]


def law_parts(law: str) -> tuple[str, int]:
    """A candidate's law, its column and degree: ``height_m`` -> (``height_m``, 1), ``height_m:2`` -> (``height_m``,
    2)."""
    column, _, degree = law.partition(":")
    return column, int(degree or 1)


def law_term(model, cand) -> "MountCompliance | None":
    """The term of ``model`` that is the law of candidate ``cand`` (None: ``cand`` is not a law, or not there)."""
    if cand.law is None:
        return None
    column, degree = law_parts(cand.law)
    return next((t for t in model.terms if isinstance(t, MountCompliance) and t.law == column
                 and t.degree == degree), None)


MOUNT_COMPLIANCE = register_cause(MountGive())
