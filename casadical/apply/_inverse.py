"""Corrected joint targets: the joints that put the calibrated tool point on a target.

A robot program holds joint targets taught or computed with the nominal
model. :func:`compensate` finds, row by row, the joints at which the
*calibrated* model (every term, the row's covariates) puts the tool point on
the desired point, starting from the programmed joints:

- position: ``cal.predict(q) = target`` (3 equations), always;
- orientation, for robots with 6 joints or more: the flange (last link
  frame) keeps the rotation the nominal model gives at the programmed joints,
  placed at the calibrated base pose (3 more equations): what the programmer
  taught; or, when the targets give the probe's orientation (``rx_deg,
  ry_deg, rz_deg``, measurement frame) and the calibration is a full-pose
  one, the probe takes that orientation through its calibrated mounting;
- whatever freedom is left (fewer than 6 joints, more than 6, or a singular
  configuration): the smallest joint change ``|q - q_programmed|``.

Near a singular configuration the equations barely see some direction of
joint motion, and reaching the target exactly would move the joints by
degrees for a fraction of a millimetre. No correction moves the joints more
than ``max_deg_per_mm`` degrees per millimetre (or per milliradian of
orientation) along any direction: where the exact solution would, that
part of the correction is damped (damped least squares with a damping that
grows as the singular value falls below the bound, Chiaverini's variable
damping; the least joint motion for what is left), the row keeps the rest
of its miss, and a warning names the rows with their conditioning.

The solver is a batched Levenberg-Marquardt iteration over all rows at once
on the exact Jacobians of the symbolic model
(:meth:`Model.predict_q_jacobian`, :meth:`Model.flange_rotation_jacobian`),
from the programmed joints. Each step is a damped pseudo-inverse (SVD) of
the equations' Jacobian, plus, in its null space (what the equations do not
see), the way back to the programmed joints: the two parts are orthogonal,
so the fixed point is exactly the least joint change and the damping only
changes the path. Along a singular value below the bound the step also
pulls back to the programmed joints, so that the damped correction is the
fixed point there (the regularised least squares ``|r|^2 + mu^2 |dq|^2``
of that direction). The residual is :meth:`CalibrationResult.predict`, the
full prediction: a smooth additive correction there is honoured, its
derivative only slows the iteration. Rows where position and orientation
cannot both be met near the programmed joints (within ``max_change_deg``
and the bound) get a second pass with the position alone.

Joint limits are hard: a row whose solution lies beyond a limit, or that
does not converge, is an error naming the file, row (and joint column).
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from ..data._checks import check_poses
from ..data._measurements import XYZ, Measurements
from ..errors import ConvergenceWarning, InputError, listing
from ..result import CalibrationResult
from ..robot import readings_from_file_units, readings_to_file_units

#: relative damping lambda of the pseudo-inverses (a singular value s gets s / (s^2 + (lambda s_max)^2)):
#: start, smallest, and largest before a row counts as stuck
LAMBDA_START, LAMBDA_MIN, LAMBDA_MAX = 1e-3, 1e-9, 1e4
#: a step is kept if it lowers the residual or leaves it below this fraction of the tolerance (the
#: steps towards the least joint change bend off the solutions by their square, the next step corrects)
SETTLE_FRACTION = 0.5
#: an orientation error of 1 rad weighs like a position error of this many metres
ORIENTATION_WEIGHT = 1.0
#: largest change of any joint in one iteration (rad)
MAX_STEP = 0.2
#: a row has settled when no joint moves more than this in a step (rad)
STEP_TOL = 1e-10
#: the orientation counts as held within this angle (rad)
ORIENTATION_TOL = 1e-8
#: relative change of a step's merit that is rounding, not a rise
ROUNDING = 1e-10
#: default bound on the joint motion per unit of correction (deg per mm, or per mrad of orientation): 0.66 % of
#: the 13,406 poses of the UR10 data (series A and B) are beyond it with the orientation held (1.66 % beyond 1 deg
#: per mm), 0.01 % for the position alone; at q2 = -90, q3 = 0, q5 = 0 the exact correction would need 399
#: (benchmarks/studies/study_singular.py)
MAX_DEG_PER_MM = 2.0


def singular_bound(max_deg_per_mm: float) -> float:
    """The smallest singular value (m per rad) of the equations that is not damped, for a bound in deg per mm."""
    return 1.0 / (np.radians(max_deg_per_mm) * 1e3)


class TargetError(InputError):
    """A target cannot be reached: no solution, or one beyond a joint limit."""


@dataclass
class CompensationResult:
    """Corrected joint targets of a robot program (one row per target).

    Attributes
    ----------
    targets : Measurements
        The input: programmed joints (``q*_deg``) and targets (``x_mm,
        y_mm, z_mm``, measurement frame), with any other columns.
    q : ndarray, shape (N, n)
        Corrected joint readings (rad).
    residual : ndarray, shape (N,)
        Distance from the calibrated model's tool point at ``q`` to the
        target (m).
    start_residual : ndarray, shape (N,)
        The same at the programmed joints: what the compensation corrects.
    orientation_error : ndarray, shape (N,), or None
        Angle between the held flange orientation and the calibrated
        model's at ``q`` (rad); None when no orientation is held.
    iterations : ndarray of int, shape (N,)
        Levenberg-Marquardt steps tried per row (both passes).
    converged : ndarray of bool, shape (N,)
        ``residual <= tolerance``.
    tolerance : float
        Position tolerance (m).
    held : str
        What is held besides the tool point.
    probe : bool
        The orientation held is the targets' probe orientation (``rx_deg, ry_deg,
        rz_deg``), not the nominal flange orientation.
    limits : ndarray, shape (n, 2)
        Joint limits of the readings (rad).
    max_change : float or ndarray, shape (n,)
        Largest admissible change of a joint (rad; m for a prismatic joint, per joint).
    smallest_sv : ndarray, shape (N,)
        Smallest singular value of each row's equations at its solution
        (m per rad; orientation rows weigh 1 m per rad).
    largest_sv : ndarray, shape (N,)
        Their largest (the condition number is the ratio).
    damped : ndarray of bool, shape (N,)
        Rows near a singular configuration: a singular value below the
        bound, the correction along it damped (the miss they keep is in
        ``residual``, and, with an orientation held, ``orientation_error``).
    max_deg_per_mm : float
        The bound on the joint motion per mm of correction (deg).
    """

    targets: Measurements
    q: np.ndarray
    residual: np.ndarray
    start_residual: np.ndarray
    orientation_error: np.ndarray | None
    iterations: np.ndarray
    converged: np.ndarray
    tolerance: float
    held: str
    limits: np.ndarray
    max_change: float | np.ndarray
    probe: bool = False
    smallest_sv: np.ndarray | None = None
    largest_sv: np.ndarray | None = None
    damped: np.ndarray | None = None
    max_deg_per_mm: float = MAX_DEG_PER_MM

    @property
    def q0(self) -> np.ndarray:
        """Programmed joint readings (rad), shape (N, n)."""
        return self.targets.q

    @property
    def dq(self) -> np.ndarray:
        """Correction ``q - q0`` (rad), shape (N, n)."""
        return self.q - self.q0

    @property
    def orientation_held(self) -> np.ndarray | None:
        """Rows whose flange orientation is held within :data:`ORIENTATION_TOL` (None if none is held)."""
        if self.orientation_error is None:
            return None
        return self.orientation_error <= ORIENTATION_TOL

    def _file(self, v, j: int) -> float:
        """A reading or change of joint ``j`` (0-based) in its file unit (deg; mm for a prismatic joint)."""
        return float(v) * 1000.0 if self.targets.prismatic[j] else float(np.degrees(v))

    def _unit(self, j: int) -> str:
        return "mm" if self.targets.prismatic[j] else "deg"

    def failures(self) -> list[TargetError]:
        """One error per failing row, in row order: not reached, or beyond a joint limit."""
        t = self.targets
        n = self.q.shape[1]
        limit = np.broadcast_to(np.asarray(self.max_change, float), (n,))
        share = np.abs(self.dq) / limit             # of each joint's largest admissible change
        out = []
        for i in range(len(t)):
            if not self.converged[i] or share[i].max() > 1:
                j = int(np.argmax(share[i]))
                within = f"{self._file(limit[j], j):g} {self._unit(j)}"
                if any(t.prismatic) and not all(t.prismatic):
                    r = next(k for k in range(n) if not t.prismatic[k])
                    p = next(k for k in range(n) if t.prismatic[k])
                    within = f"{self._file(limit[r], r):g} deg ({self._file(limit[p], p):g} mm on a linear axis)"
                out.append(TargetError(
                    f"the calibrated model does not reach this target within {within} "
                    f"of the programmed joints: after {self.iterations[i]} iterations its tool point is "
                    f"{self.residual[i] * 1e3:.4g} mm from it (tolerance {self.tolerance * 1e3:g} mm) with joints "
                    f"up to {self._file(abs(self.dq[i, j]), j):.3g} {self._unit(j)} from the programmed ones; is the "
                    "target outside the reach, near a singular configuration, or not in the measurement frame in mm?",
                    file=t.path, row=t.line(i)))
                continue
            for j in range(n):
                lo, hi = self.limits[j]
                v = self.q[i, j]
                if v < lo or v > hi:
                    u = self._unit(j)
                    out.append(TargetError(
                        f"the corrected joint would be {self._file(v, j):.4f} {u}, beyond its limit "
                        f"{self._file(lo if v < lo else hi, j):g} {u} (programmed {self._file(self.q0[i, j], j):.4f} "
                        f"{u})", file=t.path, row=t.line(i), column=t.q_columns[j]))
                    break
        return out

    def singular_text(self, rows: np.ndarray) -> str:
        """One sentence on rows near a singular configuration: their conditioning and what is left of their miss."""
        left = f"up to {self.residual[rows].max() * 1e3:.3g} mm"
        if self.orientation_error is not None:
            left += f" and {np.degrees(self.orientation_error[rows].max()):.3g} deg"
        return (f"{len(rows)} row(s) near a singular configuration, where an exact correction would move the joints "
                "more per millimetre than allowed along the direction their equations barely see: rows "
                f"{conditioning(self.targets, rows, self.smallest_sv[rows], self.largest_sv[rows])}; there the "
                f"correction is damped to at most {self.max_deg_per_mm:g} deg per mm (--max-deg-per-mm) with the least "
                f"joint motion, and {left} of the miss is left")

    def check(self) -> None:
        """Raise the first row's :class:`TargetError` (naming how many more fail), if any."""
        errors = self.failures()
        if errors:
            first, more = errors[0], [e.row for e in errors[1:]]
            message = first.message + (f"; {len(more)} more row(s) fail: {listing(more, 10)}" if more else "")
            raise TargetError(message, file=first.file, row=first.row, column=first.column)

    def joints(self) -> Measurements:
        """The output table: input columns with corrected ``q*_deg``, then ``programmed_q*_deg``,
        ``dq*_deg``, ``residual_mm`` and (orientation held) ``orientation_error_deg``."""
        t = self.targets
        qcols = t.q_columns              # qK_deg, qK_mm for a prismatic joint: in the file's units
        cols = dict(t.columns)
        q, dq = readings_to_file_units(self.q, t.prismatic), readings_to_file_units(self.dq, t.prismatic)
        for j, c in enumerate(qcols):
            cols[c] = q[:, j]
        for c in qcols:
            cols["programmed_" + c] = t.columns[c]
        for j, c in enumerate(qcols):
            cols["d" + c] = dq[:, j]
        cols["residual_mm"] = self.residual * 1e3
        if self.orientation_error is not None:
            cols["orientation_error_deg"] = np.degrees(self.orientation_error)
        return Measurements(cols, t.path, t.rows, t.moves, t.lines)

    def summary(self) -> str:
        """A few lines: rows, largest correction, largest residual, what is held."""
        t = self.targets
        dq = readings_to_file_units(np.abs(self.dq), t.prismatic)
        i, j = np.unravel_index(np.argmax(dq), dq.shape)
        k = int(np.argmax(self.residual))
        s0 = self.start_residual * 1e3
        lines = [f"{len(t)} targets; at the programmed joints the calibrated tool point is {s0.mean():.4g} mm "
                 f"from them on average, {s0.max():.4g} mm at most",
                 f"corrected: largest correction {dq[i, j]:.4f} {self._unit(j)} (row {t.line(i)}, "
                 f"{t.q_columns[j]}), "
                 f"largest residual {self.residual[k] * 1e3:.3g} mm (row {t.line(k)}), "
                 f"at most {int(self.iterations.max())} iterations",
                 f"held: {self.held}"]
        if self.damped is not None and self.damped.any():
            k = int(np.sum(self.damped))
            lines.append(f"near a singular configuration: {k} row(s) damped to {self.max_deg_per_mm:g} deg per mm "
                         f"(largest miss left {self.residual[self.damped].max() * 1e3:.3g} mm)")
        if self.orientation_error is not None:
            held = self.orientation_held
            lines.append(f"{'probe' if self.probe else 'flange'} orientation held on {int(held.sum())} of "
                         f"{len(held)} rows "
                         f"(largest deviation {np.degrees(self.orientation_error.max()):.3g} deg)")
        return "\n".join(lines)


