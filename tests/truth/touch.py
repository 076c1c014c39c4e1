"""What the tool touches: rows of the true robot touching sockets, planes and pivots, and a tool of several points.

docs/formats.md ("what the tool touches"): a row says what the tool point
touched (``point``: a socket; ``plane``: a face) instead of where it was,
or its distance to a pivot (``point`` + ``distance_mm``: a draw-wire sensor
or a ballbar), or which of the tool's points a tracker row measured
(``tool``). Written here from the definitions, in plain numpy, for the true
robot of :mod:`truth.robot` (its geometry and every effect of its drives):

- **The world** is a session's measurement frame (:class:`truth.campaign.Session`:
  the robot's base pose in it, its mount's compliance); sockets, planes,
  pivots and fixtures stand in it.
- **A touch** puts the true robot's tool point on its target: the joint
  readings are found by numeric inverse kinematics **of the true robot** (its
  readings are the unknowns; every effect of :meth:`TrueRobot.state` acts,
  so the drives stand at the reading plus their errors), from a random start
  within the limits (a random redundancy: 3 equations, 6 or 7 readings) by
  damped Gauss-Newton steps of the least norm. What is written is the
  reading: what the encoders say, not the angle the joint stands at. The
  ball sits off the socket's centre by the contact noise (Gaussian, per
  axis), a point on a face off the face along its normal.
- **A tool point** is its offset in the last link frame (the robot file's
  tool, or a named tool's own true offset); the robot's thermal growth acts
  on the robot file's tool only.
- **A pivot** (draw-wire, ballbar): the tool point anywhere (random poses
  within the limits, within ``reach`` of the pivot); the row's
  ``distance_mm`` is the true distance plus noise.
- **A fixture** is points at known coordinates in its own frame, placed at
  a pose per session (``Fixture.place``); :func:`fixture_toml` writes the
  fixture file of docs/formats.md.
- **Tracker rows of a tool of several points** (reflector nests): one pose
  measured at each point, consecutive rows with the same readings and
  ``tool`` NAME, positions as :func:`truth.campaign.measure` makes them.

:class:`Touches` holds the rows and what was hidden (the touched points,
planes and pivots in the world, each tool's offset, each fixture's pose),
and writes the measurement CSV: ``q1_deg .. qN_deg``, then where used
``x_mm, y_mm, z_mm`` (empty on touch rows), ``point``, ``plane``,
``distance_mm``, ``tool`` (empty where not), ``payload_kg``,
``temperature_c``, ``session``.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from . import transforms as tf
from .campaign import Session, measure, sample
from .robot import Effects, TrueRobot, last_moves

#: the inverse kinematics stops when the tool point is this close to its target (m)
IK_TOLERANCE = 1e-12


# --- fixtures ------------------------------------------------------------------------------------------------

@dataclass
class Fixture:
    """An artefact of known geometry: named points (m) in its own frame."""

    name: str
    points: dict[str, np.ndarray]
    sd_mm: float = 0.01

    def place(self, pose: np.ndarray) -> dict[str, np.ndarray]:
        """Its points in the world when it stands at ``pose`` (4x4: fixture frame -> world)."""
        return {k: pose[:3, :3] @ np.asarray(p, float) + pose[:3, 3] for k, p in self.points.items()}


def two_sockets(distance: float = 0.05, name: str = "two_sockets") -> Fixture:
    """A block with two sockets ``distance`` (m) apart along its x axis (MUKCa's, 50 mm)."""
    return Fixture(name, {"socket0": np.zeros(3), "socket1": np.array([distance, 0.0, 0.0])})


def fixture_toml(fixtures: list[Fixture]) -> str:
    """The fixture file of docs/formats.md: ``[[fixture]]`` tables, points in mm (Python's shortest repr)."""
    out = []
    for f in fixtures:
        out += ["[[fixture]]", f"name = {json.dumps(f.name)}", f"sd_mm = {float(f.sd_mm)!r}",
                "[fixture.points]"]
        out += [f"{k} = [{', '.join(repr(float(v) * 1000) for v in p)}]" for k, p in f.points.items()]
        out.append("")
    return "\n".join(out)


def random_pose(rng: np.random.Generator, centre, tilt: float = math.radians(5.0)) -> np.ndarray:
    """A pose at ``centre`` (m), turned by a random yaw about the world z axis and tipped by up to ``tilt``."""
    yaw = rng.uniform(-math.pi, math.pi)
    roll, pitch = rng.uniform(-tilt, tilt, 2)
    return tf.pose(centre, (roll, pitch, yaw))[0]


def reach(robot: TrueRobot) -> float:
    """An upper bound of how far the tool point gets from the base frame's origin: every length of the arm."""
    g = robot.geometry
    return float(np.sum(np.abs(g.a)) + np.sum(np.abs(g.b)) + np.sum(np.abs(g.d)) + np.linalg.norm(g.tool))


def reachable_point(robot: TrueRobot, rng: np.random.Generator, session: Session | None = None,
                    floor_z: float | None = 0.1, within: tuple[float, float] = (0.3, 0.7)) -> np.ndarray:
    """The world position of the true tool point at a random reading within the limits, above ``floor_z`` (the
    robot's base frame) and ``within`` these fractions of :func:`reach` from its base: a place the robot reaches
    in many ways."""
    session = session or Session()
    lo, hi = (f * reach(robot) for f in within)
    while True:
        q = sample(robot, 64, rng, floor_z=floor_z, margin=math.radians(15.0))
        state = robot.state(q, mount=session.mount_compliance)
        r = np.linalg.norm(robot.tool_point(state), axis=1)
        good = np.flatnonzero((r > lo) & (r < hi))
        if len(good):
            return _world_points(robot, q[good[:1]], session, None)[0]


# --- the rows ------------------------------------------------------------------------------------------------

@dataclass
class Touches:
    """Rows of one measurement file and what they hide (readings rad, positions m)."""

    q: np.ndarray
    session: list[str]
    point: list[str] = field(default_factory=list)            # per row: a touched point's name, "" none
    plane: list[str] = field(default_factory=list)
    distance: np.ndarray = field(default_factory=lambda: np.zeros(0))    # m, NaN where none
    tool: list[str] = field(default_factory=list)
    xyz: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))    # m, NaN where not a tracker row
    payload: np.ndarray | None = None                          # kg per row (None: the robot file's)
    temperature: np.ndarray | None = None                      # deg C per row (None: none)
    #: what was hidden: "points" {(session, name): world xyz}, "planes" {(session, name): (point, unit normal)},
    #: "tools" {name: offset in the last link frame}, "fixtures" {session: (fixture name, 4x4 pose)},
    #: "bases" {session: 4x4 base pose in the world}, "targets" (N, 3): where each row's true tool point stands
    #: (world; the contact noise included; NaN on tracker rows)
    truth: dict = field(default_factory=dict)

    def __len__(self) -> int:
        return len(self.q)

    def __add__(self, other: "Touches") -> "Touches":
        """Both sets of rows, in order; what they hide merged."""
        if (self.payload is None) != (other.payload is None) or (self.temperature is None) != (
                other.temperature is None):
            raise ValueError("rows with different columns")
        cat = np.concatenate
        truth = {}
        for key in set(self.truth) | set(other.truth):
            a, b = self.truth.get(key), other.truth.get(key)
            if key == "targets":            # rows without one (tracker rows) have NaN
                truth[key] = cat([np.full((len(self), 3), np.nan) if a is None else a,
                                  np.full((len(other), 3), np.nan) if b is None else b])
            else:
                truth[key] = {**(a or {}), **(b or {})}
        return Touches(np.vstack([self.q, other.q]), self.session + other.session, self.point + other.point,
                       self.plane + other.plane, cat([self.distance, other.distance]), self.tool + other.tool,
                       np.vstack([self.xyz, other.xyz]),
                       None if self.payload is None else cat([self.payload, other.payload]),
                       None if self.temperature is None else cat([self.temperature, other.temperature]), truth)

    def header_and_rows(self, session_column: bool | None = None) -> tuple[list[str], list[list[str]]]:
        n = self.q.shape[1]
        head = [f"q{j + 1}_deg" for j in range(n)]
        cols: list[list[str]] = [[repr(float(v)) for v in np.degrees(self.q[:, j])] for j in range(n)]
        tracker = ~np.isnan(self.xyz[:, 0])
        if tracker.any():
            head += ["x_mm", "y_mm", "z_mm"]
            cols += [[repr(float(v)) if ok else "" for v, ok in zip(self.xyz[:, k] * 1000, tracker)]
                     for k in range(3)]
        for name, values in (("point", self.point), ("plane", self.plane)):
            if any(values):
                head.append(name)
                cols.append(list(values))
        if not np.isnan(self.distance).all():
            head.append("distance_mm")
            cols.append(["" if math.isnan(v) else repr(float(v) * 1000) for v in self.distance])
        if any(self.tool):
            head.append("tool")
            cols.append(list(self.tool))
        for name, values in (("payload_kg", self.payload), ("temperature_c", self.temperature)):
            if values is not None:
                head.append(name)
                cols.append([repr(float(v)) for v in values])
        if session_column is None:
            session_column = len(set(self.session)) > 1
        if session_column:
            head.append("session")
            cols.append(list(self.session))
        return head, [list(r) for r in zip(*cols)]

    def write_csv(self, path, session_column: bool | None = None) -> Path:
        """The measurement CSV (a ``session`` column when the rows are of several sessions, or asked)."""
        head, rows = self.header_and_rows(session_column)
        path = Path(path)
        path.write_text("\n".join(",".join(r) for r in [head] + rows) + "\n")
        return path


