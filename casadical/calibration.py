"""Calibration: measured poses in, a calibrated model with honest uncertainties out.

>>> from casadical import load_robot, calibrate
>>> from casadical.data import Measurements
>>> robot = load_robot("ur10")
>>> data = Measurements.read_csv("problems/datasets/ur10-ipa/series_b.csv", n_joints=6)
>>> result = calibrate(robot, data.subset(slice(0, 300)), "kinematic")   # doctest: +SKIP
>>> print(result.summary())                                              # doctest: +SKIP
"""

from __future__ import annotations

import json
import math
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from . import __version__
from .alignment import align
from .calibration_file import validate_calibration_document
from .checks import check_poses
from .data import Measurements
from .errors import (CalibrationFileError, ConvergenceWarning, IdentifiabilityError, IdentifiabilityWarning,
                     InputError, ModelError, SolverError)
from .files import atomic_write
from .identifiability import Identifiability, analyse
from .kinematics import matrix_to_rpy
from .model import Model, base0_to_pose, parse_spec, pose_to_base0
from .parameters import Parameters
from .problem import CalibrationProblem
from .robot import Robot, robot_from_dict, robot_to_dict
from .simulate import sample_poses
from .solvers import SolverResult, make_solver
from .terms.base import ReferencedTerm
from .uncertainty import Uncertainty, estimate, warn_problems


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

    def to_dict(self) -> dict:
        return {"n_poses": self.n_poses, "mean_mm": self.mean_mm, "max_mm": self.max_mm,
                "std_mm": self.std_mm, "rms_mm": self.rms_mm}

    def line(self) -> str:
        return (f"mean {self.mean_mm:.4f}  max {self.max_mm:.4f}  std {self.std_mm:.4f}  "
                f"rms {self.rms_mm:.4f} mm over {self.n_poses} poses")


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

    # --- using the model ------------------------------------------------------

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

    def base_pose(self) -> tuple[np.ndarray, np.ndarray]:
        """Robot base in the measurement frame: translation (m) and roll-pitch-yaw (rad)."""
        from .kinematics import base_pose_matrix
        p = self.parameters
        delta = base_pose_matrix([p[f"base_{k}"].value for k in "xyz"],
                                 [p[f"base_{k}"].value for k in ("roll", "pitch", "yaw")])
        T = base0_to_pose(self.base0) @ delta
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
            "terms": {t.name: t.settings() for t in self.model.terms},
            "parameters": params,
            "base0": [float(x) for x in self.base0],
            "base_pose": {"xyz_m": xyz.tolist(), "rpy_deg": np.degrees(rpy).tolist()},
            "calibration": self.calibration.to_dict() if self.calibration else None,
            "solver": None,
            "notes": self.notes,
        }
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
        terms = parse_spec(doc["model"])
        for t in terms:
            for k, v in doc.get("terms", {}).get(t.name, {}).items():
                if k != "joints" and k != "harmonics":
                    setattr(t, k, v)
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
    except (KeyError, TypeError, ValueError) as e:
        raise CalibrationFileError(f"not a calibration JSON written by casadical ({e!r})", file=path) from e
    model.parameters = params
    cal = doc.get("calibration")
    return CalibrationResult(model, params, base0,
                             calibration=ErrorStats(**cal) if cal else None, notes=doc.get("notes", []))


# --- the calibration itself ---------------------------------------------------------


_GENERIC: dict = {}


def _generic_identifiable(model: Model, params: Parameters, cov: np.ndarray, seed: int = 0) -> list[str]:
    """Parameters identifiable from many random poses (what a good pose set could reach).

    Cached per robot, model and free set: diagnosis and comparisons calibrate
    the same structure many times.
    """
    varies = tuple(bool(np.ptp(cov[:, k]) > 0) for k in range(cov.shape[1]))
    key = (id(model.robot), model.spec, tuple(params.free), varies)
    if key not in _GENERIC:
        rng = np.random.default_rng(seed)
        q = sample_poses(model.robot, 200, rng, floor_z=None)
        c = cov[rng.integers(len(cov), size=len(q))]
        _, J = model.predict_jacobian(q, params.nominal, c)
        if len(_GENERIC) > 256:
            _GENERIC.clear()
        _GENERIC[key] = (model.robot, analyse(J, params).identifiable)  # robot kept: its id stays unique
    return _GENERIC[key][1]


