"""Stage ``fit_geometry``: step 2, the geometric (kinematic) calibration, and how weak the design is.

Reads ``nominal``; sets ``kinematic``, the check of the robot file's gravity against a levelled instrument's down
(``gravity``, :mod:`casadical.calibration._gravity`: a note and a warning where they disagree), the design's
assessment (:mod:`._design`) and the cross-validation folds (``schemes``; on a weak design the folds get
priors of the geometry, ``prior``, and a design of one joint at a time its own folds); returns its notes, the
second step (and the geometric finding where it is supported), and the model the search starts from (the
kinematic model where the geometry is supported, else the nominal one).
"""

from __future__ import annotations

import math

from ..calibration._gravity import warn_gravity
from ..terms import GEOMETRIC
from ._candidates import Candidate, compose_terms
from ._design import assess, priors
from ._report import Finding, Step
from ._state import DiagnosisRun, ModelUnderWay, StageOutcome
from ._validation import cv_failure, cv_record, cv_text, not_better


def fit_geometry(run: DiagnosisRun) -> StageOutcome:
    run.say("step 2: geometric (kinematic) calibration")
    nominal = run.nominal
    kin = run.kinematic = run.fit(compose_terms([]))
    notes = []
    run.gravity = warn_gravity(kin, run.s.levelled)
    if run.gravity is not None and run.gravity.warns:
        notes.append(run.gravity.text())
        run.say(f"  {notes[-1]}")
    run.design = assess(run.cal, kin, run.n_fit_eq)
    # on a design of one joint at a time, folds that leave out part of every joint's sweep, never a whole one
    run.schemes = run.fold_schemes(run.design.moving if run.design.weak and run.design.one_at_a_time else None)
    if run.design.weak:
        run.prior = priors(kin)
        notes.append(run.design.text())
        run.say(f"  {notes[-1]}")
    test = run.compare(nominal, kin, kin.loss)
    mask = run.mask(kin)
    cv0, cv1 = (run.cv(r, mask) for r in (nominal, kin))
    worse = not_better(cv0, cv1)
    ok = test.log10_p < math.log10(run.s.alpha) and test.delta_bic < 0 and not worse
    kv = run.val_stats(kin)
    reason = "; ".join([f"not significant ({test.text()})"] * (test.log10_p >= math.log10(run.s.alpha))
                       + [f"BIC does not improve ({test.delta_bic:+.1f})"] * (test.delta_bic >= 0)
                       + ([cv_failure(worse, cv0, cv1)] if worse else []))
    step = Step("kinematic", kin.calibration, kv, ok, Candidate(GEOMETRIC.name), test, cv_record(cv0, cv1), reason,
                run.val_angles(kin), parent=0, parent_mm=run.steps[0].validation.mean_mm)
    run.say(f"  validation mean {kv.mean_mm:.4f} mm ({test.text()})")
    findings = ()
    if ok:
        gain = run.steps[0].validation.mean_mm - kv.mean_mm
        findings = (Finding(Candidate(GEOMETRIC.name), gain, f"{test.text()} on the calibration poses; held-out mean "
                            + cv_text(cv0, cv1) + "; link, base and tool parameters"),)
    start = kin if ok else nominal
    return StageOutcome(notes=tuple(notes), steps=(step,), recorded=((kin, 1, None), (start, None, ())),
                        findings=(*run.findings, *findings), model=ModelUnderWay(start, (), ok, {}, {}))
