"""Simulated touches: the simulated true robot's ball put in the sockets of a block (what a study of touch
protocols measures).

A :class:`~casadical.data._simulate.Truth` (the model at its true values) stands in a measurement frame; a block
of sockets (named points at known coordinates in its own frame, docs/formats.md section 11) is placed there at a
random pose the robot reaches. A row is a configuration of the true robot whose tool point stands in a socket,
off its centre by the contact noise (Gaussian per axis): its joint readings come from an inverse kinematics of
the true robot (every term of its model acts: its compliance under the row's load, its gear errors, ...). Each
target is reached from several random starts within the joint limits, so the rows of one socket are the many
configurations a user would take by hand guiding (a 6- or 7-axis arm reaches a point in a family of ways);
the steps are damped least squares of least norm, projected on the limits. What is written is the readings and
what they touch (``point``, ``session``): the rows of a file of touches alone.

:func:`place_block` chooses where a block stands, :func:`readings_at` solves the inverse kinematics,
:func:`touch_rows` makes the rows of one or several placements.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..errors import SimulationError
from ._measurements import Measurements

#: the inverse kinematics stops when the tool point is this close to its target (m)
IK_TOLERANCE = 1e-10
#: largest joint step of an iteration (rad; m for a linear axis)
MAX_STEP = 0.3


@dataclass
class Placement:
    """Where a block stands in one session: its pose (4x4, block frame to measurement frame) and its points
    there (m)."""

    session: str
    pose: np.ndarray
    points: dict = field(default_factory=dict)


def _rotation(axis: int, angle: float) -> np.ndarray:
    c, s = math.cos(angle), math.sin(angle)
    i, j = [k for k in range(3) if k != axis]
    R = np.eye(3)
    R[i, i], R[i, j], R[j, i], R[j, j] = c, -s, s, c
    return R


def tool_points(truth, q: np.ndarray, cov: np.ndarray | None = None) -> np.ndarray:
    """The true tool point (measurement frame, m, (N, 3)) at readings ``q`` (the robot's default covariates: its
    payload)."""
    q = np.atleast_2d(q)
    cov = truth.model.default_covariates(len(q)) if cov is None else cov
    return truth.model.predict(q, truth.values, cov, truth.base0)


def place_block(truth, points: dict, rng: np.random.Generator, session: str = "", *,
                within: tuple[float, float] = (0.3, 0.7), tilt: float = math.radians(5.0),
                floor_z: float | None = 0.1) -> Placement:
    """A random placement of a block of ``points`` (m, its frame): its centre at a place the true robot reaches
    from many configurations (a tool point of a random reading within the limits, above ``floor_z`` in the
    robot's base frame and ``within`` these fractions of the arm's reach from its base), turned by a random yaw
    about the base frame's z axis and tipped by up to ``tilt``."""
    from ._simulate import sample_poses

    robot = truth.model.robot
    q = sample_poses(robot, 200, rng, floor_z=None, margin=math.radians(15.0))
    base = _base_matrix(truth)
    local = (tool_points(truth, q) - base[:3, 3]) @ base[:3, :3]          # in the base frame
    r = np.linalg.norm(local, axis=1)
    lo, hi = (f * r.max() for f in within)
    ok = (r > lo) & (r < hi) & (local[:, 2] > (-np.inf if floor_z is None else floor_z))
    if not ok.any():
        raise SimulationError(f"no reading of {robot.name} puts its tool point within {within} of its reach above "
                              f"z = {floor_z} m: the block cannot be placed")
    centre = local[rng.choice(np.flatnonzero(ok))]
    R = _rotation(2, rng.uniform(-math.pi, math.pi)) @ _rotation(1, rng.uniform(-tilt, tilt)) \
        @ _rotation(0, rng.uniform(-tilt, tilt))
    mean = np.mean([np.asarray(p, float) for p in points.values()], axis=0)
    pose = np.eye(4)
    pose[:3, :3] = base[:3, :3] @ R
    pose[:3, 3] = base[:3, :3] @ (centre - R @ mean) + base[:3, 3]
    return Placement(session, pose, {k: pose[:3, :3] @ np.asarray(p, float) + pose[:3, 3]
                                     for k, p in points.items()})


def _base_matrix(truth) -> np.ndarray:
    from ..model._symbolic import base0_to_pose

    return base0_to_pose(truth.base0)


