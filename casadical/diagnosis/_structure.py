"""Stage ``screen_structure``: what the model of the named causes leaves, and where it lives.

The catalogue never holds every cause a robot has. After the named causes, what the model leaves on the
calibration poses is tested against what an error can vary with (the **covariates**: every joint's reading
``qK``, every joint's gravity torque ``tauK``, the moment of the weights about the base (``moment``, its two
components across gravity), the pose's ``time`` or order, where the point stands for the instrument:
``azimuth``, ``elevation``, ``distance``, and the user's own columns that change from pose to pose: a tilt
sensor, an accelerometer, a temperature, a motor current, by the column's name,
:func:`casadical.data._covariates.pose_covariates`), in each way an error can show (the **effects**: a
joint's ``angle``; a joint's axis or the base tilting, ``tilt``, the base about the two axes across gravity;
the point moving in the robot's base frame, ``point_base``; the point moving in the measurement frame,
``point_measurement``). Each pair is a flexible smooth term: Legendre polynomials of degree 1 to
:data:`DEGREE` of the covariate scaled to [-1, 1], times the effect's directions (a joint's angle: the point's
derivative w.r.t. its reading; a frame: its three axes). The model's own parameters are refitted beside it
(linearised at the final fit, robust weights), so structure the model can already take counts for nothing.

With data of several sessions, a joint's angle against its own reading or its gravity torque is also tried in
each session alone (the pair's columns at that session's poses only): a joint's own parameter is the robot's,
one value in every session, so structure of that shape in one session only is what differs between the
sessions (the mount, the instrument's set-up, the warm-up: :func:`casadical.terms._cause.session_parts`, or a
load or temperature the data do not give) showing on that joint; it is reported with the session named. The
base's tilt against the moment of the weights in each session alone is the shape of that session's own mount
compliance (what :mod:`._stand_ins` asks it to explain).

A pair is structure when both hold on the calibration poses:

- an F-test of its columns at the diagnosis' level divided among every pair tried (Bonferroni), and
- held-out gain: on random folds of the calibration poses, the model with the term predicts the left-out
  poses better than the model without it, for most of the poses (a paired sign test at the same level).

The strongest pair is kept, its columns join the model, and the rest are tested again (up to
:data:`MAX_STRUCTURES`). Each becomes an ``unexplained`` finding (not in the model) that says where it lives
in words, with its ``covariate``, ``effect``, ``p_value``, its size on the validation poses (``size_mm``:
the mean norm of the term fitted on the calibration poses, judge only) and what the flexible term would gain
there (``potential_gain_mm``). The validation poses never decide.

Reads ``current`` (the model of the named causes), the folds and the level; sets ``structures``; returns the
findings with one for each structure (None: no screen).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import casadi as ca
import numpy as np
from numpy.polynomial import legendre

from ..data import Measurements
from ..data._covariates import pose_covariates
from ..kinematics import Geometry, chain_angles, forward, mount_moment
from ..result import CalibrationResult
from ..terms import UNEXPLAINED
from ..terms._cause import session_parts
from ..terms._mount_compliance import max_mount_moment
from ._candidates import Candidate
from ._report import Finding
from ._state import DiagnosisRun, StageOutcome
from ._statistics import nested_test
from ._validation import Linearized

#: highest degree of the Legendre basis of a covariate
DEGREE = 4
#: at most this many structures are reported
MAX_STRUCTURES = 3
#: random folds of the held-out check
FOLDS = 5
#: where the point stands for the instrument
INSTRUMENT = ("azimuth", "elevation", "distance")


@dataclass
class Structure:
    """One structure the model leaves: what it varies with, how it shows, its test and sizes."""

    covariate: str
    effect: str
    joint: int | None            # the joint whose angle it moves (effect ``angle``)
    session: str | None          # the session it holds in alone (None: every pose)
    log10_p: float
    test_text: str
    size_mm: float               # mean norm of the fitted term on the validation poses
    potential_gain_mm: float     # validation mean without it minus with it
    held_out_share: float        # share of left-out calibration poses it predicts better
    misses: np.ndarray = field(default_factory=lambda: np.zeros(0, int))   # set-aside poses it accounts for
    coefficients: np.ndarray = field(default_factory=lambda: np.zeros(0))   # of its flexible term, as fitted
    ranges: list = field(default_factory=list)   # the covariate's range(s) on the calibration poses
    time_name: str = "time_s"                    # the name its time covariate has in a terms file
    val_left: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))   # the validation residuals with it
                                                                                # and those before it (m)
    #: its joint is a linear axis: its ``angle`` effect is the axis' position error along it (m; reported as
    #: effect ``position``)
    linear: bool = False
    #: the two axes across gravity the base tilts about (robot base frame, (2, 3)): its ``tilt`` without a joint
    across: np.ndarray = field(default_factory=lambda: np.eye(3)[:2])

    def words(self) -> str:
        """Where it lives, in words an engineer reads."""
        return describe_pair(self.covariate, self.effect, self.joint, self.linear, self.session)

    def to_dict(self) -> dict:
        effect = "position" if self.linear and self.effect == "angle" else self.effect
        return {"covariate": self.covariate, "effect": effect, "p_value": 10 ** self.log10_p,
                "size_mm": self.size_mm, "potential_gain_mm": self.potential_gain_mm,
                **({"session": self.session} if self.session is not None else {})}

    def term(self, name: str) -> dict:
        """Its flexible term as a table of a terms file (docs/formats.md section 10): the same Legendre
        polynomials of the covariate, scaled to its range on the calibration poses, in the effect of a cause of
        one's own, one parameter per coefficient (``c1``, ...) starting at its fitted value. A place to start
        from (replace it by a physical form), and what ``plan-poses REPORT.json`` plans the poses of."""
        names = {"moment": [_along(a, ("mx", "my", "mz")) for a in self.across],
                 "time": [self.time_name]}.get(self.covariate, [self.covariate])
        c = iter(range(1, len(self.coefficients) + 1))

        def series(var: str, rng) -> str:
            lo, hi = rng
            t = f"(2 * ({var} - {lo:.9g}) / {hi - lo:.9g} - 1)"
            polys = [t, f"(3 * {t} ** 2 - 1) / 2", f"(5 * {t} ** 3 - 3 * {t}) / 2",
                     f"(35 * {t} ** 4 - 30 * {t} ** 2 + 3) / 8"][:DEGREE]
            return " + ".join(f"c{next(c)} * {poly}" for poly in polys)

        # the coefficients as _columns lays them out: for each component of the covariate (the moment's about x,
        # then about y), direction by direction, degree by degree; the base's tilt pairs each axis with its own
        ranges = self.ranges if len(names) > 1 else [self.ranges]
        if self.covariate == "moment" and self.effect == "tilt":
            per_dir = [[series(var, rng)] for var, rng in zip(names, ranges)]
        else:
            n_dir = len(self.coefficients) // (DEGREE * len(names))
            per_dir = [[] for _ in range(n_dir)]
            for var, rng in zip(names, ranges):
                for d in range(n_dir):
                    per_dir[d].append(series(var, rng))
        f = ["(" + " + ".join(parts) + ")" if parts else "0" for parts in per_dir]
        table: dict = {"name": name}
        if self.effect == "angle" and self.linear:      # a linear axis' position error (m): an offset effect
            table.update(joint=self.joint, offset=f[0])
        elif self.effect == "angle":
            table.update(joint=self.joint, angle=f[0])
        elif self.effect == "tilt" and self.joint is not None:
            table.update(joint=self.joint, frame=["0", "0", "0", f[0], f[1], "0"])
        elif self.effect == "tilt":      # about the two axes across gravity (the base's x and y where it is along z)
            table.update(base=["0", "0", "0", *[_along(a, f[:2]) for a in self.across.T]])
        elif self.effect == "point_base":
            table.update(base=[f[0], f[1], f[2], "0", "0", "0"])
        elif self.covariate == "azimuth":
            table.update(point=[f"-{f[0]} * py", f"{f[0]} * px", "0"])
        elif self.covariate == "elevation":
            rho = "sqrt(px ** 2 + py ** 2)"
            table.update(point=[f"{f[0]} * px * pz / {rho}", f"{f[0]} * py * pz / {rho}", f"-{f[0]} * {rho}"])
        elif self.covariate == "distance":
            table.update(point=[f"{f[0]} * px / distance", f"{f[0]} * py / distance", f"{f[0]} * pz / distance"])
        else:
            table.update(point=f[:3])
        metres = (self.effect in ("point_base", "point_measurement") and self.covariate not in (
            "azimuth", "elevation")) or (self.effect == "angle" and self.linear)
        top = max(float(np.abs(self.coefficients).max(initial=0.0)), 1e-6)
        table["parameters"] = {f"c{i + 1}": {"scale": top, "lower": -20 * top, "upper": 20 * top,
                                             "unit": "m" if metres else "rad", "start": float(v)}
                               for i, v in enumerate(self.coefficients)}
        return table


def _along(weights, names) -> str:
    """``sum w_k names_k`` as an expression (a name alone where its weight is 1 and the others 0; "0": none)."""
    terms = [(float(w), n) for w, n in zip(weights, names) if abs(float(w)) > 1e-12]
    if len(terms) == 1 and terms[0][0] == 1.0:
        return terms[0][1]
    return "(" + " + ".join(f"{w:.12g} * {n}" for w, n in terms) + ")" if terms else "0"


def describe_pair(covariate: str, effect: str, joint: int | None, linear: bool = False,
                  session: str | None = None) -> str:
    """A pair of covariate and effect in words an engineer reads (``linear``: the joint is a linear axis, its
    ``angle`` effect a position error along it, in mm; ``session``: it holds in that session alone)."""
    if session is not None:
        own = describe_pair(covariate, effect, joint, linear)
        what = f"what differs between the sessions ({', '.join(session_parts())}, or a load or a temperature the " \
               "data do not give)"
        if joint is None:
            return f"{own}, in session {session} only: {what}"
        return (f"{own}, in session {session} only: a joint's own parameter is the robot's, so {what} shows on "
                f"joint {joint}")
    cov = _covariate_words(covariate)
    if effect == "angle" and linear:
        own = covariate == f"q{joint}"
        return (f"axis {joint}'s position error (along it, mm) varies with "
                + ("its own position (not as any catalogue cause of that axis)" if own else cov))
    if effect == "tilt" and linear and covariate == f"q{joint}":
        return f"axis {joint}'s carriage tilts as it travels (not as the catalogue's carriage angles)"
    if effect == "angle":
        own = covariate == f"q{joint}"
        return (f"joint {joint}'s angle error varies with "
                + ("its own reading (not as any catalogue cause of that joint)" if own else cov))
    if effect == "tilt":
        if joint is None:
            return f"the robot's base tilts with {cov}"
        return f"joint {joint}'s axis tilts " + ("as it turns" if covariate == f"q{joint}" else f"with {cov}")
    if effect == "point_base":
        return f"the point moves in the robot's base frame with {cov}"
    text = f"the point moves in the measurement frame with {cov}"
    if covariate in INSTRUMENT:
        text += ": the instrument's own error or the robot's, only another session (the instrument placed " \
                "elsewhere) can tell"
    return text


def _covariate_words(cov: str) -> str:
    if cov.startswith("q"):
        return f"joint {cov[1:]}'s reading"     # a linear axis' reading is its position (mm in the files)
    if cov.startswith("tau"):
        return f"joint {cov[3:]}'s gravity torque"
    if cov == "moment":
        return "the moment of the weights about the base"
    if cov == "time":
        return "the time of the pose (its order in the measurements)"
    if cov in INSTRUMENT:
        return f"the point's {cov} as the instrument sees it"
    return f"{cov} (a column of the data)"


def _direction_key(cov: str, effect: str, joint: int | None):
    """The key of an effect's directions: the instrument's own errors move the point as their covariate says."""
    if effect == "point_measurement" and cov in INSTRUMENT:
        return effect, cov
    return effect, joint


def _range(v: np.ndarray):
    """A covariate's range on the calibration poses (per component for the moment)."""
    if v.ndim == 2:
        return [(float(np.min(v[:, k])), float(np.max(v[:, k]))) for k in range(v.shape[1])]
    return float(np.min(v)), float(np.max(v))


