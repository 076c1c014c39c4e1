"""The HTML report of a diagnosis: steps, findings with their evidence, what transfers, the final model."""

from __future__ import annotations

import math
from functools import partial
from typing import TYPE_CHECKING

import numpy as np

from ..parameters import READING
from ..result import TOUCH_WORDS
from ..terms import UNEXPLAINED
from ..terms._definitions import EFFECTS
from ._figures import AFTER, BEFORE, CURVE, SERIES, ecdf, figure, legend_above, ticks
from ._page import Page, Raw, esc, gain, model_label, num, sig
from ._parameters import parameter_table_html
from ._svg import VIRIDIS, bands

if TYPE_CHECKING:
    from ..diagnosis._report import DiagnosisReport, Finding, Step

#: casadical.diagnosis._validation.KINDS (not imported: the diagnosis package pulls in scipy)
KINDS = ("random", "time", "joint")
#: the anchor of the section on structure kept out of the model (its findings' cause)
KEPT_OUT = UNEXPLAINED.name


def short_label(cand) -> str:
    """A candidate cause in a few words: ``compliance j2``, ``periodic j2 h17``, ``backlash j3 (motion)``."""
    return "nominal" if cand is None else cand.label(short=True)


def step_label(step: Step) -> str:
    """A step in a few words (:attr:`Step.label`): ``kinematic``, ``+ compliance j2``, ``+ GP compensator``."""
    return step.label


def diagnosis_html(report: DiagnosisReport, processes: int = 1, progress=None, poses=None,
                   map_joints: tuple[int, int] | None = None) -> str:
    """A self-contained HTML report of a diagnosis (inline CSS and SVG, no script, no network).

    Every pose's mark in a figure has a hover title: its CSV line and its error in mm.

    The answer first: the findings with what to do about each and the final
    model's errors fill the first screen; the evidence (each finding's
    checks and figure, the steps, the structure kept out, the transfer, the
    periodograms, the parameters) follows.

    Parameters
    ----------
    report : DiagnosisReport
        What :func:`casadical.diagnosis.diagnose` returned.
    processes : int
        Ignored (kept so that existing calls work): the figures are written in this process, in milliseconds.
    progress : callable, optional
        Receives a line of text before and after the figures are drawn.
    poses : Measurements, optional
        The calibration poses, drawn on the map of where the model is accurate.
    map_joints : (int, int), optional
        The two joints of that map (default: the two along which the model's uncertainty varies most).
    """
    page = Page(f"casadical diagnosis: {report.robot}")
    v = report.final_validation
    final = model_label(page, _final_label(report), report.final_model)
    page.heading(f"Diagnosis of {report.robot}", 1)
    text = (f"Final model {final}: validation mean {v.mean_mm:.4f} mm over {v.n_poses} validation poses that were "
            "never fitted and never decided anything")
    k = report.kinematic_validation
    if k is not None:
        text += f"; {gain(k.mean_mm - v.mean_mm)} than the kinematic calibration ({k.mean_mm:.4f} mm)"
    nominal = report.steps[0].validation if report.steps else None
    if nominal is not None:
        text += f" and {gain(nominal.mean_mm - v.mean_mm)} than the nominal model ({nominal.mean_mm:.4f} mm)"
    named = [f for f in report.findings if f.in_model and f.candidate.kind.named]
    kept_out = [f for f in report.findings if not f.in_model]
    page.para(text + f". {len(named)} cause(s) named beyond the geometry, {len(kept_out)} joint(s) with structure "
              f"kept out of the model; {len(report.steps)} models tried in {report.time_s:.1f} s.", "lead")

    _decision(page, report)
    _errors(page, report)
    sections = [("evidence", "Evidence for each finding"), ("steps", "Steps"),
                (KEPT_OUT, "Structure kept out of the model"), ("user-terms", "Terms of your own"),
                ("transfer", "On another series"), ("periodograms", "What is left"),
                ("accuracy", "Where the model is accurate"), ("not-tried", "Not tried on these data"),
                ("parameters", "Final parameters"), ("notes", "Notes, inputs and settings")]
    present = {KEPT_OUT: bool(kept_out), "transfer": bool(report.transfer),
               "periodograms": bool(report.periodograms), "evidence": bool(report.findings),
               "accuracy": report.final.uncertainty is not None and report.final.model.robot.n >= 2,
               "not-tried": bool(report.not_tried), "user-terms": bool(report.user_terms)}
    page.para("The evidence behind them, further down:")
    page.items([page.ref(a, t) for a, t in sections if present.get(a, True)], "ol")

    _findings(page, report)
    _steps(page, report)
    if kept_out:
        _kept_out(page, report, kept_out)
    if report.user_terms:
        _user_terms(page, report)
    if report.transfer:
        _transfer(page, report)
    if report.periodograms:
        page.heading("What is left: periodograms of the final residual", anchor="periodograms")
        ref = page.figure(partial(_periodograms, report), "fig-periodograms",
                          "Share of each joint's projected calibration residual that one harmonic of its reading "
                          "explains, per harmonic (cycles per turn). Dotted lines: harmonics in the final model.")
        page.para(f"A single tall peak in {ref} is a periodic error the model lacks; a forest of small ones "
                  "is noise or structure no single harmonic holds.")
    if present["accuracy"]:
        _accuracy(page, report, poses, map_joints)
    if report.not_tried:
        page.heading("Not tried on these data", anchor="not-tried")
        page.para("Kinds of cause these poses cannot test, why, and what would let the diagnosis try them.")
        page.table(["cause", "joints", "why", "what would allow it"],
                   [[n["cause"].replace("_", " "), ", ".join(map(str, n.get("joints", []))) or "-", n["why"],
                     n["allow"]] for n in report.not_tried], text_columns=(0, 1, 2, 3), wrap_columns=(2, 3))
    page.heading("Final parameters", anchor="parameters")
    page.para("The final model fitted on the calibration poses (what <code>diagnose --out</code> writes). "
              "Angles in degrees, lengths in millimetres; greyed rows are held.")
    parameter_table_html(page, report.final, fold=True)
    _notes_and_settings(page, report)
    return page.html(progress)


