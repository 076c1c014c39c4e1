"""Straightness of a linear axis: its carriage off the straight line of its travel, across the axis."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..errors import ModelError
from ..parameters import Parameter
from ..robot import Robot
from ._base import Context, ErrorTerm, check_linear, legendre, linear_axes, register, travel
from ._cause import Cause, register_cause

#: the degrees of the Legendre polynomials of the position: the constant and the linear part of a straightness
#: are the geometry's (where the axis lies and where it points), so it starts at the bow
DEGREES = (2, 3)
#: the directions across the axis, in its frame (z along the travel)
DIRECTIONS = ("x", "y")
#: largest coefficient admitted (m): 2 mm of bow is a bent or badly laid rail, not a straightness error
MAX_STRAIGHTNESS = 2e-3


def axis_pairs(args: str, keys: tuple[str, ...], what: str) -> list[tuple[int, str]]:
    """``1`` (every key of joint 1) or ``1:x,2:y``: (joint, key) pairs of a model specification."""
    out = []
    for item in args.split(","):
        j, _, key = item.strip().partition(":")
        if key and key not in keys:
            raise ValueError(f"{what} {key!r}: expected one of {', '.join(keys)}")
        out += [(int(j), k) for k in ([key] if key else keys)]
    return out


class AxisTerm(ErrorTerm):
    """A linear axis' error of several kinds (directions, angles), each a smooth function of the position: the
    Legendre polynomials of the reading scaled by the axis' limits to [-1, 1], of :attr:`DEGREES`."""

    KEYS: tuple[str, ...] = ()
    DEGREES: tuple[int, ...] = ()
    WHAT = ""

    def __init__(self, joints=None, pairs=()):
        self.pairs = sorted({(int(j), str(k)) for j, k in pairs}) if pairs else None
        if self.pairs is not None:
            bad = [k for _, k in self.pairs if k not in self.KEYS]
            if bad:
                raise ModelError(f"{self.name}: {self.WHAT} {bad[0]!r}: expected one of {', '.join(self.KEYS)}")
        super().__init__(sorted({j for j, _ in self.pairs}) if self.pairs else joints)

    @classmethod
    def arguments(cls, args: str) -> dict:
        return {"pairs": axis_pairs(args, cls.KEYS, cls.WHAT)}

    def bind(self, robot: Robot) -> None:
        if self.joints is None:
            self.joints = [j for j in range(1, robot.n + 1) if robot.joints[j - 1].prismatic]
        bad = [j for j in self.joints if not 1 <= j <= robot.n]
        if bad:
            raise ModelError(f"term {self.name}: joints {bad} do not exist on {robot.name} (joints 1..{robot.n})")
        check_linear(self.name, self.joints, robot)
        if self.pairs is None:
            self.pairs = sorted((j, k) for j in self.joints for k in self.KEYS)

    def resolved(self, robot: Robot) -> list[tuple[int, str]]:
        """The (joint, kind) pairs on ``robot`` (before :meth:`bind` too: the superset's terms are not bound)."""
        if self.pairs is not None:
            return self.pairs
        joints = self.joints or [j for j in range(1, robot.n + 1) if robot.joints[j - 1].prismatic]
        return sorted((j, k) for j in joints for k in self.KEYS)

    def spec(self) -> str:
        if self.pairs is None or self.pairs == sorted((j, k) for j in self.joints for k in self.KEYS):
            return super().spec()
        return f"{self.name}[{','.join(f'{j}:{k}' for j, k in self.pairs)}]"

    def settings(self) -> dict:
        return {"pairs": [list(p) for p in self.pairs]} if self.pairs else {"joints": self.joints}

    def parameter_name(self, j: int, key: str, k: int) -> str:
        raise NotImplementedError

    def function(self, ctx: Context, j: int, key: str):
        """The error of kind ``key`` of axis ``j`` at the pose (m or rad)."""
        u = travel(ctx.robot, j, ctx.q[j - 1])
        return sum(ctx.p[self.parameter_name(j, key, k)] * legendre(k, u) for k in self.DEGREES)

    def slot(self, key: str) -> int:
        """Where the error of kind ``key`` goes in the carriage's change [dx, dy, dz, rx, ry, rz]."""
        raise NotImplementedError

    def geometry(self, ctx: Context, geom):
        carriage = dict(geom.carriage)
        for j, key in self.resolved(ctx.robot):
            change = list(carriage.get(j, [0.0] * 6))
            change[self.slot(key)] = change[self.slot(key)] + self.function(ctx, j, key)
            carriage[j] = change
        return replace(geom, carriage=carriage)


