"""HTML reports to act on: a calibration's and a diagnosis's (matplotlib figures as inline SVG)."""

from .calibration import calibration_html
from .diagnosis import diagnosis_html

__all__ = ["calibration_html", "diagnosis_html"]
