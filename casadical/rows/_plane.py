"""A touched plane: the tool point lies on a fixed face nobody measured (a ball's centre on a face)."""

from __future__ import annotations

import numpy as np

from ._kind import RowKind, register_row_kind


class TouchedPlane(RowKind):
    """Rows with a ``plane``: the rows of one session with the same name lie on one unknown plane, the
    least-squares plane of their model points (through their mean, normal to it the direction of least spread).
    The residual is each row's distance from it, along its normal; the plane's offset along its normal is its
    own (a ball's radius is part of it), so nothing in the robot moves the points along the normal all alike."""

    name = "plane"
    words = "the tool point on a face (a fixed plane nobody measured)"
    unknowns = 3
    per_row = 1

    def fit(self, P: np.ndarray, group) -> tuple[np.ndarray, np.ndarray]:
        c = P.mean(axis=0)
        _, _, Vt = np.linalg.svd(P - c, full_matrices=False)
        return c, Vt[-1]

    def residual(self, P: np.ndarray, fitted, group) -> np.ndarray:
        c, n = fitted
        return np.outer((P - c) @ n, n)

    def row_map(self, P: np.ndarray, fitted, group) -> np.ndarray:
        n = fitted[1]
        return np.broadcast_to(np.outer(n, n), (len(P), 3, 3))

    def basis(self, P: np.ndarray, fitted, group) -> np.ndarray:
        c, n = fitted
        # the plane's offset along n, and its tilt about two axes in it
        e1 = np.cross(n, [1.0, 0.0, 0.0] if abs(n[0]) < 0.9 else [0.0, 1.0, 0.0])
        e1 /= np.linalg.norm(e1)
        e2 = np.cross(n, e1)
        d = P - c
        cols = [np.tile(n, len(P)), *(np.outer(np.cross(n, d) @ e, n).ravel() for e in (e1, e2))]
        return np.column_stack(cols)


TOUCHED_PLANE = register_row_kind(TouchedPlane())