def _final_label(report: DiagnosisReport) -> str:
    named = sum(f.in_model and f.candidate.kind.named for f in report.findings)
    bb = any(f.in_model and f.candidate.kind.unexplained for f in report.findings)
    base = "kinematic" if any(f.candidate.kind.geometry for f in report.findings) else "nominal"
    return base + (f" + {named} cause(s)" if named else "") + (" + GP compensator" if bb else "")


# --- the answer: findings and what to do, the final model's errors ----------------------


def _decision(page: Page, report: DiagnosisReport) -> None:
    page.heading("Findings: what to do", anchor="findings")
    if not report.findings:
        page.para("Nothing: not even the geometry is supported by the calibration data.")
        return
    evidence = _evidence_anchors(report)
    rows, classes, actions = [], [], []
    for k, (f, row) in enumerate(zip(report.findings, report.decision()), 1):
        anchor = evidence.get(id(f))
        name = page.ref(anchor, row["label"]) if anchor else row["label"]
        g = gain(f.gain_mm) if f.in_model else "kept out"
        # the std with its sign and unit on one line: "\u00b1 5.8 %" never breaks
        size = row["size"].replace(" +- ", " \u00b1\u00a0").replace(" %", "\u00a0%")
        rows.append([str(k), name, row["where"], size, g, row["scope"]])
        classes.append("" if f.in_model else "off")
        actions.append("What to do: " + row["action"])
    page.para(f"Each cause the data support, with its size in the final model (&plusmn; its standard error), its "
              f"gain on the {report.final_validation.n_poses} validation poses (against the model it extends), "
              "whether it is a property of the robot or of the measurement session, and under it what to do about it. "
              "Greyed: structure kept out of the model.")
    # where and size break over lines in a narrow window: the table fits 800 px without scrolling sideways
    page.table(["#", "finding", "where", "size", "gain on validation", "scope"], rows,
               text_columns=(1, 2, 3, 4, 5), row_classes=classes, details=actions, soft_columns=(2, 3, 5))


def _evidence_anchors(report: DiagnosisReport) -> dict[int, str]:
    """Where each finding's evidence is on the page (by id of the finding)."""
    out = {id(f): f"finding-{k}" for k, f in enumerate([f for f in report.findings if f.in_model], 1)}
    out.update({id(f): KEPT_OUT for f in report.findings if not f.in_model})
    return out


def _errors(page: Page, report: DiagnosisReport) -> None:
    page.heading("Errors of the final model", anchor="errors")
    v = report.final_validation
    pose = report.final_orientation is not None
    models = [("nominal (base pose fitted)", report.steps[0].validation if report.steps else None),
              ("kinematic", report.kinematic_validation), ("final", v)]
    # rows that touch: their consistency and the fixture's distance error too (docs/formats.md section 11)
    touch = list(v.touch)
    rows = []
    for name, st in models:
        if st is None:
            continue
        rows.append([name, str(st.n_poses), num(st.mean_mm), num(st.max_mm), num(st.rms_mm),
                     *(num(st.touch.get(k)) for k in touch), gain(st.mean_mm - v.mean_mm) if name != "final" else ""])
    for s, st in report.final_sessions.items():
        rows.append([f"final, session {s}", str(st.n_poses), num(st.mean_mm), num(st.max_mm), num(st.rms_mm),
                     *(num(st.touch.get(k)) for k in touch), ""])
    page.table(["model, on the validation poses", "poses", "mean mm", "max mm", "rms mm",
                *(f"{TOUCH_WORDS[k]} mm" for k in touch), "final against it"],
               rows, text_columns=(0, 5 + len(touch)))
    extra = []
    if pose:
        o = report.final_orientation
        extra.append(f"Orientation of the probe (full pose): mean {o.mean_deg:.4f} deg, max {o.max_deg:.4f} deg, "
                     f"rms {o.rms_deg:.4f} deg.")
    if report.transfer:
        t = report.transfer
        extra.append(esc(f"On {_name(t['file'])}: {t['final']['base_mm']:.4f} mm with the base pose re-estimated "
                         f"(kinematic {t['kinematic']['base_mm']:.4f}), {t['final']['refit_mm']:.4f} mm with the "
                         f"geometry refitted (kinematic {t['kinematic']['refit_mm']:.4f}): ")
                     + page.ref("transfer", "details") + ".")
    if extra:
        page.para(" ".join(extra))
    for n in _worst_notes(report):     # what the table's max column means, beside it (not at the page's end)
        page.para("<b>Worst validation error.</b> " + esc(n), "note")


