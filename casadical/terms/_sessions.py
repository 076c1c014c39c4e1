"""Measurement sessions: a base pose per session (and a tool per session where the probe was re-mounted)."""

from __future__ import annotations

import casadi as ca
import numpy as np

from ..errors import DataFileError, ModelError
from ..parameters import Parameter
from ..robot import Robot
from ._base import Context, ErrorTerm, register
from ._geometric import ANGLE_SCALE, LENGTH_BOX, LENGTH_SCALE

#: the per-pose covariates of the reference pose of a pose's session (rotation row-major, translation)
REFERENCE = tuple(f"ref{k}" for k in range(12))
BASE = ("x", "y", "z", "roll", "pitch", "yaw")


def indicator(name: str) -> str:
    """The covariate that is 1 at the poses of session ``name``, 0 elsewhere."""
    return f"session@{name}"


@register
class SessionFrames(ErrorTerm):
    """Several measurement sessions of one robot: each has its own base pose, and its own tool if asked.

    The first session is the primary one: its base pose is the geometric
    term's ``base_*`` (and the calibration's ``base0``), its tool the
    geometric ``tool_*``. Each other session ``s`` has its own base pose
    ``base_*@s``, a deviation from its own reference pose (found by the
    closed-form alignment of that session's poses, like ``base0``), and,
    where the probe was re-mounted (``tools``), its own ``tool_*@s``.
    Everything else (the robot's geometry and every other term) is shared.

    The session of a pose enters the model as covariates: ``session@<s>``
    (1 at the poses of session ``s``) and ``ref0..ref11`` (that session's
    reference pose). Poses of no known session (a file without session
    names) are the primary session's.

    Parameters
    ----------
    names : list of str
        Every session, the primary one first.
    tools : list of str
        Sessions (other than the primary) with their own tool.
    references : dict of str to list of 12 float
        Reference pose of each session other than the primary (rotation
        row-major, translation in m); set by the calibration.
    """

    name = "sessions"
    cause = "geometric"
    is_cause = False

    def superset_member(self) -> bool:
        """The superset expresses it (its geometry and sessions come first)."""
        return True
    session = True

    def __init__(self, joints=None, names: list[str] = (), tools: list[str] = (),
                 references: dict | None = None):
        super().__init__(None)
        self.names = [str(n) for n in names]
        self.tools = [str(t) for t in tools]
        self.references: dict[str, np.ndarray] = {}
        if not self.names:      # read from a model specification: the settings come next (restore_term)
            return
        if len(self.names) < 2 or len(set(self.names)) != len(self.names):
            raise ModelError(f"sessions: needs two or more distinct session names, got {self.names}")
        unknown = [t for t in self.tools if t not in self.names[1:]]
        if unknown:
            raise ModelError(f"sessions: {unknown} are not sessions other than the primary one {self.names[0]!r}")
        for k, v in (references or {}).items():
            self.set_reference(k, v)

    def set_reference(self, name: str, base0) -> None:
        """The reference pose of session ``name`` (12 numbers, as ``base0``)."""
        if name not in self.names[1:]:
            raise ModelError(f"sessions: {name!r} is not a session other than the primary one")
        v = np.asarray(base0, dtype=float)
        R = v[:9].reshape(3, 3) if v.shape == (12,) and np.all(np.isfinite(v)) else None
        if R is None or np.abs(R.T @ R - np.eye(3)).max() > 1e-6 or np.linalg.det(R) <= 0:
            raise ModelError(f"sessions: the reference pose of {name!r} must be 12 finite numbers, a rotation "
                             "(row-major) and a translation")
        self.references[name] = v

    @property
    def covariates(self) -> tuple[str, ...]:  # type: ignore[override]
        return tuple(indicator(n) for n in self.names) + REFERENCE

    def bind(self, robot: Robot) -> None:
        """Nothing per joint (without session names, from a bare specification, the term does nothing)."""

    def spec(self) -> str:
        return self.name

    def settings(self) -> dict:
        return {"names": list(self.names), "tools": list(self.tools),
                "references": {k: [float(x) for x in v] for k, v in self.references.items()}}

    def parameters(self, robot: Robot) -> list[Parameter]:
        ps = []
        for s in self.names[1:]:
            ps += [Parameter(f"base_{k}@{s}", 0.0, "m", LENGTH_SCALE, "geometric", group="base") for k in "xyz"]
            ps += [Parameter(f"base_{k}@{s}", 0.0, "rad", ANGLE_SCALE, "geometric", group="base")
                   for k in ("roll", "pitch", "yaw")]
            if s in self.tools:
                ps += [Parameter(f"tool_{k}@{s}", v, "m", LENGTH_SCALE, "geometric", group="tool",
                                 lower=v - LENGTH_BOX, upper=v + LENGTH_BOX) for k, v in zip("xyz", robot.tool)]
        return ps

    def geometry(self, ctx: Context, geom):
        from dataclasses import replace
        h = {s: ctx.cov[indicator(s)] for s in self.names[1:]}
        rest = 1 - sum(h.values())
        base = [rest * geom.base[k] + sum(h[s] * ctx.p[f"base_{b}@{s}"] for s in h) for k, b in enumerate(BASE)]
        tool = [(1 - sum(h[s] for s in self.tools)) * geom.tool[k]
                + sum(h[s] * ctx.p[f"tool_{c}@{s}"] for s in self.tools) for k, c in enumerate("xyz")]
        return replace(geom, base=base, tool=tool)

    def reference(self, ctx: Context, R0, t0):
        """The reference pose of each pose's session: the primary's (``base0``) or its covariates."""
        rest = 1 - sum(ctx.cov[indicator(s)] for s in self.names[1:])
        ref = ca.vertcat(*[ctx.cov[r] for r in REFERENCE])
        return rest * R0 + ca.reshape(ref[:9], 3, 3).T, rest * t0 + ref[9:12]

    def covariate_values(self, data) -> dict[str, np.ndarray]:
        """The indicators and reference poses of ``data``'s poses, from its session names.

        Raises
        ------
        DataFileError
            A pose of a session the calibration does not know.
        """
        N = len(data)
        out = {indicator(s): np.zeros(N) for s in self.names}
        ref = np.zeros((N, 12))
        if data.sessions is None:
            out[indicator(self.names[0])][:] = 1.0
        else:
            unknown = sorted(set(data.sessions.tolist()) - set(self.names))
            # rows that say what they touched see no base pose (their points are fitted wherever the robot puts
            # them): a session of touches alone is the primary's frame, unless the calibration's tool is a session's
            touching = data.touching if data.touches else np.zeros(N, bool)
            unknown = [s for s in unknown if self.tools or not touching[data.sessions == s].all()]
            if unknown:
                i = int(np.flatnonzero(data.sessions == unknown[0])[0])
                raise DataFileError(f"session {unknown[0]!r} is not one of the calibration's sessions "
                                    f"({', '.join(self.names)}); take the calibration there first (calibrate "
                                    "CAL.json DATA.csv --model base)", file=data.file(i), row=data.line(i),
                                    column="session")
            known = np.isin(data.sessions, self.names)
            out[indicator(self.names[0])][~known] = 1.0
            for s in self.names:
                at = data.sessions == s
                out[indicator(s)][at] = 1.0
                if s != self.names[0]:
                    ref[at] = self.references.get(s, _IDENTITY)
        out.update({r: ref[:, k] for k, r in enumerate(REFERENCE)})
        return out


_IDENTITY = np.concatenate([np.eye(3).ravel(), np.zeros(3)])
