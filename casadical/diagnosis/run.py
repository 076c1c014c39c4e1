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
The validation poses judge every step and are never used to accept one. A
black box fitted last (:mod:`.blackbox`) tells how much structure no named
cause explains; :mod:`.transfer` takes the findings to another series.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import Callable

import numpy as np

from ..calibration import calibrate, set_references
from ..checks import check_poses
from ..data import Measurements
from ..errors import InputError
from ..model import Model, parse_spec
from ..problem import RobustLoss
from ..result import CalibrationResult
from ..robot import Robot
from . import transfer as transfer_mod
from .blackbox import blackbox
from .candidates import Candidate, compose_spec, tell_apart
from .periodic import halves, resolution
from .periodogram import Periodogram, joint_errors, periodogram
from .plots import residual_plot
from .report import DiagnosisReport, Finding, Step
from .screening import Scored, screen
from .statistics import nested_test
from .validation import CVResult, Linearized, schemes

KINDS = ("random", "time", "joint")


@dataclass
class DiagnosisSettings:
    """Settings of :func:`diagnose`.

    Parameters
    ----------
    alpha : float
        Family-wise significance level of the F-tests (Bonferroni over the
        candidates of a round, harmonics scanned included).
    max_harmonic : int
        Highest harmonic of the periodogram (cycles per joint turn).
    folds : int
        Folds of each cross-validation scheme.
    max_rounds : int
        Safety cap on the rounds; the search stops when no candidate is
        supported, and a note says if the cap stopped it instead.
    confirm : int
        Candidates fitted for real per round and tier (best scores first).
    blackbox : bool
        Try a black-box compensator on what remains.
    stability_alpha : float
        Level of the test that a periodic error's amplitude and phase agree
        on the two halves of the joint's range.
    robust : {"huber", "none"}
        Loss of every fit (see :func:`casadical.calibrate`).
    transfer_base_poses : int
        With another series: poses on which the base pose is re-estimated there.
    transfer_refit_poses : int or None
        With another series: poses on which the geometry is refitted there
        (default: as many as the calibration poses, at most half the series).
    seed : int
    """

    alpha: float = 0.001
    max_harmonic: int = 60
    folds: int = 5
    max_rounds: int = 40
    confirm: int = 3
    blackbox: bool = True
    stability_alpha: float = 0.001
    robust: str = "huber"
    transfer_base_poses: int = 30
    transfer_refit_poses: int | None = None
    seed: int = 0

    def __post_init__(self) -> None:
        if not 0 < self.alpha < 1 or not 0 < self.stability_alpha < 1:
            raise InputError(f"alpha and stability_alpha must be in (0, 1), got {self.alpha}, "
                             f"{self.stability_alpha}")
        for name in ("max_harmonic", "folds", "confirm", "transfer_base_poses"):
            if getattr(self, name) < (2 if name == "folds" else 1):
                raise InputError(f"{name} must be at least {2 if name == 'folds' else 1}, got {getattr(self, name)}")
        if self.max_rounds < 0:
            raise InputError(f"max_rounds must not be negative, got {self.max_rounds}")


