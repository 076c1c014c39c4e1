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

from ..errors import DataFileError, DataWarning, InputError
from ..robot import Robot
from ._measurements import XYZ, Measurements, looks_like_radians, session_index

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
#: the start model (nominal), its base pose fitted to the poses, may miss them by this share of the robot's
#: reach (median over the poses) at most: real data stay below 0.25 % (UR10 series A and B, the seed papers'
#: protocols, the test arms: 0.22 % at most), another robot's poses give 13 % or more (docs/formats.md)
REACH_SHARE = 0.05

FLAGS = {"limits": "--allow-outside-limits", "angles": "--angles-are-degrees",
         "positions": "--positions-are-mm", "mismatch": "--allow-mismatch"}


def check_poses(data: Measurements, robot: Robot, *, allow_outside_limits: bool = False,
                angles_are_degrees: bool = False, positions_are_mm: bool = False, allow_mismatch: bool = False,
                predicted: np.ndarray | None = None, nominal: bool = False,
                calibration: tuple[str, float | None] | None = None) -> None:
    """Every plausibility check of ``data`` for ``robot``, once per data set and robot.

    A data set that passed, or was let through by an override, is marked
    (``data.checked``, kept by its subsets): later calls for the same robot
    return at once, whatever their overrides, so the decision taken at the
    entry point holds for the calibrations inside a diagnosis or comparison.

    Parameters
    ----------
    data : Measurements
    robot : Robot
    allow_outside_limits, angles_are_degrees, positions_are_mm, allow_mismatch : bool
        Overrides of :func:`check_joint_limits`, :func:`check_angle_units`,
        :func:`check_position_units` and :func:`check_model_fits`.
    predicted : ndarray, shape (N, 3), optional
        Model positions (m, any frame) of the poses; the nominal model's by
        default. Only used when ``data`` has measured positions.
    nominal : bool
        ``predicted`` are the robot's nominal model's (judged by
        :func:`check_model_fits` as when ``predicted`` is not given).
    calibration : (str, float or None), optional
        ``predicted`` are a calibration's: its file and its mean error on its
        own poses (mm), for :func:`check_model_fits`. Predictions of any
        other model are not judged by it.

    Raises
    ------
    DataFileError
        Naming the file, row and column, with the fix and the override.
    """
    if data.n_joints != robot.n:
        raise DataFileError(f"has {data.n_joints} joint columns but robot {robot.name} has {robot.n} joints",
                            file=data.path, row=1)
    from ._measurements import check_reading_units
    check_reading_units(data.q_columns, robot, data.path)    # qK_mm for a prismatic joint, qK_deg otherwise
    key = ("poses", robot.name, robot.n, robot.limits.tobytes(), robot.tool.tobytes(), tuple(robot.tools))
    if key in data.checked:
        return
    from ..terms._tool_points import check_tool_points
    check_tool_points(data, robot)      # the rows' tool points are the robot file's (what it lacks: a note)
    check_angle_units(data, robot, allow=angles_are_degrees)
    check_joint_limits(data, robot, allow=allow_outside_limits)
    if data.has_positions and data.touches:     # the measured rows alone (a touch row has no position)
        tracked = np.flatnonzero(~data.touching)
        if len(tracked):
            check_poses(data.subset(tracked), robot, allow_outside_limits=True, angles_are_degrees=True,
                        positions_are_mm=positions_are_mm, allow_mismatch=allow_mismatch,
                        predicted=None if predicted is None else np.asarray(predicted)[tracked], nominal=nominal,
                        calibration=calibration)
    elif data.has_positions:
        judge = predicted is None or nominal or calibration is not None
        if predicted is None:
            from ..model._symbolic import Model, parse_spec
            from ..terms._tool_points import with_tool_points
            model = Model(robot, with_tool_points(parse_spec("nominal"), data), jit=False)
            predicted = model.predict(data.q, cov=model.covariates(data))
        for idx in session_index(data).values():    # each session in its own tracker frame
            check_position_units(data.subset(idx), np.asarray(predicted)[idx], allow=positions_are_mm)
        # with --positions-are-mm the user vouches for points the model's do not match in scale: not judged
        if judge and not positions_are_mm:
            check_model_fits(data, robot, predicted, calibration, allow=allow_mismatch)
    data.checked.add(key)


