"""Never worse than a kinematic calibration of the same poses, in mean and in worst case.

``calibrate --model kinematic`` is what a user has without the diagnosis: its final model must never do
worse, judged where the diagnosis judges everything, on the calibration poses' own folds
(:mod:`.validation`; the validation poses judge and never decide):

- on every kind of fold (random, time, joint, session) the held-out mean of the final model may not exceed
  the kinematic model's;
- nor may its worst held-out error exceed the kinematic model's by more than :data:`WORST_SHARE`.

When the geometry step was not supported on its own (on a weak design the unmodelled causes can hide it),
it is tried again once the causes are in the model, with the same tests. A final model that still does
worse than the kinematic one gives way to the latest model of the search that does not (down to the
kinematic model itself), and a note says what was dropped and why.

The validation poses then say, as a judge, whether the final model's worst error rose by more than
:data:`WORST_SHARE` over the kinematic model's or over the model the GP compensator extends
(:func:`validation_note`): where, how much, whether the folds saw it, and whether those poses are ones no
model of the robot predicts (beyond the robust loss's limit: a bad measurement or a transient).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import listing
from ..result import CalibrationResult
from ..terms import GEOMETRIC
from .candidates import Candidate, compose_spec
from .report import Finding, Step
from .state import DiagnosisRun
from .validation import CVResult, cv_record, cv_text, kinds

#: the worst held-out (or validation) error may rise by this share at most without a word
WORST_SHARE = 0.05
#: a robust weight below this: a pose no model of the robot predicts (as the calibration's set-aside poses)
SET_ASIDE_WEIGHT = 0.5


@dataclass
class Held:
    """Held-out errors (mm) of a model on the calibration poses' folds, by kind: mean and worst."""

    mean: dict[str, float]
    worst: dict[str, float]

    @classmethod
    def of(cls, cv: CVResult, mask: np.ndarray) -> "Held":
        errs = {k: cv.kind_errors(k)[mask] * 1000 for k in kinds(cv)}
        return cls({k: float(e.mean()) for k, e in errs.items()}, {k: float(e.max()) for k, e in errs.items()})

    def worse_than(self, ref: "Held", band: float = 0.0) -> list[str]:
        """What is worse than ``ref``: a mean above it; a worst error more than :data:`WORST_SHARE` above it and
        beyond the noise ``band`` (mm, :func:`noise_band`: a worst error inside it is a draw of the noise), where
        the mean does not drop by more than that share (:meth:`traded`)."""
        out = [f"mean {k} {ref.mean[k]:.4f} -> {self.mean[k]:.4f} mm" for k in ref.mean
               if self.mean[k] > ref.mean[k] * (1 + 1e-9)]
        traded = self.traded(ref, band)
        out += [f"worst {k} {ref.worst[k]:.4f} -> {self.worst[k]:.4f} mm" for k in self.rises(ref, band)
                if k not in traded]
        return out

    def rises(self, ref: "Held", band: float = 0.0) -> list[str]:
        """Kinds of fold where the worst error is more than :data:`WORST_SHARE` above ``ref``'s and beyond ``band``."""
        return [k for k in ref.worst if self.worst[k] > max(ref.worst[k] * (1 + WORST_SHARE), band)]

    def traded(self, ref: "Held", band: float = 0.0) -> list[str]:
        """Kinds of fold where the worst error rises (:meth:`rises`) while the mean drops by more than
        :data:`WORST_SHARE`: a trade the report states, not a model worse than ``ref``. (Two sessions
        of an arm, one holding joint 1 within 6 deg: its encoder scale, fitted on that session alone, raised the
        worst error of the other session's fold 8 % and dropped its mean 21 %; the validation mean 0.136 ->
        0.032 mm.)"""
        return [k for k in self.rises(ref, band) if self.mean[k] < ref.mean[k] * (1 - WORST_SHARE)]


