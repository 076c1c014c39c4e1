"""Is the robot file's gravity where the fitted base pose puts the instrument's down?

The robot file gives gravity in the robot's base frame (docs/formats.md section 1, ``[gravity] direction``); the
gravity torques, the compliances and the mount's moment all follow it. A calibration fits each session's base
pose, the robot's base in the measurement frame. Where the instrument is levelled (a laser tracker or a total
station on its level: its z up), that pose turns the instrument's down, ``-z``, into the robot's base frame: the
gravity the data say. A robot file whose gravity is far from it describes the arm with another mounting (an arm's
own URDF, gravity down its joint 1, for an arm on a wall or on a column's side): every gravity torque is then
wrong, and the diagnosis names joint causes of what is the mounting's (issue 49: the Doosan arm on Trailblazer's
column, described with its own URDF's gravity, was 89.5 deg off and named encoder scales and gear errors).

The instrument is levelled when the user says so (``--levelled``), or where every session's fitted base pose puts
its down within :data:`AGREE_DEG` of one direction in the robot's base frame (with two sessions or more: the
instrument placed again and again, always level); ``--not-levelled`` turns the check off. The check needs the
robot file's masses (without them gravity moves nothing).
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass

import numpy as np

from ..errors import GravityWarning
from ..result import CalibrationResult
from ..terms._mount_compliance import max_mount_moment

#: a robot file's gravity further than this (deg) from the levelled instrument's down is a warning: a robot on a
#: floor, a wall or a column is off by 90 or 180 deg; an instrument is levelled within minutes of arc and a base
#: pose fitted to a fraction of a degree
TOLERANCE_DEG = 5.0
#: sessions whose fitted base poses put the instrument's down within this (deg) of their mean direction in the
#: robot's base frame show a levelled instrument
AGREE_DEG = 2.0


@dataclass
class GravityCheck:
    """The robot file's gravity against the levelled instrument's down, in the robot's base frame.

    Attributes
    ----------
    levelled : str
        ``given`` (``--levelled``) or ``inferred`` (every session's base pose agrees on one vertical).
    gravity : ndarray
        The robot file's gravity direction (unit, robot base frame).
    down : ndarray
        The instrument's down in the robot's base frame (unit; the sessions' mean).
    off_deg : float
        The angle between the two.
    sessions : dict of str to float
        Each session's angle (deg) between its down and the robot file's gravity.
    """

    levelled: str
    gravity: np.ndarray
    down: np.ndarray
    off_deg: float
    sessions: dict

    @property
    def warns(self) -> bool:
        return self.off_deg > TOLERANCE_DEG

    def text(self) -> str:
        how = ("the instrument is levelled (--levelled)" if self.levelled == "given" else
               "every session's fitted base pose puts the instrument's down along one direction of the robot's base "
               "frame, as a levelled instrument's (say --not-levelled if it was not)")
        give = ", ".join(f"{x:.3g}" for x in _tidy(self.down))
        if not self.warns:
            return (f"the robot file's gravity agrees with the levelled instrument's down within "
                    f"{self.off_deg:.1f} deg ({how})")
        return (f"the robot file's gravity [{', '.join(f'{x:.3g}' for x in _tidy(self.gravity))}] is "
                f"{self.off_deg:.1f} deg from the instrument's down as the fitted base pose puts it ({how}): every "
                f"gravity torque, compliance and the mount's moment follow the robot file's; if the robot is mounted "
                f"as the data say, give [gravity] direction = [{give}] in the robot file (its base frame)")

    def to_dict(self) -> dict:
        return {"levelled": self.levelled, "robot_gravity": _tidy(self.gravity).tolist(),
                "instrument_down": _tidy(self.down).tolist(), "off_deg": self.off_deg, "warning": self.warns,
                "sessions_off_deg": self.sessions}


def _tidy(v: np.ndarray) -> np.ndarray:
    """A direction with its near-zero parts zero (a text to copy into a robot file)."""
    v = np.where(np.abs(v) < 5e-4, 0.0, v)
    return v + 0.0


def _angle(a: np.ndarray, b: np.ndarray) -> float:
    return math.degrees(math.acos(max(-1.0, min(1.0, float(a @ b)))))


def check_gravity(result: CalibrationResult, levelled: bool | None = None) -> GravityCheck | None:
    """The robot file's gravity against the instrument's down in the robot's base frame, as ``result``'s fitted
    base poses put it; ``levelled``: the instrument is levelled (True), is not (False), or infer it (None: two
    sessions or more whose downs agree within :data:`AGREE_DEG`). None where there is nothing to check (not
    levelled, or not inferred; a robot file without masses)."""
    robot = result.model.robot
    if levelled is False or max_mount_moment(robot) <= 0:
        return None
    names = result.sessions or [None]
    downs = {s: result.base_matrix(s)[:3, :3].T @ np.array([0.0, 0.0, -1.0]) for s in names}
    mean = np.mean(list(downs.values()), axis=0)
    mean /= np.linalg.norm(mean)
    if levelled is None and (len(names) < 2 or max(_angle(d, mean) for d in downs.values()) > AGREE_DEG):
        return None
    g = np.asarray(robot.gravity, float)
    g = g / np.linalg.norm(g)
    return GravityCheck("given" if levelled else "inferred", g, mean, _angle(g, mean),
                        {s or "": _angle(g, d) for s, d in downs.items()})


def warn_gravity(result: CalibrationResult, levelled: bool | None = None) -> GravityCheck | None:
    """:func:`check_gravity`, and a :class:`~casadical.errors.GravityWarning` where it disagrees."""
    check = check_gravity(result, levelled)
    if check is not None and check.warns:
        warnings.warn(check.text(), GravityWarning, stacklevel=2)
    return check
