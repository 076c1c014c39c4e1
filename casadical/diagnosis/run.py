"""The diagnosis: what the model gets wrong, why, and what each extension gains.

Each step is judged on validation poses that are never fitted. After the
nominal and the geometric steps, every round screens all candidate causes
at once with a score (Lagrange multiplier) test: one extended model is
linearised at the current fit, and the drop of the residual sum of squares
each candidate's parameters would bring is computed by projection. The best
candidates are then fitted for real and accepted only if supported twice:
by the calibration data (F-test with a Bonferroni-corrected level, BIC, and
k-fold cross-validation) and by a real gain on the validation poses. A
black-box compensator fitted last tells how much structure no named cause
explains.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from ..calibration import CalibrationResult, ErrorStats, calibrate
from ..checks import check_poses
from ..data import Measurements
from ..errors import InputError
from ..model import Model
from ..problem import CalibrationProblem
from ..robot import Robot
from .candidates import Candidate, compose_spec, tell_apart
from .periodogram import Periodogram, joint_errors, periodogram
from .statistics import NestedTest, nested_test, paired_gain


@dataclass
class DiagnosisSettings:
    """Settings of :func:`diagnose`.

    Parameters
    ----------
    alpha : float
        Family-wise significance level of the F-tests (Bonferroni over the
        candidates of a round, harmonics scanned included).
    min_gain : float
        Smallest relative drop of the validation mean error that counts as
        a real gain (fraction of the current mean).
    max_harmonic : int
        Highest harmonic of the periodogram (cycles per joint turn).
    folds : int
        Cross-validation folds on the calibration poses.
    max_rounds : int
        Largest number of extensions accepted.
    confirm : int
        Candidates fitted for real per round (best scores first).
    blackbox : bool
        Try a black-box compensator on what remains.
    seed : int
    """

    alpha: float = 0.01
    min_gain: float = 0.01
    max_harmonic: int = 60
    folds: int = 5
    max_rounds: int = 8
    confirm: int = 3
    blackbox: bool = True
    seed: int = 0


@dataclass
class Step:
    """One model tried, judged on the validation poses."""

    model: str
    calibration: ErrorStats
    validation: ErrorStats
    accepted: bool
    candidate: Candidate | None = None
    test: NestedTest | None = None
    cv_rms_mm: float | None = None
    reason: str = ""

    def to_dict(self) -> dict:
        d = {"model": self.model, "validation": _stats(self.validation),
             "calibration": _stats(self.calibration), "accepted": self.accepted}
        if self.candidate is not None:
            d["candidate"] = self.candidate.to_dict()
        if self.test is not None:
            d["test"] = {"f": _finite(self.test.f), "dof": list(self.test.dof),
                         "log10_p": _finite(self.test.log10_p), "delta_bic": _finite(self.test.delta_bic)}
        if self.cv_rms_mm is not None:
            d["cv_rms_mm"] = self.cv_rms_mm
        if self.reason:
            d["reason"] = self.reason
        return d


@dataclass
class Finding:
    """A cause accepted by the diagnosis."""

    candidate: Candidate
    gain_mm: float
    evidence: str
    ambiguous_with: list[dict] = field(default_factory=list)
    parameters: dict = field(default_factory=dict)
    plot: dict = field(default_factory=dict)  # residual against the relevant variable, before/after

    def to_dict(self) -> dict:
        d = self.candidate.to_dict()
        d.update(gain_mm=self.gain_mm, evidence=self.evidence)
        if self.ambiguous_with:
            d["ambiguous_with"] = self.ambiguous_with
        if self.parameters:
            d["parameters"] = self.parameters
        return d


@dataclass
class DiagnosisReport:
    """Everything :func:`diagnose` found (JSON: :meth:`to_dict`, HTML: :mod:`.html`)."""

    robot: str
    steps: list[Step]
    findings: list[Finding]
    final_model: str
    final_validation: ErrorStats
    final: CalibrationResult
    periodograms: list[Periodogram]
    plots: dict
    notes: list[str]
    time_s: float

    def to_dict(self) -> dict:
        return {
            "robot": self.robot,
            "steps": [s.to_dict() for s in self.steps],
            "findings": [f.to_dict() for f in self.findings],
            "final": {"model": self.final_model, "validation": _stats(self.final_validation)},
            "notes": self.notes,
            "time_s": self.time_s,
        }

    def text(self) -> str:
        lines = [f"diagnosis of {self.robot} ({self.time_s:.1f} s)", "",
                 f"{'model':<58}{'val mean':>10}{'val max':>10}{'val rms':>10}  accepted"]
        for s in self.steps:
            v = s.validation
            lines.append(f"{s.model[:57]:<58}{v.mean_mm:>10.4f}{v.max_mm:>10.4f}{v.rms_mm:>10.4f}  "
                         f"{'yes' if s.accepted else 'no'}")
        lines += ["", "findings:"]
        if not self.findings:
            lines.append("  none beyond the nominal model")
        for f in self.findings:
            lines.append(f"  {f.candidate.label()}: validation mean -{f.gain_mm:.4f} mm. {f.evidence}")
            for a in f.ambiguous_with:
                lines.append(f"    ambiguous with {a['label']}: {a['tell_apart']}")
        v = self.final_validation
        lines += ["", f"final model {self.final_model}: validation mean {v.mean_mm:.4f}, "
                      f"max {v.max_mm:.4f}, rms {v.rms_mm:.4f} mm"]
        lines += [f"note: {n}" for n in self.notes]
        return "\n".join(lines)


def _stats(s: ErrorStats) -> dict:
    return {"mean_mm": s.mean_mm, "max_mm": s.max_mm, "std_mm": s.std_mm, "rms_mm": s.rms_mm}


def _finite(x: float) -> float | None:
    return float(x) if math.isfinite(x) else None


# --- the procedure --------------------------------------------------------------------


class _Diagnosis:
    def __init__(self, robot: Robot, cal: Measurements, val: Measurements, settings: DiagnosisSettings,
                 progress: Callable[[str], None]):
        self.robot, self.cal, self.val, self.s = robot, cal, val, settings
        self.say = progress
        self.n_eq = 3 * len(cal)
        self.steps: list[Step] = []
        self.findings: list[Finding] = []
        self.notes: list[str] = []
        self.periodograms: list[Periodogram] = []

    def fit(self, spec: str, start: CalibrationResult | None = None, data: Measurements | None = None
            ) -> CalibrationResult:
        st = None
        if start is not None:
            st = {p.name: p.value for p in start.parameters if not p.name.startswith("base_")}
        return calibrate(self.robot, data or self.cal, spec, "lm", start=st, warn=False)

    @staticmethod
    def n_free(res: CalibrationResult) -> int:
        return int(res.parameters.free.sum())

    def cv_rms(self, spec: str, start: CalibrationResult) -> float:
        """k-fold cross-validated RMS error (mm) on the calibration poses."""
        n = len(self.cal)
        idx = np.random.default_rng(self.s.seed).permutation(n)
        errs = []
        for k in range(self.s.folds):
            test = np.sort(idx[k::self.s.folds])
            train = np.setdiff1d(np.arange(n), test)
            try:
                r = self.fit(spec, start, self.cal.subset(train))
            except InputError:
                return math.inf
            errs.append(r.errors(self.cal.subset(test)))
        e = np.concatenate(errs) * 1000
        return float(np.sqrt(np.mean(e ** 2)))

    # -- steps ---------------------------------------------------------------

    def run(self) -> tuple[CalibrationResult, str]:
        self.say("step 1: nominal model (base pose only)")
        nominal = self.nominal = self.fit("nominal")
        self.steps.append(Step("nominal", nominal.calibration, nominal.stats(self.val), True))
        self.say(f"  validation mean {self.steps[-1].validation.mean_mm:.4f} mm")
        self.say("step 2: geometric (kinematic) calibration")
        kin = self.fit("kinematic")
        test = nested_test(2 * nominal.solver.cost, self.n_free(nominal), 2 * kin.solver.cost,
                           self.n_free(kin), self.n_eq)
        kv = kin.stats(self.val)
        gain = self.steps[0].validation.mean_mm - kv.mean_mm
        ok = test.log10_p < math.log10(self.s.alpha) and gain > self.s.min_gain * self.steps[0].validation.mean_mm
        self.steps.append(Step("kinematic", kin.calibration, kv, ok, Candidate("geometric"), test))
        self.say(f"  validation mean {kv.mean_mm:.4f} mm ({test.text()})")
        if ok:
            self.findings.append(Finding(Candidate("geometric"), gain,
                                         f"{test.text()} on the calibration poses; link, base and tool "
                                         f"parameters move the validation mean from "
                                         f"{self.steps[0].validation.mean_mm:.4f} to {kv.mean_mm:.4f} mm"))
            current, geometric = kin, True
        else:
            current, geometric = nominal, False
        accepted: list[Candidate] = []
        for rnd in range(self.s.max_rounds):
            self.say(f"round {rnd + 1}: screening candidate causes")
            new = self.round(current, accepted, geometric)
            if new is None:
                break
            current, cand = new
            accepted.append(cand)
        else:
            self.notes.append(f"stopped after {self.s.max_rounds} accepted extensions (max_rounds): further "
                              "causes may still be significant; raise the limit to look for them")
        return current, compose_spec(accepted, geometric)

    def candidates(self, current: CalibrationResult, accepted: list[Candidate]) -> list[Candidate]:
        """Every candidate not yet in the model; periodic ones from the periodogram peaks."""
        have = set(accepted)
        n = self.robot.n
        out: list[Candidate] = []
        for j in range(1, n + 1):
            out += [Candidate("joint_compliance", j), Candidate("encoder_scale", j),
                    Candidate("backlash", j, source="torque"), Candidate("backlash", j, source="motion")]
        temp = self.cal.get("temperature_c")
        if temp is not None and np.ptp(temp) > 0.1:
            out.append(Candidate("thermal_expansion"))
        out.append(Candidate("drift"))  # time_s, or the row order
        # periodograms of the projected residuals
        model, p = current.model, current.parameters
        _, J = model.predict_jacobian(self.cal.q, p.values, model.covariates(self.cal), current.base0)
        resid = current.residuals(self.cal)
        H = min(self.s.max_harmonic, max(len(self.cal) // 3, 1))
        self.periodograms = []
        for j in range(1, n + 1):
            s, w = joint_errors(resid, J[:, :, p.index(f"theta{j}")])
            pg = periodogram(self.cal.q[:, j - 1], s, w, j, H)
            self.periodograms.append(pg)
            # the first harmonic always: over a small range it mimics an encoder scale error,
            # and the ambiguity can only be reported if both are screened
            out += [Candidate("joint_periodic", j, h) for h in sorted(set(pg.peaks(2)) | {1})]
        return [c for c in out if c not in have and not (c.cause == "backlash" and any(
            a.cause == "backlash" and a.joint == c.joint for a in accepted))]

    def screen(self, current: CalibrationResult, accepted: list[Candidate], cands: list[Candidate],
               geometric: bool):
        """Score test of every candidate: linearised SSR drop at the current fit."""
        big = Model(self.robot, compose_spec(accepted + cands, geometric))
        params = big.parameters.copy()
        for p in params:
            if p.name in current.parameters:
                src = current.parameters[p.name]
                p.value, p.fixed = src.value, src.fixed
            else:
                p.fixed = False
        prob = CalibrationProblem(big, params, self.cal.q, self.cal.xyz, big.covariates(self.cal), current.base0)
        r, Jx = prob.residuals_jacobian(params.values)
        free_names = [params.names[i] for i in prob.free]
        cur = [k for k, n in enumerate(free_names) if n in current.parameters and not current.parameters[n].fixed]
        Qc, _ = np.linalg.qr(Jx[:, cur])
        r_perp = r - Qc @ (Qc.T @ r)
        ssr0 = float(r_perp @ r_perp)
        p0 = len(cur)
        scored = []
        for c in cands:
            cols = [free_names.index(n) for n in c.parameter_names() if n in free_names]
            if not cols:
                continue
            Jk = Jx[:, cols]
            Jk = Jk - Qc @ (Qc.T @ Jk)
            U, sv, _ = np.linalg.svd(Jk, full_matrices=False)
            keep = sv > 1e-6 * max(np.linalg.norm(Jx[:, cols]), 1e-300)
            if not keep.any():
                continue
            proj = U[:, keep].T @ r_perp
            drop = float(proj @ proj)
            test = nested_test(ssr0, p0, ssr0 - drop, p0 + int(keep.sum()), self.n_eq)
            scored.append((test.log10_p, c, test, U[:, keep] @ proj))
        scored.sort(key=lambda t: t[0])
        return scored

    def n_tests(self, cands: list[Candidate]) -> int:
        """Tests behind a round's candidates: each periodic candidate stands for the scanned harmonics."""
        per = sum(1 for c in cands if c.cause == "joint_periodic")
        H = min(self.s.max_harmonic, max(len(self.cal) // 3, 1))
        return (len(cands) - per) + self.robot.n * H

    def round(self, current: CalibrationResult, accepted: list[Candidate], geometric: bool):
        cands = self.candidates(current, accepted)
        scored = self.screen(current, accepted, cands, geometric)
        level = math.log10(self.s.alpha / max(self.n_tests(cands), 1))
        if not scored or scored[0][0] >= level:
            best = scored[0] if scored else None
            self.say("  no candidate passes the score test" +
                     (f" (best: {best[1].label()}, {best[2].text()})" if best else ""))
            return None
        cur_val = self._last_accepted().validation
        ssr0, p0 = 2 * current.solver.cost, self.n_free(current)
        cv0 = None
        for log10p, cand, score, fitted in scored[: self.s.confirm]:
            if log10p >= level:
                break
            spec = compose_spec(accepted + [cand], geometric)
            self.say(f"  fitting {cand.label()} (score {score.text()})")
            res = self.fit(spec, current)
            test = nested_test(ssr0, p0, 2 * res.solver.cost, self.n_free(res), self.n_eq)
            vstats = res.stats(self.val)
            gain = cur_val.mean_mm - vstats.mean_mm
            reasons = []
            if test.log10_p >= level:
                reasons.append(f"F-test not significant at the corrected level ({test.text()})")
            if test.delta_bic >= 0:
                reasons.append(f"BIC does not improve ({test.delta_bic:+.1f})")
            if gain <= self.s.min_gain * cur_val.mean_mm:
                reasons.append(f"no real validation gain ({gain:+.4f} mm)")
            cv1 = None
            if not reasons:
                cv0 = self.cv_rms(compose_spec(accepted, geometric), current) if cv0 is None else cv0
                cv1 = self.cv_rms(spec, res)
                if cv1 >= cv0:
                    reasons.append(f"cross-validation does not improve ({cv0:.4f} -> {cv1:.4f} mm rms)")
            step = Step(spec, res.calibration, vstats, not reasons, cand, test, cv1, "; ".join(reasons))
            self.steps.append(step)
            if reasons:
                self.say(f"    rejected: {step.reason}")
                continue
            self.say(f"    accepted: validation mean {cur_val.mean_mm:.4f} -> {vstats.mean_mm:.4f} mm")
            self.findings.append(self.finding(cand, gain, test, cv0, cv1, res, scored, fitted, level,
                                              current))
            return res, cand
        return None

    def _last_accepted(self) -> Step:
        return next(s for s in reversed(self.steps) if s.accepted)

    def residual_plot(self, cand: Candidate, before: CalibrationResult, after: CalibrationResult) -> dict:
        """The residual against the variable the cause depends on.

        Joint causes: partial residual (residual after the fit plus the fitted
        effect, as joint j's angle error) with the fitted effect as a curve.
        Thermal expansion and drift: the residual before and after.
        """
        d = self.cal
        if cand.cause in ("thermal_expansion", "drift"):
            if cand.cause == "thermal_expansion":
                x, xlabel = d.get("temperature_c"), "temperature (deg C)"
                ys = [np.linalg.norm(r.residuals(d), axis=1) * 1000 for r in (before, after)]
                ylabel = "position error (mm)"
            else:
                t = d.get("time_s")
                x, xlabel = (t, "time (s)") if t is not None else (d.rows, "row (measurement order)")
                v = np.array([after.parameters[n].value for n in cand.parameter_names()])
                u = v / max(np.linalg.norm(v), 1e-300)
                ys = [r.residuals(d) @ u * 1000 for r in (before, after)]
                ylabel = "residual along the drift (mm)"
            return {"x": np.asarray(x, float).tolist(), "before": ys[0].tolist(), "after": ys[1].tolist(),
                    "xlabel": xlabel, "ylabel": ylabel}
        j, m, p = cand.joint, after.model, after.parameters
        cov = m.covariates(d)
        _, J = m.predict_jacobian(d.q, p.values, cov, after.base0)
        s, _ = joint_errors(after.residuals(d), J[:, :, p.index(f"theta{j}")])
        q = d.q[:, j - 1]
        value = p[cand.parameter_names()[0]].value
        if cand.cause == "joint_periodic":
            sn, cs = (p[n].value for n in cand.parameter_names())
            effect = sn * np.sin(cand.harmonic * q) + cs * np.cos(cand.harmonic * q)
            # folded by the harmonic, h cycles per turn line up into one sinusoid
            x = np.degrees(cand.harmonic * q) % 360.0
            xlabel = f"phase of {cand.harmonic} cycles per turn of joint {j} (deg)"
        elif cand.cause == "encoder_scale":
            effect, x, xlabel = value * q, np.degrees(q), f"joint {j} reading (deg)"
        elif cand.cause == "backlash" and cand.source == "motion":
            x = d.moves[:, j - 1]
            effect, xlabel = value * x, f"direction of the last move of joint {j}"
        else:
            x = m.torques(d.q, p.values, cov)[:, j - 1]
            xlabel = f"gravity torque at joint {j} (N m)"
            effect = value * (x if cand.cause == "joint_compliance" else np.sign(x))
        arcsec = np.degrees(1.0) * 3600
        order = np.argsort(x)
        return {"x": np.asarray(x, float).tolist(), "partial": ((s + effect) * arcsec).tolist(),
                "curve_x": np.asarray(x, float)[order].tolist(), "curve_y": (effect[order] * arcsec).tolist(),
                "xlabel": xlabel, "ylabel": f"joint {j} angle error: residual + fitted effect (arcsec)"}

    def finding(self, cand, gain, test, cv0, cv1, res, scored, fitted, level, current_fit) -> Finding:
        params = {}
        for name in cand.parameter_names():
            p = res.parameters[name]
            params[name] = {"value": p.to_display(p.value), "std": p.to_display(p.std)
                            if math.isfinite(p.std) else None, "unit": p.display_unit}
        what = ""
        if cand.cause == "joint_compliance":
            k, sk = res.stiffness().get(cand.joint, (math.inf, math.nan))
            what = f"; stiffness k{cand.joint} = {k:.4g} N m/rad (std {sk:.2g})"
            if self.cal.get("payload_kg") is not None and np.ptp(self.cal.get("payload_kg")) > 0:
                what += "; the rows' payloads vary and enter the torques"
        elif cand.cause == "joint_periodic":
            s_, c_ = (res.parameters[n].value for n in cand.parameter_names())
            what = (f"; amplitude {math.degrees(math.hypot(s_, c_)) * 3600:.2f} arcsec, phase "
                    f"{math.degrees(math.atan2(c_, s_)):.1f} deg, {cand.harmonic} cycles per turn of joint "
                    f"{cand.joint}")
        elif cand.cause == "encoder_scale":
            what = f"; scale error {res.parameters[f'escale{cand.joint}'].value * 1e6:.1f} ppm"
        elif cand.cause == "backlash":
            what = (f"; half play {math.degrees(res.parameters[cand.parameter_names()[0]].value) * 3600:.2f} "
                    f"arcsec, sign from the {'gravity torque' if cand.source != 'motion' else 'last move'}")
        elif cand.cause == "thermal_expansion":
            what = f"; expansion {res.parameters['thermal_alpha'].value * 1e6:.2f} ppm/K"
        elif cand.cause == "drift":
            v = np.array([res.parameters[n].value for n in cand.parameter_names()]) * 1e6
            unit = "s" if self.cal.get("time_s") is not None else "row"
            what = f"; the measured points move {np.linalg.norm(v):.3g} um per {unit} (x, y, z: " + \
                   ", ".join(f"{c:+.3g}" for c in v) + ")"
        evidence = (f"{test.text()} on the calibration poses; {self.s.folds}-fold cross-validated rms "
                    f"{cv0:.4f} -> {cv1:.4f} mm{what}")
        # candidates whose screening fit explains the same residual are ambiguous with this one
        amb = []
        best_drop = float(fitted @ fitted)
        for log10p, other, score, f_other in scored:
            if other == cand or log10p >= level or other.cause == cand.cause and other.joint == cand.joint \
                    and other.cause != "joint_periodic":
                continue
            drop = float(f_other @ f_other)
            cos = float(f_other @ fitted) / math.sqrt(max(drop * best_drop, 1e-300))
            if drop > 0.7 * best_drop and cos > 0.9:
                amb.append({**other.to_dict(), "label": other.label(), "similarity": round(cos, 4),
                            "tell_apart": tell_apart(cand, other)})
        return Finding(cand, gain, evidence, amb, params, self.residual_plot(cand, current_fit, res))

    def blackbox(self, current: CalibrationResult, spec: str):
        """What a smooth black-box compensator still removes from the residuals."""
        from ..compensators import RBFNetwork

        def features(d: Measurements) -> np.ndarray:
            tau = current.model.torques(d.q, current.parameters.values, current.model.covariates(d))
            return np.column_stack([np.sin(d.q), np.cos(d.q), tau])

        n = len(self.cal)
        if n < 20:
            return None
        X, Y = features(self.cal), current.residuals(self.cal)
        # cross-validated on the calibration poses first
        idx = np.random.default_rng(self.s.seed).permutation(n)
        before, after = [], []
        for k in range(self.s.folds):
            test = np.sort(idx[k::self.s.folds])
            train = np.setdiff1d(np.arange(n), test)
            net = RBFNetwork(n_centers="cv", seed=self.s.seed).fit(X[train], Y[train])
            before.append(np.linalg.norm(Y[test], axis=1))
            after.append(np.linalg.norm(Y[test] - net.predict(X[test]), axis=1))
        cv_b = float(np.sqrt(np.mean(np.concatenate(before) ** 2)) * 1000)
        cv_a = float(np.sqrt(np.mean(np.concatenate(after) ** 2)) * 1000)
        net = RBFNetwork(n_centers="cv", seed=self.s.seed).fit(X, Y)
        Rv = current.residuals(self.val)
        e0 = np.linalg.norm(Rv, axis=1)
        e1 = np.linalg.norm(Rv - net.predict(features(self.val)), axis=1)
        s0, s1 = ErrorStats.of(e0), ErrorStats.of(e1)
        p = paired_gain(e0, e1)
        gain = s0.mean_mm - s1.mean_mm
        ok = cv_a < cv_b and p < self.s.alpha and gain > 5 * self.s.min_gain * s0.mean_mm
        fit_cal = ErrorStats.of(np.linalg.norm(Y - net.predict(X), axis=1))
        model = spec + "+rbf_compensator"
        step = Step(model, fit_cal, s1, ok, Candidate("unexplained"), None, cv_a,
                    "" if ok else f"not supported (cv rms {cv_b:.4f} -> {cv_a:.4f} mm, validation "
                                  f"{gain:+.4f} mm, Wilcoxon p = {p:.2g})")
        self.steps.append(step)
        self.say(f"black-box compensator on the remaining residual: validation mean {s0.mean_mm:.4f} -> "
                 f"{s1.mean_mm:.4f} mm ({'accepted' if ok else 'rejected'})")
        if ok:
            self.findings.append(Finding(
                Candidate("unexplained"), gain,
                f"an RBF network on joint angles and gravity torques removes {100 * gain / s0.mean_mm:.0f}% "
                f"of the remaining validation mean error (cross-validated rms {cv_b:.4f} -> {cv_a:.4f} mm, "
                f"Wilcoxon p = {p:.2g}); no named cause explains this structure"))
            return model, s1, e1
        return None


def diagnose(robot: Robot, cal: Measurements, val: Measurements, settings: DiagnosisSettings | None = None,
             progress: Callable[[str], None] | None = None, **checks: bool) -> DiagnosisReport:
    """Calibrate step by step on ``cal``, judge every step on ``val``, name the causes.

    Parameters
    ----------
    robot : Robot
    cal, val : Measurements
        Calibration and validation poses, both with measured positions.
    settings : DiagnosisSettings, optional
    progress : callable, optional
        Receives one line of text per step (the command line prints them).
    **checks : bool
        Overrides of the plausibility checks of the poses
        (:func:`casadical.checks.check_poses`: ``allow_outside_limits``,
        ``angles_are_degrees``, ``positions_are_mm``).
    """
    t0 = time.perf_counter()
    s = settings or DiagnosisSettings()
    for d in (cal, val):
        if d.n_joints != robot.n:
            raise InputError(f"has {d.n_joints} joint columns but robot {robot.name} has {robot.n} joints",
                             file=d.path)
        check_poses(d, robot, **checks)
    dg = _Diagnosis(robot, cal, val, s, progress or (lambda _: None))
    current, spec = dg.run()
    final_spec, final_val = spec, current.stats(val)
    e_final = current.errors(val)
    if s.blackbox:
        bb = dg.blackbox(current, spec)
        if bb is not None:
            final_spec, final_val, e_final = bb
    if final_val.mean_mm > 0 and current.uncertainty is not None:
        sigma = current.uncertainty.sigma * 1000
        dg.notes.append(f"remaining calibration residual {sigma:.4f} mm per axis (rms); validation rms "
                        f"{final_val.rms_mm / math.sqrt(3):.4f} mm per axis")
    plots = {
        "val_errors_nominal_mm": (dg.nominal.errors(val) * 1000).tolist(),
        "val_errors_final_mm": (np.asarray(e_final) * 1000).tolist(),
    }
    return DiagnosisReport(robot.name, dg.steps, dg.findings, final_spec, final_val, current,
                           dg.periodograms, plots, dg.notes, time.perf_counter() - t0)
