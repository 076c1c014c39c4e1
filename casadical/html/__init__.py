"""HTML reports to act on: a calibration's and a diagnosis's (matplotlib figures as inline SVG)."""

import typing as _typing

from .._lazy import lazy

#: public name -> its module, imported on first use (PEP 562): importing one module of the package
#: imports no other
_EXPORTS = {"calibration_html": "calibration", "diagnosis_html": "diagnosis"}

__all__ = ["calibration_html", "diagnosis_html"]

if _typing.TYPE_CHECKING:
    from .calibration import calibration_html
    from .diagnosis import diagnosis_html
else:
    __getattr__, __dir__ = lazy(__name__, globals(), _EXPORTS)
