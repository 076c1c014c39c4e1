"""The diagnosis: what the model gets wrong, why, and what each extension gains.

After the nominal and the geometric steps, every round screens all
candidate causes at once with a score test (:mod:`.screening`), fits the
best for real and accepts a cause only when the calibration data support it
three ways: significance (F-test at a Bonferroni-corrected level, BIC) and
held-out error on folds that must extrapolate as well as interpolate
(random, time-blocked and joint-range-blocked cross-validation,
:mod:`.validation`). Physical causes (compliance, progressive stiffness,
encoder scale, backlash, thermal expansion, drift) are tried before
periodic errors, which must also be resolved from their neighbouring
harmonics and from geometry and agree over the two halves of the joint's
range (:mod:`.periodic`); structure that passes the statistics but not
these checks is reported as ``unexplained`` and kept out of the model.
At the end every accepted cause is tested again against the final model
(:mod:`.backward`). The validation poses judge every step and are never
used to accept one. A black box fitted last (:mod:`.blackbox`) tells how
much structure no named cause explains; :mod:`.transfer` takes the
findings to another series.
"""

from __future__ import annotations

import math
import time
from dataclasses import asdict
from typing import Callable

import numpy as np

from ..calibration import calibrate, model_for
from ..checks import check_poses
from ..data import Measurements
from ..errors import listing
from ..problem import RobustLoss
from ..result import CalibrationResult, ErrorStats
from ..robot import Robot
from ..threads import limited_threads
from . import transfer as transfer_mod
from .backward import drop_redundant
from .blackbox import blackbox_step
from .candidates import Candidate, compose_spec
from .findings import UnexplainedLog, describe
from .periodic import halves, resolution
from .periodogram import Periodogram, joint_errors, periodogram
from .plots import joint_view
from .report import DiagnosisReport, Finding, Step
from .screening import Scored, Screen, ambiguous
from .settings import DiagnosisSettings
from .statistics import nested_test
from .validation import (Linearized, by_kind, cv_failure, cv_record, cv_text, extrapolation_gain, joint_levers,
                         not_better, schemes)


#: functions of one joint's reading: each must be the same over the lower and the upper half of its range.
#: (Compliance, progressive stiffness and backlash follow the load, not the reading; on real data their
#: half-range estimates are biased by the structure still unmodelled in each half, so the test is not
#: applied to them.)
JOINT_CAUSES = ("joint_periodic", "encoder_scale")


