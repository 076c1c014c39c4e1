"""The diagnosis: what the model gets wrong, why, and what each extension gains.

After the nominal and the geometric steps, every round screens all
candidate causes at once with a score test (:mod:`.screening`), fits the
best for real and accepts a cause only when the calibration data support it
three ways: significance (F-test at a Bonferroni-corrected level, BIC) and
held-out error on folds that must extrapolate as well as interpolate
(random, time-blocked and joint-range-blocked cross-validation,
:mod:`.validation`). Physical causes (compliance, progressive stiffness,
encoder scale, backlash, thermal expansion, drift, warm-up) are tried before
periodic errors, which must also be resolved from their neighbouring
harmonics and from geometry and agree over the two halves of the joint's
range (:mod:`.periodic`); structure that passes the statistics but not
these checks is reported as ``unexplained`` and kept out of the model.
At the end every accepted cause is tested again against the final model
(:mod:`.backward`) and must still be physics (:mod:`casadical.physics`);
the final model never does worse than the kinematic one where it must
extrapolate. With several sessions every cause is asked whether one value
serves every session (the robot's) or only one session's own (the
session's; :mod:`.catalogue`). The poses the final fit sets aside are
tested for shared structure before they are called bad measurements
(:mod:`casadical.set_aside`, :mod:`.gaps`), and what these data cannot test
is said (:func:`.catalogue.not_tried`). The validation poses judge every step and are never used
to accept one. The accuracy layer last (:mod:`.layer`: a session
compensator that applies where it knows) takes what no named cause
explains; :mod:`.transfer` takes the findings to another series.
"""

from __future__ import annotations

import math
import time
from dataclasses import asdict, replace
from typing import Callable

import numpy as np

from ..calibration.for_data import model_for
from ..calibration.pipeline import calibrate
from ..checks import check_held_out, check_other_series, check_poses, check_validation_frames
from ..data import Measurements
from ..physics import sag_note, value_violations, violations
from ..problem import RobustLoss
from ..result import AngleStats, CalibrationResult, ErrorStats, learning_mask
from ..robot import Robot
from ..set_aside import of_fit
from ..threads import limited_threads
from .backward import drop_redundant, drop_unphysical
from .candidates import Candidate, compose_spec, shortlist
from .catalogue import Catalogue, not_tried
from .compensator import compensator_step
from .design import assess, priors
from .findings import UnexplainedLog, describe
from .gaps import set_aside_note, untried_alternatives
from .nameable import JOINT_CAUSES, cause_checks, unjudged
from .never_worse import final_check, validation_note
from .periodogram import Periodogram
from .report import DiagnosisReport, Finding, Step
from .screening import Scored, Screen, ambiguous
from .settings import DiagnosisSettings
from .statistics import nested_test, noise_ssr, set_aside_share
from .transfer import findings_study
from .validation import (
    EXTRAPOLATING,
    Linearized,
    by_kind,
    cv_failure,
    cv_record,
    cv_text,
    extrapolation_gain,
    joint_levers,
    not_better,
    schemes,
)


