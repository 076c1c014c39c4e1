"""Plausibility checks of poses against a robot: limits, units, a calibration that does not fit.

A measurement file can be well formed and still wrong: joint readings in
radians in the ``_deg`` columns, positions in metres in the ``_mm`` columns,
a pose beyond the joint limits, poses of another robot. Each of these gives
a calibration that looks like a result and is not. The functions here turn
them into one clear error naming the file, row and column, with the fix,
and each has an override (a keyword here, a flag on the command line) for
the rare data that really are so.

Every command that reads poses for a robot runs :func:`check_poses`, and so
do the library entry points :func:`~casadical.calibration.calibrate` and
:func:`~casadical.diagnosis.diagnose`. A data set that passed (or was
allowed) is marked, and its subsets keep the mark, so the many calibrations
inside a diagnosis or a comparison do not check again.
"""

from __future__ import annotations

import math
import warnings

import numpy as np

from .data import XYZ, Measurements, looks_like_radians
from .errors import DataFileError, DataWarning, InputError
from .robot import Robot

#: measured and predicted spreads of the tool points may differ by this factor at most
SPREAD_FACTOR = 5.0
#: below this spread of the predicted tool points (m) the poses barely move: no units check
MIN_SPREAD_M = 0.01
#: a calibration that predicts poses this many times worse than its own poses does not fit them
MISMATCH_FACTOR = 100.0
#: ... unless the error stays below this (mm): small own errors make the ratio meaningless
MISMATCH_FLOOR_MM = 5.0
#: readings this close to a limit (deg) count as within it (rounding in the file)
LIMIT_TOLERANCE_DEG = 1e-6

FLAGS = {"limits": "--allow-outside-limits", "angles": "--angles-are-degrees",
         "positions": "--positions-are-mm", "mismatch": "--allow-mismatch"}


def check_poses(data: Measurements, robot: Robot, *, allow_outside_limits: bool = False,
                angles_are_degrees: bool = False, positions_are_mm: bool = False,
                predicted: np.ndarray | None = None) -> None:
    """Every plausibility check of ``data`` for ``robot``, once per data set and robot.

    A data set that passed, or was let through by an override, is marked
    (``data.checked``, kept by its subsets): later calls for the same robot
    return at once, whatever their overrides, so the decision taken at the
    entry point holds for the calibrations inside a diagnosis or comparison.

    Parameters
    ----------
    data : Measurements
    robot : Robot
    allow_outside_limits, angles_are_degrees, positions_are_mm : bool
        Overrides of :func:`check_joint_limits`, :func:`check_angle_units`
        and :func:`check_position_units`.
    predicted : ndarray, shape (N, 3), optional
        Model positions (m, any frame) of the poses; the nominal model's by
        default. Only used when ``data`` has measured positions.

    Raises
    ------
    DataFileError
        Naming the file, row and column, with the fix and the override.
    """
    if data.n_joints != robot.n:
        raise DataFileError(f"has {data.n_joints} joint columns but robot {robot.name} has {robot.n} joints",
                            file=data.path, row=1)
    key = ("poses", robot.name, robot.n, robot.limits.tobytes(), robot.tool.tobytes())
    if key in data.checked:
        return
    check_angle_units(data, robot, allow=angles_are_degrees)
    check_joint_limits(data, robot, allow=allow_outside_limits)
    if data.has_positions:
        if predicted is None:
            from .model import Model
            predicted = Model(robot, "nominal", jit=False).predict(data.q)
        from .sessions import session_index
        for idx in session_index(data).values():    # each session in its own tracker frame
            check_position_units(data.subset(idx), np.asarray(predicted)[idx], allow=positions_are_mm)
    data.checked.add(key)


def check_joint_limits(data: Measurements, robot: Robot, allow: bool = False) -> None:
    """Every joint reading within the robot's limits (``min_deg``, ``max_deg``).

    A reading beyond a limit is a typing error, a pose of another robot or a
    robot file with wrong limits; the model is not valid there. With
    ``allow`` it is a warning.
    """
    q = data.q_deg
    lim = np.degrees(robot.limits)
    out = (q < lim[:, 0] - LIMIT_TOLERANCE_DEG) | (q > lim[:, 1] + LIMIT_TOLERANCE_DEG)
    if not out.any():
        return
    rows, joints = np.nonzero(out)
    k = int(np.argmin(data.lines[rows] * (robot.n + 1) + joints))   # first in the file
    i, j = int(rows[k]), int(joints[k])
    more = f" ({len(rows)} readings in all)" if len(rows) > 1 else ""
    where = dict(file=data.path, row=int(data.lines[i]), column=f"q{j + 1}_deg")
    what = (f"joint reading {q[i, j]:g} deg is outside joint {j + 1}'s limits "
            f"[{lim[j, 0]:g}, {lim[j, 1]:g}] deg of robot {robot.name}{more}")
    if allow:
        warnings.warn(str(DataFileError(what + f"; allowed by {FLAGS['limits']}", **where)), DataWarning,
                      stacklevel=3)
        return
    raise DataFileError(what + "; correct the reading or the robot's min_deg/max_deg, or pass "
                        f"{FLAGS['limits']} to use it anyway", **where)