def noise_band(*fits: CalibrationResult) -> float:
    """The largest error (mm) the noise alone gives a pose as the robust loss sees it: where its weight falls to
    :data:`SET_ASIDE_WEIGHT` (``sqrt(3) c sigma``, about 5 sigma per axis), the narrowest of ``fits``'.

    Within it the worst held-out error of a few dozen poses is the noise of one of them (the largest of 80
    noise vectors is 3-4 sigma): a model that predicts every pose better can move it by a few um either way,
    and that says nothing of the model's worst case."""
    out = math.inf
    for f in fits:
        sigma = f.loss.sigma if f.loss.robust else (f.uncertainty.sigma if f.uncertainty is not None else 0.0)
        if sigma > 0:
            out = min(out, math.sqrt(1 / SET_ASIDE_WEIGHT ** 2 - 1) * f.loss.c * sigma * 1000)
    return out if math.isfinite(out) else 0.0


def held(run: DiagnosisRun, res: CalibrationResult, mask: np.ndarray) -> Held:
    return Held.of(run.held_out(res), mask)


def keep_never_worse(run: DiagnosisRun) -> None:
    """Stage ``keep_never_worse``: the geometry again with the causes in the model (when it was not supported
    alone), then the final model never worse than the kinematic one on the calibration poses' folds (see the
    module). Reads ``current``, ``accepted``, ``geometric``, ``kinematic`` and the search's ``history``; sets
    the three to the final model of the named causes, and ``held_text``."""
    run.say("final check: never worse than the kinematic model, in mean and worst case")
    run.current, run.accepted, run.geometric = _final_model(run, run.current, run.accepted, run.geometric)


def _final_model(run: DiagnosisRun, current: CalibrationResult, accepted: list[Candidate], geometric: bool
                 ) -> tuple[CalibrationResult, list[Candidate], bool]:
    kin = run.kinematic
    mask = run.mask(current) & run.mask(kin)
    with_geometry = None
    if not geometric and accepted:
        with_geometry = run.fit(compose_spec(accepted, True), start=current)
        if _geometry_again(run, current, with_geometry, accepted, mask):
            current, geometric = with_geometry, True
    ref = held(run, kin, mask)
    now = held(run, current, mask)
    run.held_text = _worst_text(ref, now)
    band = noise_band(kin, current)
    bad = now.worse_than(ref, band)
    if not bad:
        if now.traded(ref, band):
            run.notes.append("the final model's worst held-out error rises where its mean drops, on the calibration "
                            "poses' folds: " + ", ".join(f"{k} worst {ref.worst[k]:.4f} -> {now.worst[k]:.4f} mm, "
                                                         f"mean {ref.mean[k]:.4f} -> {now.mean[k]:.4f} mm"
                                                         for k in now.traded(ref, band))
                            + " against the kinematic model; the poses of those folds' largest errors are where it "
                              "extrapolates least surely")
            run.say(f"  {run.notes[-1]}")
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
        for a in dropped:
            run.drop_finding(a)
        if geo and not geometric:
            _add_geometry_finding(run, fit, current)
        elif geometric and not geo:         # back to a model the geometry was tried again on
            run.findings = [f for f in run.findings if not f.candidate.kind.geometry]
        what = ("the kinematic model itself" if fit is kin else
                "the model with the geometry" if geo and not geometric else "the last model of the search that is not")
        run.notes.append("never worse than a kinematic calibration: the model with every cause did worse than the "
                        "kinematic model on the calibration poses' folds (held-out " + ", ".join(bad)
                        + f"); the final model is {what}"
                        + (", without " + ", ".join(a.label() for a in dropped) if dropped else ""))
        run.say(f"  {run.notes[-1]}")
        return fit, earlier, geo
    return current, accepted, geometric     # (not reached: the kinematic model is never worse than itself)


def _worst_text(ref: Held, final: Held) -> str:
    return ("the worst held-out error is " + ", ".join(f"{k} {final.worst[k]:.4f} mm" for k in ref.worst)
            + " (kinematic " + ", ".join(f"{ref.worst[k]:.4f}" for k in ref.worst) + ")")


