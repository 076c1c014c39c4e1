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

from .state import CalibrationRun

#: what touches cannot see, in words (docs/formats.md section 11)
BASE_WHY = "nothing measures the robot against the world"
SCALE_WHY = "no known distance"


def fix_unobservable(run: CalibrationRun) -> None:
    data, params = run.data, run.params
    if not data.touches:
        return
    measured = ~data.touching
    sessions = data.sessions if data.sessions is not None else np.full(len(data), None, dtype=object)
    names = data.session_names or [None]
    blind = [s for s in names if not measured[sessions == s].any()]
    for k, s in enumerate(names):
        if s not in blind:
            continue
        at = "" if k == 0 else f"@{s}"
        fixed = [p.name for p in params if p.group == "base" and p.name.endswith(at) and (at or "@" not in p.name)
                 and not p.fixed]
        params.fix(fixed, f"the base pose: {BASE_WHY}")
        run.unobservable.append({"what": "the base pose" + (f" of session {s}" if s else ""), "why": BASE_WHY,
                                 "parameters": fixed})
    if not data.layout.known_distance():
        lengths = [p for p in params if p.term == "geometric" and p.group == "link" and p.unit == "m"
                   and not p.fixed]
        if lengths:
            longest = max(lengths, key=lambda p: abs(p.nominal))
            params.fix([longest.name], f"the scale of every length: {SCALE_WHY}")
            run.unobservable.append({"what": "the scale of every length", "why": SCALE_WHY,
                                     "parameters": [longest.name]})