def calibrate(robot: Robot, data: Measurements, model: str | Model = "kinematic+compliance",
              solver: str = "ipopt", *, solver_options: dict | None = None, fix: tuple[str, ...] = (),
              start: dict[str, float] | None = None, check_identifiability: bool = True,
              warn: bool = True, allow_outside_limits: bool = False, angles_are_degrees: bool = False,
              positions_are_mm: bool = False) -> CalibrationResult:
    """Identify the parameters of ``model`` from measured poses.

    Parameters
    ----------
    robot : Robot
    data : Measurements
        Must contain measured positions.
    model : str or Model
        Specification such as ``"kinematic+compliance"`` or a built model.
    solver : {"ipopt", "lm", "gn", "auto"}
        ``auto`` runs Levenberg-Marquardt and hands over to IPOPT if the
        solution leaves the parameter bounds.
    solver_options : dict, optional
        Settings of the solver dataclass (e.g. ``{"max_iter": 50}``).
    fix : tuple of str
        Parameters to hold at their start values.
    start : dict, optional
        Start values (SI) by parameter name; default nominal.
    check_identifiability : bool
        Fix parameters these poses cannot identify (recommended).
    allow_outside_limits, angles_are_degrees, positions_are_mm : bool
        Overrides of the plausibility checks of the poses
        (:func:`casadical.checks.check_poses`).

    Raises
    ------
    IdentifiabilityError
        Too few poses for the model, or degenerate poses.
    SolverError
        The solver failed without a usable result.
    """
    if data.n_joints != robot.n:
        raise InputError(f"has {data.n_joints} joint columns but robot {robot.name} has {robot.n} joints",
                         file=data.path)
    if isinstance(model, str):
        terms = parse_spec(model)
        for t in terms:
            if isinstance(t, ReferencedTerm):
                col = data.get(t.reference_covariate)
                if col is None and t.reference_covariate == "time_s":
                    col = data.rows  # row order is time order
                if col is not None:
                    t.t_ref = float(np.mean(col))
        model = Model(robot, terms)
    notes: list[str] = []
    params = model.parameters.copy()
    for name, v in (start or {}).items():
        params[name].value = float(v)
    unknown = [n for n in fix if n not in params]
    if unknown:
        names = params.names
        raise ModelError(f"cannot fix {', '.join(map(repr, unknown))}: model {model.spec} has no such parameter "
                         f"(its parameters: {', '.join(names[:12])}{', ...' if len(names) > 12 else ''})")
    params.fix(fix, reason="fixed by the user")
    q, xyz, cov = data.q, data.xyz, model.covariates(data)

    # base pose: closed-form alignment of the start model's predictions to the measurements
    eye = pose_to_base0(np.eye(4))
    start_xyz = model.predict(q, params.values, cov, eye)
    check_poses(data, robot, allow_outside_limits=allow_outside_limits, angles_are_degrees=angles_are_degrees,
                positions_are_mm=positions_are_mm, predicted=start_xyz)
    T = align(start_xyz, xyz)
    base0 = pose_to_base0(T)
    for k in ("x", "y", "z", "roll", "pitch", "yaw"):
        params[f"base_{k}"].value = 0.0

    ident = None
    if check_identifiability:
        # structural question: at a perturbed start exact redundancies only look near-exact
        _, J = model.predict_jacobian(q, params.nominal, cov, base0)
        generic = _generic_identifiable(model, params, cov)
        needed = len(generic)
        if 3 * len(q) <= needed:
            raise IdentifiabilityError(
                f"{len(q)} poses give {3 * len(q)} equations for the {needed} identifiable parameters of "
                f"model {model.spec}: at least {needed // 3 + 1} poses are needed, and 3-5 times that for a "
                "reliable fit")
        ident = analyse(J, params)
        lost = [u for u in ident.unidentifiable if u.name in generic]
        if lost:
            names = ", ".join(f"{u.name} ({u.reason})" for u in lost[:6])
            notes.append(f"these poses cannot identify {len(lost)} parameter(s) that other poses could: "
                         f"{names}; they stay at their start values. Spread the poses over more of the "
                         "joint ranges (and loads) to identify them")
            if warn:
                warnings.warn(notes[-1], IdentifiabilityWarning, stacklevel=2)
        for u in ident.unidentifiable:
            if u.name not in generic:
                u.reason = "structurally " + u.reason if not u.reason.startswith("has no") else u.reason
        ident.apply(params)

    problem = CalibrationProblem(model, params, q, xyz, cov, base0)
    if len(problem.free) == 0:
        raise IdentifiabilityError("no free parameter left to identify")
    x0 = problem.x_from_values(params.values)
    opts = solver_options or {}
    if solver == "auto":
        res = make_solver("lm", **opts).solve(problem, x0)
        name = "levenberg-marquardt"
        lo, hi = problem.bounds_x()
        if np.any(res.x < lo) or np.any(res.x > hi):
            lm_time = res.solve_time_s
            res = make_solver("ipopt").solve(problem, res.x)
            res.solve_time_s += lm_time
            name = "levenberg-marquardt+ipopt"
    else:
        s = make_solver(solver, **opts)
        res = s.solve(problem, x0)
        name = s.name
    if not np.isfinite(res.cost):
        raise SolverError(f"{name} ended with a non-finite cost ({res.status}); check the data for outliers "
                          "and the robot file for wrong units")
    if not res.success:
        notes.append(f"{name} did not converge ({res.status} after {res.iterations} iterations); the result "
                     "is the last iterate. Try --solver lm or more iterations")
        if warn:
            warnings.warn(notes[-1], ConvergenceWarning, stacklevel=2)
    values = problem.values_from_x(res.x)
    params.values = values
    r, Jx = problem.residuals_jacobian(values)
    unc = estimate(r, Jx, problem.scale, [params.names[i] for i in problem.free])
    for n, s in zip(unc.names, unc.std):
        params[n].std = float(s)
    for i in np.flatnonzero(~params.free):
        params.items[i].std = 0.0 if params.items[i].identifiable is not False else math.nan
    with warnings.catch_warnings():
        if not warn:
            warnings.simplefilter("ignore")
        notes += warn_problems(unc, params)
    errors = np.linalg.norm(r.reshape(-1, 3), axis=1)
    return CalibrationResult(model, params, base0, res, name, ident, unc, ErrorStats.of(errors), notes)
