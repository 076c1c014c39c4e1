"""How the rows of a measurement set are measured: groups of rows of one kind, each with its session's unknowns.

:func:`layout` reads a :class:`~casadical.data.measurements.Measurements` (its ``point``, ``plane``,
``distance_mm`` columns and the fixtures it was given) into a :class:`Layout`: the tracker rows, and the touch
rows grouped by session and by the thing they touch. :meth:`Layout.residuals` makes every row's residual from the
model's points; :meth:`Layout.project` also the Jacobian projected away from the groups' unknowns (variable
projection, :mod:`.kind`). Data of tracker rows alone have a layout whose residual is the model's point minus
the measured one, to the bit.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .fixture import FIXTURE_POINTS, Fixture
from .kind import RowKind
from .pivot import PIVOT_DISTANCE
from .plane import TOUCHED_PLANE
from .touched import TOUCHED_POINT
from .tracker import TRACKER_POINT


@dataclass
class Group:
    """Rows of one kind that share their unknowns: one session's rows touching one thing (all tracker rows)."""

    kind: RowKind
    rows: np.ndarray                     # indices into the data
    session: str | None = None
    name: str = ""                       # the point, plane or fixture touched
    xyz: np.ndarray | None = None        # tracker rows: the measured points (m)
    distance: np.ndarray | None = None   # pivot rows: the measured distances (m)
    fixture: Fixture | None = None       # fixture rows: the fixture, and each row's point
    point_names: np.ndarray | None = None

    def subset(self, keep: np.ndarray) -> "Group | None":
        """The group's rows among ``keep`` (a mask over the data), renumbered; None if none is."""
        mine = keep[self.rows]
        if not mine.any():
            return None
        new = np.cumsum(keep) - 1
        pick = (lambda a: None if a is None else a[mine])  # noqa: E731
        return Group(self.kind, new[self.rows[mine]], self.session, self.name, pick(self.xyz), pick(self.distance),
                     self.fixture, pick(self.point_names))


@dataclass
class Layout:
    """The groups of a measurement set's rows (see the module)."""

    n: int
    groups: list[Group] = field(default_factory=list)

    @property
    def touches(self) -> bool:
        """Some rows say what they touched rather than where they were."""
        return any(g.kind is not TRACKER_POINT for g in self.groups)

    @property
    def tracked(self) -> np.ndarray:
        """The rows measured by an instrument (bool, n)."""
        out = np.zeros(self.n, bool)
        for g in self.groups:
            if g.kind is TRACKER_POINT:
                out[g.rows] = True
        return out

    def known_distance(self) -> bool:
        """Something measures a length: tracker rows, a pivot's distances, or a fixture's points."""
        return any(g.kind in (TRACKER_POINT, PIVOT_DISTANCE, FIXTURE_POINTS) for g in self.groups)

    def residuals(self, P: np.ndarray) -> np.ndarray:
        """Every row's residual (n, 3, m) from the model's points ``P`` (n, 3)."""
        return self.project(P, None)[0]

    def project(self, P: np.ndarray, J: np.ndarray | None) -> tuple[np.ndarray, np.ndarray | None]:
        """Every row's residual and, with ``J`` (n, 3, p), its Jacobian projected away from the unknowns.

        Rows that all touch (no measured row) see the robot against nothing: a turn of the whole robot turns
        every residual and changes no distance (the world's frame is not seen: the base pose, and the
        parameters that only turn the whole robot). The Jacobian is projected away from that turn too, jointly
        with the groups' unknowns (the turn's columns at each row ``e x r``, projected as the Jacobian is)."""
        r = self._each(P, None)[0]
        if J is None:
            return r, None
        gauge = not self.tracked.any()
        p = J.shape[2]
        if gauge:
            J = np.concatenate([J, np.stack([np.cross(e, r) for e in np.eye(3)], axis=2)], axis=2)
        Jp = self._each(P, J)[1]
        if gauge:
            flat = Jp.reshape(-1, p + 3)
            G = flat[:, p:]
            coef, *_ = np.linalg.lstsq(G, flat[:, :p], rcond=None)
            Jp = (flat[:, :p] - G @ coef).reshape(self.n, 3, p)
        return r, Jp

    def _each(self, P, J):
        r = np.empty((self.n, 3))
        Jp = None if J is None else np.empty_like(J)
        for g in self.groups:
            rg, Jg, _ = g.kind.project(P[g.rows], None if J is None else J[g.rows], g)
            r[g.rows] = rg
            if Jp is not None:
                Jp[g.rows] = Jg
        return r, Jp

    def fitted(self, P: np.ndarray) -> list[tuple[Group, object]]:
        """Each touch group with its unknowns fitted to the model's points ``P``."""
        return [(g, g.kind.fit(P[g.rows], g)) for g in self.groups if g.kind is not TRACKER_POINT]

    def subset(self, keep: np.ndarray) -> "Layout":
        """The layout of the rows ``keep`` (a mask), each group's own rows (a group's unknowns are fitted to the rows
        it keeps)."""
        keep = np.asarray(keep, bool)
        return Layout(int(keep.sum()), [h for g in self.groups if (h := g.subset(keep)) is not None])


def layout(data) -> Layout:
    """The layout of ``data``'s rows (its fixtures: ``data.fixtures``)."""
    n = len(data)
    point, plane = _text(data, "point"), _text(data, "plane")
    distance = data.get("distance_mm")
    touching = (point != "") | (plane != "")
    groups = []
    tracked = np.flatnonzero(~touching)
    if len(tracked):
        groups.append(Group(TRACKER_POINT, tracked, xyz=data.xyz[tracked]))
    sessions = data.sessions if data.sessions is not None else np.full(n, "", dtype=object)
    by_point = {p: f for f in getattr(data, "fixtures", ()) or () for p in f.points}
    for s in dict.fromkeys(sessions.tolist()):
        here = sessions == s
        fixtures: dict[str, list[int]] = {}
        for name in dict.fromkeys(point[here & (point != "")].tolist()):
            rows = np.flatnonzero(here & (point == name))
            if distance is not None and np.isfinite(distance[rows]).any():
                groups.append(Group(PIVOT_DISTANCE, rows, s or None, name, distance=distance[rows] / 1000.0))
            elif name in by_point:
                fixtures.setdefault(by_point[name].name, []).extend(rows.tolist())
            else:
                groups.append(Group(TOUCHED_POINT, rows, s or None, name))
        for f in getattr(data, "fixtures", ()) or ():
            if f.name in fixtures:
                rows = np.sort(np.array(fixtures[f.name]))
                groups.append(Group(FIXTURE_POINTS, rows, s or None, f.name, fixture=f, point_names=point[rows]))
        for name in dict.fromkeys(plane[here & (plane != "")].tolist()):
            groups.append(Group(TOUCHED_PLANE, np.flatnonzero(here & (plane == name)), s or None, name))
    return Layout(n, groups)


def _text(data, column: str) -> np.ndarray:
    col = data.columns.get(column)
    if col is None:
        return np.full(len(data), "", dtype=object)
    return np.array(["" if v is None else str(v).strip() for v in col], dtype=object)
