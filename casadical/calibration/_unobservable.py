"""Stage ``fix_unobservable``: what rows that say what they touched cannot see, fixed and said in words.

A touched point, plane or pivot is an unknown of its session (:mod:`casadical.rows`), so touches cannot see:

- **the base pose** of a session without a measured row: nothing measures the robot against the world (its
  points are fitted wherever the robot puts them). Its parameters are fixed at the robot's base frame; a
  calibration of touches alone predicts in that frame (``"frame": "base"``);
- **the scale of every length** without a known distance (tracker rows, a pivot's ``distance_mm``, a fixture's
  points): the robot's points shrink with its lengths, and so do their spreads about what they touch. The longest
  length of the chain is held at its nominal value, which sets the scale.

Sets ``unobservable`` (what, why, the parameters fixed) and fixes those parameters.
"""

from __future__ import annotations

import numpy as np

from ..terms._geometric import Geometric
from ._state import CalibrationRun

#: what touches cannot see, in words (docs/formats.md section 11)
BASE_WHY = "nothing measures the robot against the world"
SCALE_WHY = "no known distance"


def fix_unobservable(run: CalibrationRun) -> None:
    """What rows that touch cannot see (:func:`unseen`: the base pose; without a known distance, the scale) held at
    the robot file's values and said; sets ``run.unobservable``. Nothing for rows an instrument measured."""
    run.unobservable = unseen(run.data, run.params)
    for u in run.unobservable:
        run.params.fix(u["parameters"], f"{u['what']}: {u['why']}")


def unseen(data, params) -> list[dict]:
    """What the rows of ``data`` that touch cannot see among the free ``params``: entries ``what``, ``why`` and
    ``parameters`` (to be held); none for measured rows alone."""
    if not data.touches:
        return []
    out = []
    measured = ~data.touching
    sessions = data.sessions if data.sessions is not None else np.full(len(data), None, dtype=object)
    names = data.session_names or [None]
    blind = [s for s in names if not measured[sessions == s].any()]
    # every session's base pose at once when no row is measured; else each session's without a measured row

    def base(s) -> list[str]:
        at = "" if s == names[0] else f"@{s}"
        return [p.name for p in params if p.group == "base" and not p.fixed
                and (p.name.endswith(at) if at else "@" not in p.name)]
    if len(blind) == len(names):
        out.append({"what": "the base pose", "why": BASE_WHY, "parameters": [n for s in blind for n in base(s)]})
    else:
        out += [{"what": f"the base pose of session {s}", "why": BASE_WHY, "parameters": base(s)} for s in blind]
    if not data.layout.known_distance():
        lengths = [p for p in params if p.term == Geometric.name and p.group == "link" and p.unit == "m"
                   and not p.fixed]
        if lengths:
            longest = max(lengths, key=lambda p: abs(p.nominal))
            out.append({"what": "the scale of every length", "why": SCALE_WHY, "parameters": [longest.name]})
    return out


def whole_robot(ident, moving: set[str], unobservable: list[dict]) -> set[str]:
    """Touches alone: the parameters ``ident`` finds without effect that do move the point (``moving``: their
    columns before the projection are not zero): they only move the whole robot (the first link's place: the base
    pose's). Reworded and added to ``unobservable``'s base pose; their names."""
    whole = [u for u in ident.unidentifiable if u.name in moving and u.reason.startswith("has no effect")]
    for u in whole:
        u.reason = f"moves the whole robot: {BASE_WHY}"
    base = next((e for e in unobservable if e["what"] == "the base pose"), None)
    if base is not None:
        base["parameters"] = base["parameters"] + [u.name for u in whole]
    return {u.name for u in whole}