def _rows(q, session: Session, *, point="", plane="", distance=None, tool="", xyz=None, payload=None,
          temperature=None, truth=None) -> Touches:
    N = len(q)
    col = (lambda v: list(v) if isinstance(v, (list, tuple)) else [v] * N)   # noqa: E731
    per_row = (lambda v: None if v is None else np.broadcast_to(np.asarray(v, float), (N,)).copy())  # noqa: E731
    return Touches(np.asarray(q, float), [session.name] * N, col(point), col(plane),
                   np.full(N, np.nan) if distance is None else np.asarray(distance, float), col(tool),
                   np.full((N, 3), np.nan) if xyz is None else np.asarray(xyz, float),
                   per_row(payload), per_row(temperature), dict(truth or {}))


# --- the true tool point and the inverse kinematics ------------------------------------------------------------

def _shift(robot: TrueRobot, offset, session: Session) -> np.ndarray:
    """The shift from the robot file's tool to the tool point used (flange frame, m)."""
    base = np.zeros(3) if offset is None else np.asarray(offset, float) - robot.geometry.tool
    return base + np.asarray(session.tool_shift, float)


def _world_points(robot: TrueRobot, q: np.ndarray, session: Session, offset, payload=None, temperature=None,
                  moves: np.ndarray | None = None, jacobian: bool = False):
    """The true tool point (world, (N, 3)) at readings ``q`` (every effect of the robot; the session's mount);
    ``jacobian``: also d point / d reading of the rigid arm at the deflected pose (world, (N, 3, n)): each joint's
    axis crossed with the lever to the point (along the axis for a linear one), through the chain's couplings.
    """
    q = np.atleast_2d(q)
    state = robot.state(q, payload, temperature, last_moves(q) if moves is None else moves,
                        mount=session.mount_compliance)
    p = robot.tool_point(state, temperature, _shift(robot, offset, session))
    B = session.base()
    world = p @ B[:3, :3].T + B[:3, 3]
    if not jacobian:
        return world
    linear = np.array(robot.arm.prismatic)[None, :, None]
    J = np.where(linear, state.axes, np.cross(state.axes, p[:, None, :] - state.origins))     # (N, n, 3)
    geo = robot.geometry_at(temperature, len(q))
    J = np.einsum("nki,nkj->nij", J, robot.chain_jacobian(state.drive, geo))                  # through couplings
    return world, np.einsum("ab,nbj->naj", B[:3, :3], J)


