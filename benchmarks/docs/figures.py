"""A figure the docs quote against what a command prints now: to a tolerance no CPU changes.

The docs quote what the commands print, to the digits they print. The last of those digits are not the same on
every machine: another CPU (or BLAS kernel) rounds differently, so an iterative fit ends a rounding away from the
quoted one, and a fit the diagnosis stops once its next step is below a hundredth of every standard error
(``std_tol``) can take one step more or less. docs/guide.md's track example printed 2.9386 / 2.2791 mm on a
2-core AMD EPYC where a Xeon printed the quoted 2.9381 / 2.2796 (1.7e-4 of the figure, issue 47). So a quoted
figure matches a printed one within

    max(u, min(10 u, 1e-3 |quoted|))

where ``u`` is one unit of the quoted figure's last digit (0.0001 for 2.9381, 0.01e6 for 1.73e6): one unit,
as any figure at a rounding boundary may move; a thousandth of the figure, what a fit's tolerance leaves of it
(6x the largest difference seen); and never more than ten units of the last digit, so that a figure quoted to
many digits (a tracker position to 0.1 um, a converged parameter) keeps its precision. A whole number (no
decimal point, no exponent: a count of poses, rows, rounds) must be equal. Everything else (words, units,
punctuation) must be as quoted. A figure changed in its third significant digit is caught: 0.3651 against
0.3681, 2.9381 against 2.9481.

A number is a run of digits with an optional sign, decimals and exponent that is not part of a word: ``j2``,
``ur10`` and ``series_b`` are text.
"""

from __future__ import annotations

import bisect
import re
from dataclasses import dataclass

#: a thousandth of the figure (see the module's docstring)
REL = 1e-3
#: ... never more than this many units of its last digit
MAX_UNITS = 10

NUMBER = re.compile(r"(?<![\w.])[-+]?\d+(?:\.(\d+))?(?:[eE]([-+]?\d+))?(?!\w|\.\d)")
_SPACE = re.compile(r"\s+")


@dataclass(frozen=True)
class Figure:
    """A number as quoted: its value and the tolerance of a printed figure that stands for it."""

    text: str

    @property
    def value(self) -> float:
        return float(self.text)

    @property
    def tolerance(self) -> float:
        m = NUMBER.fullmatch(self.text)
        decimals, exponent = m.group(1), m.group(2)
        if decimals is None and exponent is None:
            return 0.0                                     # a count: exactly
        unit = 10.0 ** (int(exponent or 0) - len(decimals or ""))
        return max(unit, min(MAX_UNITS * unit, REL * abs(self.value)))

    def matches(self, printed: str) -> bool:
        # a relative 1e-12 for the binary rounding of the two decimal strings
        return abs(float(printed) - self.value) <= self.tolerance + 1e-12 * abs(self.value)


def _tokens(piece: str) -> list:
    """Text and figures of a piece of quoted text without whitespace."""
    out, pos = [], 0
    for m in NUMBER.finditer(piece):
        if m.start() > pos:
            out.append(piece[pos:m.start()])
        out.append(Figure(m.group()))
        pos = m.end()
    if pos < len(piece):
        out.append(piece[pos:])
    return out


_GAP = object()      # whitespace: any run of whitespace


class Quote:
    """Quoted text to look for in printed text: ``...`` stands for anything (elided text or lines), a run of
    whitespace for any run of whitespace (a long line may be wrapped), a figure for one within its tolerance."""

    def __init__(self, quoted: str, elide: bool = True):
        self.quoted = quoted
        # segments between the "..." (each a list of text, _GAP and Figure items)
        self.segments: list[list] = [[]]
        for piece in re.split(r"(\.\.\.|\s+)" if elide else r"(\s+)", quoted.strip()):
            if piece == "..." and elide:
                self.segments.append([])
            elif piece.isspace():
                if self.segments[-1]:          # "...\n text": the elision covers the whitespace
                    self.segments[-1].append(_GAP)
            elif piece:
                self.segments[-1].extend(_tokens(piece))

    def _at(self, segment: list, text: str, pos: int) -> int | None:
        """The end of ``segment`` matched at ``pos`` of ``text``, or None."""
        for item in segment:
            if item is _GAP:
                m = _SPACE.match(text, pos)
            elif isinstance(item, Figure):
                m = NUMBER.match(text, pos)
                if m and not item.matches(m.group()):
                    return None
            else:
                m = item if text.startswith(item, pos) else None
                if m:
                    pos += len(item)
                    continue
            if not m:
                return None
            pos = m.end()
        return pos

    def _starts(self, first, text: str, pos: int, numbers: list[int]):
        """Where a segment beginning with ``first`` may begin, from ``pos`` on."""
        if isinstance(first, str):
            k = text.find(first, pos)
            while k >= 0:
                yield k
                k = text.find(first, k + 1)
        elif isinstance(first, Figure):
            yield from numbers[bisect.bisect_left(numbers, pos):]
        else:
            yield from range(pos, len(text) + 1)

    def search(self, text: str) -> bool:
        """Whether the quote occurs in ``text``: each segment at its first place after the one before."""
        numbers = [m.start() for m in NUMBER.finditer(text)]
        pos = 0
        for segment in self.segments:
            if not segment:
                continue
            for start in self._starts(segment[0], text, pos, numbers):
                end = self._at(segment, text, start)
                if end is not None:
                    pos = end
                    break
            else:
                return False
        return True

    def fullmatch(self, text: str) -> bool:
        """Whether ``text`` is the quote, the whole of it (a quote without ``...``)."""
        return len(self.segments) == 1 and self._at(self.segments[0], text, 0) == len(text)


def same_line(quoted: str, printed: str) -> bool:
    """Whether a printed line is a quoted one (its figures within their tolerance, the rest as quoted)."""
    return Quote(quoted, elide=False).fullmatch(printed.strip())
