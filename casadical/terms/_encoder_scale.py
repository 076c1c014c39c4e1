"""Encoder (gear ratio) scale error: offset proportional to the reading."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from .._format import relative
from ..parameters import Parameter
from ..robot import Robot
from ._base import Context, ErrorTerm, register
from ._cause import Cause, register_cause


@register
class EncoderScale(ErrorTerm):
    """Joint ``j`` turns by ``(1 + s_j) q_j`` instead of ``q_j``.

    On a linear axis (a prismatic joint) the carriage travels ``(1 + s_j) q_j``: the scale error of ISO 230-1,
    ``s_j`` metres per metre of travel (reports say mm per m); its zero is the reading's zero, whose offset the
    geometry's ``d`` takes.
    """

    name = "encoder_scale"
    cause = "encoder_scale"
    bound_meaning = {"escale": {"lower": " (a scale error beyond 1 % is not an encoder's)",
                                "upper": " (a scale error beyond 1 % is not an encoder's)"}}
    weak_meaning = ("the encoder scale of {joints} is", "measure poses over more of {their} range")
    superset_order = 3
    session_local = True

    @classmethod
    def superset(cls, robot: Robot) -> list[ErrorTerm]:
        return [cls(joints=list(range(1, robot.n + 1)))]

    def parameters(self, robot: Robot) -> list[Parameter]:
        return [Parameter(f"escale{j}", 0.0, "1", 1e-4, self.name, j, lower=-0.01, upper=0.01)
                for j in self.joints]

    def joint_offsets(self, ctx: Context) -> dict:
        return {j: ctx.p[f"escale{j}"] * ctx.q[j - 1] for j in self.joints}


class Scale(Cause):
    """A joint angle error proportional to the reading (:class:`EncoderScale`)."""

    name = "encoder_scale"
    unchecked_by = "reading"
    own_variable = "q"
    first_order = True
    of_own_reading = True
    checks = ("reading_halves",)
    needs = {"still_axis": "encoder_scale", "still": "encoder_scale"}
    order = 40
    varies_text = "move joint {j} over a wider range"
    tell_apart = {
        "joint_periodic": "measure joint {j} over a wider range (more than half a turn): a scale error grows with the "
                          "angle while a first harmonic turns back",
    }

    def candidates(self, data) -> list:
        return [data.make(self.name, j) for j in data.revolute + data.moving_axes]

    def size(self, cand, values, stds, params, linear) -> str:
        if linear:
            return f"{values[0] * 1e3:.3g} mm per m{relative(stds[0], values[0])}"
        return f"{values[0] * 1e6:.0f} ppm{relative(stds[0], values[0])}"

    def unexplained_item(self, cand, values, linear) -> dict:
        v = values[cand.parameter_names()[0]]
        item = {"trend_ppm": v * 1e6, "what": f"a trend along the joint's reading ({v * 1e6:.0f} ppm)"}
        if linear:
            item["what"] = f"a trend along the axis' position ({v * 1e3:.3g} mm per m)"
        return item

    def words(self, cand, params, robot, data, linear) -> str:
        if linear:
            return (f"scale error {params[0].value * 1e3:.4g} mm per m of travel of axis {cand.joint} "
                    f"(std {params[0].std * 1e3:.2g})")
        return f"scale error {params[0].value * 1e6:.1f} ppm"

    def figure(self, cand, data, model, params, linear) -> dict:
        j = cand.joint
        q = data.q[:, j - 1]
        value = params[cand.parameter_names()[0]].value
        if linear:
            return {"x": q * 1000.0, "xlabel": f"axis {j} position (mm)", "effect": value * q}
        return {"x": np.degrees(q), "xlabel": f"joint {j} reading (deg)", "effect": value * q}

    def question(self, cand) -> tuple[list, str]:
        where = f" in session {cand.session}" if cand.session is not None else ""
        return ([cand, replace(cand, cause="joint_periodic", harmonic=1)],
                f"joint {cand.joint}{where}: a trend along the reading: encoder scale or a first harmonic?")

    def parameter_names(self, cand) -> list[str]:
        return [f"escale{cand.joint}"]

    def terms(self, cands) -> list[ErrorTerm]:
        joints = sorted({c.joint for c in self.mine(cands)})
        return [EncoderScale(joints=joints)] if joints else []


ENCODER_SCALE = register_cause(Scale())