def solve_readings(robot: TrueRobot, targets: np.ndarray, rng: np.random.Generator, session: Session | None = None,
                   offset=None, payload=None, temperature=None, margin: float = math.radians(3.0),
                   cone: float | None = None, approach=(0.0, 0.0, -1.0), attempts: int = 5,
                   starts_per_try: int | None = None, iterations: int = 30) -> np.ndarray:
    """Readings (rad, (N, n)) at which the true robot's tool point (``offset``: a named tool's, else the robot
    file's) stands at each target (world, m); in row order (a joint's last move, which backlash reads, is that
    of these readings).

    Each target's reading comes from a random start within the limits less ``margin``: ``starts_per_try``
    starts at a time (default 6; 40 with a ``cone``) brought near it on the arm without its drives' effects,
    the first that gets there then onto it on the true robot. ``cone`` (rad): only poses whose tool axis (the
    last link's z axis) lies within ``cone`` of the ``approach`` direction (world; default straight down: a
    ball on a stylus in a socket on a table). Raises ValueError for a target not reached in ``attempts``
    tries.
    """
    session = session or Session()
    targets = np.atleast_2d(np.asarray(targets, float))
    N, n = len(targets), robot.arm.n
    lim = robot.arm.limits
    lo, hi = lim[:, 0] + margin, lim[:, 1] - margin
    payload = None if payload is None else np.broadcast_to(np.asarray(payload, float), (N,)).copy()
    temperature = None if temperature is None else np.broadcast_to(np.asarray(temperature, float), (N,)).copy()
    approach = np.asarray(approach, float) / np.linalg.norm(approach)
    if starts_per_try is None:      # about 1 in 10 random poses has its tool within 45 deg of a direction
        starts_per_try = 6 if cone is None else 40
    q = np.zeros((N, n))
    solved = np.zeros(N, bool)
    todo = np.arange(N)
    rigid = robot.with_effects(Effects())       # near the target first without the drives' effects: cheaper
    for _ in range(attempts):
        # a row met before may miss now that the row before it has its reading (a joint's last move changed):
        # onto its target again from where it stands
        again = todo[solved[todo]]
        if len(again):
            q[again] = _gauss_newton(robot, q, again, targets, session, offset, payload, temperature, lo, hi,
                                     10)[0]
            todo = np.flatnonzero(_misses(robot, q, targets, session, offset, payload, temperature))
            if not len(todo):
                return q
        solved[todo] = False
        # several random starts per target at once (the rigid arm has no backlash: the batch's order is no matter)
        starts = rng.uniform(lo, hi, (starts_per_try * len(todo), n))
        which = np.repeat(todo, starts_per_try)
        pick = (lambda v: None if v is None else v[which])      # noqa: E731
        load, temp, goal = pick(payload), pick(temperature), targets[which]
        first: dict[int, int] = {}
        going = np.arange(len(starts))
        for _ in range(0, iterations, 5):           # 5 steps at a time, until a start of each target is near it
            starts[going], near = _gauss_newton(rigid, starts, going, goal, session, offset, load, temp, lo, hi,
                                                5, 1e-5)
            ok = near.copy()
            if cone is not None and near.any():      # the tool's axis within the cone about the approach
                ok[near] = _tool_axes(rigid, starts[going[near]], session) @ approach >= math.cos(cone)
            for k in going[ok]:
                first.setdefault(which[k], k)
            going = going[~near & ~np.isin(which[going], list(first))]
            if not len(going):
                break
        if first:
            found = np.array(list(first))
            q[found] = starts[list(first.values())]
            q[found] = _gauss_newton(robot, q, found, targets, session, offset, payload, temperature, lo, hi,
                                     10)[0]
            solved[found] = True
        todo = np.flatnonzero(_misses(robot, q, targets, session, offset, payload, temperature))
        if not len(todo):
            return q
    raise ValueError(f"{len(todo)} of {N} targets not reached from {attempts * starts_per_try} random starts "
                     f"(first: {targets[todo[0]]} m)")


