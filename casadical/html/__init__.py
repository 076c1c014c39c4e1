"""HTML reports to act on: a calibration's and a diagnosis's (matplotlib figures as inline SVG)."""

import typing as _typing

from .._lazy import lazy

#: public name -> its module, imported on first use (PEP 562): importing one module of the package
#: imports no other
_EXPORTS = {"calibration_html": "_calibration", "diagnosis_html": "_diagnosis", "FOLD_FOOTNOTES": "_page",
            "Page": "_page", "SERIES": "_svg", "bands": "_svg", "colour_at": "_svg", "figure": "_svg",
            "nice_ticks": "_svg", "text_width": "_svg", "tick_labels": "_svg"}

__all__ = [
    "FOLD_FOOTNOTES", "Page", "SERIES", "bands", "calibration_html", "colour_at", "diagnosis_html", "figure",
    "nice_ticks", "text_width", "tick_labels",
]

if _typing.TYPE_CHECKING:
    from ._calibration import calibration_html
    from ._diagnosis import diagnosis_html
    from ._page import FOLD_FOOTNOTES, Page
    from ._svg import SERIES, bands, colour_at, figure, nice_ticks, text_width, tick_labels
else:
    __getattr__, __dir__ = lazy(__name__, globals(), _EXPORTS)
