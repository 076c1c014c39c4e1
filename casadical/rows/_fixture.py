"""A fixture: touched points at known coordinates in its own frame (a block with sockets), placed anywhere.

The fixture file (``--fixture FILE``, TOML; docs/formats.md section 11) names each fixture and its points::

    [[fixture]]
    name = "two_sockets"          # the artefact
    sd_mm = 0.01                  # how well its geometry is known (default 0.01)
    [fixture.points]              # mm, in the fixture's frame
    socket0 = [0.0, 0.0, 0.0]
    socket1 = [50.0, 0.0, 0.0]

The fixture's pose in each session is unknown. The rows that touch its points in a session are one group: its
pose is the rigid fit (Kabsch's, each point weighed by its rows) of the points to the means of their rows' model
points, and each row's residual is its model point from where the fitted fixture puts its point: the fixture's
known distances fix the scale of the robot's lengths, which free points do not.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import DataFileError
from ._kind import RowKind, register_row_kind

_NAME = re.compile(r"^[A-Za-z0-9_.-]+$")
#: the default tolerance of a fixture's geometry (mm)
SD_MM = 0.01


@dataclass(frozen=True)
class Fixture:
    """One ``[[fixture]]`` of a fixture file: its points by name (m, in its frame) and its tolerance (m)."""

    name: str
    points: dict
    sd: float = SD_MM / 1000.0
    file: str = ""

    def distances(self) -> dict[tuple[str, str], float]:
        """The known distance between each pair of its points (m)."""
        names = list(self.points)
        return {(a, b): float(np.linalg.norm(self.points[a] - self.points[b]))
                for i, a in enumerate(names) for b in names[i + 1:]}

    def to_dict(self) -> dict:
        return {"name": self.name, "sd_mm": self.sd * 1000.0,
                "points": {k: [float(x) * 1000.0 for x in v] for k, v in self.points.items()}}


def read_fixture_file(path: str | Path) -> list[Fixture]:
    """The fixtures of a fixture file, checked: one line naming the file, the fixture and the key at fault.

    Raises
    ------
    DataFileError
    """
    from ..runtime._files import read_toml

    label = str(path)
    doc = read_toml(path, DataFileError, label)
    extra = sorted(set(doc) - {"fixture"})
    if extra:
        raise DataFileError(f"unknown key {extra[0]!r}: a fixture file holds [[fixture]] tables", file=label,
                            column=extra[0])
    tables = doc.get("fixture")
    if not isinstance(tables, list) or not tables:
        raise DataFileError("holds no [[fixture]] table", file=label, column="fixture")
    out, seen_points = [], {}
    for k, t in enumerate(tables, start=1):
        where = f"fixture[{k}]"
        if not isinstance(t, dict):
            raise DataFileError("a fixture is a table", file=label, column=where)
        unknown = sorted(set(t) - {"name", "sd_mm", "points"})
        if unknown:
            raise DataFileError(f"unknown key {unknown[0]!r} (keys: name, sd_mm, points)", file=label,
                                column=f"{where}.{unknown[0]}")
        name = t.get("name")
        if not isinstance(name, str) or not _NAME.match(name):
            raise DataFileError(f"name must be letters, digits, _ . -, got {name!r}", file=label,
                                column=f"{where}.name")
        sd = t.get("sd_mm", SD_MM)
        if isinstance(sd, bool) or not isinstance(sd, (int, float)) or not (math.isfinite(sd) and sd > 0):
            raise DataFileError(f"sd_mm must be a positive number of mm, got {sd!r}", file=label,
                                column=f"{where}.sd_mm")
        pts = t.get("points")
        if not isinstance(pts, dict) or len(pts) < 2:
            raise DataFileError("points must be a table of two or more named points (mm in the fixture's frame)",
                                file=label, column=f"{where}.points")
        points = {}
        for p, xyz in pts.items():
            key = f"{where}.points.{p}"
            if not _NAME.match(p):
                raise DataFileError(f"a point's name must be letters, digits, _ . -, got {p!r}", file=label,
                                    column=key)
            if not (isinstance(xyz, list) and len(xyz) == 3 and all(
                    isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in xyz)):
                raise DataFileError(f"a point is [x, y, z] in mm, got {xyz!r}", file=label, column=key)
            if p in seen_points:
                raise DataFileError(f"point {p!r} is in two fixtures ({seen_points[p]} and {name})", file=label,
                                    column=key)
            seen_points[p] = name
            points[p] = np.asarray(xyz, float) / 1000.0
        if np.linalg.matrix_rank(np.array(list(points.values())) - next(iter(points.values())), tol=1e-9) < 1:
            raise DataFileError("its points all stand at one place", file=label, column=f"{where}.points")
        out.append(Fixture(name, points, float(sd) / 1000.0, label))
    return out


def kabsch(x: np.ndarray, y: np.ndarray, w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The rotation R and translation t that best put the points ``x`` (k, 3) on ``y`` (k, 3), weights ``w``:
    ``y ~ R x + t``. Two points leave the turn about their line free: the least rotation is taken."""
    w = w / w.sum()
    cx, cy = w @ x, w @ y
    H = ((x - cx) * w[:, None]).T @ (y - cy)
    U, _, Vt = np.linalg.svd(H)
    D = np.diag([1.0, 1.0, np.sign(np.linalg.det(Vt.T @ U.T)) or 1.0])
    R = Vt.T @ D @ U.T
    return R, cy - R @ cx


