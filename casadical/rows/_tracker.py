"""A tracker row: the instrument measured where the tool point was."""

from __future__ import annotations

from ._kind import RowKind, register_row_kind


class TrackerPoint(RowKind):
    """Rows with ``x_mm, y_mm, z_mm``: the residual is the model's point minus the measured one, in the
    measurement frame of the row's session (whose pose, the robot's base in it, the model holds)."""

    name = "tracker"
    words = "the tool point measured (a laser tracker, a total station)"
    unknowns = 0
    min_rows = 1

    def fit(self, P, group):
        return None

    def residual(self, P, fitted, group):
        return P - group.xyz


TRACKER_POINT = register_row_kind(TrackerPoint())
