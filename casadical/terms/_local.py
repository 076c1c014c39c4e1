"""A term of one measurement session only (``drift@B``, ``joint_periodic[1:17]@A``)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..errors import ModelError
from ..parameters import Parameter
from ..robot import Robot
from ._base import Context, ErrorTerm, ReferencedTerm
from ._sessions import indicator


class SessionLocal(ErrorTerm):
    """``inner`` acting at the poses of session ``session`` only, with parameters of its own (``<name>@<session>``).

    What the diagnosis finds in one session and not in the others (a
    drift of that day, structure that moves with the tracker) is a property
    of the session, not of the robot: it is fitted as such a term, reported
    with ``scope: "session"``, and never carried to other data (a transfer
    drops it; an export never holds it). Terms that act through joint
    offsets, the measured point or the robot frame can be made local; a
    change of the geometry (thermal expansion) cannot, unless the term
    switches its change off itself where the context's ``gate`` is 0
    (``gated``: a user term's frame, tool and base effects).

    Parameters
    ----------
    inner : ErrorTerm
    session : str
    """

    session = True

    def __init__(self, inner: ErrorTerm, session: str):
        if type(inner).geometry is not ErrorTerm.geometry and not getattr(inner, "gated", False):
            raise ModelError(f"{inner.name} changes the geometry: it cannot be a term of one session only")
        super().__init__(inner.joints)
        self.inner, self.session_name = inner, str(session)
        self.name, self.cause = inner.name, inner.cause

    @property
    def covariates(self) -> tuple[str, ...]:  # type: ignore[override]
        return tuple(self.rename(c) for c in self.inner.covariates) + (indicator(self.session_name),)

    def rename(self, covariate: str) -> str:
        """A covariate of the inner term's own (``gp_gate``) is this session's (``gp_gate@B``)."""
        return f"{covariate}@{self.session_name}" if covariate in getattr(self.inner, "own_covariates", ()) else \
            covariate

    def covariate_values(self, data) -> dict:
        """The inner term's covariates; of a term whose values at a pose depend on that pose alone
        (``pose_wise``: a process's gate), made at the session's poses only (0 elsewhere, where the
        session's indicator switches the term off): a gate is a Gaussian process's predictive variance,
        0.1 ms a pose."""
        if not (getattr(self.inner, "pose_wise", False) and data.sessions is not None):
            return {self.rename(k): v for k, v in self.inner.covariate_values(data).items()}
        at = np.flatnonzero(data.sessions == self.session_name)
        out = {}
        for k, v in self.inner.covariate_values(data.subset(at)).items():
            out[self.rename(k)] = full = np.zeros(len(data))
            full[at] = v
        return out

    @property
    def t_ref(self) -> float:
        return self.inner.t_ref

    @t_ref.setter
    def t_ref(self, value: float) -> None:
        self.inner.t_ref = value

    @property
    def referenced(self) -> bool:
        """Driven by a covariate relative to a reference (a drift): referenced to its session's poses."""
        return isinstance(self.inner, ReferencedTerm)

    def bind(self, robot: Robot) -> None:
        self.inner.bind(robot)
        self.joints = self.inner.joints

    def spec(self) -> str:
        return f"{self.inner.spec()}@{self.session_name}"

    def settings(self) -> dict:
        return self.inner.settings()

    def suffix(self, name: str) -> str:
        return f"{name}@{self.session_name}"

    def parameters(self, robot: Robot) -> list[Parameter]:
        return [replace(p, name=self.suffix(p.name)) for p in self.inner.session_parameters(robot)]

    def _local(self, ctx: Context, torques: bool = True) -> Context:
        if torques:
            ctx.torques()    # computed once, shared with the inner term's view
        names = [p.name for p in self.inner.parameters(ctx.robot)]
        return replace(ctx, p={**ctx.p, **{n: ctx.p[self.suffix(n)] for n in names}},
                       cov={**ctx.cov, **{c: ctx.cov[self.rename(c)] for c in self.inner.covariates}})

    def geometry(self, ctx: Context, geom):
        if type(self.inner).geometry is ErrorTerm.geometry:
            return geom
        return self.inner.geometry(replace(self._local(ctx, False), gate=ctx.cov[indicator(self.session_name)]), geom)

    def joint_offsets(self, ctx: Context) -> dict:
        h = ctx.cov[indicator(self.session_name)]
        return {j: h * off for j, off in self.inner.joint_offsets(self._local(ctx)).items()}

    def base_offset(self, ctx: Context):
        off = self.inner.base_offset(self._local(ctx))
        return None if off is None else ctx.cov[indicator(self.session_name)] * off

    def robot_frame_offset(self, ctx: Context):
        off = self.inner.robot_frame_offset(self._local(ctx))
        return None if off is None else ctx.cov[indicator(self.session_name)] * off

    def base_tilt(self, ctx: Context):
        tilt = self.inner.base_tilt(self._local(ctx))
        return None if tilt is None else ctx.cov[indicator(self.session_name)] * tilt