class _Diagnosis:
    def __init__(self, robot: Robot, cal: Measurements, val: Measurements, settings: DiagnosisSettings,
                 progress: Callable[[str], None], allow_mismatch: bool = False):
        self.robot, self.cal, self.val, self.s = robot, cal, val, settings
        self.say = progress
        self.allow_mismatch = allow_mismatch
        self.n_eq = 3 * len(cal)          # the screening and its linearised tests: positions
        # full pose (data with orientations): every full fit, and the tests on their losses, have 6 equations a pose
        self.full_pose = cal.has_orientation and not settings.position_only
        self.n_fit_eq = (6 if self.full_pose else 3) * len(cal)
        self.schemes = self.fold_schemes()
        self.sessions = cal.session_names      # [] for one session
        self.steps: list[Step] = []
        self.findings: list[Finding] = []
        self.notes: list[str] = []
        self.periodograms: list[Periodogram] = []
        self.catalogue = Catalogue(robot, cal, settings)
        self.later: dict[Candidate, int] = {}     # not significant yet: screened again once the model grows
        self.not_tried: list = []                   # kinds of cause these data cannot test (catalogue.not_tried)
        self.unexplained = UnexplainedLog()
        self.before: dict[Candidate, CalibrationResult] = {}   # fit before each finding, by its cause
        self.support: dict[Candidate, tuple] = {}               # (test, cv before, cv after, checks) by cause
        self._val_errors: dict[int, tuple] = {}                 # id of a fit -> (fit, its validation errors)
        self._torques: tuple | None = None                      # (fit, gravity torques of the cal poses)
        self.history: list[tuple[list[Candidate], CalibrationResult]] = []   # each accepted model, in order
        self._step_of: list[tuple[CalibrationResult, int]] = []               # each accepted fit and its step
        self.design = None          # how weak the design is (casadical.diagnosis.design), after the kinematic fit
        self.prior: dict[str, float] | None = None   # the folds' priors of the geometry on a weak design
        self.held_text = ""         # the final check's worst held-out errors, in words

    def fold_schemes(self, moving: np.ndarray | None = None) -> list:
        """The cross-validation schemes of the calibration poses (``moving``: of a design of one joint at a time,
        :func:`.validation.schemes`)."""
        return schemes(self.cal.q, self.cal.rows, self.s.folds, self.s.seed, joint_levers(self.robot, self.cal),
                       sessions=self.cal.sessions, moving=moving)

    def step_of(self, res: CalibrationResult) -> int | None:
        """Index of the step whose model ``res`` is (None for a fit no step holds: a final-check refit)."""
        return next((k for fit, k in self._step_of if fit is res), None)

    # -- fitting ---------------------------------------------------------------

    def fit(self, spec: str, start: CalibrationResult | dict | None = None, loss: RobustLoss | None = None
            ) -> CalibrationResult:
        """Calibrate ``spec`` on the calibration poses (LM), from ``start``'s values (a result or a dict)."""
        model = model_for(self.robot, spec + ("+tool_orientation" if self.full_pose else ""), self.cal,
                          session_tools=self.s.session_tools)
        st = None
        if start is not None:
            values = start if isinstance(start, dict) else {p.name: p.value for p in start.parameters}
            st = {n: v for n, v in values.items() if n in model.parameters and not n.startswith("base_")}
        return calibrate(self.robot, self.cal, model, "lm", start=st, warn=False, robust=loss or self.s.robust,
                         position_only=self.s.position_only)

    def val_errors(self, res: CalibrationResult) -> np.ndarray:
        """Position errors (m) of a fit on the validation poses, predicted once per fit."""
        hit = self._val_errors.get(id(res))
        if hit is None or hit[0] is not res:
            hit = self._val_errors[id(res)] = (res, res.errors(self.val))
        return hit[1]

    def val_stats(self, res: CalibrationResult) -> ErrorStats:
        return ErrorStats.of(self.val_errors(res))

    def val_angles(self, res: CalibrationResult) -> AngleStats | None:
        """Orientation errors of a full-pose fit on the validation poses (None without orientations)."""
        if not (res.has_orientation and self.val.has_orientation):
            return None
        return AngleStats.of(res.orientation_errors(self.val))

    def u2(self, res: CalibrationResult, loss: RobustLoss) -> np.ndarray:
        """Squared residual norm of each calibration pose under ``loss``: full pose, ``|r_p|^2 + k^2 |r_o|^2``."""
        r = res.residuals(self.cal)
        u2 = np.einsum("ij,ij->i", r, r)
        if res.full_pose and math.isfinite(loss.rot_weight):
            u2 = u2 + (loss.rot_weight * res.orientation_errors(self.cal)) ** 2
        return u2

    def deviance(self, res: CalibrationResult, loss: RobustLoss, noise: bool = False) -> float:
        """Twice the loss of ``res`` on the calibration poses under ``loss`` (SSR for least squares); ``noise``:
        with the set-aside poses counted by their influence (a test's noise scale, :func:`.statistics.nested_test`)."""
        u2 = self.u2(res, loss)
        return 2.0 * float(loss.rho(u2) @ (set_aside_share(loss.weight(u2)) if noise else np.ones(len(u2))))

    def mask(self, res: CalibrationResult) -> np.ndarray:
        """Poses that count in held-out means: those the robust loss did not set aside."""
        return res.loss.weight(self.u2(res, res.loss)) >= 0.5

    def torques(self, res: CalibrationResult) -> np.ndarray:
        """Gravity torques (N m) of the calibration poses under a fit, computed once per fit."""
        if self._torques is None or self._torques[0] is not res:
            m = res.model
            self._torques = (res, m.torques(self.cal.q, res.parameters.values, m.covariates(self.cal)))
        return self._torques[1]

    def cv(self, res: CalibrationResult, mask: np.ndarray) -> dict:
        """Held-out means (mm) by kind of fold of a fit, linearised at it, over the poses of ``mask``."""
        return by_kind(Linearized.of(res, self.cal).cv(self.schemes, self.prior), mask)

    # -- the procedure ---------------------------------------------------------

    def run(self) -> tuple[CalibrationResult, list[Candidate], bool]:
        self.say("step 1: nominal model (base pose only)")
        nominal = self.nominal = self.fit("nominal")
        self.steps.append(Step("nominal", nominal.calibration, self.val_stats(nominal), True,
                               orientation=self.val_angles(nominal)))
        self._step_of.append((nominal, 0))
        # each session's validation poses in its own tracker frame (files out of order would be judged in another)
        check_validation_frames(self.val, self.val_errors(nominal), nominal.calibration.mean_mm, self.allow_mismatch)
        self.say(f"  validation mean {self.steps[-1].validation.mean_mm:.4f} mm (judge only)")
        self.say("step 2: geometric (kinematic) calibration")
        kin = self.kinematic = self.fit("kinematic")
        self.design = assess(self.cal, kin, self.n_fit_eq)
        if self.design.weak:
            self.prior = priors(kin)
            if self.design.one_at_a_time:   # folds that leave out part of every joint's sweep, never a whole one
                self.schemes = self.fold_schemes(self.design.moving)
            self.notes.append(self.design.text())
            self.say(f"  {self.notes[-1]}")
        test = nested_test(self.deviance(nominal, kin.loss), int(nominal.parameters.free.sum()),
                           self.deviance(kin, kin.loss), int(kin.parameters.free.sum()), self.n_fit_eq,
                           self.deviance(kin, kin.loss, noise=True))
        mask = self.mask(kin)
        cv0, cv1 = (self.cv(r, mask) for r in (nominal, kin))
        worse = not_better(cv0, cv1)
        ok = test.log10_p < math.log10(self.s.alpha) and test.delta_bic < 0 and not worse
        kv = self.val_stats(kin)
        reason = "; ".join([f"not significant ({test.text()})"] * (test.log10_p >= math.log10(self.s.alpha))
                           + [f"BIC does not improve ({test.delta_bic:+.1f})"] * (test.delta_bic >= 0)
                           + ([cv_failure(worse, cv0, cv1)] if worse else []))
        self.steps.append(Step("kinematic", kin.calibration, kv, ok, Candidate("geometric"), test,
                               cv_record(cv0, cv1), reason, self.val_angles(kin), parent=0,
                               parent_mm=self.steps[0].validation.mean_mm))
        self._step_of.append((kin, 1))
        self.say(f"  validation mean {kv.mean_mm:.4f} mm ({test.text()})")
        if ok:
            gain = self.steps[0].validation.mean_mm - kv.mean_mm
            self.findings.append(Finding(Candidate("geometric"), gain,
                                         f"{test.text()} on the calibration poses; held-out mean "
                                         + cv_text(cv0, cv1) + "; link, base and tool parameters"))
            current, geometric = kin, True
        else:
            current, geometric = nominal, False
        accepted: list[Candidate] = []
        self.history.append(([], current))
        self.not_tried = not_tried(self.robot, self.cal, self.torques(current), self.s)
        for rnd in range(self.s.max_rounds):
            self.say(f"round {rnd + 1}: screening candidate causes")
            new = self.round(current, accepted, geometric)
            if new is None:
                break
            cand, start, level = new
            step = next(s for s in reversed(self.steps) if s.accepted)
            # the one-step fit decided; the full fit (noise scale re-estimated) must confirm the significance
            self.say(f"  {cand.label()}: the full fit")
            new_fit = self.fit(compose_spec(accepted + [cand], geometric), start=start)
            test = nested_test(self.deviance(current, current.loss), int(current.parameters.free.sum()),
                               self.deviance(new_fit, current.loss), int(new_fit.parameters.free.sum()),
                               self.n_fit_eq, self.deviance(new_fit, current.loss, noise=True))
            reasons = []
            if test.log10_p >= level or test.delta_bic >= 0:
                reasons.append(f"not significant once fitted in full ({test.text()})")
            # the full fit must be physics, and must not do worse where the model extrapolates
            broken = violations(new_fit, self.cal, cand.parameter_names(), alpha=self.s.alpha)
            if broken:
                reasons.append("not physics once fitted in full: " + "; ".join(v.text for v in broken))
            mask = self.mask(current)
            cv0, cv1 = self.cv(current, mask), self.cv(new_fit, mask)
            worse = [k for k in EXTRAPOLATING if k in cv0 and cv1[k] > cv0[k] and k not in unjudged(cand)]
            if worse:
                reasons.append("fitted in full it does worse where the model extrapolates: "
                               + ", ".join(f"{k} {cv0[k]:.4f} -> {cv1[k]:.4f} mm" for k in worse))
            if reasons:
                step.accepted, step.test = False, test
                step.reason = "; ".join(reasons)
                self.say(f"    {cand.label()}: {step.reason}")
                self.findings.pop()
                support = self.support.pop(cand, None)
                if len(reasons) == 1 and not broken and not worse:
                    # not significant yet: screened again once another cause is in the model (a session's own
                    # structure still unmodelled inflates the noise scale)
                    self.later[cand] = len(accepted)
                else:
                    self.unexplained.excluded_causes.add(cand)
                if broken and not reasons[0].startswith("not significant") and cand.joint is not None \
                        and support is not None:
                    # real structure that is not this cause: reported, kept out of the model
                    self.unexplained.add(cand, {p.name: p.value for p in new_fit.parameters}, support[0],
                                         support[1], support[2], support[3],
                                         step.validation.mean_mm - self.val_stats(new_fit).mean_mm, step.reason)
                continue
            self.before[cand] = current
            accepted.append(cand)
            current = new_fit
            self._step_of.append((current, self.steps.index(step)))
            self.history.append((list(accepted), current))
            # the step and the finding's gain judge the full fit, not the one-step fit that decided
            full = self.val_stats(current)
            next(f for f in self.findings if f.candidate == cand).gain_mm += step.validation.mean_mm - full.mean_mm
            step.calibration, step.validation = current.calibration, full
            step.orientation = self.val_angles(current)
        else:
            if self.s.max_rounds:
                self.notes.append(f"stopped at the safety cap of {self.s.max_rounds} rounds while causes were "
                                  "still supported; raise --max-rounds to look further")
        if len(accepted) > 1:
            self.say("final check: is every cause still needed?")
            current, accepted = drop_redundant(self, current, accepted, geometric)
        if accepted:
            self.say("final check: is every cause still physics?")
            current, accepted = drop_unphysical(self, current, accepted, geometric)
        self.say("final check: never worse than the kinematic model, in mean and worst case")
        return final_check(self, current, accepted, geometric)

    def drop_finding(self, cand: Candidate) -> None:
        """Remove the finding of ``cand`` and what is kept for it."""
        self.findings = [f for f in self.findings if f.candidate != cand]
        self.support.pop(cand, None)
        self.before.pop(cand, None)

    def candidates(self, current: CalibrationResult, accepted: list[Candidate]) -> list[Candidate]:
        """Every candidate not yet in the model (:class:`.catalogue.Catalogue`)."""
        skip = self.unexplained.excluded_causes | {c for c, n in self.later.items() if n == len(accepted)}
        out = self.catalogue.candidates(current, accepted, self.unexplained.excluded, skip,
                                        lambda: self.torques(current))
        self.periodograms = self.catalogue.periodograms
        return out

    def n_tests(self, cands: list[Candidate]) -> int:
        return self.catalogue.n_tests(cands)

    def round(self, current: CalibrationResult, accepted: list[Candidate], geometric: bool):
        """Screen, fit the best candidates by one step, accept one; None when nothing is supported."""
        scr = baseline = None
        while True:
            cands = self.candidates(current, accepted)
            # screening again (after setting structure aside) reuses the linearisation and the baseline
            if scr is None:
                scr = Screen(current, accepted, cands, geometric, self.cal, self.val, self.s.session_tools)
                mask = self.mask(current)
                base = scr.fit()
                baseline = (mask, base, by_kind(base.lin.cv(self.schemes, self.prior), mask), self.val_stats(current))
            else:
                scr = scr.with_candidates(cands)
            scored = scr.scores(cands)
            level = math.log10(self.s.alpha / max(self.n_tests(cands), 1))
            if not scored or scored[0].log10_p >= level:
                best = scored[0] if scored else None
                self.say("  no candidate passes the score test" +
                         (f" (best: {best.candidate.label()}, {best.test.text()})" if best else ""))
                return None
            accepted_now, pending = self.try_tiers(scr, scored, level, baseline, current, accepted, geometric)
            if accepted_now is not None:
                return accepted_now
            for item in pending:
                self.unexplained.add(*item)
            if not pending:
                self.say("  no candidate is supported on the calibration data")
                return None
            self.say("  no cause is supported; the structure that cannot be named is set aside, and the round "
                     "screens again")

    def try_tiers(self, scr: Screen, scored: list[Scored], level: float, baseline: tuple, current: CalibrationResult,
                  accepted: list[Candidate], geometric: bool):
        """Tiers in order; in a tier, up to ``confirm`` candidates fitted and judged, the best accepted.

        ``baseline``: the current fit's pose mask, one-step fit, held-out means and validation errors.
        """
        mask, base, cv0, cur_val = baseline
        pending: list[tuple] = []   # significant structure that cannot be named (unless a cause is accepted)
        for tier in (1, 2, 3):
            passing = []
            for sc in shortlist(scored, tier, level, self.s.confirm):
                cand = sc.candidate
                self.say(f"  fitting {cand.label()} (score {sc.test.text()})")
                fit = scr.fit(cand)
                test = nested_test(base.ssr, base.n_free, fit.ssr, fit.n_free, self.n_eq, noise_ssr(fit.lin))
                cv1 = by_kind(fit.lin.cv(self.schemes, self.prior), mask)
                reasons = []
                if test.log10_p >= level:
                    reasons.append(f"F-test not significant at the corrected level ({test.text()})")
                if test.delta_bic >= 0:
                    reasons.append(f"BIC does not improve ({test.delta_bic:+.1f})")
                worse = [k for k in not_better(cv0, cv1) if k not in unjudged(cand)]
                # real structure on these poses: significant, and it predicts random held-out poses
                significant = not reasons and "random" not in worse
                if worse:
                    reasons.append(cv_failure(worse, cv0, cv1))
                checks = cause_checks(scr, fit, cand, self.cal, self.s.stability_alpha) if significant else {}
                reasons += checks.pop("reasons", [])
                # the one-step fit's values must already be physics (bounds, a spring that does not turn back)
                names = cand.parameter_names()
                values = {n: replace(scr.params[n], value=fit.values.get(n, scr.params[n].value)) for n in names}
                broken = value_violations(values, names, self.torques(current), self.cal.moves)
                if broken:
                    reasons.append("not physics: " + "; ".join(v.text for v in broken))
                vstats = ErrorStats.of(scr.validation_errors(fit))
                # its gain is against the model it extends (the current fit), never against a sibling
                step = Step(compose_spec(accepted + [cand], geometric),
                            ErrorStats.of(np.linalg.norm(fit.lin.r, axis=1)), vstats, False, cand, test,
                            cv_record(cv0, cv1), "; ".join(reasons), parent=self.step_of(current),
                            parent_mm=cur_val.mean_mm)
                self.steps.append(step)
                if reasons:
                    self.say(f"    rejected: {step.reason}")
                    if significant and (cand.cause in JOINT_CAUSES + ("nonlinear_stiffness",)
                                        or (broken and cand.joint is not None)):
                        pending.append((cand, fit.values, test, cv0, cv1, checks, cur_val.mean_mm - vstats.mean_mm,
                                        "; ".join(reasons)))
                    continue
                passing.append((extrapolation_gain(cv0, cv1), sc, fit, test, cv1, checks, step))
            if passing:
                _, sc, fit, test, cv1, checks, step = max(passing, key=lambda t: t[0])
                step.accepted = True
                self.say(f"    accepted {sc.candidate.label()}: held-out mean {cv_text(cv0, cv1)} "
                         f"(validation mean {cur_val.mean_mm:.4f} -> {step.validation.mean_mm:.4f} mm, judge only)")
                f = Finding(sc.candidate, cur_val.mean_mm - step.validation.mean_mm, "",
                            ambiguous_with=ambiguous(sc, scored, level),
                            holds_up={"test": test.text(), "cv_mm": cv_record(cv0, cv1),
                                      **{k: v.to_dict() for k, v in checks.items()
                                         if k in ("resolution", "versus_drift", "versus_harmonics")},
                                      **({"halves": [h.to_dict() for h in checks["halves"]]} if "halves" in checks
                                         else {})})
                self.support[sc.candidate] = (test, cv0, cv1, checks)
                self.findings.append(f)
                return (sc.candidate, {**{p.name: p.value for p in current.parameters}, **fit.values}, level), pending
        return None, pending


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
        taken there (:mod:`casadical.diagnosis.transfer`).
    **checks : bool
        Overrides of the plausibility checks of the poses
        (:func:`casadical.checks.check_poses`: ``allow_outside_limits``,
        ``angles_are_degrees``, ``positions_are_mm``, ``allow_mismatch``:
        poses of ``cal``, ``val`` or ``other`` the nominal model misses by
        more than 5 % of the robot's reach with its base pose fitted).

    Raises
    ------
    DataFileError
        Every validation (or ``other``) pose is a calibration pose (:func:`casadical.checks.check_held_out`,
        :func:`~casadical.checks.check_other_series`; some of them: a warning), or a check of the poses fails.
    """
    t0 = time.perf_counter()
    s = settings or DiagnosisSettings()
    say = progress or (lambda _: None)
    for d in [cal, val] + ([other] if other is not None else []):
        check_poses(d, robot, **checks)     # the joint count first
    check_held_out(cal, val)                # validation poses the fits have seen would judge nothing
    if other is not None:
        check_other_series(cal, other)
    dg = _Diagnosis(robot, cal, val, s, say, checks.get("allow_mismatch", False))
    if dg.full_pose:
        dg.notes.append("full pose: every fit is on the measured positions and orientations, weighted by their noise "
                        "scales from the data (as calibrate); the screening of candidate causes, its tests and the "
                        "cross-validation folds work on the positions; --position-only fits the positions alone")
        say("full pose: the fits weigh the measured orientations too (--position-only: positions alone)")
    current, accepted, geometric = dg.run()
    parametric = current
    final, final_spec = current, compose_spec(accepted, geometric)
    if s.blackbox:
        final, final_spec = compensator_step(current, final_spec, cal, val, dg.schemes, s, dg.steps, dg.findings, say,
                                             parent=dg.step_of(current))
    say("findings: their values, evidence and figures in the final model")
    describe(dg.findings, dg.support, dg.before, final, cal)
    untried_alternatives(dg.findings, dg.not_tried)      # a joint's named cause may be its untried compliance
    dg.findings += list(dg.unexplained.by_joint.values())
    for f in dg.findings:   # of the robot (one value serves every session) or of one session
        f.scope = f.scope or f.candidate.scope or ("robot" if len(dg.sessions) > 1 and f.in_model
                                        and f.cause != "unexplained" else None)
    final_errors = dg.val_errors(final)
    final_val = ErrorStats.of(final_errors)
    note = validation_note(final, dg.kinematic, parametric, val, dg.val_errors, dg.held_text)
    if note:
        dg.notes.append(note)
    if final.uncertainty is not None:
        dg.notes.append(f"remaining calibration residual {final.uncertainty.sigma * 1000:.4f} mm per axis (rms); "
                        f"validation rms {final_val.rms_mm / math.sqrt(3):.4f} mm per axis")
    sag = sag_note(final, cal)
    if sag:
        dg.notes.append(sag)
    # the poses the final fit set aside: bad measurements, or structure it lacks (casadical.set_aside)
    structure = of_fit(parametric, cal, learning_mask(final, cal) == 0)
    if structure.n_set_aside:
        dg.notes.append(set_aside_note(structure, dg.not_tried, cal.path))
    study = None
    if other is not None:
        study = findings_study(dg, final, parametric, accepted, geometric, other)
    plots = {"val_errors_nominal_mm": (dg.val_errors(dg.nominal) * 1000).tolist(),
             "val_errors_final_mm": (final_errors * 1000).tolist()}
    return DiagnosisReport(robot.name, dg.steps, dg.findings, final_spec, final_val, final, dg.periodograms, plots,
                           dg.notes, time.perf_counter() - t0,
                           next(st.validation for st in dg.steps if st.model == "kinematic"),
                           study.to_dict() if study is not None else {}, asdict(s),
                           final_sessions=final.session_stats(val) if len(dg.sessions) > 1 else {},
                           final_orientation=dg.val_angles(final),
                           set_aside=structure.to_dict() if structure.n_set_aside else {},
                           not_tried=[n.to_dict() for n in dg.not_tried])
