"""The GP compensator (one per session): a Gaussian process of the residual, applied where it knows."""

from __future__ import annotations

from collections.abc import Iterator

import casadi as ca
import numpy as np

from .._format import gain_words
from ..errors import ModelError
from ..robot import Robot
from ._base import Context, ErrorTerm, register
from ._cause import Cause, register_cause
from ._local import SessionLocal


@register
class GPCompensator(ErrorTerm):
    """What the named causes leave, learnt from a session's poses by a Gaussian process, where it knows.

    The process (:class:`casadical.compensators._gp.ResidualGP`) maps the
    joint readings to the residual in the robot base frame; it is fitted to
    a calibration's residuals and then frozen (no parameters of its own).
    Its predictive uncertainty says where it knows: at a pose far from the
    poses it learnt from it returns to its prior, and its correction shrinks
    with it (the covariate ``gp_gate``, the share of its posterior mean it
    applies, :meth:`~casadical.compensators._gp.ResidualGP.weight`: 1 near the
    poses it learnt from, 0 where it knows nothing, made from the poses
    themselves), so that there the physical model stands alone.

    It belongs to the measurement session it was learnt in (``session``):
    structure that no named cause explains is mostly of that session (the
    tracker's own errors, that day's state of the robot), so a transfer
    drops it (unless asked to keep it) and an export never holds it.

    Parameters
    ----------
    gp : ResidualGP or dict, optional
        The fitted process or its :meth:`~ResidualGP.to_dict`; without one
        the term adds nothing (``calibrate`` fits it).
    """

    name = "gp_compensator"
    aliases = ("gp",)
    cause = "unexplained"
    is_cause = False
    session = True
    #: covariates of its own (a term of one session renames them, so that each session's process has its own)
    own_covariates = ("gp_gate",)
    covariates = ("gp_gate",)
    #: its covariate at a pose depends on that pose alone (a term of one session makes it at its poses only)
    pose_wise = True

    def __init__(self, joints=None, gp=None):
        super().__init__(None)
        if isinstance(gp, dict):
            from ..compensators._gp import ResidualGP
            from ..errors import InputError
            try:
                gp = ResidualGP.from_dict(gp)
            except InputError as e:
                raise ModelError(f"gp_compensator: {e}") from e
        self.gp = gp

    def spec(self) -> str:
        return self.name

    def settings(self) -> dict:
        return {"gp": self.gp.to_dict() if self.gp is not None else None}

    def bind(self, robot: Robot) -> None:
        super().bind(robot)
        if self.gp is not None and self.gp.X.shape[1] != robot.n:
            raise ModelError(f"gp_compensator: the process reads {self.gp.X.shape[1]} joints, {robot.name} has "
                             f"{robot.n}")

    def robot_frame_offset(self, ctx: Context):
        if self.gp is None:
            return None
        return ctx.cov["gp_gate"] * self.gp.casadi(ca.vertcat(*[ctx.q[i] for i in range(ctx.robot.n)]))

    def covariate_values(self, data) -> dict:
        """``gp_gate``: the share of its posterior mean the process applies at each pose (its
        :meth:`~casadical.compensators._gp.ResidualGP.weight`)."""
        if self.gp is None:
            return {"gp_gate": np.zeros(len(data))}
        return {"gp_gate": self.gp.weight(data.q)}


def fitted_processes(terms, data) -> Iterator[tuple]:
    """Each fitted GP compensator among a model's ``terms``, with the rows of ``data`` it applies to: every row,
    or those of its session (none where the data name no sessions)."""
    for t in terms:
        inner = t.inner if isinstance(t, SessionLocal) else t
        if inner.name != "gp_compensator" or inner.gp is None:
            continue
        if not isinstance(t, SessionLocal):
            yield inner.gp, np.arange(len(data))
        else:
            yield inner.gp, (np.flatnonzero(data.sessions == t.session_name) if data.sessions is not None
                             else np.zeros(0, int))


class Unexplained(Cause):
    """Structure no named cause explains: taken by the GP compensator (no joint), or kept out of the model and
    located (``unexplained`` of a joint, or where the structure screen found it)."""

    name = "unexplained"
    unexplained = True

    def label(self, cand, short: bool) -> str | None:
        return "GP compensator" if short and cand.joint is None else None

    def step_label(self, cand) -> str:
        return "+ GP compensator"

    def long_label(self, finding) -> str:
        return "unexplained structure" + (f" ({finding.where})" if finding.where else "")

    def finding_label(self, finding) -> str:
        j, s = finding.candidate.joint, finding.candidate.session
        own = f" @{s}" if s is not None and not finding.in_model else ""
        return "GP compensator" if finding.in_model else (f"unexplained j{j}" if j else "unexplained") + own

    def where(self, cand, finding) -> str:
        if finding.in_model:
            sessions = [s for s in (finding.holds_up or {}).get("length_scales_deg", {}) if s]
            return "what the causes leave" + (f", sessions {', '.join(sessions)}" if len(sessions) > 1 else "")
        if finding.structure:
            return structure_where(finding.structure, cand.joint)
        return f"joint {cand.joint}" if cand.joint else ""

    def finding_size(self, finding, final) -> str:
        hu = finding.holds_up or {}
        if finding.in_model:
            k, n = hu.get("validation_known", [None, None])
            return f"applies at {k} of {n} validation poses" if n else "a Gaussian process per session"
        if finding.structure:
            return f"{finding.structure['size_mm']:.4f} mm on validation"
        items = hu.get("structures", [])
        if not items:
            return ""
        big = max(items, key=lambda x: x.get("amplitude_arcsec", 0.0))
        return big.get("what", "") + (f" and {len(items) - 1} more" if len(items) > 1 else "")

    def action(self, finding) -> str:
        if finding.in_model:
            return ("applies in this session where it knows; compensate and predict use it; a transfer to another "
                    "session drops it (scope session)")
        if finding.structure:
            instrument = finding.structure["covariate"] in ("azimuth", "elevation", "distance")
            return (f"a cause no catalogue holds (a flexible term would give {gain_words(finding.potential_gain_mm)} "
                    "here): state it as a term of your own (the finding's term in the JSON report is one to start "
                    "from) and diagnose again (docs/guide.md, 'When the report says unexplained'); plan-poses "
                    "REPORT.json plans the poses that tell its form"
                    + ("; a session with the instrument placed elsewhere tells the instrument's error from the "
                       "robot's" if instrument else ""))
        return (f"not in the model (it would give {gain_words(finding.potential_gain_mm)} here): measure joint "
                f"{finding.candidate.joint} over a wider range or in another session to tell")


def structure_where(structure: dict, joint: int | None) -> str:
    """Where structure the screen found lives, short: ``joint 4's angle, with q3``."""
    effect = {"angle": f"joint {joint}'s angle", "position": f"axis {joint}'s position",
              "tilt": f"joint {joint}'s axis" if joint else "the base's tilt",
              "point_base": "point, base frame",
              "point_measurement": "point, measurement frame"}.get(structure["effect"], structure["effect"])
    return f"{effect}, with {structure['covariate']}" + (f", in session {structure['session']} only"
                                                         if structure.get("session") else "")


UNEXPLAINED = register_cause(Unexplained())
