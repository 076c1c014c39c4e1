"""Calibration results: a calibrated model, its statistics and its JSON file.

:class:`CalibrationResult` is what :func:`casadical.calibration.calibrate`
returns (statsmodels style: the model and its results kept apart);
:func:`load_calibration` reads the JSON :meth:`CalibrationResult.save`
writes (INTERFACE.md section 4).
"""

from __future__ import annotations

import inspect
import json
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from . import __version__
from .data import Measurements
from .calibration_file import validate_calibration_document
from .coverage import Coverage
from .errors import CalibrationFileError, CasadicalError, InputError, listing
from .files import atomic_write
from .identifiability import Identifiability
from .kinematics import matrix_to_rpy
from .model import Model, base0_to_pose, parse_spec
from .parameters import Parameters
from .problem import RobustLoss
from .robot import robot_from_dict, robot_to_dict
from .solvers import SolverResult
from .terms import ErrorTerm
from .uncertainty import Uncertainty


@dataclass
class ErrorStats:
    """Position error statistics over poses (mm)."""

    n_poses: int
    mean_mm: float
    max_mm: float
    std_mm: float
    rms_mm: float

    @classmethod
    def of(cls, errors_m: np.ndarray) -> "ErrorStats":
        e = np.asarray(errors_m) * 1000.0
        return cls(len(e), float(e.mean()), float(e.max()), float(e.std()), float(np.sqrt((e ** 2).mean())))

    def to_dict(self, n_poses: bool = True) -> dict:
        """The statistics (mm), with the number of poses unless ``n_poses`` is False."""
        d = {"mean_mm": self.mean_mm, "max_mm": self.max_mm, "std_mm": self.std_mm, "rms_mm": self.rms_mm}
        return {"n_poses": self.n_poses, **d} if n_poses else d

    def line(self) -> str:
        return (f"mean {self.mean_mm:.4f}  max {self.max_mm:.4f}  std {self.std_mm:.4f}  "
                f"rms {self.rms_mm:.4f} mm over {self.n_poses} poses")


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
    from scipy.spatial.transform import Rotation   # here: scipy's import costs every command's start-up
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
    tool0: np.ndarray | None = None
    orientation: AngleStats | None = None
    full_pose: bool = False

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
        """Position error norm per pose (m)."""
        return np.linalg.norm(self.predict(data) - data.xyz, axis=1)

    def residuals(self, data: Measurements) -> np.ndarray:
        """Measured minus predicted (m, (N, 3))."""
        return data.xyz - self.predict(data)

    def stats(self, data: Measurements) -> ErrorStats:
        return ErrorStats.of(self.errors(data))

    def _check_joints(self, data: Measurements) -> None:
        if data.n_joints != self.model.robot.n:
            raise InputError(f"has {data.n_joints} joint columns but the robot has {self.model.robot.n} "
                             "joints", file=data.path)

    # --- derived quantities ---------------------------------------------------

    def base_matrix(self) -> np.ndarray:
        """Robot base in the measurement frame, 4x4."""
        from .kinematics import base_pose_matrix
        p = self.parameters
        return base0_to_pose(self.base0) @ base_pose_matrix([p[f"base_{k}"].value for k in "xyz"],
                                                             [p[f"base_{k}"].value for k in ("roll", "pitch", "yaw")])

    def base_pose(self) -> tuple[np.ndarray, np.ndarray]:
        """Robot base in the measurement frame: translation (m) and roll-pitch-yaw (rad)."""
        T = self.base_matrix()
        return T[:3, 3], matrix_to_rpy(T[:3, :3])

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
        xyz, rpy = self.base_pose()
        lines.append("base in the measurement frame: xyz [" + ", ".join(f"{v * 1000:.3f}" for v in xyz)
                     + "] mm, rpy [" + ", ".join(f"{math.degrees(v):.4f}" for v in rpy) + "] deg")
        lines += ["", "identified parameters (angles in deg, lengths in mm):",
                  self.parameters.table(show_fixed=True)]
        st = self.stiffness()
        if st:
            lines += ["", "joint stiffness k = 1/c:"]
            for j, (k, sk) in st.items():
                if not math.isfinite(k):
                    lines.append(f"  k{j}: {_NOT_POSITIVE.format(j=j, c=self.parameters[f'c{j}'].value)}")
                    continue
                lines.append(f"  k{j} = {k:.4e} N m/rad" + (f"  (std {sk:.2e})" if math.isfinite(sk) else ""))
        if self.calibration is not None:
            lines += ["", "calibration poses: " + self.calibration.line()]
        if self.orientation is not None:
            lines.append("orientation:       " + self.orientation.line())
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
                         + (f"{len(self.downweighted)} pose(s) down-weighted below half weight (file lines "
                            + listing([d["line"] for d in self.downweighted], 12) + ")"
                            if self.downweighted else "no pose down-weighted below half weight"))
        for n in self.notes:
            lines.append("note: " + n)
        return "\n".join(lines)

    def to_dict(self) -> dict:
        """The calibration JSON of INTERFACE.md section 4 (plus what rebuilds the model)."""
        params = []
        for p in self.parameters:
            params.append({"name": p.name, "value": p.to_display(p.value),
                           "std": p.to_display(p.std) if math.isfinite(p.std) else None,
                           "identifiable": bool(p.identifiable) if p.identifiable is not None else not p.fixed,
                           "unit": p.display_unit, "nominal": p.to_display(p.nominal), "fixed": p.fixed,
                           "reason": p.reason, "term": p.term, "joint": p.joint})
        for j, (k, sk) in self.stiffness().items():
            entry = {"name": f"k{j}", "value": k if math.isfinite(k) else None,
                     "std": sk if math.isfinite(sk) else None,
                     "identifiable": True, "unit": "N*m/rad", "derived": f"1/c{j}", "joint": j}
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
        if self.coverage is not None:
            doc["coverage"] = self.coverage.to_dict()
        if self.has_orientation:    # only full-pose models: a position-only calibration's JSON is as it was
            fitted = self.full_pose and math.isfinite(self.loss.sigma_rot)
            doc["orientation"] = {
                "tool0": [float(x) for x in self.tool0.ravel()],
                "tool_rotation": {"rpy_deg": np.degrees(matrix_to_rpy(self.tool_rotation())).tolist()},
                "full_pose": bool(self.full_pose),
                "sigma_mm": self.loss.sigma * 1000 if fitted else None,
                "sigma_deg": math.degrees(self.loss.sigma_rot) if fitted else None,
                "calibration": self.orientation.to_dict() if self.orientation else None}
        if self.solver is not None:
            doc["solver"] = {"name": self.solver_name, "status": self.solver.status,
                             "iterations": self.solver.iterations, "solve_time_s": self.solver.solve_time_s,
                             "setup_time_s": self.solver.setup_time_s, "success": self.solver.success}
        if self.uncertainty is not None:
            doc["uncertainty"] = {"sigma_mm": self.uncertainty.sigma * 1000, "dof": self.uncertainty.dof,
                                  "names": self.uncertainty.names,
                                  "correlation": np.round(self.uncertainty.correlation, 6).tolist()}
        return doc

    def save(self, path: str | Path, overwrite: bool = False) -> None:
        atomic_write(path, json.dumps(self.to_dict(), indent=1, allow_nan=False, default=_json_default),
                     overwrite=overwrite)