def _basis(x: np.ndarray, ref: tuple[float, float]) -> np.ndarray:
    """Legendre polynomials of degree 1..DEGREE of ``x`` scaled by ``ref`` (lo, hi) to [-1, 1]: (N, DEGREE)."""
    lo, hi = ref
    t = np.clip(2 * (x - lo) / (hi - lo) - 1, -1.5, 1.5) if hi > lo else np.zeros_like(x)
    return legendre.legvander(t, DEGREE)[:, 1:]


def _has_masses(robot) -> bool:
    return max_mount_moment(robot) > 0


def across_gravity(robot) -> np.ndarray:
    """Two unit axes across the robot file's gravity, robot base frame (2, 3): the base's x and y where gravity is
    along its z (a robot on a floor or a ceiling); else the base's x (its y, where x is near gravity's line) made
    horizontal, and the axis across both, ``up x e1`` (a robot on a wall or on a column's side)."""
    g = np.asarray(robot.gravity, float)
    up = -g / np.linalg.norm(g)
    if np.hypot(up[0], up[1]) < 1e-12:
        return np.eye(3)[:2].copy()
    e = next(e for e in np.eye(3)[:2] if np.linalg.norm(e - (e @ up) * up) > 0.1)
    e1 = e - (e @ up) * up
    e1 /= np.linalg.norm(e1)
    return np.array([e1, np.cross(up, e1)])


