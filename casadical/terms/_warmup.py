"""Warm-up: after the start of a session the measured points settle, exponentially, to where they stay."""

from __future__ import annotations

import math
from dataclasses import replace

import casadi as ca
import numpy as np

from ..errors import ModelError
from ..parameters import Parameter
from ..robot import Robot
from ._base import ErrorTerm, ReferencedTerm, register
from ._cause import Cause, register_cause


@register
class Warmup(ReferencedTerm):
    """The measurement frame is shifted by ``w exp(-(t - t_0) / T)`` at time ``t`` of a session.

    At the start of a session the robot (motors, gears, base) and the
    tracker are still warming up: the measured points of the first poses
    stand off where they settle, and the offset dies away with the time
    constant ``T`` of a first-order thermal response. ``t_0`` is the time of
    the session's first pose (``time_s``); the fitted ``w`` (three
    components, measurement frame) is the offset then. Linear in ``w``:
    the time constant is a setting (the diagnosis chooses it among a few,
    as a harmonic of a gear error). Like a drift it belongs to its
    measurement session: a calibration taken to other data drops it.

    A file without ``time_s`` has no warm-up, unless its rows are declared
    to be in time order at a known spacing (``--row-spacing-s``): the row
    number is never taken for a time silently.

    Parameters
    ----------
    time_constant_s : float
        ``T`` (s); in a model specification ``warmup[600]``.
    t_ref : float
        ``t_0``; the calibration sets it to the first time of its data (of
        its session, for ``warmup[T]@S``).
    """

    name = "warmup"
    cause = "warmup"
    covariates = ("time_s",)
    session = True

    def __init__(self, joints=None, t_ref: float = 0.0, time_constant_s: float = 600.0):
        super().__init__(None, t_ref)
        self.time_constant_s = float(time_constant_s)
        if not (math.isfinite(self.time_constant_s) and self.time_constant_s > 0):
            raise ModelError(f"warmup: the time constant must be a positive number of seconds, got "
                             f"{time_constant_s!r} (e.g. warmup[600])")

    @classmethod
    def arguments(cls, args: str) -> dict:
        """``warmup[600]``: the time constant in seconds."""
        try:
            return {"time_constant_s": float(args)}
        except ValueError as e:
            raise ModelError(f"warmup takes its time constant in seconds, e.g. warmup[600], got [{args}]") from e

    def reference_value(self, times: np.ndarray) -> float:
        """The warm-up starts at the first pose."""
        return float(np.min(times))

    def spec(self) -> str:
        return f"{self.name}[{self.time_constant_s:g}]"

    def settings(self) -> dict:
        return {"t_ref": self.t_ref, "time_constant_s": self.time_constant_s}

    def parameters(self, robot: Robot) -> list[Parameter]:
        # scale 10 um; bounds generous (1 cm)
        return [Parameter(f"warmup_{k}", 0.0, "m", 1e-5, self.name, None, lower=-0.01, upper=0.01) for k in "xyz"]

    def base_offset(self, ctx):
        g = ca.exp(-ca.fmax(ctx.cov["time_s"] - self.t_ref, 0) / self.time_constant_s)
        return ca.vertcat(*[ctx.p[f"warmup_{k}"] * g for k in "xyz"])


def decay(times: np.ndarray, t0: float, time_constant_s: float) -> np.ndarray:
    """``exp(-(t - t0) / T)`` (1 before ``t0``): the warm-up's shape at ``times``."""
    return np.exp(-np.maximum(np.asarray(times, float) - t0, 0.0) / time_constant_s)


class WarmUp(Cause):
    """An offset of the first poses dying away in time (:class:`Warmup`): of its session by nature; one cause
    scanned over a grid of time constants."""

    name = "warmup"
    explains_set_aside = ("order",)
    plannable = False
    analytic = True
    checks = ("versus_drift",)
    rival = "drift"
    unjudged_folds = frozenset({"time"})
    needs = {"time": "warmup"}
    short = "warm-up"
    tier = 3
    order = 80
    of_session = True
    session_part = "the warm-up"
    tell_apart = {
        "drift": "measure for longer, or repeat the first poses at the end: a warm-up settles, a drift goes on",
        "warmup": "measure for longer, or repeat the first poses at the end: the time constant shows in how fast the "
                  "first poses' offset dies away",
    }

    def family(self, cand):
        return replace(cand, time_constant=None)

    def candidates(self, data) -> list:
        """Each session's (or the only one's) over its grid of time constants, until one is accepted."""
        mine = [a for a in data.accepted if a.kind is self]
        if not data.timed or any(a.session is None for a in mine):
            return []
        return [data.make(self.name, session=s, time_constant=T) for s in data.scopes
                if not any(a.session == s for a in mine) for T in data.warmups.get(s, [])]

    def words(self, cand, params, robot, data, linear) -> str:
        v = np.array([p.value for p in params]) * 1000
        return (f"the first poses stand {np.linalg.norm(v):.3g} mm off (x, y, z: " + ", ".join(f"{c:+.3g}" for c in v)
                + f" mm), dying away with a time constant of {cand.time_constant:.3g} s")

    def figure(self, cand, data, model, params, linear) -> dict:
        t = data.get("time_s")
        x, xlabel = (t, "time (s)") if t is not None else (data.rows, "row (measurement order)")
        return {"x": x, "xlabel": xlabel, "along": "warm-up offset"}

    def analytic_term(self, cand):
        return Warmup()

    def analytic_column(self, cand, k, data, JA, t0, robot):
        col = np.zeros((len(data), 3))
        col[:, k] = decay(data.get("time_s"), t0[cand.session], cand.time_constant)
        return col

    def parameter_names(self, cand) -> list[str]:
        return ["warmup_x", "warmup_y", "warmup_z"]

    def terms(self, cands) -> list[ErrorTerm]:
        return [Warmup(time_constant_s=c.time_constant) for c in self.mine(cands)][:1]


WARMUP = register_cause(WarmUp())
