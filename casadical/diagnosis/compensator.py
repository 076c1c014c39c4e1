"""The diagnosis's last step: the GP compensator, judged like every step.

After the named causes, what remains is learnt by the GP compensator, one
per session (:mod:`casadical.compensators.per_session`: a Gaussian process
of the joint readings, applied where it knows). It is judged on the
calibration poses' folds (its hyperparameters from all poses, the process
conditioned on each fold's training poses): it must lower the held-out error significantly where
the model interpolates (random folds; paired, one-sided, at the diagnosis's
level), not raise it where it must extrapolate (time blocks, joint-range
blocks, each session left out: there it should know that it does not know,
and add nothing), and not raise the worst held-out error of any kind of fold
by more than :data:`~casadical.diagnosis.never_worse.WORST_SHARE`. Its
support (where it applies: the share of its prior's std below which it
knows, :data:`SUPPORTS`) is chosen on the same folds: the one with the
lowest random-fold mean among those that pass, the level of the test
divided among the supports tried (Bonferroni). What it then removes is
structure no named cause explains, of the session it was measured in: an
``unexplained`` finding with ``scope: "session"``, in the final model,
never carried to another session or into an export.
"""

from __future__ import annotations

from typing import Callable

import numpy as np

from ..compensators.gp import MAX_STD_RATIO
from ..compensators.per_session import (
    GPCompensatorFolds,
    fit_gp_compensator,
    gp_compensator_coverage,
    gp_compensator_data,
    gp_compensator_held_out,
    with_gp_compensator,
)
from ..data.measurements import Measurements
from ..result import CalibrationResult
from .candidates import Candidate, compose_spec
from .never_worse import WORST_SHARE
from .report import Finding, Step
from .state import DiagnosisRun
from .statistics import paired_gain
from .validation import EXTRAPOLATING, KINDS

#: fewer poses than this (in a session) give no GP compensator
MIN_POSES = 20
#: the supports tried: the compensator applies where its predictive std is below this share of its prior's (1.0,
#: wherever it has learnt anything, is not among them: on noise alone its folds, whose residuals are those of the
#: fit on every pose, see a gain of 4-9 % that the validation poses do not: YS100 thermal and HH800 tests)
SUPPORTS = (0.8, 0.9, MAX_STD_RATIO)


def judge(folds: GPCompensatorFolds, support: float, alpha: float) -> tuple[list[str], dict, dict, float]:
    """Why the GP compensator with ``support`` fails on the folds (nothing: it passes), its held-out means and worst
    errors by kind (mm, before and after) and the p-value of its gain on the random folds."""
    means, worst = folds.means_mm(support), folds.worst_mm(support)
    p = paired_gain(folds.before, folds.after("random", support))
    reasons = []
    if not p < alpha:
        b, a = means["random"]
        reasons.append(f"it does not lower the held-out error significantly where it interpolates (random "
                       f"{b:.4f} -> {a:.4f} mm, p = {p:.2g})")
    worse = [k for k in EXTRAPOLATING if k in means and means[k][1] > means[k][0]]
    if worse:
        reasons.append("it raises the held-out error where it must extrapolate: "
                       + ", ".join(f"{k} {means[k][0]:.4f} -> {means[k][1]:.4f} mm" for k in worse))
    high = [k for k in KINDS if k in worst and worst[k][1] > worst[k][0] * (1 + WORST_SHARE)]
    if high:
        reasons.append(f"it raises the worst held-out error by more than {WORST_SHARE:.0%}: "
                       + ", ".join(f"{k} {worst[k][0]:.4f} -> {worst[k][1]:.4f} mm" for k in high))
    return reasons, means, worst, p