def _frames_function(robot) -> ca.Function:
    """Readings and payload -> the moment of the weights about the base (3), then for each joint its axis (3),
    a point on it (3) and the x axis of the link after it (3), and the tool point (3); robot base frame, nominal
    geometry (a covariate and a direction need no calibrated millimetres)."""
    q, m = ca.SX.sym("q", robot.n), ca.SX.sym("m")
    geom = Geometry.nominal(robot)
    fr = forward(robot, chain_angles(robot, q, geom), geom)
    outs = [mount_moment(robot, fr, m)] if _has_masses(robot) else [ca.SX.zeros(3, 1)]
    for i in range(robot.n):
        outs += [fr.axis[i], fr.origin[i], fr.link[i][0][:, 0]]
    outs.append(fr.tool[1])
    return ca.Function("structure_frames", [q, m], [ca.vertcat(*outs)])


@dataclass
class Poses:
    """What the screen needs of each pose, robot base frame: the moment of the weights, the joints' axes, points
    on them and the x axes of the links after them, the tool point; and each pose's base rotation (to the
    measurement frame)."""

    moment: np.ndarray      # (N, 3)
    across: np.ndarray      # (2, 3): the axes across gravity
    axis: np.ndarray        # (N, n, 3)
    origin: np.ndarray      # (N, n, 3)
    link_x: np.ndarray      # (N, n, 3)
    point: np.ndarray       # (N, 3)
    R: np.ndarray           # (N, 3, 3) base -> measurement frame

    @classmethod
    def of(cls, res: CalibrationResult, data: Measurements) -> "Poses":
        robot, N = res.model.robot, len(data)
        payload = data.get("payload_kg")
        m = np.full(N, robot.payload_mass) if payload is None else np.asarray(payload, float)
        out = np.array(_frames_function(robot).map(N)(data.q.T, m[None, :])).T
        n = robot.n
        per_joint = out[:, 3:3 + 9 * n].reshape(N, n, 3, 3)
        if data.sessions is None:
            R = np.broadcast_to(res.base_matrix()[:3, :3], (N, 3, 3)).copy()
        else:
            R = np.empty((N, 3, 3))
            for s in data.session_names:
                R[data.sessions == s] = res.base_matrix(s)[:3, :3]
        return cls(out[:, :3], across_gravity(robot), per_joint[:, :, 0], per_joint[:, :, 1], per_joint[:, :, 2],
                   out[:, -3:], R)


