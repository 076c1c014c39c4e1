"""What a smooth black box still removes, judged on folds that must extrapolate.

An RBF network on joint angles and gravity torques (the ``rbf_compensator``
term) is fitted to the residual the named causes leave, in the robot base
frame. Its size and width are chosen by random cross-validation on the
calibration poses; it is kept only if it lowers the held-out error
significantly (paired, one-sided) on random folds and also where it must
extrapolate (time blocks, joint-range blocks). What it then
removes is structure no named cause explains: the ``unexplained`` finding.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

from ..calibration import compensator_data, rbf_candidates, with_compensator
from ..compensators.guard import fit_guarded
from ..data import Measurements
from ..result import CalibrationResult
from .candidates import Candidate
from .report import Finding, Step
from .statistics import paired_gain
from .validation import KINDS, Scheme


@dataclass
class BlackBox:
    """Outcome of the black-box step.

    Attributes
    ----------
    accepted : bool
    result : CalibrationResult or None
        The model with the compensator (if accepted).
    cv_mm : dict
        Held-out mean of the residual (mm) without and with the network, by kind of fold.
    reason : str
    """

    accepted: bool
    result: CalibrationResult | None
    cv_mm: dict
    reason: str


def blackbox(current: CalibrationResult, data: Measurements, all_schemes: list[Scheme], seed: int,
             alpha: float) -> BlackBox:
    X, Y, keep = compensator_data(current, data)
    if keep.sum() < 20:
        return BlackBox(False, None, {}, "too few poses for a black box")
    cands = rbf_candidates(int(keep.sum()), seed)
    net, info = fit_guarded(cands, X[keep], Y[keep], seed=seed)
    if net is None:
        return BlackBox(False, None, {}, info["reason"])
    factory = cands[info["chosen"]]
    idx = np.flatnonzero(keep)
    cv: dict = {}
    worse = []
    for kind in [k for k in KINDS if any(x.kind == k for x in all_schemes)]:
        group = [x for x in all_schemes if x.kind == kind]
        before, after = np.zeros(len(X)), np.zeros(len(X))
        for s in group:
            for F in s.folds:
                test = np.intersect1d(F, idx)
                train = np.setdiff1d(idx, F)
                if len(test) == 0:
                    continue
                if len(train) < 20:
                    after[test] += np.linalg.norm(Y[test], axis=1)
                else:
                    comp = factory().fit(X[train], Y[train])
                    after[test] += np.linalg.norm(Y[test] - comp.predict(X[test]), axis=1)
                before[test] += np.linalg.norm(Y[test], axis=1)
        before, after = before[idx] / len(group), after[idx] / len(group)
        cv[f"{kind}_before"] = float(np.mean(before) * 1000)
        cv[kind] = float(np.mean(after) * 1000)
        if paired_gain(before, after) >= alpha:
            worse.append(kind)
    if worse:
        return BlackBox(False, None, cv, "it does not hold up where it must extrapolate: held-out mean "
                        + ", ".join(f"{k} {cv[k + '_before']:.4f} -> {cv[k]:.4f} mm" for k in worse)
                        + " (no significant drop)")
    res = with_compensator(current, net, data, f"rbf_compensator: {net.n_centers_} Gaussian units "
                                               f"({info['reason']})")
    return BlackBox(True, res, cv, "")


def blackbox_step(current: CalibrationResult, spec: str, cal: Measurements, val: Measurements,
                  all_schemes: list[Scheme], settings, steps: list[Step], findings: list[Finding],
                  progress: Callable[[str], None]) -> tuple[CalibrationResult, str]:
    """The diagnosis's last step: try :func:`blackbox` on ``current`` (model ``spec``), record it in ``steps``
    (and ``findings`` when accepted); returns the final model and its spec."""
    bb = blackbox(current, cal, all_schemes, settings.seed, settings.alpha)
    v0 = current.stats(val)
    if not bb.accepted:
        steps.append(Step(spec + "+rbf_compensator", current.calibration, v0, False,
                          Candidate("unexplained"), cv_mm=bb.cv_mm, reason=bb.reason))
        progress(f"black-box compensator rejected: {bb.reason}")
        return current, spec
    final, spec = bb.result, spec + "+rbf_compensator"
    v1 = final.stats(val)
    steps.append(Step(spec, final.calibration, v1, True, Candidate("unexplained"), cv_mm=bb.cv_mm))
    findings.append(Finding(
        Candidate("unexplained"), v0.mean_mm - v1.mean_mm,
        "an RBF network on joint angles and gravity torques removes structure no named cause explains: "
        "held-out mean " + ", ".join(f"{k} {bb.cv_mm[k + '_before']:.4f} -> {bb.cv_mm[k]:.4f} mm"
                                     for k in KINDS if k in bb.cv_mm), where="black-box compensator (rbf_compensator)",
        holds_up={"cv_mm": bb.cv_mm}))
    progress(f"black-box compensator accepted: validation mean {v0.mean_mm:.4f} -> {v1.mean_mm:.4f} mm")
    return final, spec
