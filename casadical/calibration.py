"""Calibration: measured poses in, a calibrated model with honest uncertainties out.

>>> from casadical import load_robot, calibrate
>>> from casadical.data import Measurements
>>> robot = load_robot("ur10")
>>> data = Measurements.read_csv("problems/datasets/ur10-ipa/series_b.csv", n_joints=6)
>>> result = calibrate(robot, data.subset(slice(0, 300)), "kinematic")   # doctest: +SKIP
>>> print(result.summary())                                              # doctest: +SKIP

Given a calibration instead of a robot, only what the model specification
names is estimated again and every other value is kept: ``base`` re-fits the
base pose alone (a new tracker set-up), ``kinematic`` the geometry (a new
measurement series), ``kinematic+compliance`` the geometry and compliances.

The parameters minimise a robust loss by default (pseudo-Huber, noise scale
from the data, :class:`casadical.problem.RobustLoss`): a bad tracker shot is
down-weighted and reported by its file line instead of pulling the model.

Data with a measured orientation (``rx_deg, ry_deg, rz_deg``: a 6-DoF probe)
are calibrated on the full pose unless ``position_only``: the model gains
the probe's mounting rotation (term ``tool_orientation``, always estimated
like the base pose) and each pose's loss takes its position and orientation
residuals weighted by their noise scales, both estimated from the data.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import fields, replace

import numpy as np

from .alignment import align
from .checks import check_poses
from .coverage import Coverage
from .data import Measurements
from .errors import (CasadicalWarning, ConvergenceWarning, IdentifiabilityError, IdentifiabilityWarning, InputError,
                     PhysicsWarning, SolverError, listing)
from .identifiability import Identifiability, analyse, triangular_factor
from .model import Model, parse_spec, pose_to_base0, spec_of
from .parameters import Parameters
from .problem import ROT_WEIGHT_PRIOR, CalibrationProblem, RobustLoss, jacobian_factor, pose_chunks
from .calibration_file import restore_term
from .result import CalibrationResult, ErrorStats, load_calibration
from .robot import Robot
from .sessions import session_index
from .physics import term_causes, violations
from .significance import FitStatistics, warn_not_significant
from .simulate import sample_poses
from .solvers import Ipopt, make_solver
from .terms import ErrorTerm, ReferencedTerm, SessionLocal, make_term
from .threads import limited_threads
from .terms.rbf_compensator import RBFCompensator, features
from .terms.tool_orientation import ToolOrientation
from .uncertainty import from_normal, warn_problems

__all__ = ["CalibrationResult", "ErrorStats", "calibrate", "load_calibration"]

#: a pose whose robust weight falls below this is reported as set aside
DOWNWEIGHT_REPORT = 0.5
ROBUST_LOOPS = 6


_GENERIC: dict = {}


def _generic_identifiable(model: Model, params: Parameters, cov: np.ndarray, seed: int = 0,
                          full_pose: bool = False) -> list[str]:
    """Parameters identifiable from many random poses (what a good pose set could reach).

    Cached per robot, model and free set: diagnosis and comparisons calibrate
    the same structure many times. ``full_pose``: with the orientation rows.
    """
    varies = tuple(bool(np.ptp(cov[:, k]) > 0) for k in range(cov.shape[1]))
    key = (id(model.robot), model.spec, tuple(params.free), varies) + ((True,) if full_pose else ())
    if key not in _GENERIC:
        rng = np.random.default_rng(seed)
        q = sample_poses(model.robot, 200, rng, floor_z=None)
        c = cov[rng.integers(len(cov), size=len(q))]
        if full_pose:   # measured = predicted orientation: the rows of the orientation residual at zero
            P = model.probe_rotation(q, params.nominal, c)
            _, J, _, Jo = model.pose_jacobian(q, P, params.nominal, c)
            J = np.concatenate([J, ROT_WEIGHT_PRIOR * Jo], axis=1)
        else:
            _, J = model.predict_jacobian(q, params.nominal, c)
        if len(_GENERIC) > 256:
            _GENERIC.clear()
        _GENERIC[key] = (model.robot, analyse(J, params).identifiable)  # robot kept: its id stays unique
    return _GENERIC[key][1]


def _loss(robust: str | RobustLoss | None) -> RobustLoss:
    if isinstance(robust, RobustLoss):
        return robust
    if robust in (None, "none"):
        return RobustLoss("none")
    if robust == "huber":
        return RobustLoss("huber")
    raise InputError(f"unknown robust loss {robust!r}: use 'huber' (default) or 'none'")


def set_references(terms: list[ErrorTerm], data: Measurements) -> None:
    """Terms driven by a covariate take its mean over the data as their reference (a term of one session:
    over that session's poses)."""
    for t in terms:
        inner = t.inner if isinstance(t, SessionLocal) else t
        if isinstance(inner, ReferencedTerm):
            col = data.get(inner.reference_covariate)
            if col is not None and isinstance(t, SessionLocal):
                col = col[data.sessions == t.session_name] if data.sessions is not None else col[:0]
            if col is not None and len(col):
                t.t_ref = float(np.mean(col))


def with_sessions(terms: list[ErrorTerm], data: Measurements, tools: bool | list[str] = False) -> list[ErrorTerm]:
    """``terms`` with a base pose per session (:class:`~casadical.terms.sessions.SessionFrames`) when ``data``
    holds several sessions; ``tools``: every session other than the first (True), or those named, has its own
    tool too."""
    names = data.session_names
    terms = [t for t in terms if t.name != "sessions"]
    if len(names) < 2:
        if tools:
            raise InputError("a tool per session needs data of several sessions (several files, or a session "
                             "column)", file=data.path)
        return terms
    own = names[1:] if tools is True else list(tools or [])
    return terms + [make_term("sessions", names=names, tools=own)]


def robot_frame(model: Model, params: Parameters, data: Measurements) -> np.ndarray:
    """The model's tool points of ``data``'s poses in the robot base frame (m), every session's (its base
    parameters at zero)."""
    frames = model.term("sessions")
    if frames is not None:
        frames.references = {}
    return model.predict(data.q, params.values, model.covariates(data), pose_to_base0(np.eye(4)))


def align_sessions(model: Model, data: Measurements, start: np.ndarray, xyz: np.ndarray) -> np.ndarray:
    """The closed-form alignment of each session's robot-frame points ``start`` to its measurements ``xyz``.

    Sets the reference pose of every session other than the first in the
    model's sessions term; returns the first session's (``base0``).
    """
    frames = model.term("sessions")
    if frames is None:
        return pose_to_base0(align(start, xyz))
    idx = session_index(data)
    for s in frames.names[1:]:
        frames.set_reference(s, pose_to_base0(align(start[idx[s]], xyz[idx[s]])))
    first = idx[frames.names[0]]
    return pose_to_base0(align(start[first], xyz[first]))


def model_for(robot: Robot, spec: str | list[ErrorTerm], data: Measurements, jit: bool | None = None,
              session_tools: bool | list[str] = False) -> Model:
    """The model of ``spec`` for ``data``: terms driven by a covariate referenced to its mean there, and a base
    pose per session (``session_tools``: a tool too) when ``data`` holds several sessions."""
    terms = parse_spec(spec) if isinstance(spec, str) else spec
    set_references(terms, data)
    return Model(robot, with_sessions(terms, data, session_tools), jit=jit)


def _merge(prior: list[ErrorTerm], new: list[ErrorTerm]) -> tuple[list[ErrorTerm], set[str]]:
    """Terms of a calibration extended by a specification's terms; the names of the latter's terms.

    A term of the same kind as one already there is merged (its joints or
    harmonics joined); settings (reference temperature, network, ...) are kept.
    """
    out = list(prior)
    named: set[str] = set()
    for t in new:
        named.add(t.name)
        same = next((k for k, p in enumerate(out) if type(p) is type(t)), None)
        if same is None:
            out.append(t)
            continue
        p = out[same]
        if hasattr(t, "harmonics"):
            merged = sorted(set(p.harmonics) | set(t.harmonics))
            out[same] = restore_term(type(t)(merged), p.settings())
        elif t.joints is not None and p.joints is not None and set(t.joints) - set(p.joints):
            out[same] = restore_term(type(t)(sorted(set(p.joints) | set(t.joints))), p.settings())
    return out, named


def _named_free(params: Parameters, named: set[str], new_params: set[str]) -> list[str]:
    """Parameters re-estimated when a calibration is taken further: base, named terms (``tool``: the tool
    offset), new ones."""
    return [p.name for p in params if p.group == "base" or p.term in named or p.name in new_params
            or (p.group == "tool" and "tool" in named)]


def _check_loads(model: Model, robot: Robot, data: Measurements) -> None:
    """A compliance asked of a robot that carries no mass: no gravity torque can deflect any joint.

    Without it every compliance would be fixed as having "no effect at
    these poses", which hides the cause (a URDF without ``<inertial>``).
    """
    torque_terms = [t.spec() for t in model.terms if t.name in ("joint_compliance", "nonlinear_stiffness")]
    if not torque_terms:
        return
    payload = data.get("payload_kg")
    carried = robot.payload_mass if payload is None else float(np.max(payload, initial=0.0))
    if sum(j.mass for j in robot.joints) > 0 or carried > 0:
        return
    raise InputError(f"model {model.spec} asks for {', '.join(torque_terms)}, but robot {robot.name} has no link "
                     "masses and the poses no payload, so no gravity torque deflects a joint; give the links their "
                     "masses (<inertial> in a URDF, mass_kg in a robot TOML) or the poses a payload_kg column, or "
                     "leave the compliance out (--model kinematic)", file=robot.source or None)


@limited_threads()
def calibrate(robot: Robot | CalibrationResult, data: Measurements, model: str | Model = "kinematic+compliance",
              solver: str = "ipopt", *, solver_options: dict | None = None, fix: tuple[str, ...] = (),
              start: dict[str, float] | None = None, check_identifiability: bool = True,
              warn: bool = True, robust: str | RobustLoss = "huber", position_only: bool = False,
              allow_outside_limits: bool = False, angles_are_degrees: bool = False,
              positions_are_mm: bool = False, allow_mismatch: bool = False,
              session_tools: bool | list[str] = False, keep_compensator: bool = False) -> CalibrationResult:
    """Identify the parameters of ``model`` from measured poses.

    Parameters
    ----------
    robot : Robot or CalibrationResult
        A robot (every parameter of ``model`` starts at nominal), or a
        calibration to take further: then only the base pose and the
        parameters of the terms ``model`` names are estimated (``base``:
        the base pose alone; ``kinematic``: the geometry; terms the
        calibration lacks are added), every other value is kept.
    data : Measurements
        Must contain measured positions. With measured orientations
        (``rx_deg, ry_deg, rz_deg``) the calibration is on the full pose (see
        ``position_only``).
    model : str or Model
        Specification such as ``"kinematic+compliance"`` or a built model.
        ``+rbf_compensator`` fits a Gaussian RBF network to what the model
        leaves (in the robot base frame) and adds it to the model;
        ``+gp_compensator`` a Gaussian process of the joint readings per
        session, applied where it knows (:mod:`casadical.accuracy`).
    solver : {"ipopt", "lm", "gn", "auto"}
        ``auto`` runs Levenberg-Marquardt and hands over to IPOPT if the
        solution leaves the parameter bounds.
    solver_options : dict, optional
        Settings of the solver dataclass (e.g. ``{"max_iter": 50}``); with
        ``auto``, Levenberg-Marquardt's, of which IPOPT takes those it has
        (``max_iter``).
    fix : tuple of str
        Parameters to hold at their start values.
    start : dict, optional
        Start values (SI) by parameter name; default nominal (or the
        calibration's values).
    check_identifiability : bool
        Fix parameters these poses cannot identify (recommended).
    robust : {"huber", "none"} or RobustLoss
        The loss: pseudo-Huber on each pose's residual with the noise scale
        estimated from the data (default), or plain least squares. A
        RobustLoss with its ``sigma`` set keeps that noise scale (for full
        pose, with ``sigma_rot`` too).
    position_only : bool
        Calibrate on the positions alone even when the data have measured
        orientations. Otherwise such data are calibrated on the full pose:
        the model gains the probe's mounting rotation (``tool_roll,
        tool_pitch, tool_yaw`` from a reference R0 found in closed form, both
        always estimated like the base pose), and each pose's loss is the
        pseudo-Huber of ``|r_p|^2 + k^2 |r_o|^2`` with ``k = sigma /
        sigma_rot``, the two noise scales estimated from the data.
    allow_outside_limits, angles_are_degrees, positions_are_mm, allow_mismatch : bool
        Overrides of the plausibility checks of the poses
        (:func:`casadical.checks.check_poses`); ``allow_mismatch``: poses
        the start model (nominal, or the calibration taken further) misses
        far beyond what it can mean, even with its base pose fitted to them.
    session_tools : bool or list of str
        With data of several sessions (``data.sessions``; each has its own
        base pose): every session other than the first (True), or the named
        ones, has its own tool offset too (the probe was re-mounted).
    keep_compensator : bool
        Taking a calibration further: keep its session compensator
        (``gp_compensator``, which a transfer drops like every term of the
        calibration's session), as when the new poses are of the same
        session (a new tracker set-up in the middle of it).

    Raises
    ------
    IdentifiabilityError
        Too few poses for the model, or degenerate poses.
    SolverError
        The solver failed without a usable result.
    InputError
        The data do not fit the robot, or an unknown parameter name.
    """
    prior = robot if isinstance(robot, CalibrationResult) else None
    robot = prior.model.robot if prior is not None else robot
    if data.n_joints != robot.n:
        raise InputError(f"has {data.n_joints} joint columns but robot {robot.name} has {robot.n} joints",
                         file=data.path)
    loss = _loss(robust)
    notes: list[str] = []
    full_pose = data.has_orientation and not position_only
    if full_pose:
        measured_rot = data.rotations   # all three columns, or an error naming the missing one

    # --- the model and the free set
    free_tool = False
    if isinstance(model, Model):
        terms, built = model.terms, model
    else:
        items = [i.strip() for i in model.split("+")]
        free_tool = "tool" in items   # base+tool: the tool offset is estimated too (a re-mounted probe)
        terms, built = parse_spec("+".join(i for i in items if i != "tool") or "nominal"), None
    named_orientation = any(isinstance(t, ToolOrientation) for t in terms)
    if named_orientation and not full_pose and prior is None:
        raise InputError(f"model item tool_orientation needs measured orientations (rx_deg, ry_deg, rz_deg) "
                         f"{'and no --position-only' if data.has_orientation else 'in the data'}", file=data.path)
    if full_pose and not named_orientation:
        # the probe's mounting rotation: what full-pose data add to any model
        terms = list(terms) + [make_term("tool_orientation")]
        if built is not None:
            built = Model(robot, [t for t in terms if t.name != "geometric" or built.geometric_free], jit=built.jit)
    want_rbf = any(isinstance(t, RBFCompensator) and t.network is None for t in terms)
    want_gp = any(t.name == "gp_compensator" and getattr(t, "gp", 0) is None for t in terms)
    terms = [t for t in terms if not (isinstance(t, RBFCompensator) and t.network is None)
             and not (t.name == "gp_compensator" and getattr(t, "gp", 0) is None)]
    if prior is not None:
        merged, named = _merge(list(prior.model.terms), terms)
        # what describes the session the calibration was measured in (drift, a session compensator) is not
        # the robot's: it is dropped, unless the model names it (then it is estimated for these poses)
        dropped = [t for t in merged if t.session and (t.name not in named or isinstance(t, SessionLocal)
                                                       or t.name == "sessions")
                   and not (keep_compensator and t.name == "gp_compensator")]
        merged = [t for t in merged if t not in dropped]
        if dropped:
            notes.append(f"{', '.join(t.spec() for t in dropped)} dropped: "
                         f"{'it belongs' if len(dropped) == 1 else 'they belong'} to the measurement session of the "
                         "calibration, not to the robot; name it in the model to estimate it for these poses")
            if warn:
                warnings.warn(notes[-1], CasadicalWarning, stacklevel=2)
        if full_pose:   # the probe's mounting is estimated again, like the base pose
            named.add("tool_orientation")
        geometric = prior.model.geometric_free or "geometric" in named
        session = [t for t in merged if t.session]     # named again: estimated for these poses, from zero
        set_references(session, data)
        merged = with_sessions(merged, data, session_tools)
        session += [t for t in merged if t.name == "sessions"]
        # the same terms: the calibration's own model (its symbolic build and evaluators) serves again
        model = prior.model if spec_of(merged, geometric) == prior.model.spec and not session else \
            Model(robot, [t for t in merged if t.name != "geometric" or geometric], jit=prior.model.jit)
        old = {p.name for p in prior.parameters}
        params = model.parameters.copy()
        new_params = {p.name for p in params if p.name not in old}
        free = set(_named_free(params, named | ({"tool"} if free_tool else set()), new_params))
        for p in params:
            if p.name in old and p.term not in {t.name for t in session}:
                src = prior.parameters[p.name]
                p.value, p.std, p.identifiable = src.value, src.std, src.identifiable
            p.fixed = p.name not in free
            if p.fixed:
                p.reason = "kept from the calibration"
            elif p.name in old and prior.parameters[p.name].fixed and p.group != "base":
                # what the calibration could not identify stays put unless these poses can
                p.reason = ""
        kept = {p.name for p in params if p.fixed} - set(fix)   # their std too comes from the calibration
    else:
        kept = set()
        model = built if built is not None else model_for(robot, terms, data, session_tools=session_tools)
        params = model.parameters.copy()
        if free_tool:
            for p in params.select(term="geometric"):
                if p.group == "tool":
                    p.fixed, p.reason = False, ""
    unknown = [n for n in list(fix) + list(start or {}) if n not in params]
    if unknown:
        names = params.names
        raise InputError(f"no parameter {', '.join(map(repr, sorted(set(unknown))))} in model {model.spec} "
                         f"(its parameters: {', '.join(names[:12])}{', ...' if len(names) > 12 else ''})")
    for name, v in (start or {}).items():
        params[name].value = float(v)
    params.fix(fix, reason="fixed by the user")
    _check_loads(model, robot, data)
    q, xyz, cov = data.q, data.xyz, model.covariates(data)

    # --- base pose: closed-form alignment of the start model's predictions to the measurements
    for p in params:
        if p.group == "base":
            p.value = 0.0
    start_xyz = robot_frame(model, params, data)
    own = None
    # the rule that matches what is refitted: a calibration taken further with its geometry (or tool) estimated
    # again is judged as the robot is (its nominal model, base pose fitted); with its base pose alone, by its own
    refits = prior is not None and any(p.group != "base" and not p.fixed for p in params.select(term="geometric"))
    if prior is not None and not refits:
        label = robot.source if robot.source.lower().endswith(".json") else f"of robot {robot.name}"
        own = (label, prior.calibration.mean_mm if prior.calibration else None)
    check_poses(data, robot, allow_outside_limits=allow_outside_limits, angles_are_degrees=angles_are_degrees,
                positions_are_mm=positions_are_mm, allow_mismatch=allow_mismatch,
                predicted=None if refits else start_xyz, nominal=prior is None, calibration=own)
    where = f"{data.path}: " if data.path else ""
    try:
        base0 = align_sessions(model, data, start_xyz, xyz)
    except IdentifiabilityError as e:      # fewer than 3 poses (of a session), or all on a line
        raise IdentifiabilityError(f"{where}{e}") from e
    cov = model.covariates(data)
    # --- full pose: the probe's reference mounting R0 in closed form too, at the aligned base
    tool0, rot = (prior.tool0 if prior is not None else None), None
    if full_pose:
        mount = [params[f"tool_{k}"] for k in ("roll", "pitch", "yaw")]
        if all(not p.fixed for p in mount):
            for p in mount:
                p.value = 0.0
        if tool0 is None or any(not p.fixed for p in mount):
            tool0 = mean_mounting(model.probe_rotation(q, params.values, cov, base0), measured_rot)
        rot = measured_rot @ tool0.T

    # --- identifiability
    ident = None
    per_pose = 6 if full_pose else 3
    if check_identifiability:
        generic = _generic_identifiable(model, params, cov, full_pose=full_pose)
        needed = len(generic)
        if per_pose * len(q) <= needed:
            raise IdentifiabilityError(
                f"{where}{len(q)} poses give {per_pose * len(q)} equations for the {needed} identifiable parameters "
                f"of model {model.spec}: at least {needed // per_pose + 1} poses are needed, and 3-5 times that for "
                "a reliable fit")
        # structural question, at nominal values: at a perturbed start exact redundancies only look near-exact
        nominal = params.nominal
        if full_pose:   # the mounting's deviations have no nominal: at the reference R0
            for k in ("roll", "pitch", "yaw"):
                nominal[params.index(f"tool_{k}")] = params[f"tool_{k}"].value
        R = jacobian_factor(model, q, nominal, cov, base0, rot)
        ident = analyse(R, params, n_equations=per_pose * len(q))
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

    problem = CalibrationProblem(model, params, q, xyz, cov, base0, loss, rot)
    if len(problem.free) == 0:
        raise IdentifiabilityError("no free parameter left to identify")

    # --- solve; with the robust loss, re-estimate the noise scale until it settles (full pose: both scales,
    # for the weighting, with either loss)
    opts = solver_options or {}
    estimate = (not (math.isfinite(loss.sigma) and math.isfinite(loss.sigma_rot)) if full_pose
                else loss.robust and not math.isfinite(loss.sigma))
    res, name = _solve_robust(problem, problem.x_from_values(params.values), solver, opts, estimate)
    expected: frozenset = frozenset()    # correlations said in a note, not warned about again
    if ident is not None and np.isfinite(res.cost):
        # a combination of other parameters in the nominal model that the fitted terms tell apart (the tilt
        # of joint 1 against gravity once a compliance deflects the arm): identified when these poses
        # determine it well
        values = problem.values_from_x(res.x)
        freed = separated(problem, values, ident)
        partners = {u.name: u.confounded_with for u in ident.unidentifiable if u.name in freed}
        if partners:
            expected = frozenset(frozenset((n, c)) for n, cs in partners.items() for c in cs)
            params.values = values
            ident.free(list(partners), params)
            fitted = [t.spec() for t in model.terms[1:] if not isinstance(t, ToolOrientation)]
            notes.append(f"{', '.join(partners)}: a combination of other parameters in the nominal model, but "
                         f"the fitted terms ({', '.join(fitted)}) tell them apart on "
                         "these poses (std below a tenth of the typical size): identified; they stay strongly "
                         f"correlated with {', '.join(sorted({c for cs in partners.values() for c in cs}))}")
            first = res
            problem = CalibrationProblem(model, params, q, xyz, cov, base0, problem.loss, rot)
            res, name = _solve_robust(problem, problem.x_from_values(params.values), solver, opts, False)
            res.solve_time_s += first.solve_time_s
            res.setup_time_s += first.setup_time_s
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

    # --- uncertainty, errors, the poses the loss set aside
    lin = problem.linearize(values)
    norms = np.linalg.norm(lin.r, axis=1)
    # full pose: the orientation rows count as equations, in position units (weighted by k)
    unc = from_normal(lin.A, float(lin.weights @ (lin.u2 if full_pose else norms ** 2)), per_pose * len(q),
                      problem.scale, [params.names[i] for i in problem.free])
    for n, s in zip(unc.names, unc.std):
        params[n].std = float(s)
    for i in np.flatnonzero(~params.free):
        p = params.items[i]
        if p.name not in kept:
            p.std = 0.0 if p.identifiable is not False else math.nan
    with warnings.catch_warnings():
        if not warn:
            warnings.simplefilter("ignore")
        notes += warn_problems(unc, params, expected=expected)
        notes += warn_not_significant(model, params, unc.dof)     # a term's parameters the poses do not determine
    down = []
    if loss.robust:
        for i in np.argsort(-(lin.u2 if full_pose else norms)):
            if lin.weights[i] >= DOWNWEIGHT_REPORT:
                break
            down.append({"line": int(data.lines[i]), "residual_mm": float(norms[i] * 1000),
                         "weight": float(lin.weights[i]),
                         **({"file": data.file(i)} if data.sources is not None else {})})
            if full_pose:
                down[-1]["orientation_deg"] = math.degrees(float(np.linalg.norm(lin.r_rot[i])))
        if down:
            scale = (f"{problem.loss.sigma * 1000:.4f} mm" if not full_pose else
                     f"{problem.loss.sigma * 1000:.4f} mm and {math.degrees(problem.loss.sigma_rot):.4f} deg")
            notes.append(f"the robust loss set aside {len(down)} pose(s) of {data.path} whose residual exceeds "
                         f"{math.sqrt(DOWNWEIGHT_REPORT ** -2 - 1) * loss.c:.1f} times the noise scale of "
                         f"{scale} (lines "
                         + listing([f"{d['file']}:{d['line']}" if "file" in d else d["line"] for d in down], 10)
                         + "): likely bad measurements; check them, or pass --robust none to fit them anyway")
    by_session = {s: ErrorStats.of(norms[idx]) for s, idx in session_index(data).items()} \
        if len(data.session_names) > 1 else {}
    result = CalibrationResult(model, params, base0, res, name, ident, unc, ErrorStats.of(norms), notes,
                               problem.loss, down, Coverage.of(data.q_deg), by_session=by_session,
                               statistics=FitStatistics.of(unc), tool0=tool0 if model.orientation else None)
    if result.has_orientation and data.has_orientation:
        result.orientation = result.orientation_stats(data)
    result.full_pose = full_pose
    for note in physics_notes(result, data):
        result.notes.append(note)
        if warn:
            warnings.warn(note, PhysicsWarning, stacklevel=2)
    if want_rbf:
        result = fit_compensator(result, data, warn=warn)
    if want_gp:
        from .accuracy import fit_layer, layer_coverage, with_layer
        gps, _ = fit_layer(result, data)
        result = with_layer(result, gps, data, "gp_compensator: a Gaussian process of the residual per session, "
                                               "applied where it knows")
        known, total = layer_coverage(result, data)
        result.notes[-1] += f" ({known} of the {total} calibration poses)"
    return result


def physics_notes(result: CalibrationResult, data: Measurements) -> list[str]:
    """Notes on the terms that, as fitted, are not the physical cause their names say
    (:mod:`casadical.physics`: told apart from the geometry, meaningful over the data; bounds and significance
    have notes of their own)."""
    out = []
    for cause in term_causes(result):
        free = [n for n in cause.parameters if not result.parameters[n].fixed]   # the fixed: said by the analysis
        for v in violations(result, data, free) if free else ():
            if v.rule in ("geometry", "physics"):
                out.append(f"{cause.label}: not physics as fitted: {v.text}")
    return out

def mean_mounting(probe: np.ndarray, measured: np.ndarray) -> np.ndarray:
    """The constant rotation ``M`` (3x3) minimising ``sum |probe_i M - measured_i|^2`` (Frobenius), closed form.

    The chordal mean of ``probe_i^T measured_i``: their sum projected on the
    rotations (SVD). Starts the probe's mounting rotation as :func:`align`
    starts the base pose.
    """
    U, _, Vt = np.linalg.svd(np.einsum("nji,njk->ik", probe, measured))
    return U @ np.diag([1.0, 1.0, np.sign(np.linalg.det(U @ Vt))]) @ Vt


def _solve_robust(problem: CalibrationProblem, x: np.ndarray, solver: str, opts: dict, estimate_scale: bool):
    """Solve; with ``estimate_scale``, re-estimate the robust loss's noise scale until it settles."""
    res, name, solve_time, setup_time = None, "", 0.0, 0.0
    for _ in range(ROBUST_LOOPS if estimate_scale else 1):
        if estimate_scale and problem.full_pose:   # each kind's own robust scale: they weigh the two parts
            rp, ro = problem.residual_norms(problem.values_from_x(x))
            new = problem.loss.with_scales_from(rp, ro)
            if res is not None and max(abs(new.sigma / problem.loss.sigma - 1),
                                       abs(new.sigma_rot / problem.loss.sigma_rot - 1)) < 0.05:
                break
            problem.loss = new
        elif estimate_scale:
            norms = np.linalg.norm(problem.residuals(problem.values_from_x(x)).reshape(-1, 3), axis=1)
            new = problem.loss.with_sigma_from(norms)
            if res is not None and abs(new.sigma / problem.loss.sigma - 1) < 0.05:
                break
            problem.loss = new
        res, name = _solve(problem, x, solver, opts)
        solve_time += res.solve_time_s
        setup_time += res.setup_time_s
        x = res.x
    res.solve_time_s, res.setup_time_s = solve_time, setup_time
    return res, name


#: settings IPOPT shares with Levenberg-Marquardt, passed on by ``solver="auto"``
IPOPT_FIELDS = {f.name for f in fields(Ipopt) if not f.name.startswith("_")}
#: a structural combination of the nominal model is identified when its std is below this share of its scale
SEPARATED_STD = 0.1


def separated(problem: CalibrationProblem, values: np.ndarray, ident: Identifiability) -> list[str]:
    """Parameters fixed as combinations of others at the nominal values that the fit tells apart well.

    The structural analysis runs at nominal values, where every compliance
    is zero; a fitted compliance can break a combination (tilting joint 1
    changes the gravity torques, which moving the base does not). Such a
    parameter is freed when its column, beyond what the free columns span,
    determines it to ``SEPARATED_STD`` of its typical size at the noise of
    the fit.
    """
    model, params = problem.model, problem.params
    cands = [u.name for u in ident.unidentifiable if u.confounded_with]
    if not cands or all(t.name in ("geometric", "tool_orientation") for t in model.terms):
        return []
    f = problem.free
    cols = np.concatenate([f, [params.index(n) for n in cands]])
    scale = params.scales[cols]
    ssr = [0.0]

    def blocks():   # weighted, scaled Jacobian columns (free ones first), pose chunk by pose chunk
        for s in pose_chunks(problem.n_poses):
            r, J, _ = problem.weighted_jacobian(values, s)
            u2 = np.einsum("ij,ij->i", r, r)
            w = problem.loss.weight(u2)
            ssr[0] += float(w @ u2)
            yield J[:, :, cols] * scale * np.sqrt(w)[:, None, None]

    R = triangular_factor(blocks(), len(cols))
    sigma = math.sqrt(ssr[0] / max(problem.equations_per_pose * problem.n_poses - len(f), 1))
    out = []
    for j, name in enumerate(cands):
        perp = float(np.linalg.norm(R[len(f):, len(f) + j]))     # the column beyond the free columns' span
        if perp > 0 and sigma / perp < SEPARATED_STD:
            out.append(name)
    return out


def _solve(problem: CalibrationProblem, x0: np.ndarray, solver: str, opts: dict):
    if solver == "auto":
        res = make_solver("lm", **opts).solve(problem, x0)
        lo, hi = problem.bounds_x()
        if np.any(res.x < lo) or np.any(res.x > hi):
            lm_time = res.solve_time_s
            shared = {k: v for k, v in opts.items() if k in IPOPT_FIELDS}   # --max-iter holds for both
            res = make_solver("ipopt", **shared).solve(problem, res.x)
            res.solve_time_s += lm_time
            return res, "levenberg-marquardt+ipopt"
        return res, "levenberg-marquardt"
    s = make_solver(solver, **opts)
    return s.solve(problem, x0), s.name


def compensator_data(result: CalibrationResult, data: Measurements) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """What a residual compensator of ``result`` learns from: features, residuals, poses to train on.

    Features are sin q, cos q and the gravity torques; residuals (measured
    minus predicted) are expressed in the robot base frame; poses the robust
    loss set aside are left out of the training (mask).
    """
    m = result.model
    X = features(data.q, m.torques(data.q, result.parameters.values, m.covariates(data)))
    Y = result.residuals(data) @ result.base_matrix()[:3, :3]   # rows: R^T r, the robot base frame
    return X, Y, learning_mask(result, data)


def learning_mask(result: CalibrationResult, data: Measurements) -> np.ndarray:
    """The poses of ``data`` a compensator learns from: those the robust loss did not set aside."""
    keep = np.ones(len(data), bool)
    for d in result.downweighted:
        at = data.lines == d["line"]
        if "file" in d and data.sources is not None:
            at &= data.sources == d["file"]
        keep &= ~at
    return keep


def with_compensator(result: CalibrationResult, network, data: Measurements, note: str) -> CalibrationResult:
    """``result`` with a fitted network added to its model as a ``rbf_compensator`` term."""
    m = result.model
    model = Model(m.robot, list(m.terms if m.geometric_free else m.terms[1:])
                  + [make_term("rbf_compensator", network=network)], jit=m.jit)
    return rebuilt(result, model, data, note)


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


def fit_compensator(result: CalibrationResult, data: Measurements, seed: int = 0,
                    warn: bool = True) -> CalibrationResult:
    """``result`` with an RBF network fitted to its residuals added as a ``rbf_compensator`` term.

    The network maps sin q, cos q and the gravity torques to the residual in
    the robot base frame; its size and width are chosen by cross-validation
    on ``data``, and it is added only if it lowers the cross-validated
    error (otherwise ``result`` comes back with a note saying so). Poses the
    robust loss set aside do not train the network.
    """
    from .compensators.guard import fit_guarded  # here, not at import: 9 ms of every command's start-up

    X, Y, keep = compensator_data(result, data)
    net, info = fit_guarded(rbf_candidates(int(keep.sum()), seed), X[keep], Y[keep], seed=seed)
    if net is None:
        out = replace(result, notes=list(result.notes))
        out.notes.append(f"rbf_compensator not added: {info['reason']}")
        if warn:
            warnings.warn(out.notes[-1], CasadicalWarning, stacklevel=3)
        return out
    return with_compensator(result, net, data, f"rbf_compensator: {net.n_centers_} Gaussian units fitted to "
                                               f"the residuals of {int(keep.sum())} poses ({info['reason']})")


def rbf_candidates(n: int, seed: int = 0) -> dict:
    """RBF networks to choose from by cross-validation: 2 .. n/3 units, width the mean distance between
    centres (the GA paper's rule; choosing it by a nested cross-validation too costs five times more)."""
    from .compensators import RBFNetwork

    def make(k):
        return lambda: RBFNetwork(n_centers=k, width=None, seed=seed)
    top = max(2, n // 3)
    return {f"{k} units": make(k) for k in sorted({int(round(k)) for k in np.geomspace(2, top, 5)})}