def compensator_step(current: CalibrationResult, spec: str, cal: Measurements, val: Measurements, all_schemes,
                     settings, steps: list[Step], findings: list[Finding], progress: Callable[[str], None],
                     parent: int | None = None) -> tuple[CalibrationResult, str]:
    """Fit and judge the GP compensator on ``current`` (model ``spec``, the model of step ``parent``, None when
    no step holds it); record it in ``steps`` (and ``findings`` when kept); returns the final model and its
    specification."""
    X, Y, keep = gp_compensator_data(current, cal)
    v0 = current.stats(val)
    link = {"parent": parent, "parent_mm": v0.mean_mm}     # its gain: against the model it extends
    name = spec + "+gp_compensator"
    few = [s for s, n in _per_session(cal, keep).items() if n < MIN_POSES]
    if few:
        reason = f"too few poses for a GP compensator ({', '.join(s or 'the data' for s in few)})"
        steps.append(Step(name, current.calibration, v0, False, Candidate("unexplained"), reason=reason,
                          **link))
        progress(f"GP compensator not tried: {reason}")
        return current, spec
    progress("GP compensator: a Gaussian process of what remains, one per session")
    gps, learnt = fit_gp_compensator(current, cal, seed=settings.seed, progress=progress)
    folds = gp_compensator_held_out(gps, learnt, cal, Y, keep, all_schemes, progress=progress)
    judged = {sup: judge(folds, sup, settings.alpha / len(SUPPORTS)) for sup in SUPPORTS}
    passing = [sup for sup in SUPPORTS if not judged[sup][0]]
    support = min(passing, key=lambda sup: judged[sup][1]["random"][1]) if passing else MAX_STD_RATIO
    reasons, means, worst, p = judged[support]
    cv_mm = {}
    for kind in (k for k in KINDS if k in means):
        cv_mm[f"{kind}_before"], cv_mm[kind] = means[kind]
    if reasons:
        reason = "; ".join(reasons) + f" (at support {support:g}; no support passes)"
        steps.append(Step(name, current.calibration, v0, False, Candidate("unexplained"), cv_mm=cv_mm,
                          reason=reason, **link))
        progress(f"GP compensator rejected: {reason}")
        return current, spec
    for g in gps.values():
        g.max_std_ratio = support
    progress(f"  support chosen on the folds: where its std is below {support:g} of its prior's")
    progress("  the final model with the GP compensator, on the validation poses")
    final = with_gp_compensator(current, gps, cal, "gp_compensator: the GP compensator (one per session)")
    v1 = final.stats(val)
    known, total = gp_compensator_coverage(final, val)
    steps.append(Step(name, final.calibration, v1, True, Candidate("unexplained"), cv_mm=cv_mm, **link))
    scales = {s or "": np.degrees(g.length_scales).round(1).tolist() for s, g in gps.items()}
    findings.append(Finding(
        Candidate("unexplained"), v0.mean_mm - v1.mean_mm,
        "a Gaussian process of the joint readings removes structure no named cause explains: held-out mean "
        + ", ".join(f"{k} {means[k][0]:.4f} -> {means[k][1]:.4f} mm" for k in KINDS if k in means)
        + f" (random: p = {p:.2g}); worst held-out error "
        + ", ".join(f"{k} {worst[k][0]:.4f} -> {worst[k][1]:.4f} mm" for k in KINDS if k in worst)
        + f"; it applies where its std is below {support:g} of its prior's (chosen on the folds), at {known} of "
          f"the {total} validation poses here; it belongs to the session it was learnt in",
        where="GP compensator (gp_compensator): a Gaussian process of the residual",
        holds_up={"cv_mm": cv_mm, "worst_mm": {k: list(v) for k, v in worst.items()}, "support": support,
                  "length_scales_deg": scales, "validation_known": [known, total]},
        scope="session"))
    progress(f"GP compensator kept: validation mean {v0.mean_mm:.4f} -> {v1.mean_mm:.4f} mm "
             f"(applied at {known} of {total} validation poses)")
    return final, name


def _per_session(data: Measurements, keep: np.ndarray) -> dict[str, int]:
    if data.sessions is None:
        return {"": int(keep.sum())}
    return {s: int(keep[data.sessions == s].sum()) for s in data.session_names}


def add_compensator(run: DiagnosisRun) -> None:
    """Stage ``add_compensator``: reads the model of the named causes (``current``, ``accepted``, ``geometric``)
    and sets it as ``parametric``; with ``blackbox`` (the default) fits and judges the GP compensator on it
    (:func:`compensator_step`); sets ``final`` and ``final_spec`` to the model the diagnosis ends with."""
    run.parametric = run.current
    run.final, run.final_spec = run.current, compose_spec(run.accepted, run.geometric)
    if run.s.blackbox:
        run.final, run.final_spec = compensator_step(run.current, run.final_spec, run.cal, run.val, run.schemes,
                                                     run.s, run.steps, run.findings, run.say,
                                                     parent=run.step_of(run.current))
