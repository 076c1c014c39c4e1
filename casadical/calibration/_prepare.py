"""Stage ``prepare_data``: the poses against the robot, the loss, and whether the fit is on the full pose."""

from __future__ import annotations

from ..errors import InputError
from ..problem import RobustLoss
from ._state import CalibrationRun


def robust_loss(robust: str | RobustLoss | None) -> RobustLoss:
    """The loss a caller names: ``"huber"`` (pseudo-Huber, noise scale from the data), ``"none"`` (least
    squares), or a :class:`~casadical.problem.RobustLoss` as it is."""
    if isinstance(robust, RobustLoss):
        return robust
    if robust in (None, "none"):
        return RobustLoss("none")
    if robust == "huber":
        return RobustLoss("huber")
    raise InputError(f"unknown robust loss {robust!r}: use 'huber' (default) or 'none'")


def prepare_data(run: CalibrationRun) -> None:
    """The data's joints are the robot's; the loss; full pose when the data have measured orientations and the
    caller did not ask for positions alone (then the measured rotations, or an error naming a missing column)."""
    data, robot = run.data, run.robot
    if data.n_joints != robot.n:
        raise InputError(f"has {data.n_joints} joint columns but robot {robot.name} has {robot.n} joints",
                         file=data.path)
    run.loss = robust_loss(run.options.robust)
    # a touch row has no orientation: data that touch are calibrated on the positions
    run.full_pose = data.has_orientation and not run.options.position_only and not data.touches
    if run.full_pose:
        run.measured_rot = data.rotations   # all three columns, or an error naming the missing one