def check_angle_units(data: Measurements, robot: Robot, allow: bool = False) -> None:
    """Joint readings that look like radians in the ``_deg`` columns.

    The rule: :func:`casadical.data.looks_like_radians` (every reading of every
    joint within +-2 pi over a few rows), and a robot with a joint whose limits reach beyond
    +-2 pi degrees (on such a robot, calibration poses spread over tens of
    degrees).
    """
    lim = np.degrees(np.abs(robot.limits)).max()
    if allow or not looks_like_radians(data.q_deg) or lim <= 2 * math.pi:
        return
    raise DataFileError(f"every joint reading of the {len(data)} rows lies within +-6.3: these look like "
                        "radians, but the q<j>_deg columns hold degrees; convert radians to degrees "
                        f"(multiply by 180/pi = 57.2958), or pass {FLAGS['angles']} if they are degrees",
                        file=data.path, column="q1_deg")


def spread(points: np.ndarray) -> float:
    """Root-mean-square distance of points from their centre (rotation and translation invariant)."""
    p = np.asarray(points, dtype=float)
    if not len(p):
        return 0.0
    with np.errstate(over="ignore", invalid="ignore"):   # absurd values (1e300 mm) give inf: still judged
        s = float(np.sqrt(np.mean(np.sum((p - p.mean(axis=0)) ** 2, axis=1))))
    return s if math.isfinite(s) else math.inf


def check_position_units(data: Measurements, predicted: np.ndarray, allow: bool = False) -> None:
    """Measured positions whose scale does not match the robot's (metres in ``_mm`` columns, ...).

    A rigid motion keeps the spread of points, so the measured tool points
    of the poses and the model's tool points for their joint readings must
    spread alike, whatever the tracker's place; a factor beyond
    :data:`SPREAD_FACTOR` is a unit mistake or another robot's data.
    """
    pred = spread(predicted)
    if allow or len(data) < 3 or pred < MIN_SPREAD_M:
        return
    meas = spread(data.xyz)
    ratio = meas / pred
    if 1 / SPREAD_FACTOR <= ratio <= SPREAD_FACTOR:
        return
    fixes = [(1e-3, "metres: multiply x_mm, y_mm, z_mm by 1000"),
             (1e-1, "centimetres: multiply x_mm, y_mm, z_mm by 10"),
             (1 / 25.4, "inches: multiply x_mm, y_mm, z_mm by 25.4"),
             (1e3, "micrometres: divide x_mm, y_mm, z_mm by 1000")]
    fix = next((f"these look like {text}" for r, text in fixes
                if 0 < ratio < math.inf and abs(math.log(ratio / r)) < math.log(1.3)),
               "is it the right robot file, and are the joint readings in degrees?")
    raise DataFileError(f"the measured positions spread {meas * 1000:.4g} mm around their centre, the robot's "
                        f"tool points for these joint readings {pred * 1000:.4g} mm ({ratio:.3g} times as "
                        f"much); {fix} (or pass {FLAGS['positions']} to use them as they are)",
                        file=data.path, column=XYZ[0])


def check_calibration_fits(errors_m: np.ndarray, data: Measurements, calibration_file: str,
                           own_mean_mm: float | None, allow: bool = False) -> None:
    """A calibration that predicts measured poses far worse than its own poses does not belong to them.

    Parameters
    ----------
    errors_m : ndarray
        Position error per pose of the calibration on ``data`` (m).
    data : Measurements
        Poses with measured positions.
    calibration_file : str
        The calibration's file, for the message.
    own_mean_mm : float or None
        The calibration's mean error on its own poses.
    allow : bool
        Accept the poses anyway (a warning).
    """
    mean = float(np.mean(errors_m)) * 1000.0
    limit = max(MISMATCH_FACTOR * (own_mean_mm or 0.0), MISMATCH_FLOOR_MM)
    if not mean > limit:
        return
    own = f"{own_mean_mm:.3g} mm on its own poses" if own_mean_mm is not None else "no error of its own recorded"
    what = (f"the calibration {calibration_file} ({own}) predicts these measured poses with a mean error of "
            f"{mean:.4g} mm: they are not poses of that robot, or not in that calibration's measurement frame")
    if allow:
        warnings.warn(str(InputError(what, file=data.path)), DataWarning, stacklevel=3)
        return
    raise DataFileError(what + f"; pass {FLAGS['mismatch']} to use them anyway", file=data.path)


def check_distinct_poses(data: Measurements, m: int) -> None:
    """A pool with fewer distinct poses than the ``m`` to select (copies of one pose are no design)."""
    distinct = len(np.unique(data.q_deg, axis=0))
    if distinct < m:
        raise DataFileError(f"has only {distinct} distinct pose(s) among its {len(data)} rows: cannot select "
                            f"{m} different poses; add candidates spread over the joint ranges",
                            file=data.path)
