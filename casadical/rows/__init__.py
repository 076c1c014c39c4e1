"""Kinds of measurement row (what a row measures) and how a measurement set's rows are grouped by them.

A tracker row measured where the tool point was; a touch row says what it touched (docs/formats.md section 11):
a point (:mod:`.touched`), a plane (:mod:`.plane`), a pivot at a measured distance (:mod:`.pivot`), a fixture's
point (:mod:`.fixture`). Each kind is one :class:`~.kind.RowKind` object; :func:`~.layout.layout` groups a data
set's rows by kind and by what they touch, each group with its session's unknowns.
"""

from . import fixture, pivot, plane, touched, tracker  # noqa: F401 (the kinds register themselves)
from .fixture import Fixture, read_fixture_file
from .kind import ROW_KINDS, RowKind
from .layout import Group, Layout, layout

__all__ = ["ROW_KINDS", "Fixture", "Group", "Layout", "RowKind", "layout", "read_fixture_file"]
