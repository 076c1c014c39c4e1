"""Findings in words: the final model's values, the evidence, and the structure that cannot be named."""

from __future__ import annotations

import functools
import math

from ..data._measurements import Measurements
from ..result import CalibrationResult
from ..terms import UNEXPLAINED
from ..terms._cause import session_parts
from ._candidates import Candidate
from ._evidence import Evidence, Support
from ._plots import joint_view, residual_plot
from ._report import Finding
from ._validation import cv_record, cv_text


class UnexplainedLog:
    """Significant structure of a joint's angle error that cannot be named as a cause.

    It is kept out of the model and reported as one ``unexplained`` finding
    per joint (where it lives, its size, why it cannot be named, what it
    would give on this series), and per joint and session for structure
    that holds in one session only (what differs between the sessions,
    showing on the joint). Its harmonics (or the candidate, the robot's
    too) are not screened again.
    """

    def __init__(self) -> None:
        self.by_joint: dict[tuple, Finding] = {}          # by (joint, session or None)
        self.linear: set[int] = set()                      # the robot's linear axes (their causes in mm)
        self.excluded: set[tuple] = set()                  # periodic (joint, harmonic, session or None)
        self.excluded_causes: set[Candidate] = set()       # other candidates
        self.strongest: dict[tuple, Candidate] = {}        # per (joint, session), for the transfer study

    def add(self, evidence: Evidence) -> None:
        cand, values, checks = evidence.candidate, evidence.values, evidence.support.checks
        j = cand.joint
        if cand.harmonic is not None:       # a periodic error: its neighbours' band is not screened again
            band = checks["resolution"].band if "resolution" in checks else (cand.harmonic, cand.harmonic)
            self.excluded.update((j, h, s) for h in range(band[0], band[1] + 1) for s in {cand.session, None})
        else:
            self.excluded_causes.update({cand, cand.shared()})
        item = cand.kind.unexplained_item(cand, values, j in self.linear)     # a linear axis' in metres
        if cand.harmonic is not None:
            item = {"harmonic": cand.harmonic, "band": list(band), **item}
        key = (j, cand.session)
        f = self.by_joint.get(key)
        if f is None:
            f = self.by_joint[key] = Finding(Candidate(UNEXPLAINED.name, j, session=cand.session), 0.0, "",
                                             in_model=False, potential_gain_mm=0.0, holds_up={"structures": []})
            self.strongest[key] = cand
        # what was fitted, machine-readable (plan-poses REPORT.json plans the poses that tell it)
        item.update(candidate=cand.to_dict(), values={n: values[n] for n in cand.parameter_names() if n in values},
                    test=evidence.support.test.text(),
                    cv_mm=cv_record(evidence.support.cv_before, evidence.support.cv_after), why=evidence.why)
        if "halves" in checks:
            item["halves"] = [h.to_dict() for h in checks["halves"]]
        structures = f.holds_up["structures"]
        structures.append(item)
        f.potential_gain_mm = max(f.potential_gain_mm or 0.0, evidence.potential_gain_mm)
        f.where = f"joint {j}: " + "; ".join(x["what"] for x in structures)
        own = ""
        if cand.session is not None:
            f.where = f"joint {j}, in session {cand.session} only: " + "; ".join(x["what"] for x in structures)
            own = (f"; it holds in session {cand.session} only: a joint's own parameter is the robot's, so what "
                   f"differs between the sessions ({', '.join(session_parts())}, or a load or a temperature the data "
                   f"do not give) shows on joint {j}")
        f.evidence = (f"structure in joint {j}'s angle error that is significant on the calibration poses but "
                      "cannot be named as a cause: " + " | ".join(f"{x['what']}: {x['why']}" for x in structures)
                      + own + f". Alone it would lower this series' validation mean by up to "
                      f"{f.potential_gain_mm:.4f} mm; it is kept out of the final model because it does not hold up "
                      "as a cause")


def describe(findings: list[Finding], support: dict[Candidate, Support], before: dict,
             final: CalibrationResult, cal: Measurements) -> None:
    """Fill each accepted finding's parameters, evidence and figure from the final model."""
    view = functools.cache(lambda: joint_view(final, cal))   # made once, by the first figure that needs it
    for f in findings:
        cand = f.candidate
        if cand not in support:
            continue
        checks = support[cand].checks
        f.parameters = param_values(final, cand.parameter_names())
        text = (f"{support[cand].test.text()} on the calibration poses; held-out mean "
                f"{cv_text(support[cand].cv_before, support[cand].cv_after)}")
        for k in ("resolution", "versus_drift", "versus_harmonics"):
            if k in checks:
                text += "; " + checks[k].text()
        if "halves" in checks:
            text += "; " + "; ".join(h.text() for h in checks["halves"])
        size = what(cand, final, cal)
        f.evidence = text + (("; " + size) if size else "")
        f.plot = residual_plot(cand, before.get(cand, final), final, cal, view)


def param_values(res: CalibrationResult, names: list[str]) -> dict:
    out = {}
    for name in names:
        p = res.parameters[name]
        out[name] = {"value": p.to_display(p.value),
                     "std": p.to_display(p.std) if math.isfinite(p.std) else None, "unit": p.display_unit}
    return out


def what(cand: Candidate, res: CalibrationResult, cal: Measurements) -> str:
    """The cause's size in words, from the model's values (a cause of one session: its own, ``c2@A``; its cause's
    words, :meth:`~casadical.terms._cause.Cause.words`)."""
    P = res.parameters
    linear = cand.joint is not None and res.model.robot.joints[cand.joint - 1].prismatic
    return cand.kind.words(cand, [P[n] for n in cand.parameter_names()], res.model.robot, cal, linear)
