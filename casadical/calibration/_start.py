"""Stage ``start_pose``: the base pose in closed form, the poses' plausibility, and the probe's mounting.

Each session's base pose is the closed-form alignment (Kabsch) of the start
model's tool points to the measured ones, so the tracker may stand anywhere
at any rotation; the plausibility checks of the poses
(:func:`casadical.data._checks.check_poses`) judge the start model against them;
full-pose data start the probe's mounting rotation in closed form too
(:func:`mean_mounting`).
"""

from __future__ import annotations

import numpy as np

from ..data._checks import check_poses
from ..data._measurements import Measurements, session_index
from ..errors import IdentifiabilityError, InputError
from ..kinematics import matrix_to_rpy
from ..model._symbolic import Model, base0_to_pose, pose_to_base0
from ..parameters import Parameters
from ..problem import measured_points
from ..stats._alignment import align
from ._state import CalibrationRun


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
    model's sessions term; returns the first session's (``base0``). Rows that say what they touched have no
    measured point (NaN): a session's alignment takes its measured rows; a session of touches alone stands at
    the robot's base frame (the identity: nothing measures the robot against the world).
    """
    measured = np.isfinite(xyz).all(axis=1)

    def aligned(idx):
        idx = idx[measured[idx]]
        return pose_to_base0(np.eye(4) if not len(idx) else align(start[idx], xyz[idx]))

    frames = model.term("sessions")
    if frames is None:
        return aligned(np.arange(len(xyz)))
    idx = session_index(data)
    for s in frames.names[1:]:
        frames.set_reference(s, aligned(idx[s]))
    return aligned(idx[frames.names[0]])


def mean_mounting(probe: np.ndarray, measured: np.ndarray) -> np.ndarray:
    """The constant rotation ``M`` (3x3) minimising ``sum |probe_i M - measured_i|^2`` (Frobenius), closed form.

    The chordal mean of ``probe_i^T measured_i``: their sum projected on the
    rotations (SVD). Starts the probe's mounting rotation as :func:`align`
    starts the base pose.
    """
    U, _, Vt = np.linalg.svd(np.einsum("nji,njk->ik", probe, measured))
    return U @ np.diag([1.0, 1.0, np.sign(np.linalg.det(U @ Vt))]) @ Vt


def start_pose(run: CalibrationRun) -> None:
    """Sets ``base0`` (and every other session's reference pose), ``cov``, and for full pose ``tool0`` and
    ``rot``; raises the plausibility checks' errors."""
    model, params, data, robot, prior, opts = run.model, run.params, run.data, run.robot, run.prior, run.options
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
    check_poses(data, robot, allow_outside_limits=opts.allow_outside_limits,
                angles_are_degrees=opts.angles_are_degrees, positions_are_mm=opts.positions_are_mm,
                allow_mismatch=opts.allow_mismatch, predicted=None if refits else start_xyz,
                nominal=prior is None, calibration=own)
    try:
        run.base0 = align_sessions(model, data, start_xyz, measured_points(data))
    except IdentifiabilityError as e:      # fewer than 3 poses (of a session), or all on a line
        raise IdentifiabilityError(f"{run.where}{e}") from e
    run.cov = model.covariates(data)
    # full pose: the probe's reference mounting R0 in closed form too, at the aligned base
    run.tool0 = prior.tool0 if prior is not None else None
    if run.full_pose:
        mount = [params[f"tool_{k}"] for k in ("roll", "pitch", "yaw")]
        if all(not p.fixed for p in mount):
            for p in mount:
                p.value = 0.0
        if run.tool0 is None or any(not p.fixed for p in mount):
            run.tool0 = mean_mounting(model.probe_rotation(data.q, params.values, run.cov, run.base0),
                                      run.measured_rot)
        run.rot = run.measured_rot @ run.tool0.T
    if opts.start_from is not None:
        _start_from(run, opts.start_from)


def _start_from(run: CalibrationRun, fit) -> None:
    """``calibrate(start_from=fit)``: the solve starts at ``fit``'s solution, its base pose (each session's)
    and probe mounting expressed in this run's references (the closed forms above), its values of the other
    parameters, and the start values of those it does not have; the noise scale is still estimated first at
    the start values, as without it (``scale_at``)."""
    model, params = run.model, run.params
    frames, theirs = model.term("sessions"), fit.model.term("sessions")
    names = frames.names if frames is not None else []
    if names != (theirs.names if theirs is not None else []):
        raise InputError(f"start_from: a fit of sessions {theirs.names if theirs is not None else []}, these data "
                         f"have {names}; start from a fit of the same poses")
    run.scale_at = params.values.copy()
    for p in params:
        if p.group != "base" and not p.fixed and not p.name.startswith("tool_") and p.name in fit.parameters:
            p.value = fit.parameters[p.name].value
    for k, s in enumerate(names or [None]):
        ref = run.base0 if k == 0 else frames.references[s]
        M = np.linalg.inv(base0_to_pose(ref)) @ fit.base_matrix(s)
        at = "" if k == 0 else f"@{s}"
        for key, v in zip(("x", "y", "z", "roll", "pitch", "yaw"), [*M[:3, 3], *matrix_to_rpy(M[:3, :3])]):
            if f"base_{key}{at}" in params and not params[f"base_{key}{at}"].fixed:
                params[f"base_{key}{at}"].value = float(v)
    if run.full_pose and fit.tool0 is not None and all(f"tool_{k}" in params for k in ("roll", "pitch", "yaw")):
        D = fit.tool_rotation() @ run.tool0.T
        for key, v in zip(("roll", "pitch", "yaw"), matrix_to_rpy(D)):
            if not params[f"tool_{key}"].fixed:
                params[f"tool_{key}"].value = float(v)
