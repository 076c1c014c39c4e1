"""Thermal expansion: link lengths grow linearly with temperature."""

from __future__ import annotations

from dataclasses import replace

from ..kinematics import Geometry
from ..parameters import Parameter
from ..robot import Robot
from .base import Context, ReferencedTerm, register


@register
class ThermalExpansion(ReferencedTerm):
    """Every length of the arm scales by ``1 + alpha (T - t_ref)``.

    Parameters
    ----------
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

    def parameters(self, robot: Robot) -> list[Parameter]:
        # aluminium 23e-6/K, steel 12e-6/K: bounds allow any plausible structure
        return [Parameter("thermal_alpha", 0.0, "1/K", 1e-5, self.name, None, lower=-1e-4, upper=1e-4)]

    def geometry(self, ctx: Context, geom: Geometry) -> Geometry:
        f = 1 + ctx.p["thermal_alpha"] * (ctx.cov["temperature_c"] - self.t_ref)
        return replace(geom, a=[x * f for x in geom.a], b=[x * f for x in geom.b],
                       d=[x * f for x in geom.d], tool=[x * f for x in geom.tool],
                       loop=[x * f for x in geom.loop])