def conditioning(targets: Measurements, rows: np.ndarray, smallest: np.ndarray, largest: np.ndarray) -> str:
    """Rows named with the conditioning of their equations: condition number, joint motion per mm along the weakest."""
    per = np.degrees(1.0 / np.maximum(smallest, 1e-300)) / 1e3
    cond = largest / np.maximum(smallest, 1e-300)
    return listing([f"{targets.line(i)} (condition number {c:.3g}, {g:.3g} deg per mm)"
                    for i, c, g in zip(rows, cond, per)], 10)


def output_columns(n: int, columns: list[str] | None = None) -> list[str]:
    """Columns :meth:`CompensationResult.joints` adds to the input's, for ``n`` joints (reading ``columns``:
    ``qK_deg``, ``qK_mm`` for a prismatic joint; default all in degrees)."""
    q = columns or [f"q{j}_deg" for j in range(1, n + 1)]
    return ["programmed_" + c for c in q] + ["d" + c for c in q] + ["residual_mm", "orientation_error_deg"]


def calibrated_on_orientation(cal: CalibrationResult) -> bool:
    """The calibration was fitted on measured orientations (a full-pose calibration whose loss had them)."""
    return bool(cal.has_orientation and cal.full_pose)


def held_description(n: int, orientation: bool, probe: bool = False, position_only_calibration: bool = False) -> str:
    """What :func:`compensate` holds besides the tool point, for ``n`` joints (``probe``: the targets' orientation;
    ``position_only_calibration``: the orientation is not held by default because the calibration never measured
    it)."""
    if position_only_calibration and not orientation and n >= 6:
        return (f"nothing else, as the calibration measured positions alone (--hold-orientation holds the nominal "
                f"flange orientation): least joint change for the other {n - 3} degree(s) of freedom")
    if orientation:
        text = ("the probe orientation of the targets (rx_deg, ry_deg, rz_deg), through the calibrated probe "
                "mounting" if probe else
                "the flange orientation of the nominal model at the programmed joints (placed at the "
                "calibrated base)")
        return text + (f"; least joint change for the other {n - 6} degree(s) of freedom" if n > 6 else "")
    if n > 3:
        return f"nothing else: least joint change for the other {n - 3} degree(s) of freedom"
    return "nothing else: the joints nearest the programmed ones that reach the point"