def readings_at(truth, targets: np.ndarray, rng: np.random.Generator, *, margin: float = math.radians(3.0),
                starts: int = 6, attempts: int = 6, iterations: int = 40,
                payload_kg: np.ndarray | None = None) -> np.ndarray:
    """Readings (rad; m for a linear axis; (N, n)) at which the true robot's tool point stands at each target
    (measurement frame, m), in row order.

    Each target is reached from random starts within the joint limits less ``margin`` (``starts`` at a time, up
    to ``attempts`` times): the first start that reaches it is kept, so the configurations are spread over the
    ways the arm reaches the point. Steps: damped least squares of least norm on the true model's exact Jacobian
    of the readings, at most :data:`MAX_STEP` per joint, projected on the limits. The rows are then brought onto
    their targets together with their covariates in row order (a joint's last move, which a backlash reads).

    Raises
    ------
    SimulationError
        A target not reached from any start (out of reach, or only near the limits).
    """
    robot = truth.model.robot
    targets = np.atleast_2d(np.asarray(targets, float))
    N, n = len(targets), robot.n
    lim = robot.limits
    pad = robot.from_file_units(np.full(n, math.degrees(margin)))
    lo, hi = lim[:, 0] + pad, lim[:, 1] - pad
    load = None if payload_kg is None else np.broadcast_to(np.asarray(payload_kg, float), (N,)).copy()
    q = np.zeros((N, n))
    todo = np.arange(N)
    for _ in range(attempts):
        which = np.repeat(todo, starts)
        trial = rng.uniform(lo, hi, (len(which), n))
        extra = {} if load is None else {"payload_kg": load[which]}
        trial, miss = _steps(truth, trial, targets[which], lo, hi, iterations, extra)
        found = {}
        for k in np.flatnonzero(miss < 1e-6):        # near it: the final steps below put it on it
            found.setdefault(int(which[k]), k)
        for i, k in found.items():
            q[i] = trial[k]
        todo = np.setdiff1d(todo, list(found))
        if not len(todo):
            break
    if len(todo):
        raise SimulationError(f"{len(todo)} of {N} targets not reached from {attempts * starts} random starts "
                              f"(first: {np.round(targets[todo[0]], 4).tolist()} m)")
    extra = {} if load is None else {"payload_kg": load}
    for _ in range(4):      # the rows in their order: their covariates (last moves) as the file will have them
        q, miss = _steps(truth, q, targets, lo, hi, 10, extra, ordered=True)
        if miss.max() <= IK_TOLERANCE:
            return q
    bad = int(np.argmax(miss))
    raise SimulationError(f"row {bad + 1} stays {miss[bad] * 1000:.3g} mm off its target after its final steps")


def _steps(truth, q, targets, lo, hi, iterations, extra, ordered: bool = False):
    """Damped least-squares steps of every row of ``q`` towards its target; the rows and their misses (m)."""
    model = truth.model
    q = q.copy()
    miss = np.full(len(q), np.inf)
    active = np.arange(len(q))
    for _ in range(iterations):
        data = Measurements.from_arrays(q if ordered else q[active], prismatic=model.robot.prismatic,
                                        **({k: v if ordered else v[active] for k, v in extra.items()}))
        cov = model.covariates(data)
        if ordered:
            cov = cov[active]
        p, J = model.predict_q_jacobian(q[active], truth.values, cov, truth.base0)
        f = targets[active] - p
        miss[active] = np.linalg.norm(f, axis=1)
        going = miss[active] > IK_TOLERANCE
        if not going.any():
            break
        active, f, J = active[going], f[going], J[going]
        JJt = J @ J.transpose(0, 2, 1) + 1e-12 * np.eye(3)
        step = np.einsum("nij,ni->nj", J, np.linalg.solve(JJt, f[:, :, None])[:, :, 0])
        size = np.abs(step).max(axis=1, keepdims=True)
        step *= np.minimum(1.0, MAX_STEP / np.maximum(size, 1e-300))
        q[active] = np.clip(q[active] + step, lo, hi)
    else:
        data = Measurements.from_arrays(q, prismatic=model.robot.prismatic, **extra)
        miss = np.linalg.norm(targets - model.predict(q, truth.values, model.covariates(data), truth.base0), axis=1)
    return q, miss


def touch_rows(truth, points: dict, placements: int, rows_per_point: int, rng: np.random.Generator, *,
               contact_noise: float = 20e-6, tilt: float = math.radians(5.0), session_prefix: str = "P",
               floor_z: float | None = 0.1, interleave: bool = True) -> tuple[Measurements, list[Placement]]:
    """Rows of the true robot's tool point in the points of a block (``points``: name -> m in its frame) at
    ``placements`` random placements (sessions ``P0``, ``P1``, ...), ``rows_per_point`` at each point of each,
    the point touched to ``contact_noise`` (m, Gaussian per axis). ``interleave``: the points in turn (the order
    a user touching both sockets in turn gives), else each point's rows together.

    Returns the rows (``q*_deg``, ``point``, ``session``; in placement order, within a placement in row order)
    and the placements (the truth: where each block stood).
    """
    names = list(points)
    order = [names[k % len(names)] for k in range(rows_per_point * len(names))] if interleave else \
        [p for p in names for _ in range(rows_per_point)]
    qs, point, session, where = [], [], [], []
    for k in range(placements):
        for _ in range(10):
            place = place_block(truth, points, rng, f"{session_prefix}{k}", tilt=tilt, floor_z=floor_z)
            targets = np.array([place.points[p] for p in order]) + rng.normal(0.0, contact_noise, (len(order), 3))
            try:
                q = readings_at(truth, targets, rng)
            except SimulationError:         # a point out of reach in too few ways: place the block again
                continue
            break
        else:
            raise SimulationError(f"no placement of 10 where {truth.model.robot.name} reaches every point of the "
                                  "block")
        qs.append(q)
        point += order
        session += [place.session] * len(order)
        where.append(place)
    data = Measurements.from_arrays(np.vstack(qs), prismatic=truth.model.robot.prismatic,
                                    point=np.array(point, dtype=object), session=np.array(session, dtype=object))
    return data, where