def covariates(res: CalibrationResult, data: Measurements, torques: np.ndarray, poses: Poses,
               own: tuple = ()) -> dict[str, np.ndarray]:
    """Every covariate of the screen at ``data``'s poses (rad, N m, s, m); ``moment`` is (N, 2): about the two
    axes across gravity (:func:`across_gravity`); ``own``: the columns of one's own the screen tries."""
    out = {f"q{j + 1}": data.q[:, j] for j in range(data.q.shape[1])}
    out.update({f"tau{j + 1}": torques[:, j] for j in range(torques.shape[1])})
    if _has_masses(res.model.robot):
        out["moment"] = poses.moment @ poses.across.T
    t = data.get("time_s")
    out["time"] = np.asarray(t, float) if t is not None else np.arange(len(data), dtype=float)
    out.update({c: np.asarray(data.get(c), float) for c in own})
    if data.touches:        # no instrument looks at the rows that touch: no line of sight
        return out
    x, y, z = data.xyz.T
    out["azimuth"] = np.arctan2(y, x)
    out["elevation"] = np.arctan2(z, np.hypot(x, y))
    out["distance"] = np.linalg.norm(data.xyz, axis=1)
    return out


def directions(res: CalibrationResult, data: Measurements, poses: Poses
               ) -> dict[tuple[str, int | None], np.ndarray]:
    """Each effect's directions at ``data``'s poses, (N, 3, k) in the measurement frame: a joint's angle (the
    point's derivative w.r.t. its reading); a joint's axis tilting (the point turned about the two axes across
    the joint's axis, fixed in the link after it, through a point of the axis); the base tilting on its mount (turned
    about the two axes across gravity through the base frame's origin); the robot's base frame's axes; the
    measurement frame's axes."""
    m, p = res.model, res.parameters
    _, Jq = m.predict_q_jacobian(data.q, p.values, m.covariates(data), res.base0)
    N, n = len(data), Jq.shape[2]
    out: dict[tuple[str, int | None], np.ndarray] = {("angle", j + 1): Jq[:, :, j:j + 1] for j in range(n)}
    to_meas = lambda v: np.einsum("nij,nj->ni", poses.R, v)      # noqa: E731
    for j in range(n):
        z, o = poses.axis[:, j], poses.origin[:, j]
        u1 = poses.link_x[:, j] - np.einsum("ni,ni->n", poses.link_x[:, j], z)[:, None] * z
        u1 /= np.linalg.norm(u1, axis=1, keepdims=True)
        u2 = np.cross(z, u1)
        lever = poses.point - o
        out[("tilt", j + 1)] = np.stack([to_meas(np.cross(u1, lever)), to_meas(np.cross(u2, lever))], axis=2)
    ex, ey = poses.across
    out[("tilt", None)] = np.stack([to_meas(np.cross(np.broadcast_to(ex, (N, 3)), poses.point)),
                                    to_meas(np.cross(np.broadcast_to(ey, (N, 3)), poses.point))], axis=2)
    out[("point_base", None)] = np.ascontiguousarray(poses.R)
    out[("point_measurement", None)] = np.broadcast_to(np.eye(3), (N, 3, 3)).copy()
    if data.touches:
        return out
    # the instrument at the measurement frame's origin: the point moved along the frame's axes (with time), or
    # as the instrument's own errors move it: turned about the vertical axis (azimuth), about the horizontal axis
    # across the line of sight (elevation), along the line of sight (distance)
    p = data.xyz
    ez = np.broadcast_to(np.eye(3)[2], (N, 3))
    across = np.cross(ez, p)
    across /= np.maximum(np.linalg.norm(across, axis=1, keepdims=True), 1e-12)
    out[("point_measurement", "azimuth")] = np.cross(ez, p)[:, :, None]
    out[("point_measurement", "elevation")] = np.cross(across, p)[:, :, None]
    out[("point_measurement", "distance")] = (p / np.maximum(np.linalg.norm(p, axis=1, keepdims=True), 1e-12)
                                              )[:, :, None]
    return out