def _misses(robot, q, targets, session, offset, payload, temperature) -> np.ndarray:
    """Which rows' true tool point (in row order: the joints' last moves of all of ``q``) misses its target."""
    p = _world_points(robot, q, session, offset, payload, temperature)
    return np.linalg.norm(p - targets, axis=1) > IK_TOLERANCE


def _tool_axes(robot: TrueRobot, q: np.ndarray, session: Session) -> np.ndarray:
    """The last link's z axis (world, (N, 3)) at readings ``q``."""
    state = robot.state(np.atleast_2d(q), mount=session.mount_compliance)
    return state.flange[:, :3, 2] @ session.base()[:3, :3].T


def _gauss_newton(robot, q, rows, targets, session, offset, payload, temperature, lo, hi, iterations,
                  tolerance=IK_TOLERANCE):
    """Damped Gauss-Newton steps of the least norm, projected on the limits ``lo``, ``hi``, for ``rows`` of ``q``
    until each is within ``tolerance`` (m) of its target; the other rows stay (with them, they set the joints'
    last moves). The Jacobian is the rigid arm's at the deflected pose: the steps are approximate (they leave
    out how the drives' errors change with the readings), the target met is exact. Returns the rows' readings
    and which of them met their target (those still going after ``iterations`` did not, as far as the last step
    knew)."""
    q = q.copy()
    active = np.asarray(rows)
    for _ in range(iterations):
        pick = (lambda v: None if v is None else v[active])      # noqa: E731
        p, J = _world_points(robot, q[active], session, offset, pick(payload), pick(temperature),
                             last_moves(q)[active], jacobian=True)
        f = p - targets[active]
        going = np.linalg.norm(f, axis=1) >= tolerance
        if not going.any():
            active = active[:0]
            break
        active, f, J = active[going], f[going], J[going]
        JJt = J @ J.transpose(0, 2, 1) + 1e-12 * np.eye(3)
        step = -np.einsum("nij,ni->nj", J, np.linalg.solve(JJt, f[:, :, None])[:, :, 0])
        size = np.linalg.norm(step, axis=1, keepdims=True)
        step *= np.minimum(1.0, 0.3 / np.maximum(size, 1e-300))     # at most 0.3 rad a step
        q[active] = np.clip(q[active] + step, lo, hi)      # projected on the limits (less the margin)
    return q[rows], ~np.isin(rows, active)


