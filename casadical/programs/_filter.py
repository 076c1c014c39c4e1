"""A robot program filtered with a calibration: each target replaced by the one the calibrated robot reaches
as the program meant (``casadical compensate CAL.json PROGRAM --out FILTERED``).

What a target means, both models in the robot's own base frame (the calibration's estimated base pose, the
tracker's frame, taken away; the program's tool on the flange instead of the measured point):

- a joint target ``q_prog``: the tool pose the nominal model reaches there, ``nominal(q_prog) * tool``; the
  filtered target is ``q_new`` with ``calibrated(q_new) * tool`` on it;
- a Cartesian target ``P`` (in its base or work object frame ``B``, with its tool): the pose ``B P`` the nominal
  controller would reach. Its nominal joints ``q_prog`` are the nominal inverse kinematics of ``B P`` (numeric,
  from many starts, on the nominal model; the branch the configuration the target names, KUKA ``T``, ABB ``cf1,
  cf4, cf6``, and among those the nearest the joints before it in the program); ``q_new`` as for a joint target,
  and the filtered target is ``P' = B^-1 nominal(q_new) * tool``: the pose the nominal controller turns into
  ``q_new``.

``q_new`` comes from :func:`casadical.apply._inverse.compensate` (damped least squares near a singular
configuration, joint limits, the largest change): the tool point always, and the orientation of the flange
where the calibration measured orientation (a full-pose calibration) or when asked; otherwise the least joint
change. A target it cannot correct is left as written and said why: not reached, beyond a joint limit, near a
singular configuration (the correction damped), outside what the calibration saw (``cal.coverage``), or unfit
by itself (moved to with two tools, a component left out, never moved to).
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field, replace

import numpy as np

from ..apply._inverse import MAX_DEG_PER_MM, calibrated_on_orientation, compensate
from ..data._measurements import Measurements
from ..model._symbolic import Model, pose_to_base0
from ..result import CalibrationResult, rotation_angles_between
from ..terms._geometric import Geometric
from ._program import Program, Target

#: inverse kinematics: random starts per target besides the program's joint targets and the middle of the ranges
IK_STARTS = 24
#: inverse kinematics: random joints the starts in a pose's configuration are drawn from
IK_POOL = 50_000
#: inverse kinematics: tolerance of the tool point (mm) and of the orientation (rad) of a solution
IK_TOL_MM, IK_TOL_RAD = 1e-7, 1e-9
#: the checks of compensate's targets that the filter's own targets need not pass (they are the program's)
_TRUSTED = dict(allow_outside_limits=True, angles_are_degrees=True, positions_are_mm=True)


@dataclass
class Outcome:
    """What became of one target.

    Attributes
    ----------
    target : Target
    corrected : bool
        False: left as written (``why`` says why).
    why : str
    tool, base : str or None
        The frames its moves name.
    q_programmed : ndarray or None
        The nominal joints of the target (rad; m for a linear axis): a joint target's own, a pose's nominal
        inverse kinematics.
    q : ndarray or None
        The corrected joints (the filtered target's nominal joints).
    miss_mm, miss_deg : float
        How far the calibrated robot's tool is from what the target means at the programmed joints: position
        (mm) and orientation (deg): what the correction corrects.
    residual_mm, residual_deg : float
        The same at the corrected joints (the orientation: where it is held).
    change_mm, change_deg : float
        How much the written target changes: a pose's position (mm) and orientation (deg); a joint target's
        largest joint change (deg; mm of a linear axis in ``change_mm``).
    values : dict
        The fields written: ``{field: (value, unit)}``.
    """

    target: Target
    corrected: bool = False
    why: str = ""
    tool: str | None = None
    base: str | None = None
    q_programmed: np.ndarray | None = None
    q: np.ndarray | None = None
    miss_mm: float = math.nan
    miss_deg: float = math.nan
    residual_mm: float = math.nan
    residual_deg: float = math.nan
    change_mm: float = math.nan
    change_deg: float = math.nan
    values: dict = field(default_factory=dict)

    def to_dict(self, prismatic) -> dict:
        t = self.target
        file_q = (lambda q: None if q is None else [float(v * 1000.0 if p else math.degrees(v))
                                                    for v, p in zip(q, prismatic)])
        return {"target": t.label, "name": t.name, "kind": t.kind, "file": t.file, "line": t.line,
                "tool": self.tool, "base": self.base, "corrected": self.corrected, "why": self.why or None,
                "programmed_joints": file_q(self.q_programmed), "joints": file_q(self.q),
                "miss_mm": self.miss_mm, "miss_deg": self.miss_deg, "residual_mm": self.residual_mm,
                "residual_deg": self.residual_deg, "change_mm": self.change_mm, "change_deg": self.change_deg}


@dataclass
class FilterResult:
    """A filtered program: its outcomes, target by target, and what was held."""

    program: Program
    outcomes: list[Outcome]
    held: str
    hold_orientation: bool
    prismatic: tuple[bool, ...]

    def texts(self) -> dict[str, str]:
        """Path of each program file -> its filtered text (only the corrected targets' numbers differ)."""
        return self.program.edited({k: o.values for k, o in enumerate(self.outcomes) if o.corrected})

    @property
    def corrected(self) -> list[Outcome]:
        return [o for o in self.outcomes if o.corrected]

    @property
    def left(self) -> list[Outcome]:
        return [o for o in self.outcomes if not o.corrected]

    def summary(self) -> str:
        """The terminal report: what was held, a line per target, the targets left as written and why."""
        p = self.program
        lines = [f"{p.path}: {len(self.outcomes)} targets ({sum(o.target.kind == 'joints' for o in self.outcomes)} "
                 f"joint, {sum(o.target.kind == 'pose' for o in self.outcomes)} Cartesian); corrected "
                 f"{len(self.corrected)}, left as written {len(self.left)}",
                 f"held: {self.held}"]
        if self.corrected:
            miss = np.array([o.miss_mm for o in self.corrected])
            lines.append(f"the calibrated robot misses the corrected targets by {miss.mean():.4g} mm on average, "
                         f"{miss.max():.4g} mm at most, before; after at most "
                         f"{max(o.residual_mm for o in self.corrected):.3g} mm")
            lines.append("target                          line  kind    tool              miss mm  miss deg  "
                         "change mm  change deg")
            for o in self.corrected:
                t = o.target
                lines.append(f"{t.label[:30]:30s} {t.line:5d}  {t.kind:6s}  {str(o.tool)[:16]:16s} {o.miss_mm:8.4f} "
                             f"{o.miss_deg:9.4f} {_num(o.change_mm):>10s} {_num(o.change_deg):>11s}")
        for o in self.left:
            lines.append(f"left as written: {o.target.label} (line {o.target.line}): {o.why}")
        for s in p.skipped:
            lines.append(f"not filtered: {s.file}, line {s.line}, {s.token!r}: {s.why}")
        return "\n".join(lines)

    def to_dict(self) -> dict:
        """The ``--json`` report (docs/formats.md, compensate, program form)."""
        return {"program": self.program.path, "language": self.program.language, "held": self.held,
                "hold_orientation": self.hold_orientation,
                "targets": [o.to_dict(self.prismatic) for o in self.outcomes],
                "corrected": len(self.corrected), "left": len(self.left),
                "not_filtered": [{"file": s.file, "line": s.line, "token": s.token, "why": s.why}
                                 for s in self.program.skipped]}


def _num(v: float) -> str:
    return "" if not math.isfinite(v) else f"{v:.4f}"


def in_robot_frame(cal: CalibrationResult, tool: np.ndarray, nominal: bool = False) -> CalibrationResult:
    """``cal`` in the robot's own base frame (its estimated base pose taken away) with the tool point at
    ``tool``'s origin (4x4, m, on the flange); ``nominal``: the robot file's nominal model instead."""
    if nominal:
        model = Model(cal.model.robot, "nominal", jit=False)
        params = model.parameters.copy()
        cal = CalibrationResult(model, params, cal.base0)
    params = cal.parameters.copy()
    for p in params:
        if p.term == Geometric.name and p.group == "base":
            p.value = 0.0
    for k, axis in enumerate("xyz"):
        params[f"tool_{axis}"].value = float(tool[k, 3])
    return replace(cal, parameters=params, base0=pose_to_base0(np.eye(4)), coverage=None)


def tool_pose(at: CalibrationResult, q: np.ndarray, tool: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The tool's positions (N, 3, m) and rotations (N, 3, 3) of ``at`` (:func:`in_robot_frame`) at joints q."""
    data = Measurements.from_arrays(q, prismatic=at.model.robot.prismatic)
    xyz = at.predict(data)
    R = at.model.flange_rotation(q, at.parameters.values, at.model.covariates(data), at.base0)
    return xyz, R @ tool[:3, :3]


def filter_program(cal: CalibrationResult, program: Program, *, orientation: bool | None = None,
                   tolerance_mm: float = 1e-4, max_change_deg: float = 5.0, max_deg_per_mm: float = MAX_DEG_PER_MM,
                   extrapolate: bool = False) -> FilterResult:
    """Filter ``program``'s targets with ``cal`` (see the module).

    Parameters
    ----------
    orientation : bool, optional
        Hold the flange orientation the target means (None: where the calibration measured orientation,
        :func:`~casadical.apply._inverse.calibrated_on_orientation`; False: the tool point alone).
    tolerance_mm, max_change_deg, max_deg_per_mm
        As :func:`casadical.apply._inverse.compensate`.
    extrapolate : bool
        Correct targets outside what the calibration saw too (default: leave them as written).
    """
    robot = cal.model.robot
    n = robot.n
    prismatic = robot.prismatic
    hold = (n >= 6 and calibrated_on_orientation(cal)) if orientation is None else bool(orientation)
    outcomes = [Outcome(t) for t in program.targets]
    for o in outcomes:
        _frames_of(o, program)
    _nominal_joints(cal, program, outcomes)
    for tool in sorted({o.tool for o in outcomes if o.q_programmed is not None and not o.why}):
        group = [o for o in outcomes if o.tool == tool and o.q_programmed is not None and not o.why]
        T = program.tools[tool]
        calibrated, nominal = in_robot_frame(cal, T), in_robot_frame(cal, T, nominal=True)
        q0 = np.array([o.q_programmed for o in group])
        xyz, R = tool_pose(nominal, q0, T)
        flange = R @ T[:3, :3].T
        targets = Measurements.from_arrays(q0, xyz, prismatic=prismatic)
        targets.path = program.path
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            res = compensate(calibrated, targets, tolerance_mm=tolerance_mm, max_change_deg=max_change_deg,
                             max_deg_per_mm=max_deg_per_mm, orientation=None if hold else False,
                             flange_rotations=flange if hold else None, check=False, **_TRUSTED)
        before_xyz, before_R = tool_pose(calibrated, q0, T)
        after_xyz, after_R = tool_pose(calibrated, res.q, T)
        bad = _failing_rows(res)
        cover = _coverage(cal, q0, prismatic) if not extrapolate else [""] * len(group)
        for i, o in enumerate(group):
            o.miss_mm = float(np.linalg.norm(before_xyz[i] - xyz[i]) * 1e3)
            o.miss_deg = _angle(before_R[i], R[i])
            if i in bad:
                o.why = bad[i]
            elif hold and not res.orientation_held[i]:
                o.why = ("near a singular configuration: the orientation cannot be held within --max-change-deg of "
                         f"the programmed joints and {max_deg_per_mm:g} deg per mm (--position-only corrects the "
                         "tool point alone)")
            elif res.damped[i]:
                o.why = (f"near a singular configuration (condition number {res.largest_sv[i] / res.smallest_sv[i]:.3g}"
                         f"): the correction would move the joints more than {max_deg_per_mm:g} deg per mm "
                         "(--max-deg-per-mm)")
            elif cover[i]:
                o.why = cover[i] + " (--extrapolate corrects it anyway)"
            if o.why:
                continue
            o.q = res.q[i]
            o.corrected = True
            o.residual_mm = float(np.linalg.norm(after_xyz[i] - xyz[i]) * 1e3)
            o.residual_deg = _angle(after_R[i], R[i]) if hold else math.nan
            _written(o, nominal, T, program)
    if hold:
        held = ("the tool point and the orientation each target means (the flange's), "
                + ("as the calibration measured orientation" if orientation is None else "as asked"))
    else:
        held = "the tool point alone, with the least joint change" + (
            " (the calibration measured positions alone; --hold-orientation holds the orientation too)"
            if orientation is None and n >= 6 else "")
    return FilterResult(program, outcomes, held, hold, prismatic)


def _frames_of(o: Outcome, program: Program) -> None:
    """The tool and base of a target's moves, or why it cannot be corrected."""
    t = o.target
    if t.unfit:
        o.why = t.unfit
        return
    if not t.uses:
        o.why = "the program never moves to it"
        return
    frames = {(u.tool, u.base) for u in t.uses}
    if len(frames) > 1:
        o.why = ("moved to with several tools or bases (" + "; ".join(f"{a}, {b}" for a, b in sorted(frames))
                 + "): one target cannot be corrected for each")
        return
    o.tool, o.base = frames.pop()


def _nominal_joints(cal: CalibrationResult, program: Program, outcomes: list[Outcome]) -> None:
    """Each target's nominal joints: a joint target's own; a pose's nominal inverse kinematics, in its
    configuration, nearest the joints before it in the program (the first: the first joint target, else the
    middle of the joint ranges)."""
    robot = cal.model.robot
    lim = robot.limits
    scale = np.where(robot.prismatic, math.radians(1.0) / 1e-3, 1.0)      # a mm weighs as a degree
    known = [o.target.q for o in outcomes if o.target.kind == "joints" and o.target.q is not None]
    poses = [o for o in outcomes if o.target.kind == "pose" and not o.why]
    candidates = {}
    for tool in sorted({o.tool for o in poses}):
        group = [o for o in poses if o.tool == tool]
        candidates.update(_inverse(cal, program, group, tool, known))
    previous = known[0] if known else lim.mean(axis=1)
    for o in outcomes:
        t = o.target
        if o.why:
            continue
        if t.kind == "joints":
            o.q_programmed = t.q
            if np.any((t.q < lim[:, 0] - 1e-9) | (t.q > lim[:, 1] + 1e-9)):
                o.why = "its joints are beyond the robot's limits"
                continue
        else:
            sols = candidates.get(id(o), np.zeros((0, robot.n)))
            if not len(sols):
                o.why = ("the nominal model reaches it nowhere within the joint limits"
                         + (" in the configuration it names" if t.config else "") + ": unreachable")
                continue
            ref = previous if t.near is None else t.near        # URScript's qnear: where the controller starts
            d = np.linalg.norm((sols - ref) * scale, axis=1)
            o.q_programmed = sols[int(np.argmin(d))]
        previous = o.q_programmed


def _inverse(cal, program: Program, group: list[Outcome], tool: str, known: list) -> dict[int, np.ndarray]:
    """The nominal inverse kinematics of the poses of ``group`` (one tool): for each, every solution found from
    the starts, within the joint limits and in its configuration."""
    robot = cal.model.robot
    n, lim = robot.n, robot.limits
    T = program.tools[tool]
    nominal = in_robot_frame(cal, T, nominal=True)
    rng = np.random.default_rng(0)
    common = np.vstack([np.array(known).reshape(-1, n), lim.mean(axis=1)[None],
                        rng.uniform(lim[:, 0], lim[:, 1], (IK_STARTS, n))])
    pool = rng.uniform(lim[:, 0], lim[:, 1], (IK_POOL, n))
    S = len(common) + IK_STARTS
    frozen = np.array([j in program.external_axes for j in range(n)])      # the pose gives them
    q0, xyz, Rf = [], [], []
    for o in group:
        t = o.target
        P = program.bases[o.base] @ t.pose
        # as many starts again in the configuration the pose names (where it names one)
        fit = pool[t.matches(pool)] if t.matches is not None else pool
        fit = np.vstack([fit[:IK_STARTS], pool[:max(0, IK_STARTS - len(fit))]])
        s = np.vstack([common, fit])
        if t.near is not None:
            s[-1] = t.near
        for j, v in t.external.items():
            s[:, j] = v
        q0.append(s)
        xyz.append(np.repeat(P[None, :3, 3], S, 0))
        Rf.append(np.repeat((P[:3, :3] @ T[:3, :3].T)[None], S, 0))
    q0, xyz, Rf = np.concatenate(q0), np.concatenate(xyz), np.concatenate(Rf)
    targets = Measurements.from_arrays(q0, xyz, prismatic=robot.prismatic)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = compensate(nominal, targets, tolerance_mm=IK_TOL_MM, max_iter=200, max_change_deg=360.0,
                         max_deg_per_mm=1e9, flange_rotations=Rf, frozen=frozen, check=False, **_TRUSTED)
    ok = ((res.residual <= IK_TOL_MM * 1e-3) & (res.orientation_error <= IK_TOL_RAD)
          & np.all((res.q >= lim[:, 0] - 1e-9) & (res.q <= lim[:, 1] + 1e-9), axis=1))
    out = {}
    for k, o in enumerate(group):
        rows = np.arange(k * S, (k + 1) * S)
        sols = res.q[rows[ok[rows]]]
        if o.target.matches is not None:
            sols = sols[o.target.matches(sols)] if len(sols) else sols
        out[id(o)] = sols
    return out


def _failing_rows(res) -> dict[int, str]:
    """Rows of a compensation that failed, with why: not reached, or beyond a joint limit."""
    out = {}
    n = res.q.shape[1]
    limit = np.broadcast_to(np.asarray(res.max_change, float), (n,))
    for i in range(len(res.q)):
        if not res.converged[i] or (np.abs(res.dq[i]) > limit).any():
            out[i] = (f"not reached: the calibrated robot's tool stays {res.residual[i] * 1e3:.3g} mm from it within "
                      "the largest change (--max-change-deg): unreachable")
        elif np.any((res.q[i] < res.limits[:, 0]) | (res.q[i] > res.limits[:, 1])):
            j = int(np.argmax((res.q[i] < res.limits[:, 0]) | (res.q[i] > res.limits[:, 1])))
            out[i] = f"the corrected joint {j + 1} would be beyond its limit"
    return out


def _coverage(cal: CalibrationResult, q: np.ndarray, prismatic) -> list[str]:
    """Per row, why the joints ``q`` are outside what the calibration saw ("" where they are not)."""
    if cal.coverage is None:
        return [""] * len(q)
    from ..robot import readings_to_file_units
    beyond, far = cal.coverage.outside(readings_to_file_units(q, prismatic))
    out = []
    for b, f in zip(beyond, far):
        if b.any():
            out.append("outside the calibration's coverage: joints "
                       + ", ".join(str(j + 1) for j in np.flatnonzero(b)) + " beyond the ranges it saw")
        elif f:
            out.append("outside the calibration's coverage: far from every calibration pose")
        else:
            out.append("")
    return out


def _angle(A: np.ndarray, B: np.ndarray) -> float:
    """The angle between two rotations (deg), exact near zero."""
    return float(np.degrees(rotation_angles_between(A[None], B[None])[0]))


def _written(o: Outcome, nominal: CalibrationResult, T: np.ndarray, program: Program) -> None:
    """The fields written for a corrected target, and how much it changes."""
    t = o.target
    if t.kind == "joints":
        o.values = t.write(o.q, None)
        dq = o.q - o.q_programmed
        prism = np.array(nominal.model.robot.prismatic)
        o.change_deg = float(np.degrees(np.abs(dq[~prism])).max()) if (~prism).any() else 0.0
        o.change_mm = float(np.abs(dq[prism]).max() * 1e3) if prism.any() else math.nan
        return
    xyz, R = tool_pose(nominal, o.q[None], T)
    B = program.bases[o.base]
    P = np.linalg.inv(B) @ np.block([[R[0], xyz[0][:, None]], [np.zeros((1, 3)), np.ones((1, 1))]])
    o.values = t.write(o.q, P)
    o.change_mm = float(np.linalg.norm(P[:3, 3] - t.pose[:3, 3]) * 1e3)
    o.change_deg = _angle(P[:3, :3], t.pose[:3, :3])