#: the notes that explain the worst validation error of the errors table (casadical.diagnosis._never_worse,
#: casadical.diagnosis._worst_case): shown beside it
WORST_NOTES = ("judge only:", "worst case:")


def _worst_notes(report: DiagnosisReport) -> list[str]:
    return [n for n in report.notes if n.startswith(WORST_NOTES)]


# --- steps ---------------------------------------------------------------------------


def _held_cells(s: Step) -> list:
    """The held-out means of a step, each with its gain; the GP compensator's against its own folds' baseline,
    said in the cell (:func:`_compensator_folds`)."""
    cv = s.cv_mm or {}
    against = _is_compensator(s)
    return [Raw(num(cv.get(k)) + (f"<br><small>{gain(_drop(cv, k), unit='')}"
                                  + (f", from {num(cv.get(f'{k}_before'))}" if against else "") + "</small>"
                                  if _drop(cv, k) is not None else "")) for k in KINDS]


def _is_compensator(s: Step) -> bool:
    return s.candidate is not None and s.candidate.cause == UNEXPLAINED.name and s.candidate.joint is None


def _compensator_folds(before: float | None) -> str:
    """Why the GP compensator's held-out means start from another figure than the step before it shows."""
    return ("The GP compensator is judged on the same folds, but with the model it extends fitted once on every "
            "calibration pose" + (f" (its mean error there: {before:.4f} mm)" if before is not None else "")
            + " and only the process held out: its held-out means measure what the compensator adds to that fit, "
            "not how the whole model extrapolates, so they do not continue the held-out means of the steps "
            "before it, where every fold refits the model.")


def _val_cell(s: Step) -> Raw:
    vm = num(s.validation.mean_mm)
    if s.gain_mm is not None:
        vm += f"<br><small>{gain(s.gain_mm, unit='')}</small>"
    return Raw(vm)


def _steps(page: Page, report: DiagnosisReport) -> None:
    page.heading("Steps", anchor="steps")
    number = {id(s): k for k, s in enumerate(report.steps, 1)}
    acc = [s for s in report.steps if s.accepted]
    rejected = [s for s in report.steps if not s.accepted]

    def extends(s: Step) -> str:
        return "\u2013" if s.parent is None else str(s.parent + 1)

    page.para("Each step extends a model by one cause; it is accepted only on the calibration poses (significance "
              "and held-out means on folds that interpolate, follow time, and extrapolate over joint ranges). The "
              "validation columns judge and never decide. Under each mean, its gain (mm) against the model the "
              "step extends (column <i>extends</i>: that model's step). Hover over a step for its whole model, or "
              "see the footnotes. Steps are numbered in the order the diagnosis tried them, 1 to "
              f"{len(report.steps)}: the accepted ones are in this table, "
              + (f"the {len(rejected)} not accepted, numbered in between, in the folded table below it."
                 if rejected else "and every step tried was accepted."))
    page.table(["#", "accepted step", "extends", "calibration rms mm", "held-out mean, random folds, mm",
                "held-out mean, time folds, mm", "held-out mean, joint folds, mm", "validation mean mm",
                "validation max mm", "validation rms mm"],
               [[str(number[id(s)]), model_label(page, step_label(s), s.model), extends(s),
                 num(s.calibration.rms_mm), *_held_cells(s), _val_cell(s), num(s.validation.max_mm),
                 num(s.validation.rms_mm)] for s in acc], text_columns=(1,))
    gp = next((s for s in acc if _is_compensator(s)), None)
    if gp is not None:
        page.para(f"Step {number[id(gp)]}: " + esc(_compensator_folds((gp.cv_mm or {}).get("random_before"))),
                  "note")
    if rejected:
        better = sum(1 for s in rejected if (s.gain_mm or 0) > 0)
        page.para(f"{len(rejected)} candidate steps were not accepted ({better} of them would have lowered this "
                  "series' validation mean: a gain here is no reason to accept a cause that does not hold up where "
                  "the model must extrapolate).")
        with page.folded(f"The {len(rejected)} steps not accepted, each against the model it extends, and why"):
            page.table(["#", "step", "extends", "held-out mean, random folds, mm", "held-out mean, time folds, mm",
                        "held-out mean, joint folds, mm", "validation mean mm", "why not accepted"],
                       [[str(number[id(s)]), model_label(page, step_label(s), s.model), extends(s), *_held_cells(s),
                         _val_cell(s), s.reason] for s in rejected], text_columns=(1,), wrap_columns=(7,),
                       row_classes=["off"] * len(rejected))
    steps = [s for s in acc if s.candidate is not None]
    if steps:
        ref = page.figure(partial(_along_steps, steps), "fig-steps",
                          "Validation mean error and held-out means on the calibration poses along the accepted "
                          f"steps (the nominal model, not shown: {report.steps[0].validation.mean_mm:.4f} mm).")
        page.para(f"How the error falls along the accepted steps: {ref}.")
    # every pose, the final model against the kinematic calibration: the comparison the headline makes
    kinematic = "val_errors_kinematic_mm" in report.plots
    e0 = np.asarray(report.plots.get("val_errors_kinematic_mm" if kinematic else "val_errors_nominal_mm", []),
                    float)
    e1 = np.asarray(report.plots.get("val_errors_final_mm", []), float)
    if len(e0) and len(e1):
        name = "kinematic calibration" if kinematic else "nominal model (base fitted)"
        ref = page.figure(partial(_per_pose, e0, e1, report.plots.get("val_lines"), name), "fig-poses",
                          f"Position error of each validation pose, the {name} and the final model (the comparison "
                          "the headline makes): distribution (top) and per pose (bottom).")
        page.para(f"Every validation pose, {name} and final model: {ref}; the median goes from "
                  f"{np.median(e0):.4f} mm to {np.median(e1):.4f} mm, the worst from {e0.max():.4f} mm to "
                  f"{e1.max():.4f} mm.")


