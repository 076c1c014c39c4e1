"""What the diagnosis could not explain, in words: the poses its final fit set aside, and what was not tried.

The poses the robust loss sets aside are tested for shared structure
(:mod:`casadical.stats._outliers`) before they are called bad measurements.
Structure that remains after the search is reported with where it lives
and, where a kind of cause could not be tried on these data
(:mod:`._catalogue`), with what would allow it.
"""

from __future__ import annotations

from ..errors import listing
from ..stats._outliers import SetAsideStructure
from ..terms import CAUSES
from ._catalogue import NotTried


def set_aside_note(structure: SetAsideStructure, not_tried: list[NotTried], path: str,
                   misses: dict[int, list[int]] | None = None, where: dict[int, str] | None = None) -> str:
    """The note on the final fit's set-aside poses: the largest misses of structure the screen found (``misses``:
    finding number -> file rows; ``where``: the findings' words), bad measurements, or structure with where (and
    what would let the diagnosis try a cause of it)."""
    what = (f"the robust loss set aside {structure.n_set_aside} calibration pose(s) of {path} (rows "
            + listing(structure.lines, 10) + "): ")
    parts = [(f"row {lines[0]} is the largest miss" if len(lines) == 1 else
              f"rows {listing([str(x) for x in lines], 10)} are the largest misses")
             + f" of the structure in finding {n} ({where[n]}), not bad measurements"
             for n, lines in (misses or {}).items()]
    what += "; ".join(parts + [structure.text()] * bool(structure.text()))
    if not structure.structured:
        return what
    hints = []
    for t in structure.significant:
        for n in not_tried:
            if any(t.kind in CAUSES[c].explains_set_aside for c in n.causes) and (
                    t.joint is None or not n.joints or t.joint in n.joints):
                hint = f"{n.cause.replace('_', ' ')} could explain it but was not tried ({n.why}): {n.allow}"
                if hint not in hints:
                    hints.append(hint)
    return what + ("; " + "; ".join(hints) if hints else
                   "; no cause the diagnosis tried explains it: it stays in the residual")


def untried_alternatives(findings: list, not_tried: list[NotTried]) -> None:
    """A named cause of a joint whose compliance could not be tried (no masses) may be that compliance: each
    such finding is declared ambiguous with it, with what would allow the diagnosis to tell (a cause says what it
    can look like, :attr:`~casadical.terms._cause.Cause.looks_like`)."""
    for f in findings:
        c = f.candidate
        if c.joint is None:
            continue
        for n in not_tried:
            if n.condition != "masses" or (n.joints and c.joint not in n.joints):
                continue
            for untried in (CAUSES[name] for name in n.causes):
                if c.cause in untried.looks_like:
                    f.ambiguous_with.append({"cause": untried.name, "joint": c.joint,
                                             "label": f"{untried.name} joint {c.joint} (not tried)",
                                             "tell_apart": f"{n.why}: {n.allow}"})
