"""A touched point: the tool point sits at a fixed point nobody measured (a ball in a socket, a cone)."""

from __future__ import annotations

import numpy as np

from ._kind import RowKind, register_row_kind


class TouchedPoint(RowKind):
    """Rows with a ``point`` (and no ``distance_mm``): the rows of one session with the same name sit at one
    unknown point, whose best value for given robot parameters is the mean of their model points. The residual
    is each row's model point from that mean; the projected Jacobian, each row's minus their mean (exact: the
    point enters linearly)."""

    name = "point"
    words = "the tool point in a socket (a fixed point nobody measured)"
    unknowns = 3

    def fit(self, P: np.ndarray, group) -> np.ndarray:
        return P.mean(axis=0)

    def residual(self, P: np.ndarray, fitted, group) -> np.ndarray:
        return P - fitted

    def basis(self, P: np.ndarray, fitted, group) -> np.ndarray:
        return -np.tile(np.eye(3), (len(P), 1))


TOUCHED_POINT = register_row_kind(TouchedPoint())
