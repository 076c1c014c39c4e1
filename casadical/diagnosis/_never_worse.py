"""Never worse than a kinematic calibration of the same poses, in mean and in worst case.

``calibrate --model kinematic`` is what a user has without the diagnosis: its final model must never do
worse, judged where the diagnosis judges everything, on the calibration poses' own folds
(:mod:`._validation`; the validation poses judge and never decide):

- on every kind of fold (random, time, joint, session) the held-out mean of the final model may not exceed
  the kinematic model's;
- nor may its worst held-out error exceed the kinematic model's by more than :data:`._worst.WORST_SHARE`.

When the geometry step was not supported on its own (on a weak design the unmodelled causes can hide it),
it is tried again once the causes are in the model, with the same tests. A final model that still does
worse than the kinematic one gives way to the latest model of the search that does not (down to the
kinematic model itself), and a note says what was dropped and why.

The validation poses then say, as a judge, whether the final model's worst error rose by more than
:data:`._worst.WORST_SHARE` over the kinematic model's or over the model the GP compensator extends
(:func:`._worst.validation_note`): where, how much, whether the folds saw it, and whether those poses are ones no
model of the robot predicts (beyond the robust loss's limit: a bad measurement or a transient).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..result import CalibrationResult
from ..terms import GEOMETRIC
from ._candidates import Candidate, compose_terms, model_spec
from ._report import Finding, Step
from ._state import DiagnosisRun, StageOutcome
from ._validation import cv_record, cv_text
from ._worst import Held, noise_band


def held(run: DiagnosisRun, res: CalibrationResult, mask: np.ndarray) -> Held:
    return Held.of(run.held_out(res), mask)


@dataclass
class Changes:
    """What the check changes of the run while it runs, returned at its end: its notes, its step and the fit it
    holds (``recorded``), the findings."""

    findings: list[Finding]
    notes: list[str] = field(default_factory=list)
    steps: list[Step] = field(default_factory=list)
    recorded: list = field(default_factory=list)


def keep_never_worse(run: DiagnosisRun) -> StageOutcome:
    """Stage ``keep_never_worse``: the geometry again with the causes in the model (when it was not supported
    alone), then the final model never worse than the kinematic one on the calibration poses' folds (see the
    module). Reads the model under way, ``kinematic`` and the search's ``history``; sets ``held_text``; returns
    the final model of the named causes, the step of the geometry tried again and its fit, the notes and the
    findings."""
    run.say("final check: never worse than the kinematic model, in mean and worst case")
    changes = Changes(list(run.findings))
    model = run.under_way()
    current, accepted, geometric = _final_model(run, changes, model.current, list(model.accepted), model.geometric)
    return StageOutcome(notes=tuple(changes.notes), steps=tuple(changes.steps), recorded=tuple(changes.recorded),
                        findings=tuple(changes.findings), model=model.holding(current, accepted, geometric))


def _final_model(run: DiagnosisRun, changes: Changes, current: CalibrationResult, accepted: list[Candidate],
                 geometric: bool) -> tuple[CalibrationResult, list[Candidate], bool]:
    kin = run.kinematic
    mask = run.mask(current) & run.mask(kin)
    with_geometry = None
    if not geometric and accepted:
        with_geometry = run.fit(compose_terms(accepted, True), start=current)
        if _geometry_again(run, changes, current, with_geometry, accepted, mask):
            current, geometric = with_geometry, True
    ref = held(run, kin, mask)
    now = held(run, current, mask)
    run.held_text = _worst_text(ref, now)
    band = noise_band(kin, current)
    bad = now.worse_than(ref, band)
    if not bad:
        if now.traded(ref, band):
            changes.notes.append("the final model's worst held-out error rises where its mean drops, on the "
                                 "calibration poses' folds: "
                                 + ", ".join(f"{k} worst {ref.worst[k]:.4f} -> {now.worst[k]:.4f} mm, "
                                             f"mean {ref.mean[k]:.4f} -> {now.mean[k]:.4f} mm"
                                             for k in now.traded(ref, band))
                                 + " against the kinematic model; the poses of those folds' largest errors are where "
                                   "it extrapolates least surely")
            run.say(f"  {changes.notes[-1]}")
        return current, accepted, geometric
    options = []
    if not geometric and accepted:
        options.append((with_geometry, list(accepted), True))
    options += [(fit, list(earlier), fit.model.geometric_free) for earlier, fit in reversed(run.history)
                if set(earlier) <= set(accepted) and fit is not current]
    options.append((kin, [], True))
    for fit, earlier, geo in options:
        now = held(run, fit, mask)
        if fit is not kin and now.worse_than(ref, noise_band(kin, fit)):
            continue
        run.held_text = _worst_text(ref, now)
        dropped = [a for a in accepted if a not in earlier]
        changes.findings = [f for f in changes.findings if f.candidate not in dropped]
        if geo and not geometric:
            _add_geometry_finding(run, changes, fit, current)
        elif geometric and not geo:         # back to a model the geometry was tried again on
            changes.findings = [f for f in changes.findings if not f.candidate.kind.geometry]
        what = ("the kinematic model itself" if fit is kin else
                "the model with the geometry" if geo and not geometric else "the last model of the search that is not")
        changes.notes.append("never worse than a kinematic calibration: the model with every cause did worse than "
                             "the kinematic model on the calibration poses' folds (held-out " + ", ".join(bad)
                             + f"); the final model is {what}"
                             + (", without " + ", ".join(a.label() for a in dropped) if dropped else ""))
        run.say(f"  {changes.notes[-1]}")
        return fit, earlier, geo
    return current, accepted, geometric     # (not reached: the kinematic model is never worse than itself)


def _worst_text(ref: Held, final: Held) -> str:
    return ("the worst held-out error is " + ", ".join(f"{k} {final.worst[k]:.4f} mm" for k in ref.worst)
            + " (kinematic " + ", ".join(f"{ref.worst[k]:.4f}" for k in ref.worst) + ")")


def _geometry_again(run: DiagnosisRun, changes: Changes, current: CalibrationResult, fit: CalibrationResult,
                    accepted: list[Candidate], mask: np.ndarray) -> bool:
    """The geometry step once more, the causes in the model: the same tests as the first time (F-test, BIC,
    held-out means that drop on every kind of fold); recorded as a step, and as the geometric finding."""
    test = run.compare(current, fit, fit.loss)
    h0, h1 = held(run, current, mask), held(run, fit, mask)
    worse = [k for k in h0.mean if not h1.mean[k] < h0.mean[k]]
    ok = test.log10_p < math.log10(run.s.alpha) and test.delta_bic < 0 and not worse
    reason = "; ".join([f"not significant ({test.text()})"] * (test.log10_p >= math.log10(run.s.alpha))
                       + [f"BIC does not improve ({test.delta_bic:+.1f})"] * (test.delta_bic >= 0)
                       + ["held-out mean does not drop: " + ", ".join(f"{k} {h0.mean[k]:.4f} -> {h1.mean[k]:.4f} mm"
                                                                      for k in worse)] * bool(worse))
    parent = run.step_of(current)
    pv, v = run.val_stats(current), run.val_stats(fit)
    changes.steps.append(Step(model_spec(accepted, True), fit.calibration, v, ok, Candidate(GEOMETRIC.name), test,
                              cv_record(h0.mean, h1.mean), reason, run.val_angles(fit), parent=parent,
                              parent_mm=pv.mean_mm))
    if ok:
        changes.recorded.append((fit, len(run.steps) + len(changes.steps) - 1, tuple(accepted)))
        _add_geometry_finding(run, changes, fit, current, f"{test.text()} on the calibration poses with the causes "
                                                          f"in the model; held-out mean {cv_text(h0.mean, h1.mean)}")
        changes.notes.append("the geometry step, not supported alone, is supported once the causes are in the model "
                             f"({test.text()}): the final model has it")
        run.say(f"  geometry again, with the causes: accepted ({test.text()})")
    else:
        run.say(f"  geometry again, with the causes: not supported ({reason})")
    return ok


def _add_geometry_finding(run: DiagnosisRun, changes: Changes, fit: CalibrationResult, without: CalibrationResult,
                          evidence: str = "") -> None:
    if any(f.candidate.kind.geometry for f in changes.findings):
        return
    gain = run.val_stats(without).mean_mm - run.val_stats(fit).mean_mm
    changes.findings.insert(0, Finding(Candidate(GEOMETRIC.name), gain, evidence or
                                       "never worse than a kinematic calibration of the same poses on their folds; "
                                       "link, base and tool parameters"))