def projection(res: CalibrationResult, data: Measurements):
    """How columns at ``data``'s rows are projected: away from what rows that touch fit of their own
    (:class:`casadical.rows._layout.Projection`), unchanged for measured rows."""
    if not data.touches:
        return lambda X: X
    return data.layout.projection(res.predict(data))



def pairs(n_joints: int, moment: bool, own: tuple = (), sessions: tuple = (), instrument: bool = True
          ) -> list[tuple[str, str, int | None, str | None]]:
    """Every (covariate, effect, joint, session) the screen tries: of every pose (session None); ``own``: the
    columns of one's own it tries too (a sensor's: the base's tilt, the point in either frame, each joint's angle);
    ``sessions``: each joint's angle against its reading and its gravity torque, and the base's tilt against the
    moment of the weights (a session's own mount), in each of these alone; ``instrument``: its view too, when an
    instrument measured every row."""
    readings = [f"q{j}" for j in range(1, n_joints + 1)]
    robot_cov = readings + [f"tau{j}" for j in range(1, n_joints + 1)] + ["moment"] * moment + ["time"]
    out = [(c, "angle", j) for j in range(1, n_joints + 1) for c in robot_cov]
    out += [(c, "tilt", j) for j in range(1, n_joints + 1) for c in readings]
    out += [(c, "tilt", None) for c in ["moment"] * moment + ["time"]]
    out += [(c, "point_base", None) for c in robot_cov]
    out += [(c, "point_measurement", None) for c in INSTRUMENT * instrument + ("time",)]
    out += [(c, e, None) for c in own for e in ("tilt", "point_base") + ("point_measurement",) * instrument]
    out += [(c, "angle", j) for c in own for j in range(1, n_joints + 1)]
    out = [(*p, None) for p in out]
    out += [(c, "angle", j, s) for s in sessions for j in range(1, n_joints + 1) for c in (f"q{j}", f"tau{j}")]
    out += [("moment", "tilt", None, s) for s in sessions if moment]
    return out


