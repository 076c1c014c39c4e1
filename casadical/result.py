"""Calibration results: a calibrated model, its statistics and its JSON file.

:class:`CalibrationResult` is what :func:`casadical.calibration.calibrate`
returns (statsmodels style: the model and its results kept apart);
:func:`load_calibration` reads the JSON :meth:`CalibrationResult.save`
writes (docs/formats.md section 4).
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from . import __version__
from .data._calibration_file import restored_terms, user_definitions, validate_calibration_document
from .data._checks import check_calibration_fits, check_poses
from .data._measurements import Measurements, session_index
from .errors import CalibrationFileError, CasadicalError, InputError, listing
from .kinematics import matrix_to_rpy
from .model._symbolic import Model, base0_to_pose
from .parameters import Parameters
from .problem import RobustLoss
from .robot import robot_from_dict, robot_to_dict
from .runtime._files import atomic_write
from .solvers import SolverResult
from .stats._coverage import Coverage
from .stats._identifiability import Identifiability
from .stats._significance import (
    LEVEL,
    FitStatistics,
    ParameterTest,
    parameter_table_text,
    parameter_tests,
    stiffness_interval,
    t_critical,
)
from .stats._uncertainty import Uncertainty
from .terms._definitions import by_name


@dataclass
class ErrorStats:
    """Position error statistics over poses (mm)."""

    n_poses: int
    mean_mm: float
    max_mm: float
    std_mm: float
    rms_mm: float
    #: of rows that say what they touched (docs/formats.md section 11): ``consistency_mm`` (their mean distance from
    #: what they touched, fitted to them) and, where a fixture is given, ``distance_error_mm``
    touch: dict = field(default_factory=dict)

    @classmethod
    def of(cls, errors_m: np.ndarray, touch: dict | None = None) -> "ErrorStats":
        e = np.asarray(errors_m) * 1000.0
        return cls(len(e), float(e.mean()), float(e.max()), float(e.std()), float(np.sqrt((e ** 2).mean())),
                   dict(touch or {}))

    def to_dict(self, n_poses: bool = True) -> dict:
        """The statistics (mm), with the number of poses unless ``n_poses`` is False (and, of rows that touch,
        :attr:`touch`'s keys)."""
        d = {"mean_mm": self.mean_mm, "max_mm": self.max_mm, "std_mm": self.std_mm, "rms_mm": self.rms_mm,
             **self.touch}
        return {"n_poses": self.n_poses, **d} if n_poses else d

    @classmethod
    def from_dict(cls, d: dict) -> "ErrorStats":
        """The statistics of a JSON block (:meth:`to_dict`)."""
        fields = ("n_poses", "mean_mm", "max_mm", "std_mm", "rms_mm")
        return cls(*(d[k] for k in fields), {k: d[k] for k in ("consistency_mm", "distance_error_mm") if k in d})

    def line(self) -> str:
        touch = f", {self.touch_words()}" if self.touch else ""
        return (f"mean {self.mean_mm:.4f}  max {self.max_mm:.4f}  std {self.std_mm:.4f}  "
                f"rms {self.rms_mm:.4f} mm over {self.n_poses} poses{touch}")

    def touch_words(self) -> str:
        """:attr:`touch` in words: ``consistency 0.0304 mm, distance error 0.0050 mm``."""
        return ", ".join(f"{TOUCH_WORDS[k]} {v:.4f} mm" for k, v in self.touch.items())


@dataclass
class Validation:
    """Errors of a calibration on held-out poses (:meth:`CalibrationResult.validate`).

    Attributes
    ----------
    file : str
        The validation poses' file.
    stats : ErrorStats
    orientation : AngleStats or None
        The probe's orientation errors there (a full-pose calibration, validated on poses with
        ``rx_deg, ry_deg, rz_deg``).
    """

    file: str
    stats: ErrorStats
    orientation: "AngleStats | None" = None

    def to_dict(self) -> dict:
        """The calibration JSON's ``validation``: the file and its error statistics (mm)."""
        return {"file": self.file, **self.stats.to_dict()}

    @classmethod
    def from_dict(cls, d: dict) -> "Validation":
        return cls(str(d.get("file", "")), ErrorStats.from_dict(d))


@dataclass
class AngleStats:
    """Orientation error statistics over poses (deg): the angle of ``R_meas^T R_pred`` per pose."""

    n_poses: int
    mean_deg: float
    max_deg: float
    std_deg: float
    rms_deg: float

    @classmethod
    def of(cls, angles_rad: np.ndarray) -> "AngleStats":
        e = np.degrees(np.asarray(angles_rad, float))
        return cls(len(e), float(e.mean()), float(e.max()), float(e.std()), float(np.sqrt((e ** 2).mean())))

    def to_dict(self, n_poses: bool = True) -> dict:
        """The statistics (deg), with the number of poses unless ``n_poses`` is False."""
        d = {"mean_deg": self.mean_deg, "max_deg": self.max_deg, "std_deg": self.std_deg, "rms_deg": self.rms_deg}
        return {"n_poses": self.n_poses, **d} if n_poses else d

    def line(self) -> str:
        return (f"mean {self.mean_deg:.4f}  max {self.max_deg:.4f}  std {self.std_deg:.4f}  "
                f"rms {self.rms_deg:.4f} deg over {self.n_poses} poses")


def rotation_angles_between(A: np.ndarray, B: np.ndarray) -> np.ndarray:
    """Angle (rad) of ``A_i^T B_i`` for rotations ``A, B`` (N, 3, 3), exact at any size."""
    from scipy.spatial.transform import Rotation  # here: scipy's import costs every command's start-up
    return Rotation.from_matrix(np.einsum("nji,njk->nik", A, B)).magnitude()


@dataclass
class CalibrationResult:
    """A calibrated model (statsmodels-style results object).

    Attributes
    ----------
    model : Model
    parameters : Parameters
        Identified values, standard errors, identifiability and reasons.
    base0 : ndarray
        Reference base pose (12 numbers) the ``base_*`` deviations apply to.
    solver : SolverResult
    solver_name : str
    identifiability : Identifiability or None
    uncertainty : Uncertainty or None
    calibration : ErrorStats
        Errors on the calibration poses.
    notes : list of str
        Warnings raised during the calibration.
    loss : RobustLoss
        The loss the parameters minimise (robust by default) and its noise scale.
    downweighted : list of dict
        Calibration poses the robust loss gave less than half their weight:
        ``{"line": file line, "residual_mm": ..., "weight": ...}``.
    coverage : Coverage or None
        The joint ranges and poses the calibration saw (for extrapolation warnings).
    by_session : dict of str to ErrorStats
        Errors on the calibration poses of each session (calibrations of
        several sessions only).
    statistics : FitStatistics or None
        Size, noise, log-likelihood, AIC and BIC of the fit (None when the
        model holds a fitted network, whose parameters are not counted).
    validation : Validation or None
        Errors on held-out poses, once :meth:`validate` has run.
    tool0 : ndarray, shape (3, 3), or None
        Full-pose models (term ``tool_orientation``): the probe's reference
        mounting R0 on the flange, which ``tool_roll, tool_pitch, tool_yaw``
        deviate from (as ``base0`` for the base pose); None for a
        position-only model.
    orientation : AngleStats or None
        Orientation errors on the calibration poses (full-pose models with
        measured orientations).
    full_pose : bool
        The loss had the orientation residuals (False: fitted on positions
        alone, e.g. a full-pose calibration taken further with
        ``position_only``).
    """

    model: Model
    parameters: Parameters
    base0: np.ndarray
    solver: SolverResult | None = None
    solver_name: str = ""
    identifiability: Identifiability | None = None
    uncertainty: Uncertainty | None = None
    calibration: ErrorStats | None = None
    notes: list[str] = field(default_factory=list)
    loss: RobustLoss = field(default_factory=RobustLoss)
    downweighted: list[dict] = field(default_factory=list)
    coverage: Coverage | None = None
    by_session: dict = field(default_factory=dict)
    statistics: FitStatistics | None = None
    validation: Validation | None = None
    tool0: np.ndarray | None = None
    orientation: AngleStats | None = None
    full_pose: bool = False
    #: the frame its points are in: ``measurement`` (the instrument's, each session's), or ``base`` (the robot's base
    #: frame: calibrated from touches alone, nothing measured the robot against the world)
    frame: str = "measurement"
    #: what its data could not see ({"what", "why", "parameters"}: touches' base pose, scale)
    unobservable: list = field(default_factory=list)

    # --- using the model ------------------------------------------------------

    @property
    def has_orientation(self) -> bool:
        """True when the model predicts the probe's orientation (a full-pose calibration)."""
        return self.model.orientation and self.tool0 is not None

    def tool_rotation(self) -> np.ndarray:
        """The probe's mounting rotation on the flange (3x3): ``Rz(tool_yaw) Ry(tool_pitch) Rx(tool_roll) R0``."""
        from .kinematics import base_pose_matrix
        self._check_orientation()
        p = self.parameters
        D = base_pose_matrix([0.0, 0.0, 0.0], [p[f"tool_{k}"].value for k in ("roll", "pitch", "yaw")])[:3, :3]
        return D @ self.tool0

    def predict_rotations(self, data: Measurements) -> np.ndarray:
        """Predicted probe orientations in the measurement frame (N, 3, 3), every term and covariate included."""
        self._check_joints(data)
        self._check_orientation()
        return self.model.probe_rotation(data.q, self.parameters.values, self.model.covariates(data),
                                         self.base0) @ self.tool0

    def orientation_errors(self, data: Measurements) -> np.ndarray:
        """Orientation error per pose (rad): the angle of ``R_meas^T R_pred``."""
        return rotation_angles_between(data.rotations, self.predict_rotations(data))

    def orientation_stats(self, data: Measurements) -> AngleStats:
        return AngleStats.of(self.orientation_errors(data))

    def _check_orientation(self) -> None:
        if not self.has_orientation:
            raise InputError(f"calibration of model {self.model.spec} has no probe orientation: it was "
                             "calibrated on positions alone (full pose needs data with rx_deg, ry_deg, rz_deg)")

    def predict(self, data: Measurements) -> np.ndarray:
        """Predicted tool positions (m, (N, 3)) with every term and the rows' covariates."""
        self._check_joints(data)
        return self.model.predict(data.q, self.parameters.values, self.model.covariates(data), self.base0)

    def errors(self, data: Measurements) -> np.ndarray:
        """Position error norm per pose (m): a touch row's, its distance from what it touched (fitted to the
        rows of its session that touch it)."""
        return np.linalg.norm(self.residuals(data), axis=1)

    def residuals(self, data: Measurements) -> np.ndarray:
        """Measured minus predicted (m, (N, 3)); a touch row's, what it touched (fitted) minus its model point."""
        if data.touches:
            return -data.layout.residuals(self.predict(data))
        return data.xyz - self.predict(data)

    def stats(self, data: Measurements) -> ErrorStats:
        if data.touches:
            P = self.predict(data)
            return ErrorStats.of(np.linalg.norm(data.layout.residuals(P), axis=1), touch_stats(data.layout, P))
        return ErrorStats.of(self.errors(data))

    @property
    def sessions(self) -> list[str]:
        """The measurement sessions the calibration fitted, the primary one first ([] for one session)."""
        frames = self.model.term("sessions")
        return list(frames.names) if frames is not None else []

    def session_stats(self, data: Measurements) -> dict[str, ErrorStats]:
        """Errors on ``data`` per session (data of one session: ``{"": stats}``)."""
        e = self.errors(data)
        return {s: ErrorStats.of(e[idx]) for s, idx in session_index(data).items()}

    def _check_joints(self, data: Measurements) -> None:
        if data.n_joints != self.model.robot.n:
            raise InputError(f"has {data.n_joints} joint columns but the robot has {self.model.robot.n} "
                             "joints", file=data.path)

    # --- derived quantities ---------------------------------------------------

    def base_matrix(self, session: str | None = None) -> np.ndarray:
        """Robot base in the measurement frame (of ``session``; default: the primary one), 4x4."""
        from .kinematics import base_pose_matrix
        p = self.parameters
        sessions = self.sessions
        if session is None or not sessions or session == sessions[0]:
            ref, at = self.base0, ""
        elif session in sessions:
            ref, at = self.model.term("sessions").references[session], f"@{session}"
        else:
            raise InputError(f"no session {session!r} in this calibration (sessions: {', '.join(sessions)})")
        return base0_to_pose(ref) @ base_pose_matrix([p[f"base_{k}{at}"].value for k in "xyz"],
                                                     [p[f"base_{k}{at}"].value for k in ("roll", "pitch", "yaw")])

    def base_pose(self, session: str | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Robot base in the measurement frame (of ``session``): translation (m) and roll-pitch-yaw (rad)."""
        T = self.base_matrix(session)
        return T[:3, 3], matrix_to_rpy(T[:3, :3])

    def base_reference(self, session: str | None = None) -> tuple[np.ndarray, np.ndarray]:
        """The reference pose the base parameters ``base_x .. base_yaw`` (of ``session``: ``base_x@S ..``)
        deviate from: ``base0`` (the primary session's), else the session's reference; translation (m) and
        roll-pitch-yaw (rad). The base pose is this reference moved by the deviations (:meth:`base_pose`)."""
        sessions = self.sessions
        if session is None or not sessions or session == sessions[0]:
            ref = self.base0
        elif session in sessions:
            ref = self.model.term("sessions").references[session]
        else:
            raise InputError(f"no session {session!r} in this calibration (sessions: {', '.join(sessions)})")
        T = base0_to_pose(ref)
        return T[:3, 3], matrix_to_rpy(T[:3, :3])

    def base_lines(self) -> list[str]:
        """The base pose of each session in words, with the reference its parameters deviate from."""
        sessions = self.sessions
        out = []
        for s in sessions or [None]:
            xyz, rpy = self.base_pose(s)
            rx, rr = self.base_reference(s)
            at = "" if s is None or s == sessions[0] else f"@{s}"
            out.append(f"base in the measurement frame{f' of session {s}' if s else ''}: xyz [{_xyz(xyz)}] mm, "
                       f"rpy [{_rpy(rpy)}] deg")
            out.append(f"  = reference pose {'base0' if not at else 'of session ' + s} xyz [{_xyz(rx)}] mm, rpy "
                       f"[{_rpy(rr)}] deg (the closed-form alignment the fit started from), moved by base_x{at} .. "
                       f"base_yaw{at}")
        return out

    def stiffness(self) -> dict[int, tuple[float, float]]:
        """Joint stiffness k_j = 1 / c_j (N m/rad) with its standard error, compliant joints only.

        A compliance c_j <= 0 (an unbounded solver on a joint stiffer than the
        poses can tell) has no positive stiffness: k_j is ``inf``, its standard
        error ``nan``; the summary and the JSON say so in words.
        """
        out = {}
        for p in self.parameters.select(term="joint_compliance"):
            if p.fixed and p.identifiable is False:
                continue
            k = 1.0 / p.value if p.value > 0 else math.inf
            sk = p.std / p.value ** 2 if p.value > 0 and math.isfinite(p.std) else math.nan
            out[p.joint] = (k, sk)
        return out

    # --- significance and held-out poses -------------------------------------

    def significance(self, level: float = LEVEL) -> dict[str, ParameterTest]:
        """Each free parameter tested against its nominal value: t, p, significance, interval, relative std.

        Student's t with the fit's degrees of freedom (the normal
        distribution when they are not known); see :mod:`casadical.stats._significance`.
        """
        return parameter_tests(self.parameters, self._dof(), level)

    def _dof(self) -> float:
        """The fit's degrees of freedom (``inf`` when not known: tests on the normal distribution)."""
        dof = self.statistics.dof if self.statistics is not None else \
            self.uncertainty.dof if self.uncertainty is not None else math.inf
        return dof if dof > 0 else math.inf

    def stiffness_intervals(self, level: float = LEVEL) -> dict[int, tuple[float, float] | None]:
        """Confidence interval of each stiffness k_j = 1/c_j (N m/rad) from its compliance's.

        ``(1/c_hi, 1/c_lo)``; the upper end is ``inf`` when the compliance
        interval reaches 0, and the interval None when it lies at or below 0
        (or c_j has no usable standard error).
        """
        tests = self.significance(level)
        return {j: stiffness_interval(tests[f"c{j}"].ci) if f"c{j}" in tests else None for j in self.stiffness()}

    def validate(self, data: Measurements, *, name: str | None = None, allow_mismatch: bool = False,
                 allow_outside_limits: bool = False, angles_are_degrees: bool = False,
                 positions_are_mm: bool = False) -> ErrorStats:
        """Errors on held-out poses, kept in :attr:`validation` (and written to the JSON).

        The poses pass the plausibility checks of every command
        (:func:`casadical.data._checks.check_poses`) and the check ``predict``
        makes that they belong to this calibration (a mean error a hundred
        times its own: :func:`casadical.data._checks.check_calibration_fits`).

        Parameters
        ----------
        data : Measurements
            Poses with measured positions, never used in the fit.
        name : str, optional
            What the calibration is called in messages (its file).
        allow_mismatch, allow_outside_limits, angles_are_degrees, positions_are_mm : bool
            Overrides of those checks.

        Raises
        ------
        DataFileError
            Naming the validation file (and row and column) and the override.
        """
        if not data.measured:
            raise InputError("has no measured positions (x_mm, y_mm, z_mm) nor rows that touch (point, plane): "
                             "validation poses need them", file=data.path)
        xyz = self.predict(data)
        check_poses(data, self.model.robot, predicted=xyz, allow_outside_limits=allow_outside_limits,
                    angles_are_degrees=angles_are_degrees, positions_are_mm=positions_are_mm)
        stats = self.stats(data)
        errors = self.errors(data)
        check_calibration_fits(errors, data, name or f"of {self.model.robot.name}",
                               self.calibration.mean_mm if self.calibration else None, allow_mismatch)
        self.validation = Validation(data.path, stats)
        if self.has_orientation and data.has_orientation:
            self.validation.orientation = self.orientation_stats(data)
        return self.validation.stats

    # --- reports --------------------------------------------------------------

    def summary(self) -> str:
        """Text report: solver, identified parameters next to nominal, stiffness, errors."""
        m = self.model
        lines = [f"casadical calibration of {m.robot.name}: model {m.spec}"]
        if self.solver is not None:
            s = self.solver
            lines.append(f"solver {self.solver_name}: {s.status}, {s.iterations} iterations, "
                         f"{s.solve_time_s * 1000:.1f} ms (setup {s.setup_time_s * 1000:.1f} ms)")
        if self.identifiability is not None:
            lines.append(self.identifiability.report())
        if self.uncertainty is not None:
            lines.append(f"residual sigma {self.uncertainty.sigma * 1000:.4f} mm per axis, "
                         f"{self.uncertainty.dof} degrees of freedom")
        lines += self.base_lines()
        lines += [f"not seen by these data: {u['what']} ({u['why']}): {', '.join(u['parameters'])} held"
                  for u in self.unobservable]
        if self.frame == "base":
            lines.append("frame: the robot's base frame (touches alone: predict and compensate read and write "
                         "points in it)")
        tests = self.significance()
        lines += ["", "identified parameters (angles in deg, lengths in mm; t = deviation/std, significant at "
                      f"{100 * LEVEL:g} % when |t| > {t_critical(LEVEL, self._dof()):.3g}; rel.std = std/|deviation|):",
                  parameter_table_text(self.parameters, tests)]
        st = self.stiffness()
        if st:
            lines += ["", "joint stiffness k = 1/c:"]
            intervals = self.stiffness_intervals()
            for j, (k, sk) in st.items():
                if not math.isfinite(k):
                    lines.append(f"  k{j}: {_NOT_POSITIVE.format(j=j, c=self.parameters[f'c{j}'].value)}")
                    continue
                lines.append(f"  k{j} = {k:.4e} N m/rad" + (f"  (std {sk:.2e})" if math.isfinite(sk) else "")
                             + _stiffness_words(intervals.get(j), tests.get(f"c{j}")))
        if self.statistics is not None:
            lines += ["", self.statistics.line()]
        if self.calibration is not None:
            lines += ["", "calibration poses: " + self.calibration.line()]
        for s, st in self.by_session.items():
            tool = " (its own tool)" if s in self.model.term("sessions").tools else ""
            lines.append(f"  session {s}{tool}: " + st.line())
        if self.validation is not None:
            lines.append(f"validation poses ({self.validation.file}): " + self.validation.stats.line())
        if self.orientation is not None:
            lines.append("orientation:       " + self.orientation.line())
        if self.validation is not None and self.validation.orientation is not None:
            lines.append(f"validation orientation ({self.validation.file}): " + self.validation.orientation.line())
        if self.has_orientation:
            mount = np.degrees(matrix_to_rpy(self.tool_rotation()))
            lines.append("probe mounting on the flange: rpy [" + ", ".join(f"{v:.4f}" for v in mount) + "] deg")
        if self.full_pose:
            lines.append(f"full pose: positions and orientations weighted by their noise scales from the data, "
                         f"{self.loss.sigma * 1000:.4f} mm and {math.degrees(self.loss.sigma_rot):.4f} deg per "
                         f"axis (1 deg weighs as {self.loss.rot_weight * math.pi / 180 * 1000:.3g} mm)")
        if self.loss.robust:
            lines.append(f"robust loss: pseudo-Huber, noise scale {self.loss.sigma * 1000:.4f} mm per axis, "
                         f"linear beyond {self.loss.c:g} sigma; "
                         + (f"{len(self.downweighted)} pose(s) down-weighted below half weight (rows "
                            + listing([d["line"] for d in self.downweighted], 12) + ")"
                            if self.downweighted else "no pose down-weighted below half weight"))
        for n in self.notes:
            lines.append("note: " + n)
        return "\n".join(lines)

    def to_dict(self) -> dict:
        """The calibration JSON of docs/formats.md section 4 (plus what rebuilds the model)."""
        params = []
        tests = self.significance()
        for p in self.parameters:
            params.append({"name": p.name, "value": p.to_display(p.value),
                           "std": p.to_display(p.std) if math.isfinite(p.std) else None,
                           "identifiable": bool(p.identifiable) if p.identifiable is not None else not p.fixed,
                           "unit": p.display_unit, "nominal": p.to_display(p.nominal), "fixed": p.fixed,
                           "reason": p.reason, "term": p.term, "joint": p.joint,
                           **_test_entry(tests.get(p.name), p.to_display)})
        intervals = self.stiffness_intervals()
        for j, (k, sk) in self.stiffness().items():
            entry = {"name": f"k{j}", "value": k if math.isfinite(k) else None,
                     "std": sk if math.isfinite(sk) else None,
                     "identifiable": True, "unit": "N*m/rad", "derived": f"1/c{j}", "joint": j,
                     **_test_entry(tests.get(f"c{j}"), None, intervals.get(j))}
            if not math.isfinite(k):
                entry["reason"] = _NOT_POSITIVE.format(j=j, c=self.parameters[f"c{j}"].value)
            params.append(entry)
        xyz, rpy = self.base_pose()
        doc = {
            "casadical_version": __version__,
            "robot": robot_to_dict(self.model.robot),
            "model": self.model.spec,
            "terms": {t.spec(): t.settings() for t in self.model.terms},
            "parameters": params,
            "base0": [float(x) for x in self.base0],
            "base_pose": {"xyz_m": xyz.tolist(), "rpy_deg": np.degrees(rpy).tolist()},
            "calibration": self.calibration.to_dict() if self.calibration else None,
            "solver": None,
            "notes": self.notes,
            "robust": {"loss": "pseudo-huber" if self.loss.robust else "none", "c": self.loss.c,
                       "sigma_mm": self.loss.sigma * 1000 if self.loss.robust else None,
                       "downweighted": self.downweighted},
        }
        if self.frame != "measurement":
            doc["frame"] = self.frame
        if self.unobservable:
            doc["unobservable"] = self.unobservable
        users = list(self.model.user_definitions)
        if users:   # the definitions of the user terms: predict, compensate, export need no terms file
            doc["user_terms"] = [d.to_dict() for d in users]
        if self.coverage is not None:
            doc["coverage"] = self.coverage.to_dict()
        if self.sessions:
            tools = self.model.term("sessions").tools
            doc["sessions"] = []
            for s in self.sessions:
                xyz, rpy = self.base_pose(s)
                entry = {"name": s, "own_tool": s in tools,
                         "base_pose": {"xyz_m": xyz.tolist(), "rpy_deg": np.degrees(rpy).tolist()}}
                if s in self.by_session:
                    entry["calibration"] = self.by_session[s].to_dict()
                doc["sessions"].append(entry)
        if self.has_orientation:    # only full-pose models: a position-only calibration's JSON is as it was
            fitted = self.full_pose and math.isfinite(self.loss.sigma_rot)
            doc["orientation"] = {
                "tool0": [float(x) for x in self.tool0.ravel()],
                "tool_rotation": {"rpy_deg": np.degrees(matrix_to_rpy(self.tool_rotation())).tolist()},
                "full_pose": bool(self.full_pose),
                "sigma_mm": self.loss.sigma * 1000 if fitted else None,
                "sigma_deg": math.degrees(self.loss.sigma_rot) if fitted else None,
                "calibration": self.orientation.to_dict() if self.orientation else None}
            if self.validation is not None and self.validation.orientation is not None:
                doc["orientation"]["validation"] = self.validation.orientation.to_dict()
        if self.solver is not None:
            doc["solver"] = {"name": self.solver_name, "status": self.solver.status,
                             "iterations": self.solver.iterations, "solve_time_s": self.solver.solve_time_s,
                             "setup_time_s": self.solver.setup_time_s, "success": self.solver.success}
        if self.uncertainty is not None:
            doc["uncertainty"] = {"sigma_mm": self.uncertainty.sigma * 1000, "dof": self.uncertainty.dof,
                                  "names": self.uncertainty.names,
                                  # full precision: predict --std needs the covariance of correlated parameters
                                  "correlation": np.round(self.uncertainty.correlation, 12).tolist()}
            if self.uncertainty.interval_k is not None:
                doc["uncertainty"]["interval_k"] = self.uncertainty.interval_k
        doc["statistics"] = self.statistics.to_dict() if self.statistics is not None else None
        if self.validation is not None:
            doc["validation"] = self.validation.to_dict()
        return doc

    def save(self, path: str | Path, overwrite: bool = False) -> None:
        atomic_write(path, json.dumps(self.to_dict(), indent=1, allow_nan=False, default=_json_default),
                     overwrite=overwrite)


#: the statistics of rows that touch (:func:`touch_stats`) in words
TOUCH_WORDS = {"consistency_mm": "consistency", "distance_error_mm": "distance error"}


def touch_stats(layout, P: np.ndarray) -> dict:
    """What rows that touch say (docs/formats.md section 11): ``consistency_mm``, their mean distance from what
    they touched (fitted to them); ``distance_error_mm``, where a fixture is given, the mean absolute error of its
    known distances between its points fitted each to its own rows."""
    if not layout.touches:
        return {}
    r = np.linalg.norm(layout.residuals(P), axis=1)
    errors = []
    for g, _ in layout.fitted(P):
        if g.fixture is None:
            continue
        rows = P[g.rows]
        means = {p: rows[g.point_names == p].mean(axis=0) for p in g.fixture.points if np.any(g.point_names == p)}
        # consistency: each of the fixture's points fitted to its own rows (its known geometry judged apart)
        for p, m in means.items():
            r[g.rows[g.point_names == p]] = np.linalg.norm(rows[g.point_names == p] - m, axis=1)
        errors += [abs(float(np.linalg.norm(means[a] - means[b])) - d) for (a, b), d in g.fixture.distances().items()
                   if a in means and b in means]
    out = {"consistency_mm": float(r[~layout.tracked].mean() * 1000.0)}
    if errors:
        out["distance_error_mm"] = float(np.mean(errors) * 1000.0)
    return out


def rebuilt(result: CalibrationResult, model: Model, data: Measurements, note: str) -> CalibrationResult:
    """``result`` with another model holding the same parameters (a compensator added): every value, std and
    flag kept, its errors on ``data`` anew, ``note`` added; no fit statistics (a network's weights are not
    counted)."""
    params = model.parameters.copy()
    for p in params:
        src = result.parameters[p.name]
        p.value, p.std, p.fixed, p.identifiable, p.reason = src.value, src.std, src.fixed, src.identifiable, \
            src.reason
    out = CalibrationResult(model, params, result.base0, result.solver, result.solver_name,
                            result.identifiability, result.uncertainty, None, list(result.notes) + [note],
                            result.loss, result.downweighted, result.coverage, by_session=result.by_session,
                            tool0=result.tool0, orientation=result.orientation, full_pose=result.full_pose)
    out.calibration = out.stats(data)
    return out


def learning_mask(result: CalibrationResult, data: Measurements) -> np.ndarray:
    """The poses of ``data`` a compensator learns from: those the robust loss did not set aside."""
    keep = np.ones(len(data), bool)
    for d in result.downweighted:
        at = data.lines == d["line"]
        if "file" in d and data.sources is not None:
            at &= data.sources == d["file"]
        keep &= ~at
    return keep


_NOT_POSITIVE = ("no positive stiffness: compliance c{j} = {c:.3g} rad/(N*m) is not above 0, the joint is "
                 "stiffer than these poses and loads can tell")


def _xyz(xyz_m) -> str:
    return ", ".join(f"{v * 1000:.3f}" for v in xyz_m)


def _rpy(rpy_rad) -> str:
    return ", ".join(f"{math.degrees(v):.4f}" for v in rpy_rad)


def _test_entry(test: ParameterTest | None, display, interval: tuple[float, float] | None = None) -> dict:
    """A parameter entry's t, p, significance, interval (display units) and relative std; nulls if not tested.

    ``display`` converts SI to display units; None for a derived stiffness,
    whose ``interval`` is given (its compliance's test says the rest).
    """
    if test is None:
        return {"t": None, "p": None, "significant": None, "ci95": None, "relative_std": None}
    if display is not None:
        interval = (display(test.ci[0]), display(test.ci[1]))
    ci = None if interval is None else [v if math.isfinite(v) else None for v in interval]
    return {"t": test.t, "p": test.p, "significant": test.significant, "ci95": ci,
            "relative_std": test.relative_std if math.isfinite(test.relative_std) else None}


def _stiffness_words(interval: tuple[float, float] | None, test: ParameterTest | None) -> str:
    """The summary's interval and significance of a stiffness (from its compliance's)."""
    if test is None:
        return ""
    level = f"{100 * test.level:g} %"
    if interval is None:
        where = f", {level} interval: none positive"
    else:
        hi = f"{interval[1]:.3g}" if math.isfinite(interval[1]) else "unbounded (c's interval reaches 0)"
        where = f", {level} interval {interval[0]:.3g} .. {hi}"
    return where + ("" if test.significant else f"; not significant (t = {test.t:.2f})")


def _json_default(o):
    if isinstance(o, (np.floating, np.integer)):
        return o.item()
    raise TypeError(type(o).__name__)


def load_calibration(path: str | Path, terms=()) -> CalibrationResult:
    """Read a calibration JSON written by :meth:`CalibrationResult.save`.

    ``terms``: definitions of causes of one's own its model names that the file does not carry (a file written
    with user terms carries theirs, which take precedence). Reading a calibration changes nothing global."""
    path = str(path)
    try:
        doc = json.loads(Path(path).read_text(encoding="utf-8-sig"))
    except FileNotFoundError:
        raise CalibrationFileError("no such file", file=path) from None
    except (OSError, ValueError, RecursionError) as e:  # ValueError: not JSON, not UTF-8
        raise CalibrationFileError(f"not a calibration JSON: {e}", file=path) from e
    validate_calibration_document(doc, path, terms)
    users = list({**by_name(terms), **by_name(user_definitions(doc, path))}.values())
    try:
        robot = robot_from_dict(doc["robot"], path)
        model = Model(robot, restored_terms(doc["model"], doc.get("terms", {}), robot.n, users))
        params = model.parameters.copy()
        for entry in doc["parameters"]:
            if entry.get("derived"):
                continue
            p = params[entry["name"]]
            p.value = p.from_display(float(entry["value"]))
            p.std = p.from_display(float(entry["std"])) if entry.get("std") is not None else math.nan
            p.fixed = bool(entry.get("fixed", False))
            p.identifiable = entry.get("identifiable")
            p.reason = entry.get("reason", "")
        base0 = np.asarray(doc["base0"], dtype=float)
        rob = doc.get("robust") or {}
        loss = RobustLoss("huber", float(rob.get("c", 3.0)), float(rob["sigma_mm"]) / 1000) \
            if rob.get("loss", "none") != "none" else RobustLoss()
        coverage = Coverage.from_dict(doc["coverage"], model.robot.units) if doc.get("coverage") else None
        extra = _statistics_of(doc)
        ori = doc.get("orientation")
        tool0, angles, full_pose = None, None, False
        if ori:
            tool0 = np.asarray(ori["tool0"], dtype=float).reshape(3, 3)
            angles = AngleStats(**ori["calibration"]) if ori.get("calibration") else None
            if ori.get("validation") and extra["validation"] is not None:
                extra["validation"].orientation = AngleStats(**ori["validation"])
            full_pose = bool(ori.get("full_pose", False))
            if ori.get("sigma_deg") is not None:
                import dataclasses
                loss = dataclasses.replace(loss, sigma=float(ori["sigma_mm"]) / 1000,
                                           sigma_rot=math.radians(float(ori["sigma_deg"])))
    except (KeyError, TypeError, ValueError, CasadicalError) as e:
        raise CalibrationFileError(f"not a calibration JSON written by casadical ({e})", file=path) from e
    model.parameters = params
    cal = doc.get("calibration")
    by_session = {e["name"]: ErrorStats.from_dict(e["calibration"]) for e in doc.get("sessions") or []
                  if e.get("calibration")}
    extra["uncertainty"] = _uncertainty_of(doc, params)
    return CalibrationResult(model, params, base0, calibration=ErrorStats.from_dict(cal) if cal else None,
                             notes=doc.get("notes", []), loss=loss, downweighted=rob.get("downweighted", []),
                             coverage=coverage, by_session=by_session, tool0=tool0, orientation=angles,
                             full_pose=full_pose, frame=doc.get("frame", "measurement"),
                             unobservable=list(doc.get("unobservable") or []), **extra)


def _statistics_of(doc: dict) -> dict:
    """The fit statistics and validation of a calibration JSON.

    Files written before ``statistics`` existed have the same numbers in
    ``uncertainty`` (residual sigma, degrees of freedom, free parameters):
    taken from there, so their parameters are tested with the fit's degrees
    of freedom too. ``statistics: null`` (a model with a fitted network) stays None.
    """
    stats, val = doc.get("statistics"), doc.get("validation")
    if "statistics" not in doc:
        unc = doc.get("uncertainty")
        try:
            dof, names, sigma = int(unc["dof"]), list(unc["names"]), float(unc["sigma_mm"])
            if 0 < dof < 2 ** 53 and 0 < sigma < 1e6:
                stats = {"n_equations": dof + len(names), "n_parameters": len(names), "sigma_mm": sigma}
        except (KeyError, TypeError, ValueError, OverflowError):
            pass        # nothing usable: the tests fall back on the normal distribution
    return {"statistics": FitStatistics.from_dict(stats) if stats else None,
            "validation": Validation.from_dict(val) if val else None}


def _uncertainty_of(doc: dict, params) -> Uncertainty | None:
    """The parameter covariance a calibration JSON holds (its free parameters' std and correlation), SI."""
    unc = doc.get("uncertainty")
    try:
        names = list(unc["names"])
        corr = np.asarray(unc["correlation"], dtype=float)
        std = np.array([params[n].std for n in names], dtype=float)
        if corr.shape != (len(names), len(names)) or not np.all(np.isfinite(corr)):
            return None
        k = unc.get("interval_k")     # checked by validate_calibration_document
        return Uncertainty(names, corr * np.outer(np.nan_to_num(std), np.nan_to_num(std)),
                           float(unc["sigma_mm"]) / 1000, int(unc["dof"]), None if k is None else float(k))
    except (KeyError, TypeError, ValueError):
        return None

