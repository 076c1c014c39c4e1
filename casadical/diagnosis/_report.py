"""What a diagnosis returns: the steps tried, the findings, the final model (JSON and text)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from ..result import AngleStats, CalibrationResult, ErrorStats
from ._candidates import Candidate
from ._periodogram import Periodogram
from ._statistics import NestedTest
from ._words import action, gain, gain_words, label, scope, size, table, where, wrap, wrap_spec

#: the most characters a finding's place or size takes on a line of the terminal's findings table (a longer one,
#: an unexplained part's words, wraps within its column, so the table stays within a terminal's width)
CELL_WIDTH = 44


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
    parent : int or None
        Index (in the report's steps) of the model this step extends: the
        last accepted model when it was tried. None for the nominal model, and
        for a step after the final check changed the model (``parent_mm`` still
        holds that model's validation mean).
    parent_mm : float or None
        Validation mean (mm) of the model this step extends: its gain is
        measured against it (:attr:`gain_mm`).
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
    parent: int | None = None
    parent_mm: float | None = None

    @property
    def gain_mm(self) -> float | None:
        """Drop of the validation mean from the model this step extends to this step (None for the first)."""
        return None if self.parent_mm is None else self.parent_mm - self.validation.mean_mm

    @property
    def label(self) -> str:
        """A few words: ``nominal``, ``kinematic``, ``+ compliance j2``, ``+ periodic j2 h17``, ``+ drift @B``,
        ``+ GP compensator``; the whole model is :attr:`model`."""
        c = self.candidate
        if c is None:
            return self.model          # the nominal model
        return c.kind.step_label(c) or "+ " + c.label(short=True)

    def to_dict(self) -> dict:
        d = {"model": self.model, "validation": self.validation.to_dict(n_poses=False),
             "calibration": self.calibration.to_dict(n_poses=False), "accepted": self.accepted,
             "label": self.label, "parent": self.parent, "gain_mm": finite(self.gain_mm)}
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
    structure : dict
        For structure the structure screen found (:mod:`._structure`): its
        ``covariate``, ``effect``, ``p_value``, ``size_mm`` and
        ``potential_gain_mm`` (top-level keys of the JSON finding).
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
    structure: dict = field(default_factory=dict)

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
        d.update(self.structure)
        return d

    def label(self) -> str:
        return self.candidate.kind.long_label(self) or self.candidate.label()


@dataclass
class DiagnosisReport:
    """Everything :func:`diagnose` found (JSON: :meth:`to_dict`, HTML: :func:`casadical.html.diagnosis_html`).

    Attributes
    ----------
    final : CalibrationResult
        The final model (compensator included if one was accepted), fitted
        on the calibration poses: what ``diagnose --out`` writes.
    transfer : dict
        The final and the kinematic model taken to another series, if asked.
    final_sessions : dict of str to ErrorStats
        With several sessions: the final model's validation errors in each.
    set_aside : dict
        The poses the final fit's robust loss set aside, tested for shared
        structure (:meth:`casadical.stats._outliers.SetAsideStructure.to_dict`).
    not_tried : list of dict
        Each kind of cause these data cannot test, with why and what would
        allow it (:class:`casadical.diagnosis._catalogue.NotTried`).
    noise : dict
        The instrument's noise floor and the final model's leftover in its
        units, where the noise is known (:class:`casadical.diagnosis._noise.NoiseFloor`).
    interval_coverage : float or None
        The share of the validation poses whose measured point lies inside the final model's 95 % interval
        (:func:`casadical.prediction.prediction_interval`); None without a parameter covariance.
    user_terms : list of dict
        Each cause of the user's own (a terms file's), its definition and what the diagnosis concluded of each
        of its candidates (:func:`casadical.diagnosis._user_terms.accounts`); [] without a terms file.
    inputs : dict
        What the caller gave, for the record (the command line: the robot, the files, the options as given).
    gravity : dict
        The robot file's gravity against the levelled instrument's down (:class:`casadical.calibration._gravity.
        GravityCheck`); empty where it is not checked.
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
    set_aside: dict = field(default_factory=dict)
    not_tried: list = field(default_factory=list)
    noise: dict = field(default_factory=dict)
    interval_coverage: float | None = None
    user_terms: list = field(default_factory=list)
    inputs: dict = field(default_factory=dict)
    gravity: dict = field(default_factory=dict)

    def to_dict(self) -> dict:
        from ..robot import robot_to_dict

        params = []
        tests = self.final.significance()
        for p in self.final.parameters:
            t = tests.get(p.name)
            params.append({"name": p.name, "value": p.to_display(p.value),
                           "std": p.to_display(p.std) if math.isfinite(p.std) else None,
                           "unit": p.display_unit, "fixed": p.fixed, "term": p.term,
                           "t": finite(t.t) if t is not None else None,
                           "significant": t.significant if t is not None else None})
        doc = {
            "robot": self.robot,
            "steps": [s.to_dict() for s in self.steps],
            "findings": [{**f.to_dict(), "summary": {k: v for k, v in row.items() if k != "gain"}}
                         for f, row in zip(self.findings, self.decision())],
            "final": {"model": self.final_model, "validation": self.final_validation.to_dict(n_poses=False),
                      "parameters": params,
                      "sigma_mm": finite(self.final.uncertainty.sigma * 1000) if self.final.uncertainty else None,
                      "robust": {"sigma_mm": self.final.loss.sigma * 1000 if self.final.loss.robust else None,
                                 "set_aside": self.final.downweighted,
                                 **({"structure": self.set_aside} if self.set_aside else {})}},
            "not_tried": self.not_tried,
            "notes": self.notes,
            "time_s": self.time_s,
            "settings": self.settings,
        }
        if self.user_terms:
            doc["user_terms"] = self.user_terms
        if self.inputs:
            doc["inputs"] = dict(self.inputs)
        if self.final_sessions:
            doc["final"]["sessions"] = {s: st.to_dict() for s, st in self.final_sessions.items()}
        if self.final_orientation is not None:
            doc["final"]["orientation"] = self.final_orientation.to_dict(n_poses=False)
        if self.transfer:
            doc["transfer"] = self.transfer
        if self.noise:
            doc["final"]["noise"] = self.noise
        if self.gravity:
            doc["gravity"] = self.gravity
        doc["final"]["interval_coverage"] = self.interval_coverage
        doc["robot_description"] = robot_to_dict(self.final.model.robot)   # what plan-poses REPORT.json builds on
        return doc

    def decision(self) -> list[dict]:
        """One row per finding, what to act on: label, where, size (final model), gain, scope, what to do."""
        return [{"label": label(f), "where": where(f), "size": size(f, self.final), "gain": gain(f),
                 "scope": scope(f), "action": action(f, self)} for f in self.findings]

    def summary(self) -> str:
        """The short report: findings (what to do about each), the final model's errors, notes."""
        return self.text(verbose=False)

    def text(self, verbose: bool = True) -> str:
        """The report in words: the findings and the final model first, then (``verbose``) the evidence: every
        step with its gain against the model it extends, each model's full specification, the checks."""
        accepted = sum(s.accepted for s in self.steps)
        lines = [f"diagnosis of {self.robot}: {len(self.steps)} models tried, {accepted} accepted "
                 f"({self.time_s:.1f} s)", ""]
        n_val = self.final_validation.n_poses
        lines.append(f"findings (sizes in the final model; gains on the {n_val} validation poses, each against the "
                     "model it extends):")
        decided = self.decision()
        rows = [[str(k), r["label"], r["where"], r["size"], r["gain"], r["scope"]] for k, r in enumerate(decided, 1)]
        if not rows:
            lines.append("  none")
        else:
            grid = table(["#", "finding", "where", "size", "gain on validation", "scope"], rows, right=(0,),
                         widest={2: CELL_WIDTH, 3: CELL_WIDTH})
            lines.append(grid[0])
            for line, row in zip(grid[1:], decided):      # each finding, and what to do under it
                lines.append(line)
                lines += wrap(row["action"], " " * 9, " " * 5 + "do: ")
        if all(f.candidate.kind.geometry for f in self.findings):
            lines.append("  no cause beyond the geometry")
        lines += [""] + self._final_lines()
        if verbose:
            lines += [""] + self._steps_lines() + [""] + self._evidence_lines()
        if self.user_terms:
            lines += [""] + self._user_term_lines()
        if self.not_tried:
            lines += ["", "not tried on these data (why; what would allow it):"]
            lines += [x for n in self.not_tried for x in wrap(_not_tried_text(n), "      ", "  - ")]
        lines += [""] + [x for n in self.notes for x in wrap(n, "      ", "note: ")]
        if not verbose:
            lines += ["", "the evidence (every step with its gain, each model's full specification, the checks): "
                          "--verbose, the JSON and the HTML report"]
        return "\n".join(lines)

    def _final_lines(self) -> list[str]:
        v = self.final_validation
        out = [f"final model: validation mean {v.mean_mm:.4f} mm, max {v.max_mm:.4f} mm, rms {v.rms_mm:.4f} mm "
               f"on {v.n_poses} poses never fitted"]
        k, nominal = self.kinematic_validation, (self.steps[0].validation if self.steps else None)
        against = []
        if k is not None:
            against.append(f"the kinematic model's {k.mean_mm:.4f} mm ({gain_words(k.mean_mm - v.mean_mm)})")
        if nominal is not None:
            against.append(f"the nominal model's {nominal.mean_mm:.4f} mm "
                           f"({gain_words(nominal.mean_mm - v.mean_mm)})")
        if against:
            out.append("  against " + " and ".join(against))
        if v.touch:     # rows that touch: each row's distance from what it touched, fitted to its session's rows
            out.append(f"  touches: {v.touch_words()}")
        for s, st in self.final_sessions.items():
            out.append(f"  session {s}: validation mean {st.mean_mm:.4f} mm, max {st.max_mm:.4f} mm, rms "
                       f"{st.rms_mm:.4f} mm ({st.n_poses} poses)")
        if self.final_orientation is not None:
            o = self.final_orientation
            out.append(f"  orientation (full pose): mean {o.mean_deg:.4f} deg, max {o.max_deg:.4f} deg, rms "
                       f"{o.rms_deg:.4f} deg")
        if self.transfer:
            out += wrap(self.transfer["text"], "    ", "  ")
        out += wrap_spec(self.final_model, "    ", "  model: ")
        return out

    def _user_term_lines(self) -> list[str]:
        """Each cause of the user's own and what the diagnosis concluded of it (every term of the file, whatever
        came of it)."""
        files = sorted({u["file"] for u in self.user_terms if u.get("file")})
        out = [f"terms of your own ({', '.join(files) or 'the terms file'}): what the diagnosis concluded of each"]
        for u in self.user_terms:
            for s in u["screen"]:
                out += wrap(f"{s['label']}: {s['text']}", "      ", "  - ")
        return out

    def _steps_lines(self) -> list[str]:
        pose = any(s.orientation is not None for s in self.steps)   # full pose: the orientation's mean too
        head = ["#", "step", "extends", "val mean", "gain against it", "val max", "val rms"] + \
            (["val deg"] if pose else []) + ["accepted"]
        rows = []
        for k, s in enumerate(self.steps, 1):
            v = s.validation
            rows.append([str(k), s.label, "-" if s.parent is None else str(s.parent + 1), f"{v.mean_mm:.4f}",
                         gain_words(s.gain_mm), f"{v.max_mm:.4f}", f"{v.rms_mm:.4f}"]
                        + ([f"{s.orientation.mean_deg:.4f}" if s.orientation is not None else "-"] if pose else [])
                        + ["yes" if s.accepted else "no"])
        out = ["steps (validation errors in mm judge and never decide; each gain is against the model the step "
               "extends):"]
        out += table(head, rows, right=(0, 2, 3, 5, 6) + ((7,) if pose else ()))
        out += ["", "models (each step's full specification, and why a step was not accepted):"]
        for k, s in enumerate(self.steps, 1):
            out += wrap_spec(s.model, " " * 6, f"{k:>4}  ")
            if s.reason:
                out += wrap(s.reason, " " * 10, " " * 6 + ("not accepted: " if not s.accepted else ""))
        return out

    def _evidence_lines(self) -> list[str]:
        out = ["evidence of each finding (values of the final model):"]
        for k, f in enumerate(self.findings, 1):
            head = f"validation mean {gain_words(f.gain_mm)}" if f.in_model else "not in the final model"
            out += wrap(f"{f.label()}: {head}. {f.evidence}", " " * 6, f"{k:>4}  ")
            for a in f.ambiguous_with:
                out += wrap(f"ambiguous with {a['label']}: {a['tell_apart']}", " " * 8, " " * 6)
            if f.transfer:
                out += wrap(f"on {self.transfer.get('file', 'the other series')}: {f.transfer['text']}", " " * 8,
                              " " * 6)
        return out


def _not_tried_text(n: dict) -> str:
    """A kind of cause not tried, in words (``drift, warmup: the poses have no times (time_s); a time_s ...``)."""
    joints = n.get("joints", [])
    on = f" of joint{'s' if len(joints) > 1 else ''} {', '.join(map(str, joints))}" if joints else ""
    return f"{n['cause'].replace('_', ' ')}{on}: {n['why']}; {n['allow']}"