def check_joint_limits(data: Measurements, robot: Robot, allow: bool = False) -> None:
    """Every joint reading within the robot's limits (``min_deg``, ``max_deg``; ``min_mm``, ``max_mm`` for a
    prismatic joint).

    A reading beyond a limit is a typing error, a pose of another robot or a
    robot file with wrong limits; the model is not valid there. With
    ``allow`` it is a warning.
    """
    q = data.q_deg
    lim = robot.file_limits       # degrees, millimetres for a prismatic joint (its tolerance too)
    out = (q < lim[:, 0] - LIMIT_TOLERANCE_DEG) | (q > lim[:, 1] + LIMIT_TOLERANCE_DEG)
    if not out.any():
        return
    rows, joints = np.nonzero(out)
    k = int(np.argmin(data.lines[rows] * (robot.n + 1) + joints))   # first in the file
    i, j = int(rows[k]), int(joints[k])
    more = f" ({len(rows)} readings in all)" if len(rows) > 1 else ""
    unit = robot.joints[j].unit
    where = dict(file=data.path, row=int(data.lines[i]), column=f"q{j + 1}_{unit}")
    what = (f"joint reading {q[i, j]:g} {unit} is outside joint {j + 1}'s limits "
            f"[{lim[j, 0]:g}, {lim[j, 1]:g}] {unit} of robot {robot.name}{more}")
    if allow:
        warnings.warn(str(DataFileError(what + f"; allowed by {FLAGS['limits']}", **where)), DataWarning,
                      stacklevel=3)
        return
    raise DataFileError(what + f"; correct the reading or the robot's min_{unit}/max_{unit}, or pass "
                        f"{FLAGS['limits']} to use it anyway", **where)


def check_angle_units(data: Measurements, robot: Robot, allow: bool = False) -> None:
    """Joint readings that look like radians in the ``_deg`` columns.

    The rule: :func:`casadical.data._measurements.looks_like_radians` (every reading of every
    joint within +-2 pi over a few rows), and a robot with a joint whose limits reach beyond
    +-2 pi degrees (on such a robot, calibration poses spread over tens of
    degrees).
    """
    angles = [j for j, jt in enumerate(robot.joints) if not jt.prismatic]
    if not angles:
        return
    lim = np.degrees(np.abs(robot.limits[angles])).max()
    if allow or not looks_like_radians(data.q_deg[:, angles]) or lim <= 2 * math.pi:
        return
    raise DataFileError(f"every joint reading of the {len(data)} rows lies within +-6.3: these look like "
                        "radians, but the q<j>_deg columns hold degrees; convert radians to degrees "
                        f"(multiply by 180/pi = 57.2958), or pass {FLAGS['angles']} if they are degrees",
                        file=data.path, column=f"q{angles[0] + 1}_deg")


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


def check_model_fits(data: Measurements, robot: Robot, predicted: np.ndarray,
                     calibration: tuple[str, float | None] | None = None, allow: bool = False) -> None:
    """Poses the model cannot mean: another robot's, or joint readings and positions that do not belong together.

    The model's tool points for the joint readings are moved onto the
    measured points by the best rigid motion (the base pose, in closed
    form; one per session), fitted again on the half of the poses it brings
    nearest (a few bad readings neither move it nor decide); no calibration of the robot
    moves its points further than this leaves them, only nearer. The median
    distance left is judged: for a robot's nominal model it may be
    :data:`REACH_SHARE` of the robot's reach
    (:func:`casadical.terms._base.reach`) at most; for a calibration
    (``calibration`` given) the rule of :func:`check_calibration_fits`.

    Parameters
    ----------
    data : Measurements
        Poses with measured positions (3 or more; fewer are not judged).
    robot : Robot
    predicted : ndarray, shape (N, 3)
        The model's tool points (m, any frame).
    calibration : (str, float or None), optional
        The calibration's file and its mean error on its own poses (mm).
    allow : bool
        Accept the poses anyway (a warning).

    Raises
    ------
    DataFileError
        Naming the file, the error, the robot (or calibration) and the override.
    """
    from ..terms._base import reach

    # each session in its own tracker frame: its own base pose
    parts = [base_fitted_errors(np.asarray(predicted)[idx], data.xyz[idx]) for idx in session_index(data).values()]
    parts = [e for e in parts if e is not None]
    if not parts:
        return
    errors = np.concatenate(parts)
    if calibration is not None:
        check_calibration_fits(errors, data, calibration[0], calibration[1], allow, base_fitted=True)
        return
    median = float(np.median(errors))
    limit = REACH_SHARE * reach(robot)
    if not (median > limit or not math.isfinite(median)):
        return
    what = (f"the nominal model of robot {robot.name}, with its base pose fitted to these poses, misses half "
            f"of the measured points by more than {median * 1000:.5g} mm, {median / reach(robot):.0%} of the "
            f"robot's reach ({reach(robot) * 1000:.0f} mm; a real robot's nominal model misses by a few mm): the "
            "poses and the robot do not belong together (another robot's data, or joint readings and positions "
            "of different files)")
    if allow:
        warnings.warn(str(InputError(what + f"; allowed by {FLAGS['mismatch']}", file=data.path)), DataWarning,
                      stacklevel=4)
        return
    raise DataFileError(what + f"; check the robot file and the data, or pass {FLAGS['mismatch']} to use them "
                        "anyway", file=data.path)