def _along_steps(steps: list[Step]):
    fig, ax = figure(8.6, 3.6)
    ax = ax[0][0]
    x = np.arange(len(steps))
    labels = [step_label(s) for s in steps]
    y = [s.validation.mean_mm for s in steps]
    ax.line(x, y, AFTER, 2.2, marker="o", ms=4, label="validation mean",
            titles=[f"{k + 1}. {lab}: validation mean {v:.4f} mm" for k, (lab, v) in enumerate(zip(labels, y))])
    for kind, colour in zip(KINDS, (SERIES[2], SERIES[3], SERIES[1])):
        y = [(s.cv_mm or {}).get(kind) for s in steps]
        ax.line(x, [math.nan if v is None else v for v in y], colour, 1.1, dash="4,2", marker="s", ms=3,
                label=f"held-out, {kind} folds",
                titles=[f"{lab}: held-out mean, {kind} folds, " + ("\u2013" if v is None else f"{v:.4f} mm")
                        for lab, v in zip(labels, y)])
    ax.categories, ax.rotate = labels, 40.0
    ax.ylabel = "mean position error (mm)"
    ticks(ax, x=False)
    legend_above(ax)
    return fig


def _per_pose(e0: np.ndarray, e1: np.ndarray, lines=None, name: str = "kinematic calibration"):
    fig, ax = figure(8.6, 5.6, 2, 1)
    ecdf(ax[0][0], e0, e1, name, "final model")
    legend_above(ax[0][0])
    a = ax[1][0]
    idx = np.arange(len(e0))
    titles = None
    short = name.split()[0]
    if lines is not None and len(lines) == len(e0):
        titles = [f"row {n}: {short} {x:.4f} mm, final {y:.4f} mm" for n, x, y in zip(lines, e0, e1)]
    a.points(idx, e0, BEFORE, 1.3, 0.6, label=short, titles=titles)
    a.points(idx, e1, AFTER, 1.3, 0.8, label="final", titles=titles)
    a.xlabel, a.ylabel = "validation pose (file order)", "position error (mm)"
    ticks(a)
    return fig


# --- findings ------------------------------------------------------------------------


def _findings(page: Page, report: DiagnosisReport) -> None:
    page.heading("Evidence for each finding", anchor="evidence")
    shown = [f for f in report.findings if f.in_model]
    if len(shown) <= 1:
        page.para("No cause beyond the geometry: the kinematic model explains the data down to what the "
                  "checks can support.")
    other = report.transfer.get("file", "the other series") if report.transfer else ""
    for f in shown:
        k = report.findings.index(f)        # numbered as in the findings' table
        anchor = f"finding-{k + 1}"
        head = f"{k + 1}. {f.label()}"
        page.parts.append(f'<h3 id="{anchor}">{esc(head)}: {gain(f.gain_mm)} on validation</h3>')
        entries = []
        if f.parameters:
            entries.append(("values", esc(", ".join(_value(n, p) for n, p in f.parameters.items()))))
        hu = f.holds_up or {}
        if "test" in hu:
            entries.append(("significance", esc(hu["test"] + " on the calibration poses")))
        if "resolution" in hu:
            entries.append(("resolution", esc(_resolution(hu["resolution"]))))
        for a in f.ambiguous_with:
            alike = f" (similarity {a['similarity']})" if "similarity" in a else ""
            entries.append(("ambiguous with", esc(f"{a['label']}{alike}: {a['tell_apart']}")))
        if f.transfer:
            entries.append((f"on {_name(other)}", _transfer_text(f.transfer)))
        page.pairs(entries)
        if hu:
            page.details("The evidence in words", f.evidence)
        elif f.evidence:
            page.para(esc(f.evidence))
        if "cv_mm" in hu or hu.get("halves"):
            with page.folded("Held-out means by kind of fold" + (" and the two halves" if hu.get("halves") else "")):
                if "cv_mm" in hu:
                    if f.cause == UNEXPLAINED.name:
                        page.para(esc(_compensator_folds(hu["cv_mm"].get("random_before"))), "note")
                    page.table(["held-out folds", "before mm", "with it mm", "gain"],
                               [[kind, num(hu["cv_mm"].get(f"{kind}_before")), num(hu["cv_mm"].get(kind)),
                                 gain(_drop(hu["cv_mm"], kind))] for kind in KINDS if kind in hu["cv_mm"]
                                or f"{kind}_before" in hu["cv_mm"]], text_columns=(0, 3))
                if hu.get("halves"):
                    _halves_table(page, hu["halves"])
        if f.plot:
            page.figure(partial(_finding_plot, f), f"fig-{anchor}", _finding_caption(f))


