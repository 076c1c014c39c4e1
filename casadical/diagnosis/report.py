"""What a diagnosis returns: the steps tried, the findings, the final model (JSON and text)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from ..result import AngleStats, CalibrationResult, ErrorStats
from .candidates import Candidate
from .periodogram import Periodogram
from .statistics import NestedTest


def finite(x: float | None) -> float | None:
    return float(x) if x is not None and math.isfinite(x) else None


@dataclass
class Step:
    """One model tried: its fit, its held-out errors on the calibration data, its validation (a judge).

    Attributes
    ----------
    model : str
        Model specification.
    calibration, validation : ErrorStats
    accepted : bool
    candidate : Candidate or None
        What the step added.
    test : NestedTest or None
        F-test and BIC against the model before.
    cv_mm : dict
        Held-out mean error (mm) on the calibration poses by kind of fold
        (``random``, ``time``, ``joint``), before (``*_before``) and with the step.
    reason : str
        Why it was not accepted (or how it ended, for an unexplained structure).
    orientation : AngleStats or None
        Full pose: the orientation errors on the validation poses (full fits only, not the one-step fits of
        candidates that were not accepted).
    """

    model: str
    calibration: ErrorStats
    validation: ErrorStats
    accepted: bool
    candidate: Candidate | None = None
    test: NestedTest | None = None
    cv_mm: dict = field(default_factory=dict)
    reason: str = ""
    orientation: AngleStats | None = None

    def to_dict(self) -> dict:
        d = {"model": self.model, "validation": self.validation.to_dict(n_poses=False),
             "calibration": self.calibration.to_dict(n_poses=False), "accepted": self.accepted}
        if self.orientation is not None:
            d["orientation"] = self.orientation.to_dict(n_poses=False)
        if self.candidate is not None:
            d["candidate"] = self.candidate.to_dict()
        if self.test is not None:
            d["test"] = {"f": finite(self.test.f), "dof": list(self.test.dof),
                         "log10_p": finite(self.test.log10_p), "delta_bic": finite(self.test.delta_bic)}
        if self.cv_mm:
            d["cv_mm"] = {k: finite(v) for k, v in self.cv_mm.items()}
        if self.reason:
            d["reason"] = self.reason
        return d


@dataclass
class Finding:
    """A cause the diagnosis names (or structure it cannot name: cause ``unexplained``).

    Attributes
    ----------
    candidate : Candidate
    gain_mm : float
        Drop of the validation mean error the step brought (0 for structure
        left out of the final model).
    evidence : str
        The evidence in words.
    in_model : bool
        Part of the final model.
    where : str
        For unexplained structure: where it lives (joint, harmonics, size).
    potential_gain_mm : float or None
        For structure left out of the model: the validation gain it would
        have brought on this series.
    ambiguous_with : list of dict
    parameters : dict
        The final model's values (with standard errors) of the finding's
        parameters, in display units.
    holds_up : dict
        The checks that decided: held-out gains by kind of fold, and for
        periodic errors resolution and the two halves' amplitude and phase.
    transfer : dict
        Gains on another series (``diagnose --transfer``).
    plot : dict
        Data of the residual plot against the cause's variable.
    scope : str or None
        ``robot``: one value serves every session (data of several
        sessions); ``session``: a property of one session (its own
        parameters, ``@session``; a drift), kept out of what a calibration
        carries to other data.
    """

    candidate: Candidate
    gain_mm: float
    evidence: str
    in_model: bool = True
    where: str = ""
    potential_gain_mm: float | None = None
    ambiguous_with: list[dict] = field(default_factory=list)
    parameters: dict = field(default_factory=dict)
    holds_up: dict = field(default_factory=dict)
    transfer: dict = field(default_factory=dict)
    plot: dict = field(default_factory=dict)
    scope: str | None = None

    @property
    def cause(self) -> str:
        return self.candidate.cause

    def to_dict(self) -> dict:
        d = self.candidate.to_dict()
        d.update(gain_mm=self.gain_mm, evidence=self.evidence, in_model=self.in_model)
        if self.scope is not None:
            d["scope"] = self.scope
        if self.where:
            d["where"] = self.where
        if self.potential_gain_mm is not None:
            d["potential_gain_mm"] = self.potential_gain_mm
        if self.ambiguous_with:
            d["ambiguous_with"] = self.ambiguous_with
        if self.parameters:
            d["parameters"] = self.parameters
        if self.holds_up:
            d["holds_up"] = self.holds_up
        if self.transfer:
            d["transfer"] = self.transfer
        return d

    def label(self) -> str:
        if self.cause == "unexplained":
            return "unexplained structure" + (f" ({self.where})" if self.where else "")
        return self.candidate.label()


@dataclass
class DiagnosisReport:
    """Everything :func:`diagnose` found (JSON: :meth:`to_dict`, HTML: :func:`casadical.report.diagnosis_html`).

    Attributes
    ----------
    final : CalibrationResult
        The final model (compensator included if one was accepted), fitted
        on the calibration poses: what ``diagnose --out`` writes.
    transfer : dict
        The final and the kinematic model taken to another series, if asked.
    final_sessions : dict of str to ErrorStats
        With several sessions: the final model's validation errors in each.
    """

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
    kinematic_validation: ErrorStats | None = None
    transfer: dict = field(default_factory=dict)
    settings: dict = field(default_factory=dict)
    final_sessions: dict = field(default_factory=dict)
    final_orientation: AngleStats | None = None

    def to_dict(self) -> dict:
        params = []
        for p in self.final.parameters:
            params.append({"name": p.name, "value": p.to_display(p.value),
                           "std": p.to_display(p.std) if math.isfinite(p.std) else None,
                           "unit": p.display_unit, "fixed": p.fixed, "term": p.term})
        doc = {
            "robot": self.robot,
            "steps": [s.to_dict() for s in self.steps],
            "findings": [f.to_dict() for f in self.findings],
            "final": {"model": self.final_model, "validation": self.final_validation.to_dict(n_poses=False),
                      "parameters": params,
                      "robust": {"sigma_mm": self.final.loss.sigma * 1000 if self.final.loss.robust else None,
                                 "set_aside": self.final.downweighted}},
            "notes": self.notes,
            "time_s": self.time_s,
            "settings": self.settings,
        }
        if self.final_sessions:
            doc["final"]["sessions"] = {s: st.to_dict() for s, st in self.final_sessions.items()}
        if self.final_orientation is not None:
            doc["final"]["orientation"] = self.final_orientation.to_dict(n_poses=False)
        if self.transfer:
            doc["transfer"] = self.transfer
        return doc

    def text(self) -> str:
        pose = any(s.orientation is not None for s in self.steps)   # full pose: the orientation's mean too
        lines = [f"diagnosis of {self.robot} ({self.time_s:.1f} s)", "",
                 f"{'model':<58}{'val mean':>10}{'val max':>10}{'val rms':>10}" + (f"{'val deg':>10}" if pose else "")
                 + "  accepted"]
        for s in self.steps:
            v = s.validation
            deg = ((f"{s.orientation.mean_deg:>10.4f}" if s.orientation is not None else f"{'-':>10}") if pose else "")
            lines.append(f"{s.model[:57]:<58}{v.mean_mm:>10.4f}{v.max_mm:>10.4f}{v.rms_mm:>10.4f}{deg}  "
                         f"{'yes' if s.accepted else 'no'}")
        lines += ["", "findings (values of the final model):"]
        if not [f for f in self.findings if f.cause != "geometric"]:
            lines.append("  none beyond the geometry")
        for f in self.findings:
            head = f"validation mean -{f.gain_mm:.4f} mm" if f.in_model else "not in the final model"
            lines.append(f"  {f.label()}: {head}. {f.evidence}")
            for a in f.ambiguous_with:
                lines.append(f"    ambiguous with {a['label']}: {a['tell_apart']}")
            if f.transfer:
                lines.append(f"    on {self.transfer.get('file', 'the other series')}: {f.transfer['text']}")
        v = self.final_validation
        lines += ["", f"final model {self.final_model}: validation mean {v.mean_mm:.4f}, "
                      f"max {v.max_mm:.4f}, rms {v.rms_mm:.4f} mm"]
        lines += [f"  session {s}: validation mean {st.mean_mm:.4f}, max {st.max_mm:.4f}, rms {st.rms_mm:.4f} mm"
                  for s, st in self.final_sessions.items()]
        if self.final_orientation is not None:
            o = self.final_orientation
            lines.append(f"full pose: orientation on the validation poses mean {o.mean_deg:.4f}, max {o.max_deg:.4f}, "
                         f"rms {o.rms_deg:.4f} deg")
        if self.transfer:
            lines.append(self.transfer["text"])
        lines += [f"note: {n}" for n in self.notes]
        return "\n".join(lines)
