"""What the diagnosis could not explain, in words: the poses its final fit set aside, and what was not tried.

The poses the robust loss sets aside are tested for shared structure
(:mod:`casadical.stats.outliers`) before they are called bad measurements.
Structure that remains after the search is reported with where it lives
and, where a kind of cause could not be tried on these data
(:mod:`.catalogue`), with what would allow it.
"""

from __future__ import annotations

from ..errors import listing
from ..stats.outliers import SetAsideStructure
from .catalogue import NotTried

#: the kinds of structure each kind of cause not tried could explain
EXPLAINS = {"order": ("drift", "warmup"), "load": ("joint_compliance",), "direction": ("joint_compliance",),
            "region": ("joint_compliance",)}


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
            if any(c in n.cause for c in EXPLAINS.get(t.kind, ())) and (
                    t.joint is None or not n.joints or t.joint in n.joints):
                hint = f"{n.cause.replace('_', ' ')} could explain it but was not tried ({n.why}): {n.allow}"
                if hint not in hints:
                    hints.append(hint)
    return what + ("; " + "; ".join(hints) if hints else
                   "; no cause the diagnosis tried explains it: it stays in the residual")


#: causes of a joint's angle error that a compliance of the same joint can look like
LOAD_LOOKALIKES = ("encoder_scale", "joint_periodic", "backlash")


def untried_alternatives(findings: list, not_tried: list[NotTried]) -> None:
    """A named cause of a joint whose compliance could not be tried (no masses) may be that compliance: each
    such finding is declared ambiguous with it, with what would allow the diagnosis to tell."""
    for f in findings:
        c = f.candidate
        if c.cause not in LOAD_LOOKALIKES or c.joint is None:
            continue
        for n in not_tried:
            if "joint_compliance" in n.cause and (not n.joints or c.joint in n.joints) and "masses" in n.why:
                f.ambiguous_with.append({"cause": "joint_compliance", "joint": c.joint,
                                         "label": f"joint_compliance joint {c.joint} (not tried)",
                                         "tell_apart": f"{n.why}: {n.allow}"})