@register
class Straightness(AxisTerm):
    """Linear axis ``j``'s carriage stands ``e_x(u), e_y(u)`` off the straight line of its travel, across it.

    ``u`` is the reading scaled by the axis' limits to [-1, 1]; each direction ``e(u) = c2 P2(u) + c3 P3(u)``
    (Legendre polynomials: a bow and an S), parameters ``straight<j><x|y>_p<k>`` (m, at most 2 mm each). The
    directions are those of the axis' frame right after its travel (z along the travel, x the frame's x
    after ``theta``: the link's x in DH and MDH): the carriage, and everything it carries, moves so.

    Parameters
    ----------
    joints : list of int, optional
        The linear axes (default: every prismatic joint), each in both directions.
    pairs : list of (joint, direction)
        e.g. ``[(1, "x")]``; in a model specification ``straightness[1:x]`` (``straightness[1]``: both).
    """

    name = "straightness"
    cause = "straightness"
    weak_meaning = ("the straightness of linear axis {joints} is", "measure poses over more of {their} travel")
    superset_order = 6

    @classmethod
    def superset(cls, robot: Robot) -> list[ErrorTerm]:
        linear = linear_axes(robot)
        return [cls(joints=linear)] if linear else []
    KEYS = DIRECTIONS
    DEGREES = DEGREES
    WHAT = "direction"

    def parameter_name(self, j: int, key: str, k: int) -> str:
        return f"straight{j}{key}_p{k}"

    def parameters(self, robot: Robot) -> list[Parameter]:
        return [Parameter(self.parameter_name(j, d, k), 0.0, "m", 1e-5, self.name, j, lower=-MAX_STRAIGHTNESS,
                          upper=MAX_STRAIGHTNESS) for j, d in self.resolved(robot) for k in self.DEGREES]

    def slot(self, key: str) -> int:
        return DIRECTIONS.index(key)


def travel_curve(values, names: list[str]) -> np.ndarray:
    """A linear axis' straightness or carriage angle over its travel (201 points), from its Legendre coefficients
    (parameters ``..._p<degree>``)."""
    coef = np.zeros(4)
    for v, n in zip(values, names):
        coef[int(n.rsplit("_p", 1)[1])] += v
    return np.polynomial.legendre.legval(np.linspace(-1.0, 1.0, 201), coef)


class AxisStraightness(Cause):
    """A linear axis' carriage off its straight line, across the axis in x or y (:class:`Straightness`)."""

    name = "straightness"
    axis_shape = True
    needs = {"still_axis": "straightness"}
    order = 120
    varies_text = "move axis {j} over more of its travel"
    tell_apart = {
        "carriage_angle": "measure at each position of axis {j} with the arm stretched and folded: the carriage's "
                          "angle moves the point in proportion to the arm's reach, a straightness error by the same "
                          "amount at any reach",
        "straightness": "measure at each position of axis {j} with the tool at several heights and reaches",
    }

    def candidates(self, data) -> list:
        return [data.make(self.name, j, direction=d) for j in data.moving_axes for d in DIRECTIONS]

    def place(self, cand) -> str:
        return f"axis {cand.joint}, across it in {cand.direction}"

    def size(self, cand, values, stds, params, linear) -> str:
        return f"{np.ptp(travel_curve(values, [p.name for p in params])) * 1e3:.3g} mm over the travel"

    def unexplained_item(self, cand, values, linear) -> dict:
        v = np.array([values[n] for n in cand.parameter_names() if n in values])
        return {"what": f"a {cand.direction} straightness of the axis ({float(np.abs(v).sum()) * 1000.0:.3g} mm at "
                        "most)"}

    def words(self, cand, params, robot, data, linear) -> str:
        v = np.array([p.value for p in params])
        curve = travel_curve(v, [p.name for p in params])
        return (f"the carriage of axis {cand.joint} off its straight line in {cand.direction} by up to "
                f"{np.ptp(curve) * 1e3:.3g} mm over its travel (a bow and an S: "
                + ", ".join(f"{c * 1e3:+.3g}" for c in v) + " mm)")

    def figure(self, cand, data, model, params, linear) -> dict:
        return {"x": data.q[:, cand.joint - 1] * 1000.0, "xlabel": f"axis {cand.joint} position (mm)", "along": None}

    def parameter_names(self, cand) -> list[str]:
        return [f"straight{cand.joint}{cand.direction}_p{k}" for k in DEGREES]

    def terms(self, cands) -> list[ErrorTerm]:
        axis = sorted({(c.joint, c.direction) for c in self.mine(cands)})
        return [Straightness(pairs=axis)] if axis else []


STRAIGHTNESS = register_cause(AxisStraightness())