_NOT_POSITIVE = ("no positive stiffness: compliance c{j} = {c:.3g} rad/(N*m) is not above 0, the joint is "
                 "stiffer than these poses and loads can tell")


def _json_default(o):
    if isinstance(o, (np.floating, np.integer)):
        return o.item()
    raise TypeError(type(o).__name__)


def load_calibration(path: str | Path) -> CalibrationResult:
    """Read a calibration JSON written by :meth:`CalibrationResult.save`."""
    path = str(path)
    try:
        doc = json.loads(Path(path).read_text(encoding="utf-8-sig"))
    except FileNotFoundError:
        raise CalibrationFileError("no such file", file=path) from None
    except (OSError, ValueError, RecursionError) as e:  # ValueError: not JSON, not UTF-8
        raise CalibrationFileError(f"not a calibration JSON: {e}", file=path) from e
    validate_calibration_document(doc, path)
    try:
        robot = robot_from_dict(doc["robot"], path)
        settings = doc.get("terms", {})
        terms = [restore_term(t, settings.get(t.spec(), settings.get(t.name, {}))) for t in parse_spec(doc["model"])]
        model = Model(robot, terms)
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
        coverage = Coverage.from_dict(doc["coverage"]) if doc.get("coverage") else None
        ori = doc.get("orientation")
        tool0, angles, full_pose = None, None, False
        if ori:
            tool0 = np.asarray(ori["tool0"], dtype=float).reshape(3, 3)
            angles = AngleStats(**ori["calibration"]) if ori.get("calibration") else None
            full_pose = bool(ori.get("full_pose", False))
            if ori.get("sigma_deg") is not None:
                import dataclasses
                loss = dataclasses.replace(loss, sigma=float(ori["sigma_mm"]) / 1000,
                                           sigma_rot=math.radians(float(ori["sigma_deg"])))
    except (KeyError, TypeError, ValueError, CasadicalError) as e:
        raise CalibrationFileError(f"not a calibration JSON written by casadical ({e})", file=path) from e
    model.parameters = params
    cal = doc.get("calibration")
    return CalibrationResult(model, params, base0, calibration=ErrorStats(**cal) if cal else None,
                             notes=doc.get("notes", []), loss=loss, downweighted=rob.get("downweighted", []),
                             coverage=coverage, tool0=tool0, orientation=angles, full_pose=full_pose)


def restore_term(term: ErrorTerm, settings: dict) -> ErrorTerm:
    """``term`` (from a model specification) rebuilt with the settings a calibration saved."""
    allowed = inspect.signature(type(term).__init__).parameters
    kwargs = {k: v for k, v in settings.items() if k in allowed and k not in ("joints", "harmonics")}
    if not kwargs:
        return term
    return type(term)(joints=term.joints, **kwargs)   # a term with settings besides its joints takes joints
