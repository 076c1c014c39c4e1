"""The HTML reports under their former name: :mod:`casadical.html` holds them now."""

from .html import calibration_html, diagnosis_html

__all__ = ["calibration_html", "diagnosis_html"]