def compensate(cal: CalibrationResult, targets: Measurements, *, tolerance_mm: float = 1e-4,
               max_iter: int = 30, max_change_deg: float = 5.0, orientation: bool | None = None,
               max_deg_per_mm: float = MAX_DEG_PER_MM, check: bool = True, flange_rotations: np.ndarray | None = None,
               frozen: np.ndarray | None = None, **checks: bool) -> CompensationResult:
    """Corrected joints that put the calibrated model's tool point on each target.

    Parameters
    ----------
    cal : CalibrationResult
        The calibrated model (e.g. from :func:`~casadical.calibration.load_calibration`).
    targets : Measurements
        Programmed joints (``q1_deg..qN_deg``, the start) and desired tool
        points (``x_mm, y_mm, z_mm``, measurement frame); covariates
        (``payload_kg``, ``temperature_c``, ...) as for ``predict``.
    tolerance_mm : float
        Largest admissible distance from the calibrated tool point to the target.
    max_iter : int
        Newton iterations per row at most.
    max_change_deg : float
        Largest admissible change of any joint from its programmed value.
        A compensation moves joints by fractions of a degree; a target that
        needs more is far from the programmed point (wrong frame or units?)
        and is an error. Where holding the orientation would need more (a
        near-singular configuration) the point alone is reached instead.
    orientation : bool, optional
        Hold an orientation: the probe orientation of the targets when they
        have ``rx_deg, ry_deg, rz_deg`` (measurement frame; the calibration
        must be a full-pose one, whose probe mounting turns it into the
        flange's), else the flange orientation of the nominal model at the
        programmed joints. Default: what the calibration measured: the
        targets' probe orientation when they have one, the nominal flange
        orientation on robots with 6 joints or more when the calibration was
        fitted on measured orientations (:func:`calibrated_on_orientation`),
        else the point alone (a position-only calibration never saw the
        orientation: holding it would move the joints by degrees to correct
        what it cannot know). True: hold it anyway. False: the point alone
        (the orientation columns are then ignored).
    max_deg_per_mm : float
        Largest joint motion per millimetre of correction (or per
        milliradian of orientation), in degrees, along any direction of
        joint motion. Near a singular configuration the exact correction
        would need more: there it is damped (least joint motion), the row
        keeps part of its miss and is named in a warning with the
        conditioning of its equations. Larger values reach such targets
        more exactly with larger joint motions.
    flange_rotations : ndarray, shape (N, 3, 3), optional
        Hold these flange (last link frame) rotations, measurement frame, one
        per row, instead of the nominal model's at the programmed joints
        (an inverse kinematics of given poses: :mod:`casadical.programs`).
        Not with ``orientation=False`` nor targets with a probe orientation.
    frozen : ndarray of bool, shape (n,), optional
        Joints held at their programmed values (e.g. a linear axis whose
        position a Cartesian target gives).
    check : bool
        Raise :class:`TargetError` for a row that is not reached or whose
        solution is beyond a joint limit (default). With False the result
        carries the failures (:meth:`CompensationResult.failures`).
    **checks : bool
        Overrides of the plausibility checks of the targets
        (:func:`casadical.data._checks.check_poses`: ``allow_outside_limits``,
        ``angles_are_degrees``, ``positions_are_mm``; ``allow_mismatch`` is
        accepted and has nothing to judge here): programmed joints beyond
        the limits or in radians, target points in metres.

    Returns
    -------
    CompensationResult

    Raises
    ------
    InputError
        Targets without positions, joint count not the robot's, bad options.
    DataFileError
        A plausibility check failed (file, row and column named, with the override).
    TargetError
        With ``check``: the first failing row (file, row and joint column).
    """
    model = cal.model
    n = model.robot.n
    if targets.n_joints != n:
        raise InputError(f"has {targets.n_joints} joint columns but the calibrated robot "
                         f"{model.robot.name} has {n} joints", file=targets.path, row=1,
                         column=f"q{min(targets.n_joints, n) + 1}_deg")
    if not targets.has_positions:
        missing = next(c for c in XYZ if c not in targets.columns)
        raise InputError("has no target positions: columns x_mm, y_mm, z_mm (measurement frame) are required",
                         file=targets.path, row=1, column=missing)
    clash = [c for c in output_columns(n, targets.q_columns) if c in targets.columns]
    if clash:
        raise InputError("is an output column of compensate; give the original targets (programmed joints and "
                         "points), not a compensated file", file=targets.path, row=1, column=clash[0])
    if not (tolerance_mm > 0 and max_change_deg > 0 and max_deg_per_mm > 0 and max_iter >= 1):
        raise InputError(f"tolerance_mm, max_change_deg and max_deg_per_mm must be positive and max_iter at least "
                         f"1, got {tolerance_mm}, {max_change_deg}, {max_deg_per_mm} and {max_iter}")
    if flange_rotations is not None:
        flange_rotations = np.asarray(flange_rotations, float)
        if orientation is False or targets.has_orientation or flange_rotations.shape != (len(targets), 3, 3):
            raise InputError("flange_rotations: one rotation (3x3) per row, with orientation not False and targets "
                             "without rx_deg, ry_deg, rz_deg")
        orientation = True
    probe = targets.has_orientation and orientation is not False
    if probe and not cal.has_orientation:
        raise InputError("holds the probe orientation of each target, but the calibration has no probe mounting "
                         "(it was calibrated on positions alone): calibrate on data with measured orientations, or "
                         "pass --position-only (orientation=False) to reach the points alone",
                         file=targets.path, row=1, column="rx_deg")
    hold = (probe or (n >= 6 and calibrated_on_orientation(cal))) if orientation is None else bool(orientation)
    if hold and n < 6:
        raise InputError(f"the orientation cannot be held with {n} joints: 6 are needed"
                         + ("; pass --position-only (orientation=False) to reach the points alone" if probe else ""),
                         file=targets.path if probe else None, row=1 if probe else None,
                         column="rx_deg" if probe else None)
    programmed = cal.predict(targets)    # the calibrated tool points at the programmed joints
    check_poses(targets, model.robot, predicted=programmed, **checks)

    eqs = _Equations(cal, targets, hold, probe, flange_rotations, frozen)
    tol = tolerance_mm * 1e-3
    N = len(targets)
    # max_change_deg: millimetres for a prismatic joint (the reading's file unit)
    limit = readings_from_file_units(np.full(n, float(max_change_deg)), model.robot.prismatic)
    eps = singular_bound(max_deg_per_mm)
    # the solver's joints are scaled so that a millimetre of a linear axis weighs as a degree of a revolute joint
    # (in the least joint change, the bound per mm of correction, the largest change); all 1 without one
    S = eqs.scale
    u, r, iterations, settled = _levenberg_marquardt(eqs, np.arange(N), targets.q * S, hold, tol, max_iter,
                                                     limit * S, eps)
    on_point = np.zeros(N, dtype=bool)    # rows solved for the point alone
    if hold:
        # rows where position and orientation cannot both be met near the programmed joints (a singular
        # configuration): the point alone, with the least joint change, from the start again
        loose = np.flatnonzero((np.linalg.norm(r[:, :3], axis=1) > tol)
                               | (np.linalg.norm(r[:, 3:], axis=1) > ORIENTATION_TOL * ORIENTATION_WEIGHT))
        if loose.size:
            u[loose], r2, it2, settled[loose] = _levenberg_marquardt(eqs, loose, targets.q[loose] * S, False,
                                                                     tol, max_iter, limit * S, eps)
            r[loose, :3] = r2
            r[loose, 3:] = eqs.orientation(loose, u[loose]) * ORIENTATION_WEIGHT
            iterations[loose] += it2
            on_point[loose] = True
    # the conditioning of each row's equations at its solution
    small, large = np.empty(N), np.empty(N)
    for rows, with_orientation in ((np.flatnonzero(~on_point), hold), (np.flatnonzero(on_point), False)):
        if rows.size:
            sv = np.linalg.svd(eqs(rows, u[rows], with_orientation)[1], compute_uv=False)
            small[rows], large[rows] = sv[:, -1], sv[:, 0]
    damped = small < eps
    q = u / S
    residual = np.linalg.norm(r[:, :3], axis=1)
    angle = np.linalg.norm(r[:, 3:], axis=1) / ORIENTATION_WEIGHT if hold else None
    start = np.linalg.norm(programmed - targets.xyz, axis=1)
    held = held_description(n, hold, probe, orientation is None and not calibrated_on_orientation(cal))
    result = CompensationResult(targets, q, residual, start, angle, iterations,
                                (residual <= tol) | (damped & settled), tol, held, model.robot.limits, limit, probe,
                                small, large, damped, max_deg_per_mm)
    if hold:
        loose = np.flatnonzero(result.converged & on_point & ~result.orientation_held)
        if loose.size:
            sv = np.linalg.svd(eqs(loose, targets.q[loose] * S, True)[1], compute_uv=False)   # at the programmed joints
            warnings.warn(f"{targets.path}: the {'probe' if probe else 'flange'} orientation cannot be held within "
                          f"{max_change_deg:g} deg of the programmed joints and {max_deg_per_mm:g} deg per mm of "
                          f"correction (--max-deg-per-mm) on {loose.size} row(s), near a singular configuration: "
                          f"rows {conditioning(targets, loose, sv[:, -1], sv[:, 0])}; there the point is reached "
                          f"with the least joint change (the orientation up to {np.degrees(angle[loose].max()):.3g} "
                          "deg off)", ConvergenceWarning, stacklevel=2)
    near = np.flatnonzero(result.converged & damped)
    if near.size:
        warnings.warn(f"{targets.path}: {result.singular_text(near)}", ConvergenceWarning, stacklevel=2)
    if check:
        result.check()
    return result


