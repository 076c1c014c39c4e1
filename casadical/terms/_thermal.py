"""Thermal expansion: link lengths grow linearly with temperature."""

from __future__ import annotations

from dataclasses import replace

from .._format import relative
from ..errors import ModelError
from ..kinematics import Geometry
from ..parameters import Parameter
from ..robot import Robot
from ._base import Context, ErrorTerm, ReferencedTerm, register
from ._cause import Cause, register_cause


@register
class ThermalExpansion(ReferencedTerm):
    """Lengths of the arm grow with temperature: ``1 + alpha (T - t_ref)``.

    Without joints, one coefficient ``thermal_alpha`` scales every length
    (links, tool, loop). With joints (``thermal_expansion[2,3]``), each
    listed link has its own coefficient ``thermal_alpha<j>`` for its lengths
    (``a``, ``b``, ``d`` of that joint's row) and the rest does not grow:
    arms of mixed materials, or links heated by their own motors.

    Parameters
    ----------
    joints : list of int, optional
        Links with their own coefficient; None: one coefficient for all.
    t_ref : float
        Temperature (deg C) at which the geometric parameters hold; the
        calibration sets it to the mean of its data so they stay meaningful.
    """

    name = "thermal_expansion"
    aliases = ("thermal",)
    cause = "thermal_expansion"
    covariates = ("temperature_c",)
    superset_order = 9

    @classmethod
    def superset(cls, robot: Robot) -> list:
        """Every link's one coefficient and each link's own, their reference 0 (a model's temperature comes
        minus its own reference)."""
        return [cls(t_ref=0.0), cls(joints=list(range(1, robot.n + 1)), t_ref=0.0)]

    def __init__(self, joints=None, t_ref: float = 20.0):
        super().__init__(None, t_ref)
        self.joints = None if joints is None else sorted({int(j) for j in joints})

    def bind(self, robot: Robot) -> None:
        bad = [j for j in self.joints or [] if not 1 <= j <= robot.n]
        if bad:
            raise ModelError(f"term thermal_expansion: links {bad} do not exist on {robot.name} "
                             f"(links 1..{robot.n})")

    def settings(self) -> dict:
        return {"t_ref": self.t_ref, "joints": self.joints}

    def parameters(self, robot: Robot) -> list[Parameter]:
        # aluminium 23e-6/K, steel 12e-6/K: bounds allow any plausible structure
        if self.joints is None:
            return [Parameter("thermal_alpha", 0.0, "1/K", 1e-5, self.name, None, lower=-1e-4, upper=1e-4)]
        return [Parameter(f"thermal_alpha{j}", 0.0, "1/K", 1e-5, self.name, j, lower=-1e-4, upper=1e-4)
                for j in self.joints]

    def geometry(self, ctx: Context, geom: Geometry) -> Geometry:
        dT = ctx.cov["temperature_c"] - self.t_ref
        if self.joints is None:
            f = 1 + ctx.p["thermal_alpha"] * dT
            return replace(geom, a=[x * f for x in geom.a], b=[x * f for x in geom.b],
                           d=[x * f for x in geom.d], tool=[x * f for x in geom.tool],
                           loop=[x * f for x in geom.loop])
        f = [1 + ctx.p[f"thermal_alpha{j}"] * dT if j in self.joints else 1 for j in range(1, ctx.robot.n + 1)]
        return replace(geom, a=[x * k for x, k in zip(geom.a, f)], b=[x * k for x, k in zip(geom.b, f)],
                       d=[x * k for x, k in zip(geom.d, f)])


class Expansion(Cause):
    """Link lengths that grow with the temperature: every link's one coefficient, or a link's own
    (:class:`ThermalExpansion`)."""

    name = "thermal_expansion"
    needs = {"temperature": "thermal_expansion", "temperature_range": "thermal_expansion"}
    short = "thermal"
    order = 60
    joint_word = "link"
    tell_apart = {
        "thermal_expansion": "measure while the arm warms up, with the links' temperatures if possible: links that "
                             "grow differently need their own coefficients",
        "drift": "measure in random pose order while the temperature changes: thermal growth scales with the arm's "
                 "reach, drift of the measurement frame does not",
    }

    def candidates(self, data) -> list:
        if not data.temperature_varies:
            return []
        return [data.make(self.name)] + [data.make(self.name, j) for j, jt in enumerate(data.robot.joints, start=1)
                                         if abs(jt.a) + abs(jt.d) + abs(jt.b or 0.0) > 0]

    def place(self, cand) -> str:
        return "every link" if cand.joint is None else f"link {cand.joint}"

    def size(self, cand, values, stds, params, linear) -> str:
        return f"{values[0] * 1e6:.2f} ppm/K{relative(stds[0], values[0])}"

    def words(self, cand, params, robot, data, linear) -> str:
        where = "every length" if cand.joint is None else f"the lengths of link {cand.joint}"
        return f"expansion {params[0].value * 1e6:.2f} ppm/K of {where}"

    def figure(self, cand, data, model, params, linear) -> dict:
        return {"x": data.get("temperature_c"), "xlabel": "temperature (deg C)", "along": None}

    def parameter_names(self, cand) -> list[str]:
        return ["thermal_alpha" if cand.joint is None else f"thermal_alpha{cand.joint}"]

    def terms(self, cands) -> list[ErrorTerm]:
        mine = self.mine(cands)
        links = sorted({c.joint for c in mine if c.joint is not None})
        return (([ThermalExpansion()] if any(c.joint is None for c in mine) else [])
                + ([ThermalExpansion(joints=links)] if links else []))


THERMAL_EXPANSION = register_cause(Expansion())
