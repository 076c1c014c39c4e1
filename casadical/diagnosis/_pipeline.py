"""``diagnose()``: what the model gets wrong, why, and what each extension gains, through named stages.

After the nominal and the geometric steps, every round screens all
candidate causes at once with a score test (:mod:`._screening`), fits the
best for real and accepts a cause only when the calibration data support it
three ways: significance (F-test at a Bonferroni-corrected level, BIC) and
held-out error on folds that must extrapolate as well as interpolate
(random, time-blocked and joint-range-blocked cross-validation,
:mod:`._validation`). Physical causes (compliance, progressive stiffness,
encoder scale, backlash, thermal expansion, drift, warm-up) are tried before
periodic errors, which must also be resolved from their neighbouring
harmonics and from geometry and agree over the two halves of the joint's
range (:mod:`._periodic`); structure that passes the statistics but not
these checks is reported as ``unexplained`` and kept out of the model.
At the end every accepted cause is tested again against the final model
(:mod:`._redundancy`) and must still be physics (:mod:`._unphysical`, :mod:`casadical.stats._physics`);
the final model never does worse than the kinematic one where it must
extrapolate. With several sessions every cause is asked whether one value
serves every session (the robot's) or only one session's own (the
session's; :mod:`._catalogue`). The poses the final fit sets aside are
tested for shared structure before they are called bad measurements
(:mod:`casadical.stats._outliers`, :mod:`._gaps`), and what these data cannot test
is said (:func:`._catalogue.not_tried`). The validation poses judge every step and are never used
to accept one. The GP compensator last (:mod:`._compensator`: one per
session, applied where it knows) takes what no named cause explains;
:mod:`._transfer` takes the findings to another series.

Each stage is a function ``stage(run)`` of its own module that reads what the stages before it set on the
:class:`~._state.DiagnosisRun` and sets the fields only it sets; what several stages change (the notes, the steps
and the fits they hold, the findings, the model under way, the final model) a stage returns in a
:class:`~._state.StageOutcome` (its model of the named causes a :class:`~._state.ModelUnderWay`, its final model a
:class:`~._state.FinalModel`), and the pipeline installs it (:meth:`~._state.DiagnosisRun.install`), so that each
field of the run has one writer and no stage rewrites another's model or log in place
(``tests/diagnosis/test_stage_writes.py``). :data:`STAGES` is their order. To add a stage, write it in a module
of this package (a docstring saying what it reads, sets and returns), give the run the fields only it sets,
return what it adds to the shared ones, and put it in :data:`STAGES` where its inputs are ready.
"""

from __future__ import annotations

from typing import Callable

from ..data._measurements import Measurements
from ..robot import Robot
from ..runtime._threads import limited_threads
from ._compensator import add_compensator
from ._describe import describe_findings
from ._geometry import fit_geometry
from ._intervals import calibrate_intervals
from ._judge import judge_final_model
from ._never_worse import keep_never_worse
from ._nominal import fit_nominal
from ._outcome import assemble_report
from ._prepare import check_data
from ._redundancy import drop_redundant
from ._report import DiagnosisReport
from ._search import search_causes
from ._settings import DiagnosisSettings
from ._stand_ins import drop_stand_ins
from ._state import DiagnosisRun, StageOutcome
from ._structure import screen_structure
from ._transfer import transfer_findings
from ._unphysical import drop_unphysical
from ._worst_case import keep_worst_case

#: the stages of :func:`diagnose`, in order
STAGES: tuple[Callable[[DiagnosisRun], StageOutcome | None], ...] = (
    check_data,         # the poses against the robot, the validation poses held out; equations, folds, sessions
    fit_nominal,        # step 1: the nominal model, its base pose fitted
    fit_geometry,       # step 2: the kinematic calibration; how weak the design is; where the search starts
    search_causes,      # rounds: screen every candidate cause, fit the best, accept one the data support
    drop_redundant,     # final check: is every cause still needed?
    drop_unphysical,    # final check: is every cause still physics?
    drop_stand_ins,     # final check: does every named cause explain the structure it stands for?
    keep_never_worse,   # final check: never worse than the kinematic model, in mean and worst case
    screen_structure,   # what the named causes leave: structure no catalogue cause explains, and where it lives
    add_compensator,    # the GP compensator of what no named cause explains (one per session), judged like a step
    keep_worst_case,    # a worst validation error above the kinematic model's: what to drop (--worst-case: dropped)
    calibrate_intervals,  # the 95 % interval's factor of the named causes, calibrated on the folds
    describe_findings,  # each finding's values, evidence, figure and scope; the structure that cannot be named
    judge_final_model,  # the validation poses on the final model; the residual, sag and set-aside poses
    transfer_findings,  # with another series: does each finding hold up there?
    assemble_report,    # the DiagnosisReport
)


@limited_threads()
def diagnose(robot: Robot, cal: Measurements, val: Measurements, settings: DiagnosisSettings | None = None,
             progress: Callable[[str], None] | None = None, other: Measurements | None = None,
             **checks: bool) -> DiagnosisReport:
    """Calibrate step by step on ``cal``, judge every step on ``val``, name the causes.

    Parameters
    ----------
    robot : Robot
    cal, val : Measurements
        Calibration and validation poses, both with measured positions. The
        validation poses judge; they never decide.
    settings : DiagnosisSettings, optional
    progress : callable, optional
        Receives one line of text per step (the command line prints them).
    other : Measurements, optional
        Another measurement series of the same robot: every finding is
        taken there (:mod:`casadical.diagnosis._transfer`).
    **checks : bool
        Overrides of the plausibility checks of the poses
        (:func:`casadical.data._checks.check_poses`: ``allow_outside_limits``,
        ``angles_are_degrees``, ``positions_are_mm``, ``allow_mismatch``:
        poses of ``cal``, ``val`` or ``other`` the nominal model misses by
        more than 5 % of the robot's reach with its base pose fitted).

    Raises
    ------
    DataFileError
        Every validation (or ``other``) pose is a calibration pose (:func:`casadical.data._checks.check_held_out`,
        :func:`~casadical.data._checks.check_other_series`; some of them: a warning), or a check of the poses fails.
    """
    run = DiagnosisRun(robot, cal, val, settings or DiagnosisSettings(), progress or (lambda _: None), other,
                       checks)
    for stage in STAGES:
        made = stage(run)
        if made is not None:
            run.install(made)
    return run.report