def _columns(cov: np.ndarray, ref, dirs: np.ndarray, at: np.ndarray | None = None) -> np.ndarray:
    """(N, 3, DEGREE * k): each basis function times each direction. A covariate of two components (the moment
    about x and y): a tilt about the base's x (y) axis by a function of the moment about it; any other effect by
    functions of each component. ``at``: the poses of the session it holds in alone (a mask; zeros elsewhere)."""
    if at is not None:
        return _columns(cov, ref, dirs) * at[:, None, None]
    if cov.ndim == 2:
        if dirs.shape[2] == 2:     # the base's tilt about x and about y
            return np.concatenate([_columns(cov[:, k], ref[k], dirs[:, :, k:k + 1]) for k in (0, 1)], axis=2)
        return np.concatenate([_columns(cov[:, k], ref[k], dirs) for k in (0, 1)], axis=2)
    B = _basis(cov, ref)
    return (dirs[:, :, :, None] * B[:, None, None, :]).reshape(len(cov), 3, -1)


def weighted(X: np.ndarray, sw: np.ndarray) -> np.ndarray:
    """(N, 3, k) columns as the rows of a weighted least-squares problem: (3N, k), each pose by its weight."""
    return X.reshape(-1, X.shape[2]) * sw[:, None]


class _Folds:
    """The random folds of the held-out check beside fixed columns ``J`` (N, 3, p) at weights ``w``: each fold's
    fit without a term and its left-out errors are the same for every term tried, so they are made once."""

    def __init__(self, J: np.ndarray, r: np.ndarray, w: np.ndarray, folds: list[np.ndarray]):
        self.J, self.r, self.w = J, r, w
        self.parts = []
        for test in folds:
            train = np.setdiff1d(np.arange(len(r)), test)
            sw = np.sqrt(np.repeat(w[train], 3))
            rt = r[train].ravel() * sw
            A0 = weighted(J[train], sw)
            x0 = np.linalg.lstsq(A0, rt, rcond=None)[0]
            self.parts.append((test, train, sw, rt, A0, np.linalg.norm(r[test] - J[test] @ x0, axis=1)))

    def held_out_share(self, X: np.ndarray) -> tuple[float, int, int]:
        """Left-out poses predicted better with the term ``X`` than without: (share, wins, counted)."""
        wins = counted = 0
        for test, train, sw, rt, A0, e0 in self.parts:
            A1 = np.hstack([A0, weighted(X[train], sw)])
            x1 = np.linalg.lstsq(A1, rt, rcond=None)[0]
            e1 = np.linalg.norm(self.r[test] - np.concatenate([self.J[test], X[test]], axis=2) @ x1, axis=1)
            keep = self.w[test] >= 0.5
            wins += int(np.sum((e1 < e0) & keep))
            counted += int(np.sum(keep))
        return (wins / counted if counted else 0.0), wins, counted


def _sign_log10_p(wins: int, n: int) -> float:
    """log10 of the one-sided sign test's p-value of ``wins`` of ``n`` (normal approximation)."""
    if n == 0:
        return 0.0
    z = (wins - 0.5 * n) / math.sqrt(0.25 * n)
    return math.log10(max(0.5 * math.erfc(z / math.sqrt(2)), 1e-300))


@dataclass
class Found:
    """The strongest structure of a residual: its pair, its columns on the calibration poses, its test."""

    covariate: str
    effect: str
    joint: int | None
    session: str | None
    X: np.ndarray
    log10_p: float
    test_text: str
    held_out_share: float


#: a structure screen keeps its pairs' columns where all of them take less than this (bytes; 300 poses: about 20 MB)
KEEP_BYTES = 256e6


