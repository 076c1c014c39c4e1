"""Numbers in the plain-text tables: one formatter for the parameter tables of
:mod:`casadical.parameters` and :mod:`casadical.stats._significance`; the short forms of the reports' words
(:func:`g3`, :func:`relative`)."""

from __future__ import annotations

import math
import re


def number(x: float, digits: int = 6, exp_digits: int | None = None) -> str:
    """``x`` in ``digits`` significant digits between 1e-3 and 1e5 (and 0), otherwise in exponent form with
    ``exp_digits`` decimals (default ``max(digits - 3, 2)``); ``-`` for a value that is not finite."""
    if not math.isfinite(x):
        return "-"
    if x == 0 or 1e-3 <= abs(x) < 1e5:
        return f"{x:.{digits}g}"
    return f"{x:.{max(digits - 3, 2) if exp_digits is None else exp_digits}e}"


def g3(x: float) -> str:
    """Three significant digits, a power of ten written short: ``5.38e4``, ``0.0123``."""
    return re.sub(r"e([+-])0*(\d)", lambda m: "e" + ("-" if m.group(1) == "-" else "") + m.group(2), f"{x:.3g}")


def relative(std: float, value: float) -> str:
    """`` +- 6.2 %``: a standard error relative to its value ('' when unknown)."""
    if not (math.isfinite(std) and math.isfinite(value)) or value == 0:
        return ""
    r = 100 * abs(std / value)
    return f" +- {r:.1f} %" if r < 10 else f" +- {r:.0f} %" if r < 1000 else " +- > 999 %"


def gain_words(drop_mm: float | None, digits: int = 4, unit: str = " mm") -> str:
    """A drop of an error in words, never a signed number: ``0.0292 mm better``, ``0.0030 mm worse``."""
    if drop_mm is None or not math.isfinite(drop_mm):
        return "-"
    if round(drop_mm, digits) == 0:
        return "no change"
    return f"{abs(drop_mm):.{digits}f}{unit} {'better' if drop_mm > 0 else 'worse'}"
