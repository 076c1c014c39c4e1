"""Stage ``check_data``: the poses against the robot, the validation poses held out, the folds.

Reads the caller's robot, calibration, validation and other poses and the settings; sets the equation counts
(``n_eq``: positions, the screening's; ``n_fit_eq``: every full fit's, 6 a pose on the full pose), the sessions
and the catalogue of candidate causes; returns its notes. A check that fails raises before any fit.
"""

from __future__ import annotations

from ..data._checks import check_held_out, check_other_series, check_poses
from ..terms._tool_points import check_tool_points
from ._catalogue import Catalogue
from ._state import DiagnosisRun, StageOutcome


def check_data(run: DiagnosisRun) -> StageOutcome:
    """Check the poses (:func:`casadical.data._checks.check_poses`, the joint count first), that the validation (and
    other) poses are not the calibration poses; then set up what every later stage counts on."""
    cal = run.cal
    for d in [cal, run.val] + ([run.other] if run.other is not None else []):
        check_poses(d, run.robot, **run.checks)
    check_held_out(cal, run.val)            # validation poses the fits have seen would judge nothing
    notes = []
    said = check_tool_points(cal, run.robot)    # tool points the robot file gives no nominal offset
    if said:
        notes.append(f"{run.robot.source or run.robot.name}: {said}")
    if run.other is not None:
        check_other_series(cal, run.other)
    # rows that touch: their layout's equations (each touched thing's unknowns used up, casadical.rows)
    run.n_eq = cal.layout.equations if cal.touches else 3 * len(cal)
    run.full_pose = cal.has_orientation and not run.s.position_only
    run.n_fit_eq = run.n_eq * (2 if run.full_pose else 1)
    run.sessions = cal.session_names
    run.catalogue = Catalogue(run.robot, cal, run.s)
    if run.full_pose:
        notes.append("full pose: every fit is on the measured positions and orientations, weighted by their "
                         "noise scales from the data (as calibrate); the screening of candidate causes, its tests "
                         "and the cross-validation folds work on the positions; --position-only fits the positions "
                         "alone")
        run.say("full pose: the fits weigh the measured orientations too (--position-only: positions alone)")
    return StageOutcome(notes=tuple(notes))
