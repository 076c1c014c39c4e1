"""How the rows of a measurement set are measured: groups of rows of one kind, each with its session's unknowns.

:func:`layout` reads a :class:`~casadical.data._measurements.Measurements` (its ``point``, ``plane``,
``distance_mm`` columns and the fixtures it was given) into a :class:`Layout`: the tracker rows, and the touch
rows grouped by session and by the thing they touch. :meth:`Layout.residuals` makes every row's residual from the
model's points; :meth:`Layout.project` also the Jacobian projected away from the groups' unknowns (variable
projection, :mod:`._kind`). Data of tracker rows alone have a layout whose residual is the model's point minus
the measured one, to the bit.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ._fixture import FIXTURE_POINTS, Fixture
from ._kind import RowKind
from ._pivot import PIVOT_DISTANCE
from ._plane import TOUCHED_PLANE
from ._touched import TOUCHED_POINT
from ._tracker import TRACKER_POINT


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

    @property
    def equations(self) -> int:
        """The independent equations the rows give: each row's (3 for a point, 1 for a distance or a distance from
        a plane) less each group's unknowns (:meth:`~._kind.RowKind.rank`) and, for touches alone, the whole
        robot's turn."""
        n = sum(g.kind.per_row * len(g.rows) - g.kind.rank(g) for g in self.groups)
        return n - (3 if self.touches and not self.tracked.any() else 0)

    def residuals(self, P: np.ndarray) -> np.ndarray:
        """Every row's residual (n, 3, m) from the model's points ``P`` (n, 3)."""
        return self.projection(P).r

    def project(self, P: np.ndarray, J: np.ndarray | None) -> tuple[np.ndarray, np.ndarray | None]:
        """Every row's residual and, with ``J`` (n, 3, p), its Jacobian projected away from the unknowns
        (:class:`Projection`)."""
        proj = self.projection(P, gauge=J is not None)
        return proj.r, None if J is None else proj(J)

    def projection(self, P: np.ndarray, gauge: bool = True) -> "Projection":
        """The rows' residuals at the model's points ``P`` and the projection of any columns there
        (:class:`Projection`); ``gauge=False``: without the whole robot's turn (the residuals need none)."""
        return Projection(self, P, gauge)

    def fitted(self, P: np.ndarray) -> list[tuple[Group, object]]:
        """Each touch group with its unknowns fitted to the model's points ``P``."""
        return [(g, g.kind.fit(P[g.rows], g)) for g in self.groups if g.kind is not TRACKER_POINT]

    def subset(self, keep: np.ndarray) -> "Layout":
        """The layout of the rows ``keep`` (a mask), each group's own rows (a group's unknowns are fitted to the rows
        it keeps)."""
        keep = np.asarray(keep, bool)
        return Layout(int(keep.sum()), [h for g in self.groups if (h := g.subset(keep)) is not None])


class Projection:
    """A layout's residuals at the model's points ``P``, and the projection of columns (n, 3, p) there.

    Each group's unknowns are fitted once; a column is projected away from what they can take (Kaufman's
    variable projection, :mod:`._kind`), so that ``r + project(J) d`` is the residual after a small change ``d``
    of the robot's parameters with every group's unknowns fitted again. Rows that all touch (no measured row) see
    the robot against nothing: a turn of the whole robot turns every residual and changes no distance (the
    world's frame is not seen: the base pose, and the parameters that only turn the whole robot); the columns are
    projected away from that turn too, jointly with the groups' unknowns (the turn's columns at each row
    ``e x r``, projected as the columns are). Linear in the columns: projecting them one by one or together is
    the same.

    Attributes
    ----------
    r : ndarray (n, 3)
        Every row's residual (m).
    """

    def __init__(self, layout: Layout, P: np.ndarray, gauge: bool = True):
        self.layout = layout
        self.r = np.empty((layout.n, 3))
        self._groups = []
        for g in layout.groups:
            if g.kind.unknowns == 0:
                self.r[g.rows] = g.kind.residual(P[g.rows], None, g)
                continue
            fitted = g.kind.fit(P[g.rows], g)
            self.r[g.rows] = g.kind.residual(P[g.rows], fitted, g)
            A = g.kind.basis(P[g.rows], fitted, g)
            M = g.kind.row_map(P[g.rows], fitted, g)
            U, sv, _ = np.linalg.svd(A, full_matrices=False)
            U = U[:, sv > 1e-9 * max(sv.max(initial=0.0), 1e-300)]
            self._groups.append((g, M, U))
        self._G = None
        if gauge and not layout.tracked.any():
            G = self._groups_only(np.stack([np.cross(e, self.r) for e in np.eye(3)], axis=2)).reshape(-1, 3)
            U, sv, _ = np.linalg.svd(G, full_matrices=False)
            self._G = U[:, sv > 1e-9 * max(sv.max(initial=0.0), 1e-300)]

    def _groups_only(self, J: np.ndarray) -> np.ndarray:
        out = J.copy()
        for g, M, U in self._groups:
            Jg = J[g.rows] if M is None else np.einsum("nij,njp->nip", M, J[g.rows])
            flat = Jg.reshape(-1, J.shape[2])
            out[g.rows] = (flat - U @ (U.T @ flat)).reshape(Jg.shape)
        return out

    def __call__(self, J: np.ndarray) -> np.ndarray:
        """The columns ``J`` (n, 3, p) projected (a column (n, 3) alone: the same shape back)."""
        if not self._groups and self._G is None:
            return J        # tracker rows alone: nothing to project
        one = J.ndim == 2
        J = J[:, :, None] if one else J
        if J.shape[2] == 0:
            return J.copy()
        out = self._groups_only(J)
        if self._G is not None:
            flat = out.reshape(-1, J.shape[2])
            out = (flat - self._G @ (self._G.T @ flat)).reshape(J.shape)
        return out[:, :, 0] if one else out


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
