"""Measuring the true robot: sessions (where the tracker stood, how the probe was mounted, its drift), noise,
bad shots, and the measurement CSV of docs/formats.md section 2.

- The measured point is ``base pose x flange x (tool point + probe shift)``
  plus the session's drift ``v (t - t_ref)`` (the measurement frame
  translates; m/s of ``time_s``) plus noise; the base pose is
  Trans(xyz) Rz(yaw) Ry(pitch) Rx(roll) (fixed-axis roll-pitch-yaw).
- The measured orientation (a 6-DoF probe) is the probe's frame in the
  measurement frame, ``R = R_base R_flange R_mount`` (R_mount: the probe's
  mounting on the flange, fixed-axis rpy), written as ``rx_deg, ry_deg,
  rz_deg`` with ``R = Rx(rx) Ry(ry) Rz(rz)`` (intrinsic XYZ), turned by a
  small random rotation (its noise) about the probe's axes.
- A bad shot is a point off by a gross error (``bad_mm``) in a random
  direction.
- The instrument's own errors (of the tracker, not the robot), on the point
  in the measurement frame (the tracker at its origin, its vertical axis
  its z), before the noise: an **angular error** of its azimuth, the point
  turned about the z axis by ``A sin(az + phi)``, ``az = atan2(y, x)`` the
  point's azimuth as the tracker sees it (``Session.angle_error = (A,
  phi)``, rad); a **distance scale** error, the point at ``(1 + s)`` times
  its distance from the tracker (``Session.distance_scale = s``). The
  measured orientation is not turned by them.
- A session's ``mount_compliance`` (None: the robot's,
  :class:`truth.robot.Effects`) is the compliance of the mount the robot
  stood on then; the robot's ``Effects.mount_law`` adds ``c x value`` (or
  ``f(value)``) of the session's own ``columns`` to it.
- A session's ``columns`` (name -> value, e.g. ``{"height_m": 2.4}``: a
  column's height, a payload on a tool changer, a track position) are its
  covariates: constant over its poses, written as columns of its rows.
- A **tilting floor** (a mobile base): each pose, the robot's base frame
  turns about its own x and y axes at its origin by the rotation vector
  ``(t_x, t_y, 0)``, each drawn uniform in ``[-floor_tilt, floor_tilt]``
  (rad), after the mount's tilt and before the base pose: the measured
  point is ``base pose x R(t) x (the arm's point)``, the orientation ``R_base
  R(t) R_flange R_mount``. A tilt sensor on the base reads it: columns
  ``tilt_x_rad``, ``tilt_y_rad``, ``t`` plus Gaussian noise ``tilt_noise``
  (rad, per axis). The torques are those of the untilted arm (as the
  mount's). ``unrelated`` names a sensor column that follows nothing: values
  drawn uniform in the same range (``[-floor_tilt, floor_tilt]``, 2 mrad
  without a tilt), so a test can tell "follows a sensor" from "follows any
  column".
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from . import transforms as tf
from .robot import TrueRobot, last_moves


@dataclass
class Session:
    """One measurement session: the tracker's placement, the probe's mounting, the session's drift."""

    name: str = "A"
    base_xyz: tuple = (0.0, 0.0, 0.0)           # m: the robot base in the measurement frame
    base_rpy: tuple = (0.0, 0.0, 0.0)           # rad, fixed axis
    tool_shift: tuple = (0.0, 0.0, 0.0)         # m, flange frame: the probe's point off the robot's tool point
    mount_rpy: tuple = (0.0, 0.0, 0.0)          # rad: the probe's frame on the flange (orientation only)
    drift: tuple = (0.0, 0.0, 0.0)              # m/s: the measurement frame translates
    t_ref: float = 0.0                          # s: when the base pose holds
    mount_compliance: float | tuple | None = None   # rad/(N m): the mount's in this session (None: the robot's)
    angle_error: tuple = (0.0, 0.0)             # (A, phi) rad: the tracker's azimuth error A sin(az + phi)
    distance_scale: float = 0.0                 # s: the tracker measures (1 + s) times the distance
    columns: dict = field(default_factory=dict)  # the session's covariates: name -> value, a constant column
    floor_tilt: float = 0.0                     # rad: each pose the base tilts about its x and y by up to this
    tilt_noise: float = 0.0                     # rad per axis: the tilt sensor's (tilt_x_rad, tilt_y_rad) noise
    unrelated: str = ""                         # the name of a sensor column that follows nothing ("": none)

    def base(self) -> np.ndarray:
        return tf.pose(self.base_xyz, self.base_rpy)[0]