# --- the kinds of rows ---------------------------------------------------------------------------------------

def socket_rows(robot: TrueRobot, sockets: dict[str, np.ndarray], per_socket: int, rng: np.random.Generator,
                session: Session | None = None, *, tool: str = "", offset=None, contact_noise: float = 0.0,
                payload=None, temperature=None, interleave: bool = False, cone: float | None = None) -> Touches:
    """``per_socket`` rows per socket (world positions, m) with the true tool point in it: ``point`` = its name.
    The ball sits off the socket's centre by Gaussian ``contact_noise`` (m, per axis). ``interleave``: the
    sockets in turn (else all rows of one socket, then the next). ``tool``/``offset``: a named tool point and
    its true offset (last link frame, m). ``cone``: the tool axis within it of straight down
    (:func:`solve_readings`)."""
    session = session or Session()
    names = list(sockets)
    order = [names[i % len(names)] for i in range(per_socket * len(names))] if interleave else \
        [k for k in names for _ in range(per_socket)]
    targets = np.array([sockets[k] for k in order]) + rng.normal(0.0, contact_noise, (len(order), 3))
    q = solve_readings(robot, targets, rng, session, offset, payload, temperature, cone=cone)
    truth = {"points": {(session.name, k): np.asarray(sockets[k], float) for k in names},
             "bases": {session.name: session.base()}, "targets": targets}
    if tool:
        truth["tools"] = {tool: np.asarray(offset, float)}
    return _rows(q, session, point=order, tool=tool, payload=payload, temperature=temperature, truth=truth)


def plane_rows(robot: TrueRobot, name: str, origin, normal, count: int, rng: np.random.Generator,
               session: Session | None = None, *, radius: float = 0.1, contact_noise: float = 0.0, tool: str = "",
               offset=None, payload=None, temperature=None, cone: float | None = None) -> Touches:
    """``count`` rows with the true tool point on the plane through ``origin`` (world, m) with ``normal``, at
    random points within ``radius`` of ``origin``, off it along its normal by Gaussian ``contact_noise``:
    ``plane`` = ``name``. ``cone``: the tool axis within it of the normal, pointing into the face."""
    session = session or Session()
    nrm = np.asarray(normal, float) / np.linalg.norm(normal)
    u = np.cross(nrm, [1.0, 0.0, 0.0] if abs(nrm[0]) < 0.9 else [0.0, 1.0, 0.0])
    u /= np.linalg.norm(u)
    v = np.cross(nrm, u)
    r = radius * np.sqrt(rng.uniform(0, 1, count))
    phi = rng.uniform(-math.pi, math.pi, count)
    targets = (np.asarray(origin, float) + (r * np.cos(phi))[:, None] * u + (r * np.sin(phi))[:, None] * v
               + rng.normal(0.0, contact_noise, count)[:, None] * nrm)
    q = solve_readings(robot, targets, rng, session, offset, payload, temperature, cone=cone,
                       approach=-nrm)
    truth = {"planes": {(session.name, name): (np.asarray(origin, float), nrm)},
             "bases": {session.name: session.base()}, "targets": targets}
    if tool:
        truth["tools"] = {tool: np.asarray(offset, float)}
    return _rows(q, session, plane=name, tool=tool, payload=payload, temperature=temperature, truth=truth)