def _levenberg_marquardt(eqs: "_Equations", index: np.ndarray, q_start: np.ndarray, hold: bool, tol: float,
                         max_iter: int, max_change, eps: float
                         ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Solve rows ``index`` from ``q_start``: joints, residuals (position m, weighted orientation), steps, settled.

    Each step lowers ``|r|^2 + |W (q - q_start)|^2``, where ``W`` damps the
    directions of joint motion whose singular value is below ``eps``
    (:func:`_weak_rows`, at the step's joints). A step that would move a joint more than
    ``max_change`` (rad, m for a prismatic joint; per joint) from the start counts as a failed step. A row stops
    when it has settled (on the point, or at its damped solution) or when no
    damping makes progress.
    """
    M = len(index)
    q = q_start.copy()
    r, J = eqs(index, q, hold)
    lam = np.full(M, LAMBDA_START)
    iterations = np.zeros(M, dtype=int)
    done = np.zeros(M, dtype=bool)
    floor = (SETTLE_FRACTION * tol) ** 2
    act = np.arange(M)
    for _ in range(max_iter):
        W, weak = _weak_rows(J[act], eps)
        step = _newton_step(J[act], r[act], W, q_start[act] - q[act], lam[act])
        big = np.abs(step).max(axis=1)
        settled = ((np.linalg.norm(r[act, :3], axis=1) <= tol) | weak) & (big <= STEP_TOL)
        done[act[settled]] = True
        keep = ~settled & (lam[act] < LAMBDA_MAX)
        act, W = act[keep], W[keep]
        step = step[keep] * np.minimum(1.0, MAX_STEP / np.maximum(big[keep], 1e-300))[:, None]
        if act.size == 0:
            break
        trial = q[act] + step
        rt, Jt = eqs(index[act], trial, hold)
        iterations[act] += 1
        # a step is kept if it does not raise the residual and the damped motion (this step's damping, beyond
        # their rounding), or keeps the residual well within the tolerance, and stays within max_change of the
        # start; else more damping
        ok = ((_merit(rt, W, trial - q_start[act])
               <= np.maximum(_merit(r[act], W, q[act] - q_start[act]) * (1 + ROUNDING), floor))
              & ((np.abs(trial - q_start[act]) / max_change).max(axis=1) <= 1))
        good, bad = act[ok], act[~ok]
        q[good], r[good], J[good] = trial[ok], rt[ok], Jt[ok]
        lam[good] = np.maximum(lam[good] / 3.0, LAMBDA_MIN)
        lam[bad] *= 10.0
    return q, r, iterations, done


def _weak_rows(J: np.ndarray, eps: float) -> tuple[np.ndarray, np.ndarray]:
    """The damping of each row, shape (M, n, n), and the rows it acts on (a singular value below ``eps``).

    Along a singular value ``s < eps`` of ``J`` the
    row weighs its joint motion by ``mu^2 = (eps^2 - s^2) / 2`` (Chiaverini's
    variable damping): the solution moves the joints ``2 s / (eps^2 + s^2) <=
    1 / eps`` per unit of correction along it, exactly ``1 / s`` where ``s >=
    eps``.
    """
    _, s, Vt = np.linalg.svd(J)
    k = s.shape[1]
    mu = np.sqrt(np.where(s < eps, 0.5 * (eps * eps - s * s), 0.0))
    W = np.zeros((len(J), Vt.shape[1], Vt.shape[1]))
    W[:, :k] = mu[:, :, None] * Vt[:, :k]
    return W, s[:, -1] < eps


def _merit(r: np.ndarray, W: np.ndarray, moved: np.ndarray) -> np.ndarray:
    """What the steps lower, per row: ``|r|^2 + |W moved|^2``."""
    w = np.einsum("mkn,mn->mk", W, moved)
    return np.sum(r * r, axis=1) + np.sum(w * w, axis=1)


def _newton_step(J: np.ndarray, r: np.ndarray, W: np.ndarray, to_start: np.ndarray, lam: np.ndarray) -> np.ndarray:
    """Damped Newton step of every row towards ``r + J step = 0`` and ``W (q + step - q_start) = 0``, shape (M, n).

    Parameters
    ----------
    J, r : ndarray, shapes (M, m, n) and (M, m)
        Jacobian and residual.
    W : ndarray, shape (M, n, n)
        The damping of the weak directions (:func:`_weak_rows`).
    to_start : ndarray, shape (M, n)
        ``q_start - q``, followed in the null space of both: the fixed
        point is the least joint change from the start.
    lam : ndarray, shape (M,)
        Relative damping: singular value s acts as (s^2 + (lam s_max)^2) / s.
    """
    A = np.concatenate([J, W], axis=1)
    b = np.concatenate([r, -np.einsum("mkn,mn->mk", W, to_start)], axis=1)
    U, s, Vt = np.linalg.svd(A, full_matrices=False)
    null = s <= 1e-12 * s[:, :1]        # what neither the equations nor the damping see
    g = np.where(null, 0.0, s / (s * s + (lam[:, None] * s[:, :1]) ** 2 + 1e-300))
    back = np.where(null, np.einsum("mkn,mn->mk", Vt, to_start), 0.0)
    return np.einsum("mkn,mk->mn", Vt, g * np.einsum("mik,mi->mk", U, -b) + back)


class _Equations:
    """Residuals and Jacobians of rows ``index`` at joints ``q``: position (m), then weighted orientation.

    The joints are the solver's: each reading times :attr:`scale` (1 for a revolute joint, rad per mm for a linear
    axis, so that a millimetre weighs as a degree), the Jacobian with respect to them."""

    def __init__(self, cal: CalibrationResult, targets: Measurements, hold: bool, probe: bool = False,
                 rotations: np.ndarray | None = None, frozen: np.ndarray | None = None):
        self.cal, self.targets, self.model = cal, targets, cal.model
        self.scale = np.where(np.array(cal.model.robot.prismatic, bool), np.radians(1.0) / 1e-3, 1.0)
        # a frozen joint's columns are zero: the step's null space, where it goes back to the start, holds it
        self.moving = np.ones(cal.model.robot.n) if frozen is None else (~np.asarray(frozen, bool)).astype(float)
        self.p, self.base0 = cal.parameters.values, cal.base0
        self.cov = self.model.covariates(targets)
        self.goal = targets.xyz
        self.R_goal = None
        if hold and rotations is not None:
            self.R_goal = rotations
        elif hold and probe:
            # the flange orientation that puts the probe at the target's: probe = flange x mounting
            self.R_goal = targets.rotations @ cal.tool_rotation().T
        elif hold:
            # the nominal geometry at the calibrated base: what the programmer taught
            nominal = cal.parameters.nominal
            base = [k for k, prm in enumerate(cal.parameters) if prm.group == "base"]
            nominal[base] = self.p[base]
            self.R_goal = self.model.flange_rotation(targets.q, nominal, self.cov, self.base0)

    def __call__(self, index: np.ndarray, q: np.ndarray, hold: bool) -> tuple[np.ndarray, np.ndarray]:
        # the residual is CalibrationResult.predict itself, so that whatever it adds is honoured; the
        # Jacobian is the model's
        q = q / self.scale
        r = self.cal.predict(_at(self.targets, index, q)) - self.goal[index]
        _, J = self.model.predict_q_jacobian(q, self.p, self.cov[index], self.base0)
        J = J * (self.moving / self.scale)
        if not hold:
            return r, J
        R, Jw = self.model.flange_rotation_jacobian(q, self.p, self.cov[index], self.base0)
        Jw = Jw * (self.moving / self.scale)
        return (np.concatenate([r, ORIENTATION_WEIGHT * self._from_held(R, index)], axis=1),
                np.concatenate([J, ORIENTATION_WEIGHT * Jw], axis=1))

    def orientation(self, index: np.ndarray, q: np.ndarray) -> np.ndarray:
        """Rotation vector from the held flange orientation to the model's at the solver's joints ``q`` (rad)."""
        return self._from_held(self.model.flange_rotation(q / self.scale, self.p, self.cov[index], self.base0), index)

    def _from_held(self, R: np.ndarray, index: np.ndarray) -> np.ndarray:
        """Rotation vectors from the held orientations of rows ``index`` to the rotations ``R`` (rad)."""
        return Rotation.from_matrix(R @ self.R_goal[index].transpose(0, 2, 1)).as_rotvec()


def _at(targets: Measurements, index: np.ndarray, q: np.ndarray) -> Measurements:
    """Rows ``index`` of the targets with joints ``q`` (rad); covariates and row order kept."""
    sub = targets.subset(index)
    values = readings_to_file_units(q, targets.prismatic)
    for j, c in enumerate(targets.q_columns):
        sub.columns[c] = values[:, j]
    return sub
