"""The SVG writer of the reports' figures: round ticks inside the axes, enough of them, labels that say them.

Its layout in a real browser (text inside each figure, no text over text) is checked by
tests/report/test_html.py, on the reports and on figures made here of awkward data.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from casadical.html import bands, colour_at, nice_ticks, text_width, tick_labels

RNG = np.random.default_rng(37)
RANGES = [tuple(sorted(RNG.normal(0, 10.0 ** e, 2))) for e in RNG.uniform(-5, 6, 300)]


@pytest.mark.parametrize("n, least", [(7, 4), (5, 4), (4, 4), (3, 3)])
def test_ticks_are_round_inside_and_enough(n, least):
    for lo, hi in RANGES:
        t = nice_ticks(lo, hi, n, least)
        assert least <= len(t) <= max(n + 1, least + 3), (lo, hi, t)
        assert lo - 1e-9 * (hi - lo) <= t[0] and t[-1] <= hi + 1e-9 * (hi - lo)
        step = t[1] - t[0]
        assert np.allclose(np.diff(t), step)
        mantissa = step / 10.0 ** math.floor(math.log10(step))
        assert min(abs(mantissa - m) for m in (1, 2, 2.5, 5, 10)) < 1e-6, step
        # the labels tell the ticks apart and read back as them
        labels = tick_labels(t)
        assert len(set(labels)) == len(labels)
        back = [float(s.replace("\u2212", "-")) for s in labels]
        assert np.allclose(back, t, rtol=1e-3, atol=1e-12 + 1e-3 * step)


def test_bands_cover_the_range_at_round_bounds():
    for lo, hi in RANGES:
        b = bands(lo, hi, 12)
        assert b[0] <= lo and b[-1] >= hi and 2 <= len(b) <= 16


def test_colour_map_ends_and_text_widths_grow():
    assert colour_at(("#000000", "#ffffff"), 0) == "#000000" and colour_at(("#000000", "#ffffff"), 2) == "#ffffff"
    assert colour_at(("#000000", "#ffffff"), 0.5) in ("#7f7f7f", "#808080")
    assert text_width("mmm", 10) > text_width("iii", 10) > 0
    assert text_width("0.25", 10) < text_width("0.255", 10)
