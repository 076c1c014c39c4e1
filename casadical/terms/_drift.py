"""Drift: the measured points move linearly in time (tracker or robot base settling, warming up)."""

from __future__ import annotations

import math

import casadi as ca
import numpy as np

from .._format import g3, relative
from ..parameters import Parameter
from ..robot import Robot
from ._base import ErrorTerm, ReferencedTerm, register
from ._cause import Cause, register_cause


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
    superset_order = 11
    session_local = True

    @classmethod
    def superset(cls, robot: Robot) -> list:
        return [cls()]
    covariates = ("time_s",)
    session = True

    def fitted_causes(self, names, joint_of, where) -> list:
        return [(None, names, f"drift{where}")]

    def parameters(self, robot: Robot) -> list[Parameter]:
        # scale: 1 um per unit of time; bounds generous (1 mm/s)
        return [Parameter(f"drift_{k}", 0.0, "m/s", 1e-6, self.name, None, lower=-1e-3, upper=1e-3)
                for k in "xyz"]

    def base_offset(self, ctx):
        dt = ctx.cov["time_s"] - self.t_ref
        return ca.vertcat(*[ctx.p[f"drift_{k}"] * dt for k in "xyz"])


class FrameDrift(Cause):
    """The measurement frame translating in time (:class:`Drift`): of its session by nature."""

    name = "drift"
    explains_set_aside = ("order",)
    checks = ("time_halves",)
    needs = {"time": "drift"}
    tier = 3
    order = 70
    of_session = True
    session_part = "the instrument's set-up"

    def candidates(self, data) -> list:
        return [data.make(self.name, session=s) for s in data.scopes] if data.timed else []

    def place(self, cand) -> str:
        return "measurement frame"

    def size(self, cand, values, stds, params, linear) -> str:
        speed = float(np.linalg.norm(values))
        std = math.sqrt(((values * stds) ** 2).sum()) / speed if speed > 0 else math.nan
        return f"{g3(speed * 1e6)} um/s{relative(std, speed)}"

    def words(self, cand, params, robot, data, linear) -> str:
        v = np.array([p.value for p in params]) * 1e6
        return (f"the measured points move {np.linalg.norm(v):.3g} um per s (x, y, z: "
                + ", ".join(f"{c:+.3g}" for c in v) + ")")

    def figure(self, cand, data, model, params, linear) -> dict:
        t = data.get("time_s")
        x, xlabel = (t, "time (s)") if t is not None else (data.rows, "row (measurement order)")
        return {"x": x, "xlabel": xlabel, "along": "drift"}

    def parameter_names(self, cand) -> list[str]:
        return ["drift_x", "drift_y", "drift_z"]

    def terms(self, cands) -> list[ErrorTerm]:
        return [Drift()] if self.mine(cands) else []


DRIFT = register_cause(FrameDrift())