def _value(name: str, p: dict) -> str:
    """A finding's parameter, value and std, in the unit a person reads (a relative scale in ppm, not "1")."""
    unit, factor = READING.get(p["unit"], (p["unit"], 1.0))
    std = f" \u00b1 {sig(p['std'] * factor, 2)}" if p.get("std") is not None else ""
    return f"{name} = {sig(p['value'] * factor)}{std}" + (f" {unit}" if unit else "")


def _drop(cv: dict, kind: str) -> float | None:
    a, b = cv.get(f"{kind}_before"), cv.get(kind)
    return None if a is None or b is None else a - b


def _resolution(r: dict) -> str:
    lo, hi = r.get("band", ["?", "?"])
    covered = (f"the {r['range_mm']:.0f} mm the axis covers" if r.get("range_mm") is not None else
               f"the {r.get('range_deg', math.nan):.0f} deg the joint covers")
    if r.get("resolved"):
        return (f"resolved over {covered}: no neighbouring "
                f"harmonic fits as well (margin {r.get('neighbour_margin', math.nan):.3g}); "
                f"{100 * r.get('outside_geometry', math.nan):.0f} % of it lies outside what the geometry fits")
    return f"not resolved: harmonics {lo}..{hi} fit about as well over {covered}"


def _halves_table(page: Page, halves: list[dict]) -> None:
    rows = []
    for k, h in enumerate(halves):
        what = "joint range: lower / upper half" if h.get("split") == "joint" else "time: first / second half"
        if "amplitude_arcsec" in h:
            a, b = h["amplitude_arcsec"]
            pa, pb = h["phase_deg"]
            size, phase = f"{a:.1f} / {b:.1f} arcsec", f"{pa:.0f} / {pb:.0f} deg"
        elif "amplitude_mm" in h:       # a linear axis' periodic error
            a, b = h["amplitude_mm"]
            pa, pb = h["phase_deg"]
            size, phase = f"{sig(a, 3)} / {sig(b, 3)} mm", f"{pa:.0f} / {pb:.0f} deg"
        else:
            unit, factor = READING.get(h.get("unit", ""), (h.get("unit", ""), 1.0))
            a, b = (v * factor for v in h["values"])
            size, phase = f"{sig(a, 4)} / {sig(b, 4)} {unit}", ""
            if a * b < 0 and h["agree"]:
                size += " (opposite signs, within their errors)"
        decides = h.get("decides", k == 0)
        limit = h.get("chi2_limit")
        rows.append([what, size, phase, f"{h['chi2']:.1f}" + (f" (limit {limit:.1f})" if limit is not None else ""),
                     ("the same within their errors" if h["agree"] else "differ")
                     + ("" if decides else "; reported only")])
    page.table(["stable over", "size (each half)", "phase (each half)", "chi2", "verdict"], rows,
               text_columns=(0, 1, 2, 4), soft_columns=(1, 4))
    if any(not h.get("decides", k == 0) for k, h in enumerate(halves)):
        page.para("Accepted on the halves of the range: the term fitted on each half, their difference tested "
                  "against the halves' standard errors (chi-square); below the limit the halves cannot be told "
                  "apart, whatever their signs. The halves in time are reported only, not tested: a function of a "
                  "joint's reading is judged over the joint's range, and halves in time can differ because they "
                  "cover different parts of it, or because something changed while measuring (a drift, a "
                  "warm-up: causes the diagnosis tries where the poses have times).", "note")


def _transfer_text(t: dict) -> Raw:
    return Raw(f"{esc(t['verdict'])}: {gain(t['base_gain_mm'])} with the base pose re-estimated, "
               f"{gain(t['refit_gain_mm'])} with the geometry refitted")


def _name(path: str) -> str:
    return path.replace("\\", "/").rsplit("/", 1)[-1]


def _finding_caption(f: Finding) -> str:
    if "partial" in f.plot:
        return (f"{f.label()}: the calibration residual as joint {f.candidate.joint}'s angle error plus the fitted "
                "effect (points) against the cause's variable, and the fitted effect (line).")
    return f"{f.label()}: calibration residual before and after the finding, against its variable."


