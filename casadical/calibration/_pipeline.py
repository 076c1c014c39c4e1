"""``calibrate()``: measured poses in, a calibrated model out, through named stages.

Each stage is a function ``stage(run)`` of its own module that reads what
the stages before it set on the :class:`~._state.CalibrationRun` and sets its
own fields; :data:`STAGES` is their order. To add a stage, write it in a
module of this package (a docstring saying what it reads and sets), give the
run the fields it sets, and put it in :data:`STAGES` where its inputs are
ready.
"""

from __future__ import annotations

from typing import Callable

from ..data._measurements import Measurements
from ..model._symbolic import Model
from ..problem import RobustLoss
from ..result import CalibrationResult
from ..robot import Robot
from ..runtime._threads import limited_threads
from ._build import build_model
from ._gp_compensator import add_gp_compensator
from ._identify import analyse_identifiability
from ._outcome import assemble_result, note_set_aside
from ._physics_notes import note_physics
from ._precision import estimate_precision
from ._prepare import prepare_data
from ._rbf_compensator import add_rbf_compensator
from ._solve import solve_parameters
from ._spec import read_model_spec
from ._start import start_pose
from ._state import CalibrationRun, Options
from ._unobservable import fix_unobservable

#: the stages of :func:`calibrate`, in order
STAGES: tuple[Callable[[CalibrationRun], None], ...] = (
    prepare_data,             # the poses against the robot, the loss, full pose or positions
    read_model_spec,          # the terms asked for; compensators to fit after the model
    build_model,              # the model for these data (or the calibration's, taken further), the free set
    start_pose,               # base pose (each session's) and probe mounting in closed form; plausibility
    fix_unobservable,         # touches: what they cannot see (a base pose, the scale), fixed and said
    analyse_identifiability,  # enough poses; fix what these poses cannot identify
    solve_parameters,         # the robust solve; free and re-solve what the fit tells apart
    estimate_precision,       # standard errors, correlations, significance
    note_set_aside,           # the poses the robust loss set aside
    assemble_result,          # the CalibrationResult
    note_physics,             # terms that, as fitted, are not the physics their names say
    add_rbf_compensator,      # +rbf_compensator
    add_gp_compensator,       # +gp_compensator
)


@limited_threads()
def calibrate(robot: Robot | CalibrationResult, data: Measurements, model: str | Model = "kinematic+compliance",
              solver: str = "ipopt", *, solver_options: dict | None = None, fix: tuple[str, ...] = (),
              start: dict[str, float] | None = None, start_from: CalibrationResult | None = None,
              check_identifiability: bool = True,
              warn: bool = True, robust: str | RobustLoss = "huber", position_only: bool = False,
              allow_outside_limits: bool = False, angles_are_degrees: bool = False,
              positions_are_mm: bool = False, allow_mismatch: bool = False,
              session_tools: bool | list[str] = False, keep_compensator: bool = False,
              terms=()) -> CalibrationResult:
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
        session, applied where it knows (the GP compensator, one per session:
        :mod:`casadical.calibration._per_session`).
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
    start_from : CalibrationResult, optional
        A fit of the same poses (the same sessions) to start the solve
        from: its base pose (each session's), probe mounting and values,
        ``start``'s values for the parameters it does not have. A model near
        that fit (the diagnosis fits each model from its parent so) then
        starts at its solution, not at a closed-form alignment of the start
        values, and needs a few iterations, not a dozen. The noise scale is
        still first estimated at ``start``'s values, so the result is the one
        without it (to the solver's tolerance).
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
        (:func:`casadical.data._checks.check_poses`); ``allow_mismatch``: poses
        the start model (nominal, or the calibration taken further) misses
        far beyond what it can mean, even with its base pose fitted to them.
    session_tools : bool or list of str
        With data of several sessions (``data.sessions``; each has its own
        base pose): every session other than the first (True), or the named
        ones, has its own tool offset too (the probe was re-mounted).
    keep_compensator : bool
        Taking a calibration further: keep its GP compensator
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
    options = Options(solver=solver, solver_options=solver_options or {}, fix=fix, start=start or {},
                      start_from=start_from,
                      check_identifiability=check_identifiability, warn=warn, robust=robust,
                      position_only=position_only, allow_outside_limits=allow_outside_limits,
                      angles_are_degrees=angles_are_degrees, positions_are_mm=positions_are_mm,
                      allow_mismatch=allow_mismatch, session_tools=session_tools, keep_compensator=keep_compensator,
                      terms=tuple(terms))
    prior = robot if isinstance(robot, CalibrationResult) else None
    run = CalibrationRun(prior.model.robot if prior is not None else robot, data, model, options, prior)
    for stage in STAGES:
        stage(run)
    return run.result