def _geometry_again(run: DiagnosisRun, current: CalibrationResult, fit: CalibrationResult, accepted: list[Candidate],
                    mask: np.ndarray) -> bool:
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
    run.steps.append(Step(compose_spec(accepted, True), fit.calibration, v, ok, Candidate(GEOMETRIC.name), test,
                         cv_record(h0.mean, h1.mean), reason, run.val_angles(fit), parent=parent, parent_mm=pv.mean_mm))
    if ok:
        run.record(fit, len(run.steps) - 1, accepted)
        _add_geometry_finding(run, fit, current, f"{test.text()} on the calibration poses with the causes in the "
                                               f"model; held-out mean {cv_text(h0.mean, h1.mean)}")
        run.notes.append("the geometry step, not supported alone, is supported once the causes are in the model "
                        f"({test.text()}): the final model has it")
        run.say(f"  geometry again, with the causes: accepted ({test.text()})")
    else:
        run.say(f"  geometry again, with the causes: not supported ({reason})")
    return ok


def _add_geometry_finding(run: DiagnosisRun, fit: CalibrationResult, without: CalibrationResult,
                          evidence: str = "") -> None:
    if any(f.candidate.kind.geometry for f in run.findings):
        return
    gain = run.val_stats(without).mean_mm - run.val_stats(fit).mean_mm
    run.findings.insert(0, Finding(Candidate(GEOMETRIC.name), gain, evidence or
                                  "never worse than a kinematic calibration of the same poses on their folds; "
                                  "link, base and tool parameters"))


def validation_note(final: CalibrationResult, kinematic: CalibrationResult, extended: CalibrationResult | None,
                    val, val_errors, held_text: str = "", structure: tuple | None = None) -> str | None:
    """A note (judge only) when the final model's worst validation error is more than :data:`WORST_SHARE` above
    the kinematic model's, or above that of the model the GP compensator extends (``extended``; None: no
    compensator): where, how much, what the folds said (``held_text``), and the poses no model of the robot predicts.

    ``val_errors(res)``: a model's position errors (m) on ``val``. ``structure``: (the validation poses that
    structure the screen found accounts for, its finding's number and words): those poses are its largest misses,
    not bad measurements.
    """
    e_final, e_kin = val_errors(final) * 1000, val_errors(kinematic) * 1000
    rises = []
    if e_final.max() > e_kin.max() * (1 + WORST_SHARE):
        rises.append(f"{(e_final.max() / e_kin.max() - 1):.0%} above the kinematic model's {e_kin.max():.4f} mm")
    if extended is not None and extended is not final:
        e_ext = val_errors(extended) * 1000
        if e_final.max() > e_ext.max() * (1 + WORST_SHARE):
            rises.append(f"{(e_final.max() / e_ext.max() - 1):.0%} above the {e_ext.max():.4f} mm of the model the "
                         "GP compensator extends")
    if not rises:
        return None
    i = int(np.argmax(e_final))
    text = (f"judge only: the final model's worst validation error, {e_final[i]:.4f} mm at {_where(val, i)}, is "
            + " and ".join(rises))
    if held_text:
        text += f"; on the calibration poses' folds {held_text}"
    # poses no model of the robot predicts: beyond the robust loss's limit under the final model and the kinematic
    r = final.residuals(val)
    away = (final.loss.weight(np.einsum("ij,ij->i", r, r)) < SET_ASIDE_WEIGHT) & \
           (kinematic.loss.weight((e_kin / 1000) ** 2) < SET_ASIDE_WEIGHT)
    if away[i]:
        k = int(away.sum())
        order = np.flatnonzero(away)[np.argsort(-e_final[away])]
        text += (f"; that pose{f' and {k - 1} more' if k > 1 else ''} ("
                 + listing([_where(val, j) for j in order], 5)
                 + ") miss both models by far more than the noise (beyond the robust loss's limit): ")
        if structure is not None and structure[0][i]:
            text += (f"the largest misses of the structure in finding {structure[1]} ({structure[2]}), which no "
                     "term of the model holds")
        else:
            text += "likely bad measurements or a transient no model of the robot predicts"
        if k < len(e_final):
            text += (f"; without {'them' if k > 1 else 'it'} the worst error is {e_final[~away].max():.4f} mm "
                     f"(kinematic {e_kin[~away].max():.4f} mm)")
    return text


def _where(data, i: int) -> str:
    return f"{data.file(i)}:{data.line(i)}"