class _Diagnosis:
    def __init__(self, robot: Robot, cal: Measurements, val: Measurements, settings: DiagnosisSettings,
                 progress: Callable[[str], None]):
        self.robot, self.cal, self.val, self.s = robot, cal, val, settings
        self.say = progress
        self.n_eq = 3 * len(cal)
        self.schemes = schemes(cal.q, cal.rows, settings.folds, settings.seed, _levers(robot, cal))
        self.steps: list[Step] = []
        self.findings: list[Finding] = []
        self.notes: list[str] = []
        self.periodograms: list[Periodogram] = []
        self.excluded: set[tuple[int, int]] = set()        # periodic (joint, harmonic) found unexplained
        self.excluded_causes: set[Candidate] = set()        # other candidates found unexplained
        self.unexplained: dict[int, Finding] = {}           # by joint
        self.extra: dict[int, list[Candidate]] = {}         # unexplained periodic terms, by joint
        self.before: dict[int, CalibrationResult] = {}      # fit before each finding, by finding index
        self.support: dict[int, tuple] = {}                  # (test, cv before, cv after, checks) by finding

    # -- fitting ---------------------------------------------------------------

    def model(self, spec: str) -> Model:
        terms = parse_spec(spec)
        set_references(terms, self.cal)
        return Model(self.robot, terms, jit=False)

    def fit(self, spec: str, start: CalibrationResult | None = None, loss: RobustLoss | None = None,
            data: Measurements | None = None) -> CalibrationResult:
        model = self.model(spec)
        st = None
        if start is not None:
            st = {p.name: p.value for p in start.parameters if p.name in model.parameters
                  and not p.name.startswith("base_")}
        return calibrate(self.robot, data or self.cal, model, "lm", start=st, warn=False,
                         robust=loss or self.s.robust)

    def deviance(self, res: CalibrationResult, loss: RobustLoss) -> float:
        """Twice the loss of ``res`` on the calibration poses under ``loss`` (SSR for least squares)."""
        r = res.residuals(self.cal)
        return 2.0 * float(loss.rho(np.einsum("ij,ij->i", r, r)).sum())

    @staticmethod
    def n_free(res: CalibrationResult) -> int:
        return int(res.parameters.free.sum())

    def cv(self, res: CalibrationResult) -> CVResult:
        return Linearized.of(res, self.cal).cv(self.schemes)

    def cv_kinds(self, cv: CVResult, mask: np.ndarray) -> dict:
        """Held-out means (mm) by kind of fold."""
        return {k: cv.kind_mean_mm(k, mask) for k in KINDS}

    @staticmethod
    def not_better(cv0: dict, cv1: dict) -> list[str]:
        """Kinds of fold on which the held-out mean error does not drop."""
        return [k for k in KINDS if not cv1[k] < cv0[k]]

    def mask(self, res: CalibrationResult) -> np.ndarray:
        """Poses that count in held-out means: those the robust loss did not set aside."""
        r = res.residuals(self.cal)
        return res.loss.weight(np.einsum("ij,ij->i", r, r)) >= 0.5

    # -- the procedure ---------------------------------------------------------

    def run(self) -> tuple[CalibrationResult, list[Candidate], bool]:
        self.say("step 1: nominal model (base pose only)")
        nominal = self.nominal = self.fit("nominal")
        self.steps.append(Step("nominal", nominal.calibration, nominal.stats(self.val), True))
        self.say(f"  validation mean {self.steps[-1].validation.mean_mm:.4f} mm (judge only)")
        self.say("step 2: geometric (kinematic) calibration")
        kin = self.kinematic = self.fit("kinematic")
        loss = kin.loss
        test = nested_test(self.deviance(nominal, loss), self.n_free(nominal), self.deviance(kin, loss),
                           self.n_free(kin), self.n_eq)
        mask = self.mask(kin)
        cv0, cv1 = self.cv_kinds(self.cv(nominal), mask), self.cv_kinds(self.cv(kin), mask)
        worse = self.not_better(cv0, cv1)
        ok = test.log10_p < math.log10(self.s.alpha) and test.delta_bic < 0 and not worse
        kv = kin.stats(self.val)
        reason = "" if ok else "; ".join([f"not significant ({test.text()})"] * (test.log10_p >= math.log10(
            self.s.alpha)) + ([_cv_failure(worse, cv0, cv1)] if worse else []))
        self.steps.append(Step("kinematic", kin.calibration, kv, ok, Candidate("geometric"), test,
                               _cv_record(cv0, cv1), reason))
        self.say(f"  validation mean {kv.mean_mm:.4f} mm ({test.text()})")
        if ok:
            gain = self.steps[0].validation.mean_mm - kv.mean_mm
            self.findings.append(Finding(Candidate("geometric"), gain,
                                         f"{test.text()} on the calibration poses; held-out mean "
                                         + _cv_text(cv0, cv1) + "; link, base and tool parameters"))
            current, geometric = kin, True
        else:
            current, geometric = nominal, False
        accepted: list[Candidate] = []
        for rnd in range(self.s.max_rounds):
            self.say(f"round {rnd + 1}: screening candidate causes")
            new = self.round(current, accepted, geometric)
            if new is None:
                break
            res, cand = new
            self.before[len(self.findings) - 1] = current
            accepted.append(cand)
            current = self.fit(compose_spec(accepted, geometric), start=res)   # noise scale re-estimated
        else:
            if self.s.max_rounds:
                self.notes.append(f"stopped at the safety cap of {self.s.max_rounds} rounds while causes were "
                                  "still supported; raise --max-rounds to look further")
        return current, accepted, geometric

    def candidates(self, current: CalibrationResult, accepted: list[Candidate]) -> list[Candidate]:
        """Every candidate not yet in the model; periodic ones from the periodogram peaks."""
        have = set(accepted)
        n = self.robot.n
        out: list[Candidate] = []
        for j in range(1, n + 1):
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
        # periodograms of the projected residuals
        model, p = current.model, current.parameters
        _, J = model.predict_jacobian(self.cal.q, p.values, model.covariates(self.cal), current.base0)
        resid = current.residuals(self.cal)
        H = self.max_harmonic()
        self.periodograms = []
        for j in range(1, n + 1):
            s, w = joint_errors(resid, J[:, :, p.index(f"theta{j}")])
            pg = periodogram(self.cal.q[:, j - 1], s, w, j, H)
            self.periodograms.append(pg)
            ranked = [h for h in pg.harmonics[np.argsort(-pg.power)] if (j, int(h)) not in self.excluded][:2]
            # the first harmonic always: over a small range it mimics an encoder scale error,
            # and the ambiguity can only be reported if both are screened
            hs = {int(h) for h in ranked} | ({1} if (j, 1) not in self.excluded else set())
            out += [Candidate("joint_periodic", j, h) for h in sorted(hs)]
        return [c for c in out if c not in have and c not in self.excluded_causes and not (c.cause == "backlash" and any(
            a.cause == "backlash" and a.joint == c.joint for a in accepted))]

    def max_harmonic(self) -> int:
        return min(self.s.max_harmonic, max(len(self.cal) // 3, 1))

    def n_tests(self, cands: list[Candidate]) -> int:
        """Tests behind a round's candidates: each periodic candidate stands for the scanned harmonics."""
        per = sum(1 for c in cands if c.cause == "joint_periodic")
        return (len(cands) - per) + self.robot.n * self.max_harmonic()

    def round(self, current: CalibrationResult, accepted: list[Candidate], geometric: bool):
        cands = self.candidates(current, accepted)
        scored = screen(current, accepted, cands, geometric, self.cal)
        level = math.log10(self.s.alpha / max(self.n_tests(cands), 1))
        if not scored or scored[0].log10_p >= level:
            best = scored[0] if scored else None
            self.say("  no candidate passes the score test" +
                     (f" (best: {best.candidate.label()}, {best.test.text()})" if best else ""))
            return None
        loss = current.loss
        mask = self.mask(current)
        cv0 = self.cv_kinds(self.cv(current), mask)
        dev0, p0 = self.deviance(current, loss), self.n_free(current)
        cur_val = current.stats(self.val)
        # significant periodic structure that cannot be named: reported as unexplained unless the round
        # accepts a cause (then the next round screens again what is left)
        pending: list[tuple] = []
        for tier in (1, 2, 3):
            tried = [sc for sc in scored if sc.candidate.tier == tier and sc.log10_p < level][: self.s.confirm]
            passing = []
            for sc in tried:
                cand = sc.candidate
                spec = compose_spec(accepted + [cand], geometric)
                self.say(f"  fitting {cand.label()} (score {sc.test.text()})")
                res = self.fit(spec, start=current, loss=loss)
                test = nested_test(dev0, p0, self.deviance(res, loss), self.n_free(res), self.n_eq)
                cv1 = self.cv_kinds(self.cv(res), mask)
                reasons = []
                if test.log10_p >= level:
                    reasons.append(f"F-test not significant at the corrected level ({test.text()})")
                if test.delta_bic >= 0:
                    reasons.append(f"BIC does not improve ({test.delta_bic:+.1f})")
                worse = self.not_better(cv0, cv1)
                # real structure on these poses: significant, and it predicts random held-out poses
                significant = not reasons and "random" not in worse
                if worse:
                    reasons.append(_cv_failure(worse, cv0, cv1))
                checks: dict = {}
                if cand.cause in ("joint_periodic", "encoder_scale") and significant:
                    # a function of the joint's reading: the same over the lower and the upper half of its range
                    hv = halves(res, self.cal, cand.parameter_names(), cand.joint, self.s.stability_alpha)
                    checks["halves"] = hv
                    if cand.cause == "joint_periodic":
                        checks["resolution"] = rs = resolution(current, self.cal, cand.joint, cand.harmonic)
                        if not rs.resolved:
                            reasons.append(rs.text())
                    if not hv[0].agree:
                        reasons.append("the halves of the joint's range disagree: " + hv[0].text())
                vstats = res.stats(self.val)
                step = Step(spec, res.calibration, vstats, False, cand, test, _cv_record(cv0, cv1),
                            "; ".join(reasons))
                self.steps.append(step)
                if reasons:
                    self.say(f"    rejected: {step.reason}")
                    if cand.cause in ("joint_periodic", "encoder_scale") and significant:
                        pending.append((cand, res, test, cv0, cv1, checks, cur_val.mean_mm - vstats.mean_mm,
                                        "; ".join(reasons)))
                    continue
                passing.append((_extrapolation_gain(cv0, cv1), sc, res, test, cv1, checks, step))
            if passing:
                gain_x, sc, res, test, cv1, checks, step = max(passing, key=lambda t: t[0])
                step.accepted = True
                gain = cur_val.mean_mm - step.validation.mean_mm
                self.say(f"    accepted {sc.candidate.label()}: held-out mean {_cv_text(cv0, cv1)} "
                         f"(validation mean {cur_val.mean_mm:.4f} -> {step.validation.mean_mm:.4f} mm, judge only)")
                f = Finding(sc.candidate, gain, "", ambiguous_with=self.ambiguous(sc, scored, level))
                f.holds_up = {"test": test.text(), "cv_mm": _cv_record(cv0, cv1)}
                if "resolution" in checks:
                    f.holds_up["resolution"] = checks["resolution"].to_dict()
                if "halves" in checks:
                    f.holds_up["halves"] = [h.to_dict() for h in checks["halves"]]
                self.support[len(self.findings)] = (test, cv0, cv1, checks)
                self.findings.append(f)
                return res, sc.candidate
        for item in pending:
            self.record_unexplained(*item)
        if not pending:
            self.say("  no candidate is supported on the calibration data")
            return None
        self.say("  no cause is supported; the periodic structure that cannot be named is set aside, and the "
                 "round screens again")
        return self.round(current, accepted, geometric)

    def record_unexplained(self, cand: Candidate, res: CalibrationResult, test, cv0, cv1, checks: dict,
                           potential: float, why: str) -> None:
        """Significant structure of a joint's angle error that cannot be named: kept out of the model, reported."""
        j = cand.joint
        if cand.cause == "joint_periodic":
            band = checks["resolution"].band if "resolution" in checks else (cand.harmonic, cand.harmonic)
            self.excluded.update((j, h) for h in range(band[0], band[1] + 1))
            s_, c_ = (res.parameters[n].value for n in cand.parameter_names())
            size = math.degrees(math.hypot(s_, c_)) * 3600
            what = f"harmonic {cand.harmonic} ({size:.1f} arcsec)"
            item = {"harmonic": cand.harmonic, "band": list(band), "amplitude_arcsec": size}
        else:
            self.excluded_causes.add(cand)
            p = res.parameters[cand.parameter_names()[0]]
            what = f"a trend along the joint's reading ({p.value * 1e6:.0f} ppm)"
            item = {"trend_ppm": p.value * 1e6}
        f = self.unexplained.get(j)
        if f is None:
            f = Finding(Candidate("unexplained", j), 0.0, "", in_model=False, potential_gain_mm=0.0)
            f.holds_up = {"structures": []}
            self.unexplained[j] = f
            self.extra[j] = [cand]          # the strongest, for the transfer study
        item.update(what=what, test=test.text(), cv_mm=_cv_record(cv0, cv1), why=why)
        if "halves" in checks:
            item["halves"] = [h.to_dict() for h in checks["halves"]]
        f.holds_up["structures"].append(item)
        f.potential_gain_mm = max(f.potential_gain_mm or 0.0, potential)
        f.where = f"joint {j}: " + "; ".join(x["what"] for x in f.holds_up["structures"])
        f.evidence = (f"structure in joint {j}'s angle error that is significant on the calibration poses but "
                      "cannot be named as a cause: " + " | ".join(f"{x['what']}: {x['why']}"
                                                                 for x in f.holds_up["structures"])
                      + f". Alone it would lower this series' validation mean by up to {f.potential_gain_mm:.4f} mm;"
                      " it is kept out of the final model because it does not hold up as a cause")

    def ambiguous(self, best: Scored, scored: list[Scored], level: float) -> list[dict]:
        """Candidates whose screening fit explains the same residual as the accepted one."""
        amb = []
        best_drop = float(best.fitted @ best.fitted)
        cand = best.candidate
        for sc in scored:
            other = sc.candidate
            if other == cand or sc.log10_p >= level or (other.cause == cand.cause and other.joint == cand.joint
                                                        and other.cause != "joint_periodic"):
                continue
            drop = float(sc.fitted @ sc.fitted)
            cos = float(sc.fitted @ best.fitted) / math.sqrt(max(drop * best_drop, 1e-300))
            if drop > 0.7 * best_drop and cos > 0.9:
                amb.append({**other.to_dict(), "label": other.label(), "similarity": round(cos, 4),
                            "tell_apart": tell_apart(cand, other)})
        return amb

    # -- the final model, described with its own values -----------------------------

    def describe(self, final: CalibrationResult) -> None:
        for k, f in enumerate(self.findings):
            cand = f.candidate
            if k not in self.support:
                continue
            f.parameters = _param_values(final, cand.parameter_names())
            test, cv0, cv1, checks = self.support[k]
            text = f"{test.text()} on the calibration poses; held-out mean {_cv_text(cv0, cv1)}"
            what = _what(cand, final, self.cal)
            if "resolution" in checks:
                text += "; " + checks["resolution"].text()
            if "halves" in checks:
                text += "; " + "; ".join(h.text() for h in checks["halves"])
            f.evidence = text + (("; " + what) if what else "")
            f.plot = residual_plot(cand, self.before.get(k, final), final, self.cal)


def _levers(robot: Robot, data: Measurements) -> np.ndarray:
    """How far the tool point moves per radian of each joint (RMS over the poses, m)."""
    m = Model(robot, "nominal", jit=False)
    _, J = m.predict_jacobian(data.q, cov=m.covariates(data))
    return np.array([np.sqrt(np.mean(np.sum(J[:, :, m.parameters.index(f"theta{j}")] ** 2, axis=1)))
                     for j in range(1, robot.n + 1)])


def _param_values(res: CalibrationResult, names: list[str]) -> dict:
    out = {}
    for name in names:
        p = res.parameters[name]
        out[name] = {"value": p.to_display(p.value),
                     "std": p.to_display(p.std) if math.isfinite(p.std) else None, "unit": p.display_unit}
    return out


def _what(cand: Candidate, res: CalibrationResult, cal: Measurements) -> str:
    """The cause's size in words, from the model's values."""
    P = res.parameters
    if cand.cause == "joint_compliance":
        k, sk = res.stiffness().get(cand.joint, (math.inf, math.nan))
        what = f"stiffness k{cand.joint} = {k:.4g} N m/rad (std {sk:.2g})"
        if cal.get("payload_kg") is not None and np.ptp(cal.get("payload_kg")) > 0:
            what += "; the rows' payloads vary and enter the torques"
        return what
    if cand.cause == "nonlinear_stiffness":
        p = P[f"cubic{cand.joint}"]
        kind = "stiffens" if p.value < 0 else "softens"
        return (f"progressive term {p.value:.3g} rad/(N m)^3 (std {p.std:.2g}): the joint {kind} with load")
    if cand.cause == "joint_periodic":
        s_, c_ = (P[n].value for n in cand.parameter_names())
        return (f"amplitude {math.degrees(math.hypot(s_, c_)) * 3600:.2f} arcsec, phase "
                f"{math.degrees(math.atan2(c_, s_)):.1f} deg, {cand.harmonic} cycles per turn of joint {cand.joint}")
    if cand.cause == "encoder_scale":
        return f"scale error {P[f'escale{cand.joint}'].value * 1e6:.1f} ppm"
    if cand.cause == "backlash":
        return (f"half play {math.degrees(P[cand.parameter_names()[0]].value) * 3600:.2f} arcsec, sign from the "
                f"{'gravity torque' if cand.source != 'motion' else 'last move'}")
    if cand.cause == "thermal_expansion":
        name = cand.parameter_names()[0]
        where = "every length" if cand.joint is None else f"the lengths of link {cand.joint}"
        return f"expansion {P[name].value * 1e6:.2f} ppm/K of {where}"
    if cand.cause == "drift":
        v = np.array([P[n].value for n in cand.parameter_names()]) * 1e6
        unit = "s" if cal.get("time_s") is not None else "row"
        return (f"the measured points move {np.linalg.norm(v):.3g} um per {unit} (x, y, z: "
                + ", ".join(f"{c:+.3g}" for c in v) + ")")
    return ""


def _cv_record(cv0: dict, cv1: dict) -> dict:
    """The held-out means before and after, for the report."""
    return {**{f"{k}_before": cv0[k] for k in KINDS}, **{k: cv1[k] for k in KINDS}}


def _cv_text(cv0: dict, cv1: dict) -> str:
    return ", ".join(f"{k} {cv0[k]:.4f} -> {cv1[k]:.4f} mm" for k in KINDS)


def _cv_failure(worse: list[str], cv0: dict, cv1: dict) -> str:
    return ("held-out mean does not drop where it must " + ("interpolate" if worse == ["random"] else "extrapolate")
            + ": " + ", ".join(f"{k} {cv0[k]:.4f} -> {cv1[k]:.4f} mm" for k in worse))


def _extrapolation_gain(cv0: dict, cv1: dict) -> float:
    return 0.5 * ((cv0["time"] - cv1["time"]) + (cv0["joint"] - cv1["joint"]))


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
        ``angles_are_degrees``, ``positions_are_mm``).
    """
    t0 = time.perf_counter()
    s = settings or DiagnosisSettings()
    say = progress or (lambda _: None)
    for d in [cal, val] + ([other] if other is not None else []):
        if d.n_joints != robot.n:
            raise InputError(f"has {d.n_joints} joint columns but robot {robot.name} has {robot.n} joints",
                             file=d.path)
        check_poses(d, robot, **checks)
    dg = _Diagnosis(robot, cal, val, s, say)
    current, accepted, geometric = dg.run()
    parametric = current
    final, final_spec = current, compose_spec(accepted, geometric)
    if s.blackbox:
        bb = blackbox(current, cal, dg.schemes, s.seed, s.alpha)
        v0 = current.stats(val)
        if bb.accepted:
            final, final_spec = bb.result, final_spec + "+rbf_compensator"
            v1 = final.stats(val)
            dg.steps.append(Step(final_spec, final.calibration, v1, True, Candidate("unexplained"),
                                 cv_mm=bb.cv_mm))
            dg.findings.append(Finding(
                Candidate("unexplained"), v0.mean_mm - v1.mean_mm,
                "an RBF network on joint angles and gravity torques removes structure no named cause explains: "
                "held-out mean " + ", ".join(f"{k} {bb.cv_mm[k + '_before']:.4f} -> {bb.cv_mm[k]:.4f} mm"
                                             for k in KINDS), where="black-box compensator (rbf_compensator)",
                holds_up={"cv_mm": bb.cv_mm}))
            say(f"black-box compensator accepted: validation mean {v0.mean_mm:.4f} -> {v1.mean_mm:.4f} mm")
        else:
            dg.steps.append(Step(final_spec + "+rbf_compensator", current.calibration, v0, False,
                                 Candidate("unexplained"), cv_mm=bb.cv_mm, reason=bb.reason))
            say(f"black-box compensator rejected: {bb.reason}")
    dg.describe(final)
    dg.findings += list(dg.unexplained.values())
    final_val = final.stats(val)
    if final.uncertainty is not None:
        dg.notes.append(f"remaining calibration residual {final.uncertainty.sigma * 1000:.4f} mm per axis (rms); "
                        f"validation rms {final_val.rms_mm / math.sqrt(3):.4f} mm per axis")
    if final.downweighted:
        dg.notes.append(f"the robust loss set aside {len(final.downweighted)} calibration pose(s) of {cal.path} "
                        "(lines " + ", ".join(str(d["line"]) for d in final.downweighted[:10])
                        + (" ..." if len(final.downweighted) > 10 else "") + "): likely bad measurements")
    study = None
    if other is not None:
        named = [k for k, f in enumerate(dg.findings) if f.in_model and f.cause not in ("geometric", "unexplained")]
        n_refit = s.transfer_refit_poses or min(len(cal), len(other) // 2)
        if not s.transfer_base_poses < len(other) or not n_refit < len(other):
            raise InputError(f"has {len(other)} poses: too few to re-estimate the base on "
                             f"{s.transfer_base_poses} and the geometry on {n_refit} and judge on the rest",
                             file=other.path)

        def without(k: int) -> CalibrationResult | None:
            f = dg.findings[k]
            if f.cause == "unexplained" and not f.in_model:
                # structure left out: what would it have done there?
                return dg.fit(compose_spec(accepted + dg.extra[f.candidate.joint], geometric), start=parametric)
            if k not in named:
                return None
            return dg.fit(compose_spec([a for a in accepted if a != f.candidate], geometric), start=parametric)

        study = transfer_mod.study(final, dg.kinematic, without, len(dg.findings), other,
                                   s.transfer_base_poses, n_refit, s.seed, say)
        # the named causes alone there (the final model unless a black box was added)
        named_only = study.final if parametric is final else transfer_mod.travel(parametric, other, study.split)
        for k, f in enumerate(dg.findings):
            if k in study.gains:
                with_it, without_it = ((study.final, study.gains[k]) if f.in_model else (study.gains[k], named_only))
                f.transfer = transfer_mod.finding_gain(with_it, without_it)
            elif f.cause == "unexplained" and f.in_model:
                f.transfer = transfer_mod.finding_gain(study.final, named_only)
    plots = {"val_errors_nominal_mm": (dg.nominal.errors(val) * 1000).tolist(),
             "val_errors_final_mm": (final.errors(val) * 1000).tolist()}
    settings_doc = {k: getattr(s, k) for k in s.__dataclass_fields__}
    return DiagnosisReport(robot.name, dg.steps, dg.findings, final_spec, final_val, final, dg.periodograms, plots,
                           dg.notes, time.perf_counter() - t0, dg.kinematic.stats(val),
                           study.to_dict() if study is not None else {}, settings_doc)
