"""Kinds of measurement row: what a row measures, and how its residual is made from the model's point.

A tracker row measures where the tool point was (``x_mm, y_mm, z_mm``: its residual is the model's point minus
the measured one). A touch row says what the tool point touched instead (docs/formats.md section 11): a point
(a socket), a plane (a face), a pivot at a measured distance; the thing touched is an unknown of its session,
the same for every row that touches it, and is eliminated in closed form (variable projection): for given robot
parameters its best value is fitted to its rows' model points, the residual is each row's distance from it, and
the Jacobian is the model's projected on what the unknown cannot take (Kaufman's), so that Gauss-Newton,
Levenberg-Marquardt and IPOPT solve the robot's parameters alone with exact derivatives of the projected loss.

Each kind is one :class:`RowKind` object in its module of this package, registered in :data:`ROW_KINDS`: its
name (the column that makes a row of it), its unknowns per session, its residual and Jacobian (a group of rows at
a time), its validation measure and its words.
"""

from __future__ import annotations

from typing import ClassVar

import numpy as np

#: every kind of row by its name
ROW_KINDS: dict[str, "RowKind"] = {}


class RowKind:
    """One kind of measurement row.

    A kind that measures positions (the tracker) has no unknown of its own; a touch kind has, per group (its
    rows of one session that touch the same thing): :attr:`unknowns` numbers, fitted by :meth:`fit` to the
    rows' model points ``P`` (n, 3); :meth:`residual` gives each row's 3-vector from them, :meth:`row_map` how a
    change of a model point moves it, and :meth:`basis` the derivative of the stacked residual with respect to
    the unknowns (3n, :attr:`unknowns`), which the Jacobian is projected away from
    (:class:`~casadical.rows._layout.Projection`).
    """

    #: the kind's name: the column that makes a row of it (``point``, ``plane``), or ``tracker``
    name: ClassVar[str] = ""
    #: what one of its rows measures, in words
    words: ClassVar[str] = ""
    #: the unknowns of one group of its rows (3: a point; 3: a plane's normal and offset; 6: a fixture's pose)
    unknowns: ClassVar[int] = 0
    #: the independent equations one row gives (3: a point; 1: a distance, a distance from a plane)
    per_row: ClassVar[int] = 3
    #: the fewest rows a group needs to fix its unknowns with room left to check the robot
    min_rows: ClassVar[int] = 4

    def rank(self, group) -> int:
        """How many of the group's unknowns its rows fix (its equations used up)."""
        return self.unknowns

    def fit(self, P: np.ndarray, group) -> object:
        """The group's unknowns fitted to its rows' model points ``P`` (n, 3)."""
        raise NotImplementedError

    def residual(self, P: np.ndarray, fitted, group) -> np.ndarray:
        """Each row's residual (n, 3, metres): the model's point from what it touched."""
        raise NotImplementedError

    def row_map(self, P: np.ndarray, fitted, group) -> np.ndarray | None:
        """How the model point's change moves the residual, row by row (n, 3, 3); None: one to one."""
        return None

    def basis(self, P: np.ndarray, fitted, group) -> np.ndarray:
        """d (stacked residual) / d (unknowns), (3n, :attr:`unknowns`)."""
        raise NotImplementedError

    def __repr__(self) -> str:
        return f"<row kind {self.name}>"


def register_row_kind(kind: RowKind) -> RowKind:
    """Make ``kind`` known by its name (a module of this package calls it once)."""
    ROW_KINDS[kind.name] = kind
    return kind
