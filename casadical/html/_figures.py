"""Figures of the HTML reports: written as inline SVG by :mod:`._svg` (no plotting library), one shared style.

Each figure is a small function of the report's data that returns a
:class:`._svg.Figure`; :func:`render` writes them in order. Writing the SVG
directly with a fixed layout costs a few milliseconds a figure (matplotlib
took 0.9 s for the README job's twelve, plus 0.42 s to import), so the
figures are drawn in this process, one after the other.
"""

from __future__ import annotations

from typing import Callable

from ..runtime._interrupts import checkpoint
from ._svg import AFTER, BEFORE, CURVE, SERIES, Axes, Figure, ecdf, figure

__all__ = ["AFTER", "BEFORE", "CURVE", "SERIES", "Axes", "Figure", "ecdf", "figure", "legend_above", "render",
           "ticks"]


def ticks(ax: Axes, x: bool = True, y: bool = True, n: int = 7, least: int = 4) -> None:
    """Enough ticks: about ``n`` and never fewer than ``least``."""
    if x:
        ax.xticks_n, ax.xleast = n, least
    if y:
        ax.yticks_n, ax.yleast = n, least


def legend_above(ax: Axes) -> None:
    """The legend above the axes (one row, wrapping when it is wider than the figure), where it never covers data."""
    ax.legend = True


def render(jobs: list[tuple[Figure | Callable[[], Figure], str, str]]) -> list[str]:
    """``<svg>`` elements of figures, in order.

    Parameters
    ----------
    jobs : list of (Figure or callable, str, str)
        A figure or a function making one, its key (unused: the SVG has no
        ids to keep apart) and its label (the image's accessible name).
    """
    checkpoint("figures")
    return [(fig() if callable(fig) else fig).svg(label) for fig, _, label in jobs]