def _finding_plot(f: Finding):
    pl = f.plot
    fig, ax = figure(6.8, 3.2)
    ax = ax[0][0]
    x = np.asarray(pl["x"], float)
    lines, err = pl.get("lines"), pl.get("error_mm")
    has = lines is not None and err is not None and len(lines) == len(x)
    if "partial" in pl:
        y = np.asarray(pl["partial"], float)
        titles = None
        if has:
            titles = [f"row {n}: error {e:.4f} mm; {v:.1f} arcsec at {u:.4g}" for n, e, v, u in zip(lines, err, y, x)]
        ax.points(x, y, AFTER, 1.5, 0.55, label="residual + fitted effect", titles=titles, legend_r=3.0)
        ax.line(pl["curve_x"], pl["curve_y"], CURVE, 2.0, label="fitted effect")
    else:
        b, a = np.asarray(pl["before"], float), np.asarray(pl["after"], float)
        titles = None
        if has:
            titles = [f"row {n}: error {e:.4f} mm; before {u:.4f}, after {v:.4f}"
                      for n, e, u, v in zip(lines, err, b, a)]
        ax.points(x, b, BEFORE, 1.5, 0.6, label="before", titles=titles, legend_r=3.0)
        ax.points(x, a, AFTER, 1.5, 0.7, label="after", titles=titles, legend_r=3.0)
    ax.xlabel, ax.ylabel = pl["xlabel"], _wrap(pl["ylabel"])
    ticks(ax)
    legend_above(ax)
    return fig


