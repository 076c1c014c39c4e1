"""The roll, pitch and yaw of a linear axis' carriage as it travels."""

from __future__ import annotations

from ..model.parameters import Parameter
from ..robot import Robot
from .base import register
from .straightness import AxisTerm

#: the degrees of the Legendre polynomials of the position: a constant angle is the geometry's (the frame after
#: the axis), a slope and a bow are not
DEGREES = (1, 2)
#: the carriage's angles: roll about the travel (the axis frame's z), pitch about its x, yaw about its y
ANGLES = ("roll", "pitch", "yaw")
#: where each goes in a carriage's change [dx, dy, dz, rx, ry, rz]
SLOTS = {"roll": 5, "pitch": 3, "yaw": 4}
#: largest coefficient admitted (rad): 2 mrad is a carriage coming loose, not a guide's error
MAX_ANGLE = 2e-3


@register
class CarriageAngle(AxisTerm):
    """Linear axis ``j``'s carriage turns by ``roll(u), pitch(u), yaw(u)`` as it travels (ISO 230-1's angular
    errors of a linear axis).

    ``u`` is the reading scaled by the axis' limits to [-1, 1]; each angle ``c1 P1(u) + c2 P2(u)`` (Legendre
    polynomials: a slope and a bow), parameters ``<roll|pitch|yaw><j>_p<k>`` (rad, at most 2 mrad each). Roll
    turns about the travel (the axis frame's z right after its travel), pitch about that frame's x, yaw about its
    y; the turn is about the carriage frame's origin and everything the carriage carries turns with it.

    Parameters
    ----------
    joints : list of int, optional
        The linear axes (default: every prismatic joint), each with its three angles.
    pairs : list of (joint, angle)
        e.g. ``[(1, "pitch")]``; in a model specification ``carriage_angle[1:pitch]`` (``carriage_angle[1]``:
        all three).
    """

    name = "carriage_angle"
    cause = "carriage_angle"
    KEYS = ANGLES
    DEGREES = DEGREES
    WHAT = "angle"

    def parameter_name(self, j: int, key: str, k: int) -> str:
        return f"{key}{j}_p{k}"

    def parameters(self, robot: Robot) -> list[Parameter]:
        return [Parameter(self.parameter_name(j, a, k), 0.0, "rad", 1e-5, self.name, j, lower=-MAX_ANGLE,
                          upper=MAX_ANGLE) for j, a in self.resolved(robot) for k in self.DEGREES]

    def slot(self, key: str) -> int:
        return SLOTS[key]
