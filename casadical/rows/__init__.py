"""Kinds of measurement row (what a row measures) and how a measurement set's rows are grouped by them.

A tracker row measured where the tool point was; a touch row says what it touched (docs/formats.md section 11):
a point (:mod:`._touched`), a plane (:mod:`._plane`), a pivot at a measured distance (:mod:`._pivot`), a fixture's
point (:mod:`._fixture`). Each kind is one :class:`~._kind.RowKind` object; :func:`~._layout.layout` groups a data
set's rows by kind and by what they touch, each group with its session's unknowns.
"""

import typing as _typing

from .._lazy import lazy
from . import _fixture, _pivot, _plane, _touched, _tracker  # noqa: F401 (the kinds register themselves)
from ._fixture import Fixture, read_fixture_file
from ._kind import ROW_KINDS, RowKind
from ._layout import Group, Layout, layout

__all__ = [
    "FIXTURE_POINTS", "Fixture", "Group", "Layout", "ROW_KINDS", "RowKind", "TRACKER_POINT", "layout",
    "read_fixture_file",
]

#: public name -> its private module, imported on first use (PEP 562)
_EXPORTS = {"FIXTURE_POINTS": "_fixture", "TRACKER_POINT": "_tracker"}

if _typing.TYPE_CHECKING:
    from ._fixture import FIXTURE_POINTS
    from ._tracker import TRACKER_POINT
else:
    __getattr__, __dir__ = lazy(__name__, globals(), _EXPORTS)