def _wrap(label: str, width: int = 34) -> str:
    """An axis label on two lines when long (a label longer than its axis would be cut)."""
    if len(label) <= width:
        return label
    cut = label.rfind(" ", 0, len(label) // 2 + 8)
    return label if cut < 0 else label[:cut] + "\n" + label[cut + 1:]


# --- the user's own terms, the inputs and the settings --------------------------------------------


def _user_terms(page: Page, report: DiagnosisReport) -> None:
    """Each cause of the user's own (a terms file's) and what the diagnosis concluded of it: every term of the
    file, whatever came of it (casadical.diagnosis._user_terms)."""
    page.heading("Terms of your own", anchor="user-terms")
    files = sorted({u["file"] for u in report.user_terms if u.get("file")})
    page.para("The causes of " + (", ".join(f"<code>{esc(f)}</code>" for f in files) or "the terms file")
              + ", screened beside the catalogue's by the same tests and rules, and what the diagnosis concluded of "
              "each: named (a finding), fitted and not accepted (why), screened and never supported (its best "
              "score test against the round's corrected level), or not screened (why).")
    rows, details = [], []
    for u in report.user_terms:
        joints = u.get("joints", [u["joint"]] if "joint" in u else [])
        where = (f"joint{'s' if len(joints) > 1 else ''} {', '.join(map(str, joints))}" if joints else "-")
        for s in u["screen"]:
            outcome = s["outcome"]
            if outcome == "named":
                outcome = Raw(page.ref(f"finding-{s['finding']}", f"named: finding {s['finding']}"))
            rows.append([u["name"] + (f" @{s['session']}" if s.get("session") else ""), f"{where}, {u['scope']}",
                         outcome])
            details.append(s["text"])
    page.table(["term", "where, scope", "outcome"], rows, text_columns=(0, 1, 2), details=details,
               row_classes=["" if r[2] != "not screened" else "off" for r in rows])
    with page.folded("The terms as the file states them"):
        page.table(["term", "effects", "parameters (unit, bounds, start)"],
                   [[u["name"], "; ".join(f"{k} = {', '.join(v) if isinstance(v, list) else v}" for k, v in u.items()
                                         if k in EFFECTS),
                     "; ".join(f"{n} ({p.get('unit') or 'no unit'}, {p['lower']:g} .. {p['upper']:g}, "
                               f"{p.get('start', 0.0):g})" for n, p in u.get("parameters", {}).items())]
                    for u in report.user_terms], text_columns=(0,), wrap_columns=(1, 2))


#: what a command line's inputs are called on the page (DiagnosisReport.inputs)
_INPUTS = (("robot", "robot"), ("data", "calibration poses"), ("validate", "validation poses"),
           ("transfer", "other series (--transfer)"), ("terms", "terms file (--terms)"))


def _notes_and_settings(page: Page, report: DiagnosisReport) -> None:
    """The notes (but those beside the errors table), what the user gave and the settings of the diagnosis,
    in words (yes / no, not set), not as Python prints them."""
    page.heading("Notes, inputs and settings", anchor="notes")
    page.items([esc(n) for n in report.notes if not n.startswith(WORST_NOTES)])
    given = report.inputs or {}
    inputs = [(label, esc(_setting(given[k]))) for k, label in _INPUTS if given.get(k) not in (None, [], "")]
    if "terms" not in given and report.settings.get("terms"):
        inputs.append(("terms file (--terms)", esc(_setting(report.settings["terms"]))))
    if report.user_terms:
        inputs.append(("terms of your own", page.ref("user-terms", ", ".join(u["name"] for u in report.user_terms))))
    if inputs:
        page.para("<b>Inputs</b>")
        page.pairs(inputs)
    page.para("<b>Settings of the diagnosis</b>")
    page.pairs([(k.replace("_", " "), esc(_setting(v))) for k, v in report.settings.items()])
    options = given.get("options")
    if options:
        with page.folded(f"The command line's {len(options)} options, as given or by default"):
            page.pairs([(f"--{k.replace('_', '-')}", esc(_setting(v))) for k, v in options.items()])


def _setting(v) -> str:
    """A setting in words: yes / no, not set, a list joined."""
    if isinstance(v, bool):
        return "yes" if v else "no"
    if v is None:
        return "not set"
    if isinstance(v, (list, tuple)):
        return ", ".join(_setting(x) for x in v) or "none"
    if isinstance(v, float):
        return f"{v:g}"
    return str(v)


# --- unexplained, transfer, periodograms ------------------------------------------------


def _kept_out(page: Page, report: DiagnosisReport, kept: list[Finding]) -> None:
    page.heading("Structure kept out of the model", anchor=KEPT_OUT)
    screened = [f for f in kept if f.structure]
    if screened:
        page.para("What the named causes leave, found by the structure screen against every joint's reading and "
                  "load, the moment on the mount, time and the instrument's view, in each way an error can show "
                  "(docs/diagnosis.md, 'What no cause explains'); its size and what a flexible term would give are "
                  "judged on the validation poses. Each finding's term, in the JSON report, is a cause of your own "
                  "to start from.")
        page.table(["#", "where it lives", "varies with", "how", "p", "size on validation", "a flexible term would "
                    "give"], [[str(report.findings.index(f) + 1), f.where, f.structure["covariate"],
                               f.structure["effect"], f"{f.structure['p_value']:.2g}",
                               f"{f.structure['size_mm']:.4f} mm", gain(f.potential_gain_mm)] for f in screened],
                   text_columns=(1, 2, 3, 6), wrap_columns=(1,))
    kept = [f for f in kept if not f.structure]
    if not kept:
        return
    page.para("Significant on the calibration poses, but it does not hold up as a cause (not resolved from its "
              "neighbouring harmonics, or not the same over the halves of the joint's range), so the final model "
              "leaves it out. What it would have given: on this series' validation poses, and taken to the other "
              "series the same two ways as the findings.")
    other = _name(report.transfer.get("file", "")) if report.transfer else ""
    rows, details = [], []
    for f in kept:
        structures = f.holds_up.get("structures", [])
        sizes = [s["amplitude_arcsec"] for s in structures if "amplitude_arcsec" in s]
        row = [f"joint {f.candidate.joint}" if f.candidate.joint else "", str(len(structures)),
               f"{max(sizes):.1f} arcsec" if sizes else "", gain(f.potential_gain_mm)]
        if other:
            row.append(_transfer_text(f.transfer) if f.transfer else "")
        rows.append(row)
        details.append(f.where)
    header = ["where", "structures", "largest", "on this series' validation"] + ([f"on {other}"] if other else [])
    page.table(header, rows, text_columns=(0, 2, 3), wrap_columns=(4,), details=details)
    rows = [[f"joint {f.candidate.joint}", s.get("what", ""), s.get("why", "")]
            for f in kept for s in f.holds_up.get("structures", [])]
    if rows:
        with page.folded(f"Why each of the {len(rows)} structures was kept out"):
            page.table(["where", "structure", "why kept out"], rows, text_columns=(0, 1), wrap_columns=(2,))


def _transfer(page: Page, report: DiagnosisReport) -> None:
    t = report.transfer
    page.heading(f"On another series: {_name(t['file'])}", anchor="transfer")
    fb, fr = t["final"]["base_mm"], t["final"]["refit_mm"]
    kb, kr = t["kinematic"]["base_mm"], t["kinematic"]["refit_mm"]
    page.para(esc(f"The final and the kinematic model taken to {t['file']} the two ways a calibration travels: "
                  f"only the base pose re-estimated on {t['n_base']} of its poses (a new tracker set-up), or the "
                  f"geometry refitted on {t['n_refit']} of them with the findings frozen (a new series of the same "
                  "robot); the other poses judge."))
    page.table(["taken there with", "kinematic mean mm", "final mean mm", "final against kinematic"],
               [["base pose re-estimated", num(kb), num(fb), gain(kb - fb)],
                ["geometry refitted", num(kr), num(fr), gain(kr - fr)]], text_columns=(0, 3))
    ref = page.figure(partial(_transfer_plot, t), "fig-transfer",
                      f"Mean error on {_name(t['file'])}, kinematic and final model, both ways of taking them there.")
    rows = [[f.label(), gain(f.transfer["base_gain_mm"]), gain(f.transfer["refit_gain_mm"]), f.transfer["verdict"]]
            for f in report.findings if f.transfer and f.in_model]
    if rows:
        page.para(f"Each finding there ({ref} shows the whole model): the model with the finding against the same "
                  "model without it.")
        page.table(["finding", "base re-estimated", "geometry refitted", "verdict"], rows,
                   text_columns=(0, 1, 2, 3))


def _transfer_plot(t: dict):
    fig, ax = figure(5.6, 3.0)
    ax = ax[0][0]
    x = np.arange(2)
    w = 0.36
    ways = ["base pose re-estimated", "geometry refitted"]
    for k, (who, colour) in enumerate((("kinematic", BEFORE), ("final", AFTER))):
        vals = [t[who]["base_mm"], t[who]["refit_mm"]]
        ax.bars(x + (k - 1) * w, [w, w], vals, colour, label=f"{who} model", values=[f"{v:.3f}" for v in vals],
                titles=[f"{who} model, {way}: {v:.4f} mm" for way, v in zip(ways, vals)])
    ax.categories = ways
    ax.ylabel = "mean position error (mm)"
    ax.ymargin = 0.15
    ax.grid_x = False
    ticks(ax, x=False)
    legend_above(ax)
    return fig


def _periodograms(report: DiagnosisReport):
    pgs = report.periodograms
    ncols = 2 if len(pgs) > 3 else 1
    nrows = math.ceil(len(pgs) / ncols)
    fig, ax = figure(8.6, 1.45 * nrows + 0.9, nrows, ncols, sharex=True, sharey=True)
    in_model: dict[int, list[int]] = {}
    for f in report.findings:
        c = f.candidate
        if f.in_model and c.harmonic is not None:
            in_model.setdefault(c.joint, []).append(c.harmonic)
    for k, pg in enumerate(pgs):
        a = ax[k // ncols][k % ncols]
        for h in in_model.get(pg.joint, []):
            a.vline(h)
        a.line(pg.harmonics, pg.power, AFTER, 1.2)
        a.corner = f"joint {pg.joint}"
        ticks(a, n=5)
        if k % ncols == 0:
            a.ylabel = "share"
    for k in range(len(pgs), nrows * ncols):
        ax[k // ncols][k % ncols].visible = False
    for a in ax[-1]:
        a.xlabel = "harmonic (cycles per turn)"
    if len(pgs) % ncols:
        ax[-2][-1].show_xticklabels = True
        ax[-2][-1].xlabel = "harmonic (cycles per turn)"
    return fig


def _accuracy(page: Page, report: DiagnosisReport, poses, joints) -> None:
    from ..prediction import accuracy_map

    m = accuracy_map(report.final, poses.q if poses is not None else None, joints)
    ja, jb = m["joints"]
    page.heading("Where the model is accurate", anchor="accuracy")
    others = ", ".join(f"q{k + 1} {v:.0f} {u}" for k, (v, u) in enumerate(zip(m["others"], m["units"]))
                       if k + 1 not in (ja, jb))
    where = "the calibration poses' median" if poses is not None else "the middle of their ranges"
    caption = (f"Predicted uncertainty of the final model's tool point (rms 3-D error of the prediction, mm: the "
               f"parameters' covariance plus the GP compensator's predictive std) over joints {ja} and {jb}; the "
               f"other joints at {where} ({others})." + (" Dots: the calibration poses." if poses is not None
                                                            else ""))
    ref = page.figure(partial(_accuracy_plot, m, poses.lines if poses is not None else None), "fig-accuracy",
                      caption)
    lo, hi = float(np.min(m["std_mm"])), float(np.max(m["std_mm"]))
    page.para(f"{ref}: from {lo:.4f} mm to {hi:.4f} mm over the two joints' ranges. Where it is low a program can "
              "trust the model; where it is high, measure next (<code>plan-poses REPORT.json</code> picks the "
              "poses; <code>predict FINAL.json POSES.csv --std</code> gives it at any pose).")


def _accuracy_plot(m: dict, lines=None):
    fig, axes = figure(6.4, 4.2)
    ax = axes[0][0]
    ja, jb = m["joints"]
    # the grid refined 4 times (bilinear), its cells coloured in bands at round values (as filled contours)
    s = np.asarray(m["std_mm"], float)
    xg, yg = np.asarray(m["x"], float), np.asarray(m["y"], float)
    ua, ub = m["units"][ja - 1], m["units"][jb - 1]
    xf, yf = (np.linspace(g[0], g[-1], 4 * (len(g) - 1) + 1) for g in (xg, yg))
    xc, yc = (xf[:-1] + xf[1:]) / 2, (yf[:-1] + yf[1:]) / 2
    fine = np.array([np.interp(xc, xg, row) for row in s])
    fine = np.array([np.interp(yc, yg, col) for col in fine.T]).T
    lo, hi = float(np.min(s)), float(np.max(s))
    levels = bands(lo, hi, 12)
    ax.cells(xf, yf, fine, VIRIDIS, levels[0], levels[-1], levels=levels)
    ax.colorbar = (VIRIDIS, float(levels[0]), float(levels[-1]), "predicted uncertainty (mm)", levels)
    if m["measured"] is not None:
        q = np.asarray(m["measured"], float)
        titles = None
        if lines is not None and len(lines) == len(q):
            titles = [f"row {n}: q{ja} {a:.1f} {ua}, q{jb} {b:.1f} {ub}" for n, a, b in zip(lines, q[:, 0], q[:, 1])]
        ax.points(q[:, 0], q[:, 1], "#fff", 1.5, edge="#000", label="calibration poses", titles=titles,
                  legend_r=2.5)
        legend_above(ax)
    ax.xlabel, ax.ylabel = f"q{ja} ({ua})", f"q{jb} ({ub})"
    ticks(ax)
    return fig
