"""A tool of several points: each named point (a reflector nest, a ball) its own offset in the last link frame."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..errors import DataFileError
from ..parameters import Parameter
from ..robot import Robot
from .base import Context, ErrorTerm, register
from .geometric import LENGTH_SCALE


def indicator(name: str) -> str:
    """The covariate that is 1 at the rows that measure tool point ``name``, 0 elsewhere."""
    return f"tool@{name}"


@register
class ToolPoints(ErrorTerm):
    """The rows of a ``tool`` column measure the tool point they name: each name other than the primary one has its
    own offset in the last link frame, ``tool_x:NAME, tool_y:NAME, tool_z:NAME`` (its nominal: the robot file's
    ``[tool.NAME]``, or ``[tool]``), which the geometry's ``tool_*`` stands for at the other rows. The robot's
    parameters and each session's base pose are shared: several points of one pose give its orientation.

    Parameters
    ----------
    names : list of str
        The tool points the rows name, in order of appearance; the primary one (its rows use the geometry's
        ``tool_*``) is the robot file's ``[tool]`` where the rows leave ``tool`` empty, else the first named.
    primary : str
        The name of the rows that use the geometry's tool ('' : the rows without a name).
    """

    name = "tool_points"
    cause = "geometric"
    is_cause = False
    session = False

    def __init__(self, joints=None, names: list[str] = (), primary: str = ""):
        super().__init__(None)
        self.names = [str(n) for n in names]
        self.primary = str(primary)

    @property
    def own(self) -> list[str]:
        """The named points with offsets of their own (all but the primary)."""
        return [n for n in self.names if n != self.primary]

    @property
    def covariates(self) -> tuple[str, ...]:  # type: ignore[override]
        return tuple(indicator(n) for n in self.own)

    def bind(self, robot: Robot) -> None:
        """Nothing per joint."""

    def spec(self) -> str:
        return self.name

    def settings(self) -> dict:
        return {"names": list(self.names), "primary": self.primary}

    def parameters(self, robot: Robot) -> list[Parameter]:
        out = []
        for n in self.own:
            nominal = robot.tools.get(n, robot.tool)
            out += [Parameter(f"tool_{k}:{n}", float(v), "m", LENGTH_SCALE, "geometric", group="tool",
                              lower=float(v) - 0.05, upper=float(v) + 0.05) for k, v in zip("xyz", nominal)]
        return out

    def geometry(self, ctx: Context, geom):
        h = {n: ctx.cov[indicator(n)] for n in self.own}
        rest = 1 - sum(h.values())
        tool = [rest * geom.tool[k] + sum(h[n] * ctx.p[f"tool_{c}:{n}"] for n in h) for k, c in enumerate("xyz")]
        return replace(geom, tool=tool)

    def covariate_values(self, data) -> dict[str, np.ndarray]:
        """Each own point's indicator from the rows' ``tool``.

        Raises
        ------
        DataFileError
            A row names a tool point the calibration does not know.
        """
        names = tool_column(data)
        unknown = sorted(set(names[names != ""].tolist()) - set(self.names))
        if unknown:
            i = int(np.flatnonzero(names == unknown[0])[0])
            raise DataFileError(f"tool point {unknown[0]!r} is not one of the calibration's ({', '.join(self.names)})",
                                file=data.file(i), row=data.line(i), column="tool")
        return {indicator(n): (names == n).astype(float) for n in self.own}


def tool_column(data) -> np.ndarray:
    """Each row's tool point name ('' where none)."""
    col = data.columns.get("tool")
    if col is None:
        return np.full(len(data), "", dtype=object)
    return np.array(["" if v is None or (isinstance(v, float) and np.isnan(v)) else str(v).strip() for v in col],
                    dtype=object)


def tool_points_of(data) -> "ToolPoints | None":
    """The tool points term of ``data``'s ``tool`` column (None without one, or with no name in it)."""
    names = tool_column(data)
    named = list(dict.fromkeys(names[names != ""].tolist()))
    if not named:
        return None
    return ToolPoints(names=named, primary="" if (names == "").any() else named[0])