def pivot_rows(robot: TrueRobot, name: str, pivot, count: int, rng: np.random.Generator,
               session: Session | None = None, *, reach: tuple[float, float] = (0.15, 0.6), noise: float = 0.0,
               tool: str = "", offset=None, payload=None, temperature=None) -> Touches:
    """``count`` rows at random readings within the limits whose true tool point lies ``reach`` (m, min, max)
    from the ``pivot`` (world, m): ``point`` = ``name``, ``distance_mm`` = the true distance plus Gaussian
    ``noise`` (m) (a draw-wire sensor from the pivot to the tool point)."""
    session = session or Session()
    pivot = np.asarray(pivot, float)
    kept = np.zeros((0, robot.arm.n))
    for _ in range(200):
        q = sample(robot, 8 * count, rng, floor_z=None, margin=math.radians(3.0))
        d = np.linalg.norm(_world_points(robot, q, session, offset, payload, temperature) - pivot, axis=1)
        kept = np.vstack([kept, q[(d >= reach[0]) & (d <= reach[1])]])
        if len(kept) >= count:
            break
    else:
        raise ValueError(f"pivot {name!r} at {pivot} m: fewer than {count} poses within {reach} m of it")
    q = kept[:count]
    points = _world_points(robot, q, session, offset, payload, temperature)
    true = np.linalg.norm(points - pivot, axis=1)
    truth = {"points": {(session.name, name): pivot}, "bases": {session.name: session.base()}, "targets": points}
    if tool:
        truth["tools"] = {tool: np.asarray(offset, float)}
    return _rows(q, session, point=name, distance=true + rng.normal(0.0, noise, count), tool=tool,
                 payload=payload, temperature=temperature, truth=truth)


def tool_rows(robot: TrueRobot, q: np.ndarray, tools: dict[str, np.ndarray], rng: np.random.Generator,
              session: Session | None = None, *, noise: float = 20e-6, payload=None, temperature=None) -> Touches:
    """Tracker rows of a tool of several points (reflector nests): each pose of ``q`` measured at each tool point
    in turn (consecutive rows, the same readings), ``tool`` = its name, ``x_mm, y_mm, z_mm`` as
    :func:`truth.campaign.measure` makes them (the session's base pose, instrument errors, noise) with the
    tool point at its true offset (last link frame, m)."""
    session = session or Session()
    q = np.atleast_2d(np.asarray(q, float))
    names = list(tools)
    moves = last_moves(q)            # the robot stands still while the tracker measures each point
    shots = {k: measure(robot, q, rng, session=replace(session, tool_shift=tuple(_shift(robot, tools[k], session))),
                        noise=noise, payload_kg=payload, temperature_c=temperature, moves=moves) for k in names}
    order = [(i, k) for i in range(len(q)) for k in names]
    rows_q = np.array([q[i] for i, _ in order])
    xyz = np.array([shots[k].xyz[i] for i, k in order])
    per_row = (lambda v: None if v is None else np.broadcast_to(np.asarray(v, float), (len(q),))[  # noqa: E731
        [i for i, _ in order]])
    truth = {"tools": {k: np.asarray(tools[k], float) for k in names}, "bases": {session.name: session.base()}}
    return _rows(rows_q, session, tool=[k for _, k in order], xyz=xyz, payload=per_row(payload),
                 temperature=per_row(temperature), truth=truth)


def fixture_session(robot: TrueRobot, fixture: Fixture, per_point: int, rng: np.random.Generator,
                    session: Session | None = None, *, contact_noise: float = 0.0, tilt: float = math.radians(5.0),
                    **kw) -> Touches:
    """One placement of ``fixture``: at a random pose near a place the robot reaches (random yaw, tipped by up to
    ``tilt``), ``per_point`` socket rows at each of its points (:func:`socket_rows`)."""
    session = session or Session()
    for _ in range(10):
        pose = random_pose(rng, reachable_point(robot, rng, session), tilt)
        try:
            rows = socket_rows(robot, fixture.place(pose), per_point, rng, session, contact_noise=contact_noise,
                               **kw)
        except ValueError:      # a point out of reach in too few ways: place it again
            continue
        rows.truth["fixtures"] = {session.name: (fixture.name, pose)}
        return rows
    raise ValueError(f"fixture {fixture.name!r}: no placement of 10 where the robot reaches every point")