class StructureScreen:
    """The structure screen of one fit on the calibration poses: its covariates, effects' directions, folds."""

    def __init__(self, res: CalibrationResult, cal: Measurements, torques: np.ndarray, alpha: float,
                 seed: int = 0, val: Measurements | None = None):
        self.res, self.cal = res, cal
        self.poses = Poses.of(res, cal)
        # the columns of one's own the validation poses have too (the size of a structure is judged there)
        self.own = tuple(c for c in pose_covariates(cal) if val is None or val.get(c) is not None)
        self.cov = covariates(res, cal, torques, self.poses, self.own)
        self.dirs = directions(res, cal, self.poses)
        self.project = projection(res, cal)
        self.refs = {k: (_range(v)) for k, v in self.cov.items()}
        sessions = tuple(cal.session_names) if len(cal.session_names) > 1 else ()
        self.tried = pairs(cal.q.shape[1], "moment" in self.cov, self.own, sessions, "azimuth" in self.cov)
        self.level = math.log10(alpha / len(self.tried))
        self.folds = np.array_split(np.random.default_rng(seed).permutation(len(cal)), FOLDS)
        self._kept: dict[tuple, np.ndarray] = {}

    def columns(self, cov: str, effect: str, joint: int | None, session: str | None = None) -> np.ndarray:
        """The pair's columns at the calibration poses (N, 3, k), read-only: kept while every pair's together
        take less than :data:`KEEP_BYTES` (the stand-in check asks each pair once per named cause)."""
        X = self._kept.get((cov, effect, joint, session))
        if X is None:
            at = None if session is None else (self.cal.sessions == session).astype(float)
            X = self.project(_columns(self.cov[cov], self.refs[cov], self.dirs[_direction_key(cov, effect, joint)],
                                      at))
            X.flags.writeable = False
            if X.nbytes * len(self.tried) <= KEEP_BYTES:
                self._kept[cov, effect, joint, session] = X
        return X

    def strongest(self, base: np.ndarray, r: np.ndarray, w: np.ndarray, skip=(), only=None) -> Found | None:
        """The pair that explains most of ``r`` beside the columns ``base`` (N, 3, p) at weights ``w``, if it is
        significant at the level and predicts left-out poses better (see the module); ``skip``: pairs not to
        try; ``only``: the pairs to try (default: every pair)."""
        sw = np.sqrt(np.repeat(w, 3))
        Q, _ = np.linalg.qr(weighted(base, sw))
        rw = r.ravel() * sw
        r0 = rw - Q @ (Q.T @ rw)
        ssr0 = float(r0 @ r0)
        scored = []
        for pair in self.tried if only is None else only:
            if pair in skip:
                continue
            X = self.columns(*pair)
            Xw = weighted(X, sw)
            Xw = Xw - Q @ (Q.T @ Xw)
            # one singular value decomposition gives the rank (matrix_rank's tolerance) and the least-squares
            # residual (lstsq's default cut-off: machine epsilon times the larger dimension)
            U, sv, _ = np.linalg.svd(Xw, full_matrices=False)
            k = int(np.sum(sv > 1e-10 * max(np.abs(Xw).max(), 1e-300)))
            if k == 0:
                continue
            Uk = U[:, sv > np.finfo(float).eps * max(Xw.shape) * sv[0]]
            ssr1 = float(np.sum((r0 - Uk @ (Uk.T @ r0)) ** 2))
            test = nested_test(ssr0, base.shape[2], ssr1, base.shape[2] + k, len(rw))
            scored.append((test.log10_p, pair, test))     # not its columns: 140 pairs of 20,000 poses are 0.8 GB
        scored.sort(key=lambda t: t[0])
        folds = None
        for log10_p, pair, test in scored:
            if log10_p >= self.level or test.delta_bic >= 0:
                return None
            folds = folds or _Folds(base, r, w, self.folds)
            X = self.columns(*pair)
            share, wins, counted = folds.held_out_share(X)
            if share > 0.5 and _sign_log10_p(wins, counted) < self.level:
                return Found(*pair, X, log10_p, test.text(), share)
        return None


