"""A tool of several points: each named point (a reflector nest, a ball) its own offset in the last link frame."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from ..errors import DataFileError
from ..parameters import Parameter
from ..robot import Robot
from ._base import Context, ErrorTerm, register
from ._geometric import LENGTH_BOX, LENGTH_SCALE


def indicator(name: str) -> str:
    """The covariate that is 1 at the rows that measure tool point ``name``, 0 elsewhere."""
    return f"tool@{name}"


@register
class ToolPoints(ErrorTerm):
    """The rows of a ``tool`` column measure the tool point they name: each named point has its own offset in the
    last link frame, ``tool_x:NAME, tool_y:NAME, tool_z:NAME``, which stands for the geometry's ``tool_*`` at its
    rows (the geometry's ``tool_*``, the robot file's ``[tool]``, stay the point of the rows that name none). The
    robot's parameters and each session's base pose are shared: several points of one pose give its orientation.

    A point's nominal offset is the robot file's ``[tool.NAME]``, and its bounds that nominal plus or minus the
    geometry's length box (:attr:`~._geometric.Geometric.length_box`, 50 mm: the bound of every length of the
    geometry). A point the robot file does not name (a robot file without ``[tool.NAME]`` tables: a URDF, a
    built-in robot) starts at ``[tool]``, unbounded: nothing says where it is, and its offset enters the model
    linearly, so the fit needs no bound to find it.

    Parameters
    ----------
    names : list of str
        The tool points the rows name, in order of appearance.
    """

    name = "tool_points"
    cause = "geometric"
    is_cause = False
    session = False

    def __init__(self, joints=None, names: list[str] = ()):
        super().__init__(None)
        self.names = [str(n) for n in names]

    @property
    def covariates(self) -> tuple[str, ...]:  # type: ignore[override]
        return tuple(indicator(n) for n in self.names)

    def bind(self, robot: Robot) -> None:
        """Nothing per joint."""

    def spec(self) -> str:
        return self.name

    def settings(self) -> dict:
        return {"names": list(self.names)}

    def parameters(self, robot: Robot) -> list[Parameter]:
        out = []
        for n in self.names:
            own = n in robot.tools
            box = LENGTH_BOX if own else math.inf
            out += [Parameter(f"tool_{k}:{n}", float(v), "m", LENGTH_SCALE, "geometric", group="tool",
                              lower=float(v) - box, upper=float(v) + box)
                    for k, v in zip("xyz", robot.tools[n] if own else robot.tool)]
        return out

    def geometry(self, ctx: Context, geom):
        h = {n: ctx.cov[indicator(n)] for n in self.names}
        rest = 1 - sum(h.values())
        tool = [rest * geom.tool[k] + sum(h[n] * ctx.p[f"tool_{c}:{n}"] for n in h) for k, c in enumerate("xyz")]
        return replace(geom, tool=tool)

    def covariate_values(self, data) -> dict[str, np.ndarray]:
        """Each point's indicator from the rows' ``tool``.

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
        return {indicator(n): (names == n).astype(float) for n in self.names}


def tool_column(data) -> np.ndarray:
    """Each row's tool point name ('' where none)."""
    col = data.columns.get("tool")
    if col is None:
        return np.full(len(data), "", dtype=object)
    return np.array(["" if v is None or (isinstance(v, float) and np.isnan(v)) else str(v).strip() for v in col],
                    dtype=object)


def tool_points_of(data) -> "ToolPoints | None":
    """The tool points term of ``data``'s ``tool`` column (None without one, or with no name in it)."""
    named = named_points(data)
    return ToolPoints(names=named) if named else None


def named_points(data) -> list[str]:
    """The tool points ``data``'s rows name, in order of appearance."""
    names = tool_column(data)
    return list(dict.fromkeys(names[names != ""].tolist()))


def with_tool_points(terms: list[ErrorTerm], data) -> list[ErrorTerm]:
    """``terms`` with the tool points term of ``data`` in place of any they hold (none where no row names one)."""
    points = tool_points_of(data)
    return [t for t in terms if t.name != ToolPoints.name] + ([points] if points else [])


def check_tool_points(data, robot: Robot) -> str | None:
    """The rows' tool points against the robot file's ``[tool.NAME]`` tables: where the file names tool points, a row
    must name one of them; where it names none, every named point starts at ``[tool]`` (returned: what to say of the
    robot file then, after its name; None where nothing needs saying).

    Raises
    ------
    DataFileError
        A row names a tool point the robot file (which names some) does not.
    """
    named = named_points(data)
    if not named:
        return None
    names = tool_column(data)
    if robot.tools:
        missing = [n for n in named if n not in robot.tools]
        if missing:
            i = int(np.flatnonzero(names == missing[0])[0])
            raise DataFileError(
                f"tool point {missing[0]!r} is not one of robot file {robot.source or robot.name}'s "
                f"({', '.join(robot.tools)}): give it its nominal offset there ([tool.{missing[0]}] with a_m, b_m, "
                "d_m), or correct the name", file=data.file(i), row=data.line(i), column="tool")
        return None
    tool = ", ".join(f"{v * 1000:.6g}" for v in robot.tool)
    return (f"gives no tool point a nominal offset of its own ([tool.NAME] tables, docs/formats.md): the rows' "
            f"{', '.join(named)} each start at its [tool] ({tool} mm), unbounded, and its nominal model puts every "
            "one there")