@dataclass
class Shots:
    """Rows of one measurement file (readings in rad, points in m, rotations (N, 3, 3) or None)."""

    q: np.ndarray
    xyz: np.ndarray
    R: np.ndarray | None = None
    columns: dict = field(default_factory=dict)     # payload_kg, temperature_c, time_s, then any other: per row
    session: list | None = None                     # session name per row (a 'session' column) or None
    bad: np.ndarray = field(default_factory=lambda: np.zeros(0, int))   # rows with a gross error
    prismatic: tuple = ()               # per joint: a linear axis (its column qK_mm, mm); empty: none

    def __len__(self) -> int:
        return len(self.q)

    def __add__(self, other: "Shots") -> "Shots":
        """Both files' rows, in order (each with its session's name)."""
        if (self.R is None) != (other.R is None) or set(self.columns) != set(other.columns):
            raise ValueError("shots with different columns")
        names = (self.session or [""] * len(self)) + (other.session or [""] * len(other))
        return Shots(np.vstack([self.q, other.q]), np.vstack([self.xyz, other.xyz]),
                     None if self.R is None else np.concatenate([self.R, other.R]),
                     {k: np.concatenate([v, other.columns[k]]) for k, v in self.columns.items()},
                     names, np.concatenate([self.bad, other.bad + len(self)]), self.prismatic)

    def header_and_rows(self, session_column: bool = False) -> tuple[list[str], list[list[str]]]:
        n = self.q.shape[1]
        linear = [bool(self.prismatic and self.prismatic[j]) for j in range(n)]
        head = [f"q{j + 1}_{'mm' if linear[j] else 'deg'}" for j in range(n)] + ["x_mm", "y_mm", "z_mm"]
        cols = [self.q[:, j] * 1000 if linear[j] else np.degrees(self.q[:, j]) for j in range(n)]
        cols += [self.xyz[:, k] * 1000 for k in range(3)]
        known = ("payload_kg", "temperature_c", "time_s")
        for name in [k for k in known if k in self.columns] + [k for k in self.columns if k not in known]:
            head.append(name)
            cols.append(np.asarray(self.columns[name], float))
        if self.R is not None:
            head += ["rx_deg", "ry_deg", "rz_deg"]
            ang = np.degrees(tf.intrinsic_xyz(self.R))
            cols += [ang[:, k] for k in range(3)]
        rows = [[repr(float(c[i])) for c in cols] for i in range(len(self))]
        if session_column:
            head.append("session")
            for r, s in zip(rows, self.session):
                r.append(s)
        return head, rows

    def write_csv(self, path, session_column: bool | None = None) -> Path:
        """The measurement CSV (every number as Python's shortest exact repr); a ``session`` column when the
        rows are of several sessions (or asked)."""
        if session_column is None:
            session_column = self.session is not None and len(set(self.session)) > 1
        head, rows = self.header_and_rows(session_column)
        path = Path(path)
        path.write_text("\n".join(",".join(r) for r in [head] + rows) + "\n")
        return path