def base_fitted_errors(predicted: np.ndarray, measured: np.ndarray) -> np.ndarray | None:
    """Distances (m) of measured points from model points moved by the best rigid motion onto them.

    The motion is fitted on every point, then again on the half it brings
    nearest, so that a few gross errors do not move it. None when there are
    fewer than 3 points or they lie on a line (no motion to fit).
    """
    from ..errors import IdentifiabilityError
    from ..stats._alignment import align

    if len(measured) < 3:
        return None

    def distances(T):
        with np.errstate(over="ignore", invalid="ignore"):
            return np.linalg.norm(predicted @ T[:3, :3].T + T[:3, 3] - measured, axis=1)

    try:
        errors = distances(align(predicted, measured))
        best = np.argsort(errors)[: max(3, len(errors) // 2)]
        return distances(align(predicted[best], measured[best]))
    except (IdentifiabilityError, np.linalg.LinAlgError, ValueError):
        return None


def check_calibration_fits(errors_m: np.ndarray, data: Measurements, calibration_file: str,
                           own_mean_mm: float | None, allow: bool = False, base_fitted: bool = False) -> None:
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
    base_fitted : bool
        The errors are after a base pose fitted to the poses (:func:`base_fitted_errors`): their median
        is judged (a few bad readings do not decide), and the message says so.
    """
    mean = float(np.median(errors_m) if base_fitted else np.mean(errors_m)) * 1000.0
    if not _beyond_its_own(mean, own_mean_mm):
        return
    own = f"{own_mean_mm:.3g} mm on its own poses" if own_mean_mm is not None else "no error of its own recorded"
    if base_fitted:
        what = (f"the calibration {calibration_file} ({own}), with its base pose fitted to these measured poses, "
                f"misses half of them by more than {mean:.5g} mm: the poses and the calibration do not belong together "
                "(another robot's data, or joint readings and positions of different files)")
    else:
        what = (f"the calibration {calibration_file} ({own}) predicts these measured poses with a mean error of "
                f"{mean:.4g} mm: they are not poses of that robot, or not in that calibration's measurement frame")
    if allow:
        warnings.warn(str(InputError(what, file=data.path)), DataWarning, stacklevel=3)
        return
    raise DataFileError(what + f"; pass {FLAGS['mismatch']} to use them anyway", file=data.path)


def _beyond_its_own(mean_mm: float, own_mean_mm: float | None) -> bool:
    """A model's mean error on poses is beyond anything it can mean there: over :data:`MISMATCH_FACTOR` times its
    error on its own poses and over :data:`MISMATCH_FLOOR_MM` (or not finite)."""
    return mean_mm > max(MISMATCH_FACTOR * (own_mean_mm or 0.0), MISMATCH_FLOOR_MM) or not math.isfinite(mean_mm)


def check_distinct_poses(data: Measurements, m: int) -> None:
    """A pool with fewer distinct poses than the ``m`` to select (copies of one pose are no design)."""
    distinct = len(np.unique(data.q_deg, axis=0))
    if distinct < m:
        raise DataFileError(f"has only {distinct} distinct pose(s) among its {len(data)} rows: cannot select "
                            f"{m} different poses; add candidates spread over the joint ranges",
                            file=data.path)


def repeated_rows(first: Measurements, second: Measurements) -> np.ndarray:
    """Which rows of ``second`` are rows of ``first``: the same joint readings and the same measured point, to
    the last digit (a pose measured again differs in its point; a row copied does not). None of them where either
    has no measured points."""
    def keys(d: Measurements) -> np.ndarray:
        a = np.ascontiguousarray(np.column_stack([d.q, d.xyz]), dtype=float) + 0.0     # -0.0 reads as 0.0
        return a.view(np.dtype((np.void, a.dtype.itemsize * a.shape[1]))).ravel()

    # without measured points two files may well hold one joint program (targets measured in two sessions)
    if not (first.has_positions and second.has_positions) or first.n_joints != second.n_joints:
        return np.zeros(len(second), bool)
    return np.isin(keys(second), keys(first))


def check_held_out(cal: Measurements, val: Measurements) -> None:
    """Validation poses must not be calibration poses: an error on a pose the fit has seen is not held out.

    Raises
    ------
    DataFileError
        Every validation pose is a calibration pose (the same file given twice, or its copy).

    Warns
    -----
    DataWarning
        Some are: how many, and the first one's row.
    """
    _apart(cal, val, ("is a calibration pose of", "are calibration poses of"), "errors on them are not held out",
           "validate on poses the calibration did not use (casadical split makes both)")


def check_validation_frames(val: Measurements, errors_m: np.ndarray, own_mean_mm: float, allow: bool = False,
                            what: str = "validation poses") -> None:
    """Each session's validation poses must be in that session's measurement frame.

    With several sessions, validation poses are matched to sessions by their
    ``session`` column or by the order of the files; a file given out of order
    is judged in another tracker frame. The nominal model with each session's
    base pose fitted to its calibration poses misses poses in the right frame
    by about what it misses its own poses by, and poses in another frame by
    metres.

    Parameters
    ----------
    val : Measurements
    errors_m : ndarray
        Position errors (m) of that model on ``val``.
    own_mean_mm : float
        Its mean error on its own (the calibration) poses.
    allow : bool
        Accept them anyway (a warning).
    what : str
        What the poses are, for the message.

    Raises
    ------
    DataFileError
        A session's validation poses are missed by more than 100 times the model's own error and 5 mm.
    """
    for s, idx in session_index(val).items():
        mean = float(np.mean(errors_m[idx])) * 1000.0 if len(idx) else 0.0
        if not _beyond_its_own(mean, own_mean_mm):
            continue
        file = str(val.sources[idx[0]]) if val.sources is not None else val.path
        text = (f"the {what}{f' of session {s}' if s else ''} are missed by {mean:.4g} mm on average by the "
                f"nominal model with the base pose fitted to the calibration poses{f' of {s}' if s else ''} "
                f"({own_mean_mm:.3g} mm on those): they are not in that measurement frame"
                + ("; --validate files are taken in the order of the DATA files, or by their session column"
                   if s else ""))
        if allow:
            warnings.warn(str(InputError(text + f"; allowed by {FLAGS['mismatch']}", file=file)), DataWarning,
                          stacklevel=3)
            continue
        raise DataFileError(text + f"; pass {FLAGS['mismatch']} to use them anyway", file=file)


def check_other_series(cal: Measurements, other: Measurements) -> None:
    """A series findings are taken to (``diagnose --transfer``) must not be the calibration poses: refitted and
    judged there, a transfer would only repeat the calibration."""
    _apart(cal, other, ("is a calibration pose of", "are calibration poses of"),
           "a transfer to them is no test of another series", "give the file of another measurement series")


def check_sessions_apart(parts: list[Measurements]) -> None:
    """Sessions must be different measurements: a file given twice (or its copy) counts its poses twice and
    makes every uncertainty too small."""
    for j, later in enumerate(parts):
        for earlier in parts[:j]:
            _apart(earlier, later, ("is also in", "are also in"), "the same measurements given twice count twice",
                   "give each session's file once")


def _apart(first: Measurements, second: Measurements, relation: tuple[str, str], why: str, fix: str) -> None:
    key = ("apart", id(first), len(first))       # once per pair: a command checks before its work, the library again
    if key in second.checked:
        return
    shared = repeated_rows(first, second)
    what = "the same joint readings and measured point" + (", the same file given twice" if first.path == second.path
                                                           else "")
    if shared.all() and len(shared):
        raise DataFileError(f"every one of its {len(second)} poses {relation[0]} {first.path} ({what}): {why}; {fix}",
                            file=second.path)
    second.checked.add(key)
    if shared.any():
        i = int(np.flatnonzero(shared)[0])
        where = f"row {second.lines[i]}" + (f" of {second.sources[i]}" if second.sources is not None else "")
        warnings.warn(str(InputError(f"{int(shared.sum())} of its {len(second)} poses (the first in {where}) "
                                     f"{relation[1]} {first.path} ({what}): {why}", file=second.path)),
                      DataWarning, stacklevel=3)
