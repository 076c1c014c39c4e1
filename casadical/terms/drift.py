"""Drift: the measured points move linearly in time (tracker or robot base settling, warming up)."""

from __future__ import annotations

import casadi as ca

from ..model.parameters import Parameter
from ..robot import Robot
from .base import ReferencedTerm, register


@register
class Drift(ReferencedTerm):
    """The measurement frame translates by ``v (t - t_ref)``.

    The time is the ``time_s`` column (seconds); a file without one has no
    drift, unless its rows are declared to be in time order at a known
    spacing (``--row-spacing-s``, :meth:`Measurements.with_row_times`): the
    row number is never taken for a time silently. A drift belongs to its
    measurement session: a calibration taken to other data (``calibrate
    CAL.json``) drops it.

    Parameters
    ----------
    t_ref : float
        Time at which the base pose holds; the calibration sets it to the
        mean of its data.
    """

    name = "drift"
    cause = "drift"
    covariates = ("time_s",)
    session = True

    def parameters(self, robot: Robot) -> list[Parameter]:
        # scale: 1 um per unit of time; bounds generous (1 mm/s)
        return [Parameter(f"drift_{k}", 0.0, "m/s", 1e-6, self.name, None, lower=-1e-3, upper=1e-3)
                for k in "xyz"]

    def base_offset(self, ctx):
        dt = ctx.cov["time_s"] - self.t_ref
        return ca.vertcat(*[ctx.p[f"drift_{k}"] * dt for k in "xyz"])