def measure(robot: TrueRobot, q: np.ndarray, rng: np.random.Generator | None = None, *,
            session: Session | None = None, noise: float = 20e-6, orientation_noise: float | None = None,
            payload_kg=None, temperature_c=None, time_s=None, bad: int | list = 0, bad_mm: float = 5.0,
            moves: np.ndarray | None = None) -> Shots:
    """Shots of ``robot`` at readings ``q`` (rad, rows in measurement order) in ``session``.

    ``payload_kg``, ``temperature_c``, ``time_s``: per row (or one value), written as columns when given
    (without ``payload_kg`` the robot file's payload is carried), then the session's ``columns``, its tilt
    sensor's and its ``unrelated`` column (:class:`Session`); ``orientation_noise`` (rad per axis):
    measure the probe's orientation too; ``bad``: the number of bad shots (rows drawn at random) or their
    row indices; ``moves``: the sign of each joint's last move (default: from the readings' order).
    """
    rng = rng or np.random.default_rng(0)
    session = session or Session()
    q = np.atleast_2d(np.asarray(q, float))
    N = len(q)
    cols = {}
    for name, v in (("payload_kg", payload_kg), ("temperature_c", temperature_c), ("time_s", time_s)):
        if v is not None:
            cols[name] = np.broadcast_to(np.asarray(v, float), (N,)).copy()
    if any(session.drift) and "time_s" not in cols:
        raise ValueError("a drift needs the rows' times (time_s)")
    for name, v in session.columns.items():
        cols[name] = np.full(N, float(v))
    temp = cols.get("temperature_c")
    state = robot.state(q, cols.get("payload_kg"), temp, last_moves(q) if moves is None else moves,
                        mount=mount_of(robot, session))
    point = robot.tool_point(state, temp, np.asarray(session.tool_shift, float))
    floor = np.tile(np.eye(3), (N, 1, 1))
    if session.floor_tilt:
        t = rng.uniform(-session.floor_tilt, session.floor_tilt, (N, 2))
        floor = tf.rotation_vector_to_matrix(np.column_stack([t, np.zeros(N)]))
        point = np.einsum("nij,nj->ni", floor, point)
        sensed = t + rng.normal(0.0, session.tilt_noise, (N, 2))
        cols["tilt_x_rad"], cols["tilt_y_rad"] = sensed[:, 0], sensed[:, 1]
    B = session.base()
    xyz = point @ B[:3, :3].T + B[:3, 3]
    if any(session.drift):
        xyz = xyz + np.outer(cols["time_s"] - session.t_ref, session.drift)
    xyz = instrument(xyz, session)
    xyz = xyz + rng.normal(0.0, noise, (N, 3))
    R = None
    if orientation_noise is not None:
        mount = tf.fixed_rpy(*session.mount_rpy)[0, :3, :3]
        R = B[:3, :3] @ floor @ state.flange[:, :3, :3] @ mount
        R = R @ tf.rotation_vector_to_matrix(rng.normal(0.0, orientation_noise, (N, 3)))
    rows = np.asarray(rng.choice(N, size=bad, replace=False) if isinstance(bad, int) else bad, int)
    if len(rows):
        u = rng.normal(size=(len(rows), 3))
        xyz[rows] += bad_mm / 1000 * u / np.linalg.norm(u, axis=1)[:, None]
    if session.unrelated:        # drawn last: the rest of the shots are those without it
        span = session.floor_tilt or 2e-3
        cols[session.unrelated] = rng.uniform(-span, span, N)
    return Shots(q, xyz, R, cols, [session.name] * N, np.sort(rows), robot.arm.prismatic)


def mount_of(robot: TrueRobot, session: Session):
    """The mount's compliance in ``session``: its own (None: the robot's) plus the robot's law over the session's
    columns (``Effects.mount_law``: ``c x value``, or ``f(value)`` for a function)."""
    law = robot.effects.mount_law
    if not law:
        return session.mount_compliance
    missing = sorted(set(law) - set(session.columns))
    if missing:
        raise ValueError(f"the mount law follows {missing}, which session {session.name!r} has no value of")
    grow = sum(c(float(session.columns[k])) if callable(c) else c * float(session.columns[k]) for k, c in law.items())
    own = robot.effects.mount_compliance if session.mount_compliance is None else session.mount_compliance
    return np.asarray(own, float) + grow if np.ndim(own) else own + grow


def instrument(xyz: np.ndarray, session: Session) -> np.ndarray:
    """What the tracker reads for the points ``xyz`` (measurement frame, (N, 3)): its azimuth error turns them
    about its vertical axis by ``A sin(az + phi)``, its distance scale stretches them by ``1 + s``."""
    A, phi = session.angle_error
    if A:
        w = A * np.sin(np.arctan2(xyz[:, 1], xyz[:, 0]) + phi)
        c, s = np.cos(w), np.sin(w)
        xyz = np.column_stack([c * xyz[:, 0] - s * xyz[:, 1], s * xyz[:, 0] + c * xyz[:, 1], xyz[:, 2]])
    if session.distance_scale:
        xyz = (1 + session.distance_scale) * xyz
    return xyz


def sample(robot: TrueRobot, n: int, rng: np.random.Generator, floor_z: float | None = 0.0,
           margin: float = math.radians(5.0)) -> np.ndarray:
    """Readings (rad, (n, joints)) uniform within the limits less ``margin``, whose nominal tool point lies
    above ``floor_z`` (robot base frame; None: anywhere); a four-bar kept away from its dead points."""
    arm = robot.arm
    lim = arm.limits.copy()
    inner = lim + [margin, -margin]
    ok = inner[:, 0] < inner[:, 1]
    lim[ok] = inner[ok]
    nominal = TrueRobot(arm)
    kept = np.zeros((0, arm.n))
    while len(kept) < n:
        q = rng.uniform(lim[:, 0], lim[:, 1], (4 * n + 16, arm.n))
        keep = np.ones(len(q), bool)
        if floor_z is not None:
            geo = nominal.geometry_at(None, len(q))
            frames = nominal.frames(nominal.chain_angles(q, geo), geo, np.zeros(len(q)))
            keep &= nominal.tool_point(frames)[:, 2] > floor_z
        if arm.loop is not None:
            j = arm.loop.joint - 1
            keep &= np.abs(np.sin(q[:, j] - q[:, j - 1])) > 0.5
        kept = np.vstack([kept, q[keep]])
    return kept[:n]