class FixturePoints(RowKind):
    """Rows with a ``point`` that a fixture names: the fixture's rows of one session are one group, whose unknown
    is the fixture's pose (6 numbers); each row's residual is its model point from the fixture's point there."""

    name = "fixture"
    words = "the tool point in a socket of a fixture of known geometry"
    unknowns = 6

    def rank(self, group) -> int:
        """6; 5 when the points touched lie on one line (the turn about it is free)."""
        x = np.array([group.fixture.points[p] for p in dict.fromkeys(group.point_names.tolist())])
        return 6 if np.linalg.matrix_rank(x - x[0], tol=1e-9) >= 2 else 5

    @staticmethod
    def _points(group) -> tuple[np.ndarray, np.ndarray]:
        """The fixture's points the rows touch ((k, 3), in its frame) and each row's index among them; kept on the
        group (a solver asks for them at every evaluation)."""
        hit = group.__dict__.get("_fixture_points")
        if hit is None:
            names, which = np.unique(np.asarray(group.point_names, dtype=str), return_inverse=True)
            hit = group.__dict__["_fixture_points"] = (np.array([group.fixture.points[p] for p in names]),
                                                       which.ravel())
        return hit

    def fit(self, P: np.ndarray, group):
        known, which = self._points(group)
        counts = np.bincount(which, minlength=len(known)).astype(float)
        means = np.stack([np.bincount(which, weights=P[:, k], minlength=len(known)) for k in range(3)], axis=1)
        return kabsch(known, means / counts[:, None], counts)

    def placed(self, fitted, group) -> np.ndarray:
        """Where the fitted fixture puts each row's point (n, 3)."""
        R, t = fitted
        known, which = self._points(group)
        return (known @ R.T + t)[which]

    def residual(self, P: np.ndarray, fitted, group) -> np.ndarray:
        return P - self.placed(fitted, group)

    def basis(self, P: np.ndarray, fitted, group) -> np.ndarray:
        """d r / d (translation, small rotation about the origin), (3n, 6)."""
        x = self.placed(fitted, group)
        B = np.zeros((len(x), 3, 6))
        B[:, :, :3] = -np.eye(3)
        B[:, 0, 4], B[:, 0, 5] = -x[:, 2], x[:, 1]           # the cross-product matrix of x
        B[:, 1, 3], B[:, 1, 5] = x[:, 2], -x[:, 0]
        B[:, 2, 3], B[:, 2, 4] = -x[:, 1], x[:, 0]
        return B.reshape(-1, 6)


FIXTURE_POINTS = register_row_kind(FixturePoints())
