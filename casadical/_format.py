"""Numbers in the plain-text tables: one formatter for the parameter tables of
:mod:`casadical.model.parameters` and :mod:`casadical.stats.significance`."""

from __future__ import annotations

import math


def number(x: float, digits: int = 6, exp_digits: int | None = None) -> str:
    """``x`` in ``digits`` significant digits between 1e-3 and 1e5 (and 0), otherwise in exponent form with
    ``exp_digits`` decimals (default ``max(digits - 3, 2)``); ``-`` for a value that is not finite."""
    if not math.isfinite(x):
        return "-"
    if x == 0 or 1e-3 <= abs(x) < 1e5:
        return f"{x:.{digits}g}"
    return f"{x:.{max(digits - 3, 2) if exp_digits is None else exp_digits}e}"