def screen(res: CalibrationResult, lin: Linearized, cal: Measurements, val: Measurements, cal_torques: np.ndarray,
           val_torques: np.ndarray, alpha: float, seed: int = 0, known: frozenset = frozenset()) -> list[Structure]:
    """The structures ``res`` leaves on ``cal`` (see the module; ``lin``: ``res`` linearised on ``cal``), strongest
    first; ``known``: (joint, session) of structure of one session the search reported already (its joint's
    pairs in that session are not tried)."""
    scr = StructureScreen(res, cal, cal_torques, alpha, seed, val)
    r, w = lin.r, lin.weights
    sw = np.sqrt(np.repeat(w, 3))
    lin_v = dir_v = base_v = cov_v = proj_v = None
    found: list[Structure] = []
    base = lin.J
    while len(found) < MAX_STRUCTURES:
        skip = {(f.covariate, f.effect, f.joint, f.session) for f in found} | {
            (c, "angle", j, s) for j, s in known if s is not None for c in (f"q{j}", f"tau{j}")}
        s = scr.strongest(base, r, w, skip=skip)
        if s is None:
            break
        # the term fitted with the model's parameters on the calibration poses, taken to the validation poses
        # (the parameters refitted beside it: the term alone is not what it changes where it is confounded)
        base = np.concatenate([base, s.X], axis=2)
        x1 = np.linalg.lstsq(weighted(base, sw), r.ravel() * sw, rcond=None)[0]
        if lin_v is None:
            poses_v = Poses.of(res, val)
            lin_v, dir_v = Linearized.of(res, val), directions(res, val, poses_v)
            cov_v = covariates(res, val, val_torques, poses_v, scr.own)
            base_v, proj_v = lin_v.J, projection(res, val)
        at_v = None if s.session is None else (val.sessions == s.session).astype(float)
        Xv = proj_v(_columns(cov_v[s.covariate], scr.refs[s.covariate],
                             dir_v[_direction_key(s.covariate, s.effect, s.joint)], at_v))
        base_v = np.concatenate([base_v, Xv], axis=2)
        change = base_v @ x1
        before = np.linalg.norm(lin_v.r, axis=1)
        after = np.linalg.norm(lin_v.r - change, axis=1)
        # the poses the robust loss set aside that this structure (with those before it) brings back within its
        # limit: the largest misses of the structure, not bad measurements
        left = r - base @ x1
        back = np.flatnonzero((w < 0.5) & (res.loss.weight(np.einsum("ij,ij->i", left, left)) >= 0.5))
        back = np.setdiff1d(back, np.concatenate([f.misses for f in found] + [np.zeros(0, int)]))
        found.append(Structure(s.covariate, s.effect, s.joint, s.session, s.log10_p, s.test_text,
                               float(np.mean(np.linalg.norm(change, axis=1)) * 1000),
                               float((before.mean() - after.mean()) * 1000), s.held_out_share, back,
                               x1[-s.X.shape[2]:], scr.refs[s.covariate],
                               "time_s" if cal.get("time_s") is not None else "row", lin_v.r - change,
                               s.joint is not None and res.model.robot.joints[s.joint - 1].prismatic,
                               scr.poses.across))
    return found


def screen_structure(run: DiagnosisRun) -> StageOutcome | None:
    """Stage: screen what the model of the named causes (``current``) leaves; each structure found is an
    ``unexplained`` finding, not in the model."""
    if not run.s.structure:
        return None
    res = run.current
    run.say("structure screen: what the named causes leave, against every joint's reading and torque, the moment "
            "of the weights, time" + (" and the data's own columns (no instrument looks at rows that touch)"
                                      if run.cal.touches else ", the instrument's view and the data's own columns"))
    val_torques = res.model.torques(run.val.q, res.parameters.values, res.model.covariates(run.val))
    found = screen(res, run.linearized(res), run.cal, run.val, run.torques(res), val_torques, run.s.alpha,
                   run.s.seed, frozenset(run.unexplained.by_joint))
    if not found:
        run.say("  nothing the named causes leave is structure")
    findings = list(run.findings)
    for s in found:
        run.say(f"  {s.words()} (p = {10 ** s.log10_p:.2g}; {s.size_mm:.4f} mm on the validation poses)")
        finding = Finding(
            Candidate(UNEXPLAINED.name, s.joint, session=s.session), 0.0,
            f"structure no cause of the catalogue explains: {s.words()}; {s.test_text} on the calibration poses "
            f"(a flexible term of degree {DEGREE} in the covariate, the model's parameters refitted beside it); it "
            f"predicts {s.held_out_share:.0%} of the left-out calibration poses better; judged on the validation "
            f"poses it is {s.size_mm:.4f} mm on average, and a flexible term would lower their mean error by "
            f"{s.potential_gain_mm:.4f} mm",
            in_model=False, where=s.words(), potential_gain_mm=s.potential_gain_mm,
            structure={**s.to_dict(), "term": s.term(f"structure{len(run.structures) + 1}")})
        findings.append(finding)
        run.structures.append((s, finding))
    return StageOutcome(findings=tuple(findings))
