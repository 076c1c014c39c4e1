"""Thermal expansion: link lengths grow linearly with temperature."""

from __future__ import annotations

from dataclasses import replace

from ..errors import ModelError
from ..model.kinematics import Geometry
from ..model.parameters import Parameter
from ..robot import Robot
from .base import Context, ReferencedTerm, register


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
