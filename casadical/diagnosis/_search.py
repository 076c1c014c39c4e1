"""Stage ``search_causes``: round after round, screen every candidate cause, fit the best, accept one.

Every round screens all candidate causes at once with a score test (:mod:`._screening`) from the current
fit's linearisation, fits the best by one Gauss-Newton step and accepts a cause only when the calibration
data support it three ways: significance (F-test at a Bonferroni-corrected level, BIC) and held-out error on
folds that must extrapolate as well as interpolate (random, time-blocked and joint-range-blocked
cross-validation, :mod:`._validation`). Physical causes are tried before periodic errors (tiers,
:func:`._candidates.shortlist`), which must also be resolved from their neighbouring harmonics and from
geometry and agree over the two halves of the joint's range (:mod:`._nameable`); structure that passes the
statistics but not these checks is kept out of the model (:class:`._findings.UnexplainedLog`). The chosen
cause is then fitted in full (the noise scale re-estimated), and must stay significant, physics, and not do
worse where the model extrapolates (:func:`judge_full_fit`).

With several sessions a cause of the robot's joint that does worse on the leave-one-session-out folds, while its
copy in one session alone explains it, is not named: a joint's own parameter is the robot's, and that structure is
what differs between the sessions showing on that joint, kept out as an ``unexplained`` finding of the joint and
the session (:func:`one_session`).

Reads the model under way (:mod:`._geometry`); sets ``later``, ``unexplained``, ``not_tried``, ``round`` (and the
user terms' scores, :func:`._user_terms.record_scores`); keeps what it changes of the run in a :class:`Rounds` while
it runs, and returns the model the search ends with, the steps of every candidate fitted, the fits of the accepted
ones, the findings and a note where it stopped at the safety cap.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from ..result import CalibrationResult, ErrorStats
from ..stats._physics import value_violations, violations
from ._candidates import TIERS, Candidate, compose_terms, model_spec, shortlist
from ._catalogue import not_tried
from ._evidence import Evidence, Support
from ._nameable import cause_checks, drops, unjudged
from ._report import Finding, Step
from ._screening import Scored, Screen, ambiguous
from ._state import DiagnosisRun, ModelUnderWay, StageOutcome
from ._statistics import NestedTest, nested_test, noise_ssr
from ._user_terms import record_scores
from ._validation import EXTRAPOLATING, by_kind, cv_failure, cv_record, cv_text, extrapolation_gain, not_better


@dataclass
class Chosen:
    """The cause a round chose: its one-step values start its full fit, judged at the round's corrected level
    (log10)."""

    candidate: Candidate
    start: dict
    level: float


@dataclass
class Baseline:
    """A round's reference: the current fit's pose mask, its one-step fit (the screen's), its held-out means
    and its validation errors."""

    mask: np.ndarray
    fit: object
    cv: dict
    validation: ErrorStats


@dataclass
class Trial:
    """A candidate that passed every test of its tier, with what its acceptance records."""

    gain: float                 # held-out gain where the model extrapolates (:func:`._validation.extrapolation_gain`)
    scored: Scored
    fit: object                 # its one-step fit
    support: Support
    step: Step


@dataclass
class Verdict:
    """What the full fit of a chosen cause says of it: each reason it fails (none: accepted), the rules of
    physics it breaks, and the kinds of fold where it does worse while extrapolating."""

    test: NestedTest
    reasons: list[str]
    broken: list
    worse: list[str]

    @property
    def not_yet(self) -> bool:
        """Only not significant yet: screened again once another cause is in the model (a session's own
        structure still unmodelled inflates the noise scale)."""
        return len(self.reasons) == 1 and not self.broken and not self.worse


@dataclass
class Rounds:
    """What the search changes of the run while it runs, returned at its end (:meth:`outcome`): the model under way
    (``current``, ``accepted``, ``geometric``), what is kept for each cause (``support``, ``before``), the findings,
    the steps it adds (the first of them is the run's step ``first``) and the fits they hold (``recorded``)."""

    current: CalibrationResult
    accepted: list[Candidate]
    geometric: bool
    support: dict
    before: dict
    findings: list[Finding]
    first: int
    known: tuple               # the run's fits of its steps
    steps: list[Step] = field(default_factory=list)
    recorded: list = field(default_factory=list)

    @classmethod
    def of(cls, run: DiagnosisRun) -> Rounds:
        return cls(run.current, list(run.accepted), run.geometric, dict(run.support), dict(run.before),
                   list(run.findings), len(run.steps), tuple(run.fits_of_steps))

    def step_of(self, res: CalibrationResult) -> int | None:
        """:meth:`._state.DiagnosisRun.step_of`, among the run's steps and the search's."""
        return next((k for fit, k in (*self.known, *((f, k) for f, k, _ in self.recorded)) if fit is res), None)

    def outcome(self, notes: tuple[str, ...]) -> StageOutcome:
        return StageOutcome(notes=notes, steps=tuple(self.steps), recorded=tuple(self.recorded),
                            findings=tuple(self.findings),
                            model=ModelUnderWay(self.current, tuple(self.accepted), self.geometric, self.support,
                                                self.before))


def search_causes(run: DiagnosisRun) -> StageOutcome:
    run.not_tried = not_tried(run.robot, run.cal, run.torques(run.current), run.s)
    run.unexplained.linear = {j for j, jt in enumerate(run.robot.joints, start=1) if jt.prismatic}
    way = Rounds.of(run)
    for rnd in range(run.s.max_rounds):
        run.round = rnd + 1
        run.say(f"round {rnd + 1}: screening candidate causes")
        chosen = screen_round(run, way)
        if chosen is None:
            break
        cand = chosen.candidate
        step = next(s for s in reversed(way.steps) if s.accepted)
        # the one-step fit decided; the full fit (noise scale re-estimated) must confirm the significance
        run.say(f"  {cand.label()}: the full fit")
        new_fit = run.fit(compose_terms(way.accepted + [cand], way.geometric), start=chosen.start, parent=way.current)
        verdict = judge_full_fit(run, way.current, cand, new_fit, chosen.level)
        if verdict.reasons:
            reject(run, way, cand, step, new_fit, verdict)
            continue
        way.before[cand] = way.current
        way.accepted.append(cand)
        way.current = new_fit
        way.recorded.append((new_fit, way.first + way.steps.index(step), tuple(way.accepted)))
        # the step and the finding's gain judge the full fit, not the one-step fit that decided
        full = run.val_stats(new_fit)
        next(f for f in way.findings if f.candidate == cand).gain_mm += step.validation.mean_mm - full.mean_mm
        step.calibration, step.validation = new_fit.calibration, full
        step.orientation = run.val_angles(new_fit)
    else:
        if run.s.max_rounds:
            return way.outcome((f"stopped at the safety cap of {run.s.max_rounds} rounds while causes were "
                                "still supported; raise --max-rounds to look further",))
    return way.outcome(())


def judge_full_fit(run: DiagnosisRun, current: CalibrationResult, cand: Candidate, new_fit: CalibrationResult,
                   level: float) -> Verdict:
    """The full fit of ``cand`` against the ``current`` model: significant at ``level`` and by BIC, physics
    (:func:`casadical.stats._physics.violations`), not worse on the folds where the model extrapolates."""
    test = run.compare(current, new_fit, current.loss)
    reasons = []
    if test.log10_p >= level or test.delta_bic >= 0:
        reasons.append(f"not significant once fitted in full ({test.text()})")
    # the full fit must be physics, and must not do worse where the model extrapolates
    broken = violations(new_fit, run.cal, cand.parameter_names(), alpha=run.s.alpha)
    if broken:
        reasons.append("not physics once fitted in full: " + "; ".join(v.text for v in broken))
    mask = run.mask(current)
    cv0, cv1 = run.cv(current, mask), run.cv(new_fit, mask)
    worse = [k for k in EXTRAPOLATING if k in cv0 and cv1[k] > cv0[k] and k not in unjudged(cand)]
    if worse:
        reasons.append("fitted in full it does worse where the model extrapolates: "
                       + ", ".join(f"{k} {cv0[k]:.4f} -> {cv1[k]:.4f} mm" for k in worse))
    return Verdict(test, reasons, broken, worse)


def reject(run: DiagnosisRun, way: Rounds, cand: Candidate, step: Step, new_fit: CalibrationResult,
           verdict: Verdict) -> None:
    """The full fit does not confirm ``cand``: its step and finding are withdrawn; it is screened again later
    (only not significant yet), or never again; real structure that is not this cause is kept as evidence."""
    step.accepted, step.test = False, verdict.test
    step.reason = "; ".join(verdict.reasons)
    run.say(f"    {cand.label()}: {step.reason}")
    way.findings.pop()
    support = way.support.pop(cand, None)
    if verdict.not_yet:
        run.later[cand] = len(way.accepted)
    else:
        run.unexplained.excluded_causes.add(cand)
    if verdict.broken and not verdict.reasons[0].startswith("not significant") and cand.joint is not None \
            and support is not None:
        # real structure that is not this cause: reported, kept out of the model
        run.unexplained.add(Evidence(cand, {p.name: p.value for p in new_fit.parameters}, support,
                                     step.validation.mean_mm - run.val_stats(new_fit).mean_mm, step.reason))


def screen_round(run: DiagnosisRun, way: Rounds) -> Chosen | None:
    """Screen, fit the best candidates by one step, choose one; None when nothing is supported."""
    current = way.current
    scr = baseline = None
    while True:
        cands = run.candidates(current, way.accepted)
        # screening again (after setting structure aside) reuses the linearisation and the baseline
        if scr is None:
            scr = Screen(current, way.accepted, cands, way.geometric, run.cal, run.val, run.s.session_tools)
            mask = run.mask(current)
            base = scr.fit()
            baseline = Baseline(mask, base, by_kind(base.lin.cv(run.schemes, run.prior), mask),
                                run.val_stats(current))
        else:
            scr = scr.with_candidates(cands)
        scored = scr.scores(cands)
        level = math.log10(run.s.alpha / max(run.n_tests(cands), 1))
        record_scores(run, scored, level, way.first + len(way.steps))   # the user's own terms: in the report
        if not scored or scored[0].log10_p >= level:
            best = scored[0] if scored else None
            run.say("  no candidate passes the score test" +
                    (f" (best: {best.candidate.label()}, {best.test.text()})" if best else ""))
            return None
        chosen, pending = try_tiers(run, way, scr, scored, level, baseline)
        if chosen is not None:
            return chosen
        for evidence in pending:
            run.unexplained.add(evidence)
        if not pending:
            run.say("  no candidate is supported on the calibration data")
            return None
        run.say("  no cause is supported; the structure that cannot be named is set aside, and the round "
                "screens again")


def try_tiers(run: DiagnosisRun, way: Rounds, scr: Screen, scored: list[Scored], level: float, baseline: Baseline
              ) -> tuple[Chosen | None, list[Evidence]]:
    """Tiers in order; in a tier, up to ``confirm`` candidates fitted and judged, the best chosen.

    Returns the chosen cause (None: none) and the significant structure that cannot be named (kept out of
    the model unless a cause is chosen).
    """
    current, mask, base, cv0, cur_val = way.current, baseline.mask, baseline.fit, baseline.cv, baseline.validation
    pending: list[Evidence] = []
    for tier in TIERS:
        passing: list[Trial] = []
        for sc in shortlist(scored, tier, level, run.s.confirm):
            cand = sc.candidate
            run.say(f"  fitting {cand.label()} (score {sc.test.text()})")
            fit = scr.fit(cand)
            test = nested_test(base.ssr, base.n_free, fit.ssr, fit.n_free, run.n_eq, noise_ssr(fit.lin))
            cv1 = by_kind(fit.lin.cv(run.schemes, run.prior), mask)
            reasons = []
            if test.log10_p >= level:
                reasons.append(f"F-test not significant at the corrected level ({test.text()})")
            if test.delta_bic >= 0:
                reasons.append(f"BIC does not improve ({test.delta_bic:+.1f})")
            worse = [k for k in not_better(cv0, cv1) if k not in unjudged(cand)]
            # real structure on these poses: significant, and it predicts random held-out poses
            tested = not reasons
            significant = tested and "random" not in worse
            if worse:
                reasons.append(cv_failure(worse, cv0, cv1))
            checks = cause_checks(scr, fit, cand, run.cal, run.s.stability_alpha) if significant else {}
            reasons += checks.pop("reasons", [])
            # the one-step fit's values must already be physics (bounds, a spring that does not turn back)
            names = cand.parameter_names()
            values = {n: replace(scr.params[n], value=fit.values.get(n, scr.params[n].value)) for n in names}
            broken = value_violations(values, names, run.torques(current), run.cal.moves)
            if broken:
                reasons.append("not physics: " + "; ".join(v.text for v in broken))
            vstats = ErrorStats.of(scr.validation_errors(fit))
            # its gain is against the model it extends (the current fit), never against a sibling
            step = Step(model_spec(way.accepted + [cand], way.geometric),
                        ErrorStats.of(np.linalg.norm(fit.lin.r, axis=1)), vstats, False, cand, test,
                        cv_record(cv0, cv1), "; ".join(reasons), parent=way.step_of(current),
                        parent_mm=cur_val.mean_mm)
            way.steps.append(step)
            support = Support(test, cv0, cv1, checks)
            if reasons and tested and "session" in worse:
                alone = one_session(run, current, scr, cand, level)
                if alone is not None:       # what differs between the sessions, showing on this joint
                    run.say(f"    rejected: {step.reason}; it holds in session {alone[0].session} only")
                    pending.append(alone[1])
                    continue
            if reasons:
                run.say(f"    rejected: {step.reason}")
                # structure of a joint's reading or of its load that a check of its cause refused: kept as evidence
                if significant and ({"reading_halves", "versus_harmonics"} & set(cand.kind.checks)
                                    or (broken and cand.joint is not None)):
                    pending.append(Evidence(cand, fit.values, support, cur_val.mean_mm - vstats.mean_mm,
                                            "; ".join(reasons)))
                continue
            passing.append(Trial(extrapolation_gain(cv0, cv1), sc, fit, support, step))
        if passing:
            best = max(passing, key=lambda t: t.gain)
            return _choose(run, way, best, scored, level, cur_val), pending
    return None, pending


def one_session(run: DiagnosisRun, current: CalibrationResult, scr: Screen, cand: Candidate, level: float
                ) -> tuple[Candidate, Evidence] | None:
    """Where a candidate of the robot that does worse on the leave-one-session-out folds lives: its copy of one
    session alone is significant at ``level``, predicts random held-out poses better, and no other session's adds
    anything beside it (a joint's own parameter is the robot's, one value in every session: structure of its shape
    in one session only is what differs between the sessions showing on that joint). That copy and its evidence
    (kept out of the model), or None. Not for a cause of a session (its sessions' own are candidates already), nor
    a cause of the user's own (whose terms file says its scope)."""
    sessions = run.cal.session_names
    if cand.session is not None or cand.kind.session_part is not None or cand.user or len(sessions) < 2:
        return None
    copies = [replace(cand, session=s) for s in sessions]
    own = scr.with_candidates(copies)
    scored = own.scores(copies)
    if not scored or scored[0].log10_p >= level:
        return None
    # beside the strongest session's copy, no other session's adds anything (the robot's, fitted to every session,
    # moves the others' geometry: alone their copies may be significant too)
    drop, _ = drops(own)
    r_perp = own.projection()[2]
    ssr = float(r_perp @ r_perp)
    mine = own.columns(scored[0].candidate)
    p0 = len(own.cur) + len(mine)
    for sc in scored[1:]:
        other = own.columns(sc.candidate)
        test = nested_test(ssr - drop(own.J[:, :, mine]), p0, ssr - drop(own.J[:, :, mine + other]),
                           p0 + len(other), len(r_perp))
        if test.log10_p < level:
            return None
    best = scored[0].candidate
    fit = own.fit(best)
    base = own.fit()
    test = nested_test(base.ssr, base.n_free, fit.ssr, fit.n_free, run.n_eq, noise_ssr(fit.lin))
    cv0 = by_kind(base.lin.cv(run.schemes, run.prior), run.mask(current))
    cv1 = by_kind(fit.lin.cv(run.schemes, run.prior), run.mask(current))
    if not cv1["random"] < cv0["random"]:
        return None
    gain = run.val_stats(current).mean_mm - ErrorStats.of(own.validation_errors(fit)).mean_mm
    why = (f"it holds in session {best.session} only ({test.text()}; the robot's does worse on the "
           "leave-one-session-out folds): a joint's own parameter is the robot's, one value in every session")
    return best, Evidence(best, fit.values, Support(test, cv0, cv1, {}), gain, why)


def _choose(run: DiagnosisRun, way: Rounds, best: Trial, scored: list[Scored], level: float, cur_val: ErrorStats
            ) -> Chosen:
    """Accept ``best``'s step, record its finding and support; its one-step values start the full fit."""
    sc, sup, step = best.scored, best.support, best.step
    step.accepted = True
    run.say(f"    accepted {sc.candidate.label()}: held-out mean {cv_text(sup.cv_before, sup.cv_after)} "
            f"(validation mean {cur_val.mean_mm:.4f} -> {step.validation.mean_mm:.4f} mm, judge only)")
    checks = sup.checks
    f = Finding(sc.candidate, cur_val.mean_mm - step.validation.mean_mm, "",
                ambiguous_with=ambiguous(sc, scored, level),
                holds_up={"test": sup.test.text(), "cv_mm": cv_record(sup.cv_before, sup.cv_after),
                          **{k: v.to_dict() for k, v in checks.items()
                             if k in ("resolution", "versus_drift", "versus_harmonics")},
                          **({"halves": [h.to_dict() for h in checks["halves"]]} if "halves" in checks else {})})
    way.support[sc.candidate] = sup
    way.findings.append(f)
    return Chosen(sc.candidate, {**{p.name: p.value for p in way.current.parameters}, **best.fit.values}, level)
