"""The diagnosis's last step: the accuracy layer, judged like every step.

After the named causes, what remains is learnt by a session compensator
(:mod:`casadical.accuracy`: a Gaussian process of the joint readings per
session, applied where it knows). It is kept only when, on the calibration
poses' folds (its hyperparameters from all poses, the process conditioned
on each fold's training poses), it lowers the held-out error significantly
where the model interpolates (random folds; paired, one-sided, at the
diagnosis's level) and does not raise it where it must extrapolate (time
blocks, joint-range blocks, each session left out): there it should know
that it does not know, and add nothing. What it then removes is structure
no named cause explains, of the session it was measured in: an
``unexplained`` finding with ``scope: "session"``, in the final model,
never carried to another session or into an export.
"""

from __future__ import annotations

from typing import Callable

import numpy as np

from ..accuracy import fit_layer, held_out, layer_coverage, layer_data, with_layer
from ..data import Measurements
from ..result import CalibrationResult
from .candidates import Candidate
from .report import Finding, Step
from .statistics import paired_gain
from .validation import KINDS

#: fewer poses than this (in a session) give no layer
MIN_POSES = 20


def layer_step(current: CalibrationResult, spec: str, cal: Measurements, val: Measurements, all_schemes,
               settings, steps: list[Step], findings: list[Finding], progress: Callable[[str], None],
               parent: int | None = None) -> tuple[CalibrationResult, str]:
    """Fit and judge the accuracy layer on ``current`` (model ``spec``, the model of step ``parent``, None when
    no step holds it); record it in ``steps`` (and ``findings`` when kept); returns the final model and its
    specification."""
    X, Y, keep = layer_data(current, cal)
    v0 = current.stats(val)
    link = {"parent": parent, "parent_mm": v0.mean_mm}     # its gain: against the model it extends
    name = spec + "+gp_compensator"
    few = [s for s, n in _per_session(cal, keep).items() if n < MIN_POSES]
    if few:
        reason = f"too few poses for a session compensator ({', '.join(s or 'the data' for s in few)})"
        steps.append(Step(name, current.calibration, v0, False, Candidate("unexplained"), reason=reason,
                          **link))
        progress(f"accuracy layer not tried: {reason}")
        return current, spec
    progress("accuracy layer: a Gaussian process of what remains, per session")
    gps, learnt = fit_layer(current, cal, seed=settings.seed, progress=progress)
    cv = held_out(gps, learnt, cal, Y, keep, all_schemes, progress=progress)
    cv_mm = {}
    for kind in (k for k in KINDS if k in cv):
        cv_mm[f"{kind}_before"], cv_mm[kind] = (float(np.mean(x) * 1000) for x in cv[kind])
    reasons = []
    p = paired_gain(*cv["random"])
    if not p < settings.alpha:
        reasons.append(f"it does not lower the held-out error significantly where it interpolates (random "
                       f"{cv_mm['random_before']:.4f} -> {cv_mm['random']:.4f} mm, p = {p:.2g})")
    worse = [k for k in ("time", "joint", "session") if k in cv and cv_mm[k] > cv_mm[f"{k}_before"]]
    if worse:
        reasons.append("it raises the held-out error where it must extrapolate: "
                       + ", ".join(f"{k} {cv_mm[k + '_before']:.4f} -> {cv_mm[k]:.4f} mm" for k in worse))
    if reasons:
        reason = "; ".join(reasons)
        steps.append(Step(name, current.calibration, v0, False, Candidate("unexplained"), cv_mm=cv_mm,
                          reason=reason, **link))
        progress(f"accuracy layer rejected: {reason}")
        return current, spec
    progress("  the final model with the session compensator, on the validation poses")
    final = with_layer(current, gps, cal, "gp_compensator: the session compensator of the accuracy layer")
    v1 = final.stats(val)
    known, total = layer_coverage(final, val)
    steps.append(Step(name, final.calibration, v1, True, Candidate("unexplained"), cv_mm=cv_mm, **link))
    scales = {s or "": np.degrees(g.length_scales).round(1).tolist() for s, g in gps.items()}
    findings.append(Finding(
        Candidate("unexplained"), v0.mean_mm - v1.mean_mm,
        "a Gaussian process of the joint readings removes structure no named cause explains: held-out mean "
        + ", ".join(f"{k} {cv_mm[k + '_before']:.4f} -> {cv_mm[k]:.4f} mm" for k in KINDS if k in cv)
        + f" (random: p = {p:.2g}); it applies where it knows the residual, at {known} of the {total} "
          "validation poses here; it belongs to the session it was learnt in",
        where="session compensator (gp_compensator): a Gaussian process of the residual",
        holds_up={"cv_mm": cv_mm, "length_scales_deg": scales, "validation_known": [known, total]},
        scope="session"))
    progress(f"accuracy layer kept: validation mean {v0.mean_mm:.4f} -> {v1.mean_mm:.4f} mm "
             f"(applied at {known} of {total} validation poses)")
    return final, name


def _per_session(data: Measurements, keep: np.ndarray) -> dict[str, int]:
    if data.sessions is None:
        return {"": int(keep.sum())}
    return {s: int(keep[data.sessions == s].sum()) for s in data.session_names}