class _Diagnosis:
    def __init__(self, robot: Robot, cal: Measurements, val: Measurements, settings: DiagnosisSettings,
                 progress: Callable[[str], None]):
        self.robot, self.cal, self.val, self.s = robot, cal, val, settings
        self.say = progress
        self.n_eq = 3 * len(cal)
        self.schemes = schemes(cal.q, cal.rows, settings.folds, settings.seed, joint_levers(robot, cal))
        self.steps: list[Step] = []
        self.findings: list[Finding] = []
        self.notes: list[str] = []
        self.periodograms: list[Periodogram] = []
        self._periodograms_of: CalibrationResult | None = None    # the fit they were computed for
        self.unexplained = UnexplainedLog()
        self.before: dict[Candidate, CalibrationResult] = {}   # fit before each finding, by its cause
        self.support: dict[Candidate, tuple] = {}               # (test, cv before, cv after, checks) by cause
        self._val_errors: dict[int, tuple] = {}                 # id of a fit -> (fit, its validation errors)

    # -- fitting ---------------------------------------------------------------

    def fit(self, spec: str, start: CalibrationResult | dict | None = None, loss: RobustLoss | None = None
            ) -> CalibrationResult:
        """Calibrate ``spec`` on the calibration poses (LM), from ``start``'s values (a result or a dict)."""
        model = model_for(self.robot, spec, self.cal, jit=False)
        st = None
        if start is not None:
            values = start if isinstance(start, dict) else {p.name: p.value for p in start.parameters}
            st = {n: v for n, v in values.items() if n in model.parameters and not n.startswith("base_")}
        return calibrate(self.robot, self.cal, model, "lm", start=st, warn=False, robust=loss or self.s.robust)

    def val_errors(self, res: CalibrationResult) -> np.ndarray:
        """Position errors (m) of a fit on the validation poses, predicted once per fit."""
        hit = self._val_errors.get(id(res))
        if hit is None or hit[0] is not res:
            hit = self._val_errors[id(res)] = (res, res.errors(self.val))
        return hit[1]

    def val_stats(self, res: CalibrationResult) -> ErrorStats:
        return ErrorStats.of(self.val_errors(res))

    def deviance(self, res: CalibrationResult, loss: RobustLoss) -> float:
        """Twice the loss of ``res`` on the calibration poses under ``loss`` (SSR for least squares)."""
        r = res.residuals(self.cal)
        return 2.0 * float(loss.rho(np.einsum("ij,ij->i", r, r)).sum())

    def mask(self, res: CalibrationResult) -> np.ndarray:
        """Poses that count in held-out means: those the robust loss did not set aside."""
        r = res.residuals(self.cal)
        return res.loss.weight(np.einsum("ij,ij->i", r, r)) >= 0.5

    # -- the procedure ---------------------------------------------------------

    def run(self) -> tuple[CalibrationResult, list[Candidate], bool]:
        self.say("step 1: nominal model (base pose only)")
        nominal = self.nominal = self.fit("nominal")
        self.steps.append(Step("nominal", nominal.calibration, self.val_stats(nominal), True))
        self.say(f"  validation mean {self.steps[-1].validation.mean_mm:.4f} mm (judge only)")
        self.say("step 2: geometric (kinematic) calibration")
        kin = self.kinematic = self.fit("kinematic")
        test = nested_test(self.deviance(nominal, kin.loss), int(nominal.parameters.free.sum()),
                           self.deviance(kin, kin.loss), int(kin.parameters.free.sum()), self.n_eq)
        mask = self.mask(kin)
        cv0, cv1 = (by_kind(Linearized.of(r, self.cal).cv(self.schemes), mask) for r in (nominal, kin))
        worse = not_better(cv0, cv1)
        ok = test.log10_p < math.log10(self.s.alpha) and test.delta_bic < 0 and not worse
        kv = self.val_stats(kin)
        reason = "; ".join([f"not significant ({test.text()})"] * (test.log10_p >= math.log10(self.s.alpha))
                           + [f"BIC does not improve ({test.delta_bic:+.1f})"] * (test.delta_bic >= 0)
                           + ([cv_failure(worse, cv0, cv1)] if worse else []))
        self.steps.append(Step("kinematic", kin.calibration, kv, ok, Candidate("geometric"), test,
                               cv_record(cv0, cv1), reason))
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
        for rnd in range(self.s.max_rounds):
            self.say(f"round {rnd + 1}: screening candidate causes")
            new = self.round(current, accepted, geometric)
            if new is None:
                break
            cand, start, level = new
            step = next(s for s in reversed(self.steps) if s.accepted)
            # the one-step fit decided; the full fit (noise scale re-estimated) must confirm the significance
            new_fit = self.fit(compose_spec(accepted + [cand], geometric), start=start)
            test = nested_test(self.deviance(current, current.loss), int(current.parameters.free.sum()),
                               self.deviance(new_fit, current.loss), int(new_fit.parameters.free.sum()), self.n_eq)
            if test.log10_p >= level or test.delta_bic >= 0:
                step.accepted, step.test = False, test
                step.reason = f"not significant once fitted in full ({test.text()})"
                self.say(f"    {cand.label()}: {step.reason}")
                self.findings.pop()
                self.support.pop(cand, None)
                self.unexplained.excluded_causes.add(cand)
                continue
            self.before[cand] = current
            accepted.append(cand)
            current = new_fit
            # the step and the finding's gain judge the full fit, not the one-step fit that decided
            full = self.val_stats(current)
            next(f for f in self.findings if f.candidate == cand).gain_mm += step.validation.mean_mm - full.mean_mm
            step.calibration, step.validation = current.calibration, full
        else:
            if self.s.max_rounds:
                self.notes.append(f"stopped at the safety cap of {self.s.max_rounds} rounds while causes were "
                                  "still supported; raise --max-rounds to look further")
        if len(accepted) > 1:
            self.say("final check: is every cause still needed?")
            current, accepted = drop_redundant(self, current, accepted, geometric)
        return current, accepted, geometric

    def drop_finding(self, cand: Candidate) -> None:
        """Remove the finding of ``cand`` and what is kept for it."""
        self.findings = [f for f in self.findings if f.candidate != cand]
        self.support.pop(cand, None)
        self.before.pop(cand, None)

    def candidates(self, current: CalibrationResult, accepted: list[Candidate]) -> list[Candidate]:
        """Every candidate not yet in the model; periodic ones from the periodogram peaks."""
        have = set(accepted)
        out: list[Candidate] = []
        for j in range(1, self.robot.n + 1):
            out += [Candidate("joint_compliance", j), Candidate("encoder_scale", j),
                    Candidate("backlash", j, source="torque"), Candidate("backlash", j, source="motion")]
            if Candidate("joint_compliance", j) in have:
                out.append(Candidate("nonlinear_stiffness", j))
        temp = self.cal.get("temperature_c")
        if temp is not None and np.ptp(temp) > 0.1:
            out.append(Candidate("thermal_expansion"))
            out += [Candidate("thermal_expansion", j) for j, jt in enumerate(self.robot.joints, start=1)
                    if abs(jt.a) + abs(jt.d) + abs(jt.b or 0.0) > 0]
        out.append(Candidate("drift"))  # time_s, or the row order
        # periodograms of the projected residuals (the same while the fit is the same)
        if self._periodograms_of is not current:
            # a joint angle error moves the tool point along the derivative w.r.t. the joint's angle
            resid, JA = joint_view(current, self.cal)
            self.periodograms = []
            for j in range(1, self.robot.n + 1):
                s, w = joint_errors(resid, JA[:, :, j - 1])
                self.periodograms.append(periodogram(self.cal.q[:, j - 1], s, w, j, self.max_harmonic()))
            self._periodograms_of = current
        for j, pg in enumerate(self.periodograms, start=1):
            ranked = [int(h) for h in pg.harmonics[np.argsort(-pg.power)]
                      if (j, int(h)) not in self.unexplained.excluded][:2]
            # the first harmonic always: over a small range it mimics an encoder scale error,
            # and the ambiguity can only be reported if both are screened
            hs = set(ranked) | ({1} if (j, 1) not in self.unexplained.excluded else set())
            out += [Candidate("joint_periodic", j, h) for h in sorted(hs)]
        return [c for c in out if c not in have and c not in self.unexplained.excluded_causes and not (
            c.cause == "backlash" and any(a.cause == "backlash" and a.joint == c.joint for a in accepted))]

    def max_harmonic(self) -> int:
        return min(self.s.max_harmonic, max(len(self.cal) // 3, 1))

    def n_tests(self, cands: list[Candidate]) -> int:
        """Tests behind a round's candidates: each periodic candidate stands for the scanned harmonics."""
        per = sum(1 for c in cands if c.cause == "joint_periodic")
        return (len(cands) - per) + self.robot.n * self.max_harmonic()

    def round(self, current: CalibrationResult, accepted: list[Candidate], geometric: bool):
        """Screen, fit the best candidates by one step, accept one; None when nothing is supported."""
        scr = baseline = None
        while True:
            cands = self.candidates(current, accepted)
            # screening again (after setting structure aside) reuses the linearisation and the baseline
            if scr is None:
                scr = Screen(current, accepted, cands, geometric, self.cal, self.val)
                mask = self.mask(current)
                base = scr.fit()
                baseline = (mask, base, by_kind(base.lin.cv(self.schemes), mask), self.val_stats(current))
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
            for sc in [sc for sc in scored if sc.candidate.tier == tier and sc.log10_p < level][: self.s.confirm]:
                cand = sc.candidate
                self.say(f"  fitting {cand.label()} (score {sc.test.text()})")
                fit = scr.fit(cand)
                test = nested_test(base.ssr, base.n_free, fit.ssr, fit.n_free, self.n_eq)
                cv1 = by_kind(fit.lin.cv(self.schemes), mask)
                reasons = []
                if test.log10_p >= level:
                    reasons.append(f"F-test not significant at the corrected level ({test.text()})")
                if test.delta_bic >= 0:
                    reasons.append(f"BIC does not improve ({test.delta_bic:+.1f})")
                worse = not_better(cv0, cv1)
                # real structure on these poses: significant, and it predicts random held-out poses
                significant = not reasons and "random" not in worse
                if worse:
                    reasons.append(cv_failure(worse, cv0, cv1))
                checks = self.joint_checks(scr, fit, cand) if significant else {}
                reasons += checks.pop("reasons", [])
                vstats = ErrorStats.of(scr.validation_errors(fit))
                step = Step(compose_spec(accepted + [cand], geometric),
                            ErrorStats.of(np.linalg.norm(fit.lin.r, axis=1)), vstats, False, cand, test,
                            cv_record(cv0, cv1), "; ".join(reasons))
                self.steps.append(step)
                if reasons:
                    self.say(f"    rejected: {step.reason}")
                    if cand.cause in JOINT_CAUSES and significant:
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
                                      **{k: v.to_dict() for k, v in checks.items() if k == "resolution"},
                                      **({"halves": [h.to_dict() for h in checks["halves"]]} if "halves" in checks
                                         else {})})
                self.support[sc.candidate] = (test, cv0, cv1, checks)
                self.findings.append(f)
                return (sc.candidate, {**{p.name: p.value for p in current.parameters}, **fit.values}, level), pending
        return None, pending

    def joint_checks(self, scr: Screen, fit, cand: Candidate) -> dict:
        """A function of a joint's reading (periodic error, encoder scale) is the same over both halves of the
        joint's range, and a periodic error must be resolved from its neighbours and from geometry; a drift
        (a velocity) is the same over both halves of the measurement time."""
        if cand.cause not in JOINT_CAUSES + ("drift",):
            return {}
        out: dict = {"reasons": []}
        params = [scr.params[n] for n in cand.parameter_names() if n in fit.lin.names]
        if cand.cause == "drift":
            hv = out["halves"] = halves(fit, params, self.cal, None, self.s.stability_alpha)
            if not hv[0].agree:
                out["reasons"].append("the first and second half in time disagree: " + hv[0].text())
            return out
        hv = out["halves"] = halves(fit, params, self.cal, cand.joint, self.s.stability_alpha)
        if cand.cause == "joint_periodic":
            rs = out["resolution"] = resolution(scr, cand.joint, cand.harmonic)
            if not rs.resolved:
                out["reasons"].append(rs.text())
        if not hv[0].agree:
            out["reasons"].append("the halves of the joint's range disagree: " + hv[0].text())
        return out


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
    """
    t0 = time.perf_counter()
    s = settings or DiagnosisSettings()
    say = progress or (lambda _: None)
    for d in [cal, val] + ([other] if other is not None else []):
        check_poses(d, robot, **checks)     # the joint count first
    dg = _Diagnosis(robot, cal, val, s, say)
    current, accepted, geometric = dg.run()
    parametric = current
    final, final_spec = current, compose_spec(accepted, geometric)
    if s.blackbox:
        final, final_spec = blackbox_step(current, final_spec, cal, val, dg.schemes, s, dg.steps, dg.findings, say)
    describe(dg.findings, dg.support, dg.before, final, cal)
    dg.findings += list(dg.unexplained.by_joint.values())
    final_errors = dg.val_errors(final)
    final_val = ErrorStats.of(final_errors)
    if final.uncertainty is not None:
        dg.notes.append(f"remaining calibration residual {final.uncertainty.sigma * 1000:.4f} mm per axis (rms); "
                        f"validation rms {final_val.rms_mm / math.sqrt(3):.4f} mm per axis")
    if final.downweighted:
        dg.notes.append(f"the robust loss set aside {len(final.downweighted)} calibration pose(s) of {cal.path} "
                        "(lines " + listing([d["line"] for d in final.downweighted], 10) + "): likely bad measurements")
    study = None
    if other is not None:
        study = transfer_mod.findings_study(dg, final, parametric, accepted, geometric, other)
    plots = {"val_errors_nominal_mm": (dg.val_errors(dg.nominal) * 1000).tolist(),
             "val_errors_final_mm": (final_errors * 1000).tolist()}
    return DiagnosisReport(robot.name, dg.steps, dg.findings, final_spec, final_val, final, dg.periodograms, plots,
                           dg.notes, time.perf_counter() - t0,
                           next(st.validation for st in dg.steps if st.model == "kinematic"),
                           study.to_dict() if study is not None else {}, asdict(s))
