"""A pivot at a measured distance: a draw-wire sensor or a ballbar, one end fixed at a point nobody measured."""

from __future__ import annotations

import numpy as np

from ._kind import RowKind, register_row_kind

#: Gauss-Newton steps of the pivot's own fit, from the algebraic sphere fit
STEPS = 8


class PivotDistance(RowKind):
    """Rows with a ``point`` and a ``distance_mm``: the measured distance from an unknown pivot (the rows of one
    session with the same name share it) to the tool point. The pivot is fitted to the rows' model points (the
    algebraic fit of ``|p - c|^2 = d^2``, then Gauss-Newton on ``|p - c| - d``); the residual is each row's
    distance error along the line from the pivot. A known distance: it fixes the scale of the robot's lengths,
    which points and planes alone do not."""

    name = "pivot"
    words = "the distance from a fixed pivot nobody measured to the tool point (a draw-wire sensor, a ballbar)"
    unknowns = 3
    per_row = 1

    def fit(self, P: np.ndarray, group) -> np.ndarray:
        d = group.distance
        # |p|^2 - d^2 = 2 p.c - (|c|^2): linear in (c, |c|^2)
        A = np.column_stack([2 * P, -np.ones(len(P))])
        sol, *_ = np.linalg.lstsq(A, np.einsum("ij,ij->i", P, P) - d * d, rcond=None)
        c = sol[:3]
        for _ in range(STEPS):
            v = P - c
            r = np.linalg.norm(v, axis=1)
            u = v / r[:, None]
            step, *_ = np.linalg.lstsq(-u, -(r - d), rcond=None)
            c = c - step
        return c

    def _directions(self, P, c):
        v = P - c
        return v / np.linalg.norm(v, axis=1)[:, None]

    def residual(self, P: np.ndarray, fitted, group) -> np.ndarray:
        u = self._directions(P, fitted)
        return (np.linalg.norm(P - fitted, axis=1) - group.distance)[:, None] * u

    def row_map(self, P: np.ndarray, fitted, group) -> np.ndarray:
        u = self._directions(P, fitted)
        return np.einsum("ni,nj->nij", u, u)

    def basis(self, P: np.ndarray, fitted, group) -> np.ndarray:
        u = self._directions(P, fitted)
        return -np.einsum("ni,nj->nij", u, u).reshape(-1, 3)


PIVOT_DISTANCE = register_row_kind(PivotDistance())
