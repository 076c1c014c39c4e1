"""The roll, pitch and yaw of a linear axis' carriage as it travels."""

from __future__ import annotations

import numpy as np

from ..parameters import Parameter
from ..robot import Robot
from ._base import ErrorTerm, linear_axes, register
from ._cause import Cause, register_cause
from ._straightness import AxisTerm, travel_curve

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
    weak_meaning = ("the carriage's angles of linear axis {joints} are", "measure poses over more of {their} travel, "
                    "the arm reaching out along the carriage's axes")
    superset_order = 7

    @classmethod
    def superset(cls, robot: Robot) -> list:
        linear = linear_axes(robot)
        return [cls(joints=linear)] if linear else []
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


class CarriageTurn(Cause):
    """A linear axis' carriage turning in roll, pitch or yaw as it travels (:class:`CarriageAngle`)."""

    name = "carriage_angle"
    axis_shape = True
    needs = {"still_axis": "carriage_angle"}
    short = "carriage"
    order = 130
    varies_text = "move axis {j} over more of its travel"
    tell_apart = {
        "carriage_angle": "measure at each position of axis {j} with the arm reaching along each of the carriage's "
                          "axes",
    }

    def candidates(self, data) -> list:
        return [data.make(self.name, j, angle=a) for j in data.moving_axes for a in ANGLES]

    def place(self, cand) -> str:
        return f"axis {cand.joint}'s carriage, {cand.angle}"

    def size(self, cand, values, stds, params, linear) -> str:
        return f"{np.ptp(travel_curve(values, [p.name for p in params])) * 1e3:.3g} mrad over the travel"

    def unexplained_item(self, cand, values, linear) -> dict:
        v = np.array([values[n] for n in cand.parameter_names() if n in values])
        return {"what": f"a {cand.angle} of its carriage ({float(np.abs(v).sum()) * 1000.0:.3g} mrad at most)"}

    def words(self, cand, params, robot, data, linear) -> str:
        v = np.array([p.value for p in params])
        curve = travel_curve(v, [p.name for p in params])
        return (f"the carriage of axis {cand.joint} turns in {cand.angle} by up to {np.ptp(curve) * 1e3:.3g} mrad "
                "over its travel (a slope and a bow: " + ", ".join(f"{c * 1e3:+.3g}" for c in v) + " mrad)")

    def figure(self, cand, data, model, params, linear) -> dict:
        return {"x": data.q[:, cand.joint - 1] * 1000.0, "xlabel": f"axis {cand.joint} position (mm)", "along": None}

    def parameter_names(self, cand) -> list[str]:
        return [f"{cand.angle}{cand.joint}_p{k}" for k in DEGREES]

    def terms(self, cands) -> list[ErrorTerm]:
        axis = sorted({(c.joint, c.angle) for c in self.mine(cands)})
        return [CarriageAngle(pairs=axis)] if axis else []


CARRIAGE_ANGLE = register_cause(CarriageTurn())
