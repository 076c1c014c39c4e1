"""The HTML report of one calibration: errors before and after, residuals, parameters, what to act on."""

from __future__ import annotations

import math
from functools import partial

import numpy as np

from ..calibration import calibrate
from ..data._measurements import Measurements
from ..result import CalibrationResult, ErrorStats
from ._figures import AFTER, BEFORE, ecdf, figure, legend_above, ticks
from ._page import Page, Raw, esc, gain, model_label, num
from ._parameters import correlation_figure, parameter_table_html, strongest_pairs

AXES = ("x", "y", "z")


def calibration_html(result: CalibrationResult, data: Measurements, before: CalibrationResult | None = None,
                     before_label: str = "nominal model, base pose fitted", processes: int = 1,
                     validation: Measurements | None = None, progress=None) -> str:
    """A self-contained HTML report of a calibration.

    Parameters
    ----------
    result : CalibrationResult
        What :func:`casadical.calibrate` returned.
    data : Measurements
        The poses it was fitted to.
    before : CalibrationResult, optional
        The model to compare with; default the robot's nominal model with its
        base pose fitted to ``data`` (the error a calibration starts from).
    before_label : str
        What ``before`` is, in words.
    processes : int
        Ignored (kept so that existing calls work): the figures are written in this process, in milliseconds.
    validation : Measurements, optional
        Held-out poses: the errors of both models on them get a section of
        their own (without them, the errors ``result.validation`` holds, if any).
    progress : callable, optional
        Receives a line of text before and after the figures are drawn.

    Returns
    -------
    str
        One HTML document (inline CSS and SVG, no script, no network); every pose's mark in a figure has a
        hover title with its CSV line and its error in mm.
    """
    if before is None:
        before = calibrate(result.model.robot, data, "nominal", "lm", warn=False,
                           robust="huber" if result.loss.robust else "none", position_only=not result.full_pose)
    robot = result.model.robot.name
    page = Page(f"casadical calibration: {robot}, {result.model.spec}")
    r0, r1 = before.residuals(data) * 1000, result.residuals(data) * 1000
    n0, n1 = np.linalg.norm(r0, axis=1), np.linalg.norm(r1, axis=1)    # mm
    e0, e1 = ErrorStats.of(n0 / 1000), ErrorStats.of(n1 / 1000)

    page.heading(f"Calibration of {robot}", 1)
    drop = e0.mean_mm - e1.mean_mm
    page.para(f"Model {model_label(page, _short(result.model.spec), result.model.spec)} fitted to "
              f"{len(data)} poses of <code>{esc(data.path)}</code>: mean position error {e1.mean_mm:.4f} mm, "
              f"{gain(drop)} than the {esc(before_label)} ({e0.mean_mm:.4f} mm, "
              f"{100 * drop / e0.mean_mm:.0f} % less). These are errors on the poses the model was fitted to: "
              "judge a model on poses it never saw (<code>casadical predict</code>, <code>casadical "
              "diagnose</code>).", "lead")
    held_out = _held_out(result, before, before_label, validation)
    if held_out:
        page.para(held_out[0], "lead")
    page.pairs(_summary(result))

    page.heading("Errors before and after", anchor="errors")
    page.table(["model", "poses", "mean mm", "max mm", "std mm", "rms mm"],
               [[before_label, str(e0.n_poses), num(e0.mean_mm), num(e0.max_mm), num(e0.std_mm), num(e0.rms_mm)],
                [Raw("calibrated: " + model_label(page, _short(result.model.spec), result.model.spec)),
                 str(e1.n_poses), num(e1.mean_mm), num(e1.max_mm), num(e1.std_mm), num(e1.rms_mm)]])
    if result.has_orientation and before.has_orientation and data.has_orientation:
        a0, a1 = before.orientation_stats(data), result.orientation_stats(data)
        page.para("Orientation of the probe (angle between the measured and the predicted orientation; the "
                  "calibration weighed it against the position by their noise scales):")
        page.table(["model", "poses", "mean deg", "max deg", "std deg", "rms deg"],
                   [[before_label, str(a0.n_poses), num(a0.mean_deg), num(a0.max_deg), num(a0.std_deg),
                     num(a0.rms_deg)],
                    [Raw("calibrated: " + model_label(page, _short(result.model.spec), result.model.spec)),
                     str(a1.n_poses), num(a1.mean_deg), num(a1.max_deg), num(a1.std_deg), num(a1.rms_deg)]])
    ref = page.figure(partial(_distribution, n0, n1, before_label),
                      "fig-errors", "Distribution of the position error over the calibration poses, before "
                      "and after: histogram (left) and cumulative share of poses (right).")
    page.para(f"The whole distribution moves ({ref}): the median pose error goes from "
              f"{np.median(n0):.4f} mm to {np.median(n1):.4f} mm, "
              f"the worst from {e0.max_mm:.4f} mm to {e1.max_mm:.4f} mm.")

    if held_out:
        page.heading("Errors on the validation poses", anchor="validation")
        page.para(held_out[1])
        page.table(["model", "poses", "mean mm", "max mm", "std mm", "rms mm"], held_out[2])

    page.heading("Residuals per axis", anchor="residuals")
    ref_pose = page.figure(partial(_per_pose, data, r0, r1, before_label), "fig-axes",
                           "Measured minus predicted position along each axis of the measurement frame, per pose "
                           "in file order, before and after.")
    ref_joint = page.figure(partial(_per_joint, data, r1), "fig-joints",
                            "Residual of the calibrated model along each axis against each joint's reading. A "
                            "trend or a wave here is structure the model does not have (run casadical diagnose).")
    page.para(f"Drifts along the file (time) show in {ref_pose}; what depends on a joint's angle in {ref_joint}.")

    page.heading("Parameters", anchor="parameters")
    page.para("Angles in degrees, lengths in millimetres. Standard errors from the residual scale and the "
              "Jacobian at the solution; greyed rows are held at their value (not identifiable from these poses, "
              "or fixed on request). Each identified parameter is tested against its nominal value: t = deviation "
              "/ std, significant at 95 % when its p-value is below 0.05 (Student's t with the fit's degrees of "
              "freedom); rel. std = std / |deviation|; the 95 % interval is value &plusmn; t<sub>0.975</sub> std. "
              "<b>Highlighted rows are not significant</b>: these poses do not tell the deviation from zero.")
    parameter_table_html(page, result)

    if result.uncertainty is not None and len(result.uncertainty.names) >= 2:
        page.heading("Correlations of the free parameters", anchor="correlations")
        ref = page.figure(partial(correlation_figure, result), "fig-correlation",
                          "Correlation matrix of the identified parameters (red positive, blue negative). Pairs "
                          "near +1 or -1 are told apart poorly by these poses.")
        pairs = strongest_pairs(result)
        if pairs:
            page.para(f"The strongest pairs ({ref}); above 0.95 their individual values are uncertain, add poses "
                      "that move them differently:")
            page.table(["parameter", "with", "correlation"],
                       [[a, b, Raw(f"<b>{c:+.3f}</b>" if abs(c) > 0.95 else f"{c:+.3f}")] for a, b, c in pairs],
                       text_columns=(0, 1))
        else:
            page.para(f"No pair of parameters is correlated above 0.5 ({ref}).")

    page.heading("Poses the robust loss set aside", anchor="outliers")
    if not result.loss.robust:
        page.para("Plain least squares: every pose weighs the same (<code>--robust none</code>).")
    elif not result.downweighted:
        page.para(f"None: every pose kept at least half its weight (noise scale {result.loss.sigma * 1000:.4f} mm "
                  f"per axis, pseudo-Huber linear beyond {result.loss.c:g} sigma).")
    else:
        # the calibration's verdict on them (casadical.stats._outliers): bad measurements, or structure the model lacks
        note = next((n for n in result.notes if n.startswith("the robust loss set aside")), "")
        verdict = note.split("): ", 1)[1] if "): " in note else "likely bad measurements"
        page.para(f"{len(result.downweighted)} pose(s) weighed less than half (noise scale "
                  f"{result.loss.sigma * 1000:.4f} mm per axis): {esc(verdict)}. These rows of "
                  f"<code>{esc(data.path)}</code>:")
        page.table(["file row", "residual mm", "weight"],
                   [[str(d["line"]), num(d["residual_mm"]), f"{d['weight']:.3f}"]
                    for d in sorted(result.downweighted, key=lambda d: -d["residual_mm"])])

    page.heading("Identifiability", anchor="identifiability")
    _identifiability(page, result)

    if result.notes:
        page.heading("Notes", anchor="notes")
        page.items([esc(n) for n in result.notes])
    return page.html(progress)


def _short(spec: str) -> str:
    """A model's label for tables: its first 37 characters when longer than 40 (the whole in a footnote)."""
    return spec if len(spec) <= 40 else spec[:37] + "..."


def _summary(result: CalibrationResult) -> list[tuple[str, str]]:
    out = []
    if result.solver is not None:
        s = result.solver
        out.append(("solver", esc(f"{result.solver_name}: {s.status}, {s.iterations} iterations, "
                                  f"{s.solve_time_s:.2f} s")))
    if result.loss.robust:
        out.append(("loss", esc(f"pseudo-Huber, noise scale {result.loss.sigma * 1000:.4f} mm per axis, linear "
                                f"beyond {result.loss.c:g} sigma")))
    else:
        out.append(("loss", "least squares"))
    if result.full_pose:
        out.append(("full pose", esc(f"positions and orientations, weighted by their noise scales from the data: "
                                     f"{result.loss.sigma * 1000:.4f} mm and {math.degrees(result.loss.sigma_rot):.4f}"
                                     " deg per axis")))
    if result.orientation is not None:
        out.append(("orientation", esc(f"mean {result.orientation.mean_deg:.4f} deg, max "
                                       f"{result.orientation.max_deg:.4f} deg on the calibration poses")))
    if result.uncertainty is not None:
        u = result.uncertainty
        out.append(("residual", esc(f"{u.sigma * 1000:.4f} mm per axis (rms), {u.dof} degrees of freedom")))
    if result.statistics is not None:
        f = result.statistics
        out.append(("fit statistics", esc(f"log-likelihood {f.log_likelihood:.2f} (residuals in mm), AIC "
                                          f"{f.aic:.2f}, BIC {f.bic:.2f}; {f.n_parameters} free parameters, "
                                          f"{f.n_equations} equations (compare models fitted to the same poses "
                                          "only)")))
    sessions = result.sessions
    for s in sessions or [None]:
        xyz, rpy = result.base_pose(s)
        at = "" if s is None or s == sessions[0] else f"@{s}"
        out.append((f"base pose{f', session {s}' if s else ''}",
                    esc("xyz " + ", ".join(f"{v * 1000:.3f}" for v in xyz) + " mm; roll, pitch, yaw "
                        + ", ".join(f"{math.degrees(v):.4f}" for v in rpy) + " deg")
                    + Page.ref("parameters", f" (the reference pose {'base0' if not at else 'of ' + s} moved by "
                                             f"base_x{at} .. base_yaw{at})")))
    free = sum(not p.fixed for p in result.parameters)
    out.append(("parameters", f"{free} identified of {len(result.parameters)}"))
    return out


def _held_out(result: CalibrationResult, before: CalibrationResult, before_label: str,
              validation: Measurements | None):
    """The lead sentence, the section's text and the table rows of the errors on validation poses; None without."""
    if validation is None:
        if result.validation is None:
            return None
        v = result.validation.stats
        rows = [["calibrated", str(v.n_poses), num(v.mean_mm), num(v.max_mm), num(v.std_mm), num(v.rms_mm)]]
        lead = (f"On {v.n_poses} validation poses it never saw (<code>{esc(result.validation.file)}</code>): mean "
                f"error {v.mean_mm:.4f} mm, rms {v.rms_mm:.4f} mm.")
        return lead, "The calibrated model on poses it was not fitted to.", rows
    v0, v1 = before.stats(validation), result.stats(validation)
    drop = v0.mean_mm - v1.mean_mm
    rows = [[label, str(v.n_poses), num(v.mean_mm), num(v.max_mm), num(v.std_mm), num(v.rms_mm)]
            for label, v in ((before_label, v0), ("calibrated", v1))]
    lead = (f"On {v1.n_poses} validation poses it never saw (<code>{esc(validation.path)}</code>): mean error "
            f"{v1.mean_mm:.4f} mm, {gain(drop)} than the {esc(before_label)} ({v0.mean_mm:.4f} mm).")
    text = ("Both models predict poses they were not fitted to (the base pose of each as fitted above): what "
            "to expect of the calibrated model elsewhere in the same workspace.")
    return lead, text, rows


def _identifiability(page: Page, result: CalibrationResult) -> None:
    ident = result.identifiability
    if ident is not None:
        page.para(esc(f"{len(ident.identifiable)} parameters identified from {ident.n_equations} equations; "
                      f"condition number {ident.condition_number:.3g} (Jacobian scaled by each parameter's "
                      "typical deviation, columns normalised)."))
    held = [p for p in result.parameters if p.fixed]
    if not held:
        page.para("Every parameter of the model was identified.")
        return
    page.para("What these poses cannot identify is held at its value, with the reason: a parameter that is "
              "structurally a combination of others is absorbed by them, so its own value stays nominal.")
    page.table(["parameter", "held because"], [[p.name, p.reason or "fixed on request"] for p in held],
               wrap_columns=(1,))


def _distribution(e0, e1, before_label: str):
    fig, ax = figure(8.6, 3.1, 1, 2)
    edges = np.histogram_bin_edges(np.concatenate([e0, e1]), bins=30)
    a, b = ax[0]
    for e, colour, alpha, label in ((e0, BEFORE, 0.55, before_label), (e1, AFTER, 0.65, "calibrated")):
        counts = np.histogram(e, edges)[0]
        a.bars(edges[:-1], np.diff(edges), counts, colour, alpha, label=label,
               titles=[f"{label}: {n} poses from {lo:.4f} to {hi:.4f} mm"
                       for n, lo, hi in zip(counts, edges[:-1], edges[1:])])
    a.xlabel, a.ylabel = "position error (mm)", "poses"
    a.grid_x = False
    ecdf(b, e0, e1, before_label, "calibrated")
    ticks(a)
    ticks(b)
    legend_above(a)
    return fig


def _per_pose(data: Measurements, r0, r1, before_label: str):
    fig, ax = figure(8.6, 5.6, 3, 1, sharex=True)
    x = data.lines
    n0, n1 = np.linalg.norm(r0, axis=1), np.linalg.norm(r1, axis=1)
    for k, name in enumerate(AXES):
        a = ax[k][0]
        for r, n, colour, alpha, label in ((r0, n0, BEFORE, 0.6, before_label), (r1, n1, AFTER, 0.8, "calibrated")):
            a.points(x, r[:, k], colour, 1.5, alpha, label=label, legend_r=3.0,
                     titles=[f"row {ln}: {name} {v:+.4f} mm, error {e:.4f} mm ({label})"
                             for ln, v, e in zip(x, r[:, k], n)])
        a.hline(0)
        a.ylabel = f"{name} residual (mm)"
        ticks(a, n=5)
    ax[-1][0].xlabel = f"row in {data.path.rsplit('/', 1)[-1]}"
    legend_above(ax[0][0])
    return fig


def _per_joint(data: Measurements, r1):
    n = data.n_joints
    fig, ax = figure(min(1.75 * n + 0.8, 12), 5.2, 3, n, sharey="row")
    q = data.q_deg
    err = np.linalg.norm(r1, axis=1)
    for j in range(n):
        unit = "mm" if data.prismatic[j] else "deg"
        for k, name in enumerate(AXES):
            a = ax[k][j]
            a.points(q[:, j], r1[:, k], AFTER, 1.25, 0.7,
                     titles=[f"row {ln}: q{j + 1} {v:.1f} {unit}, {name} {r:+.4f} mm, error {e:.4f} mm"
                             for ln, v, r, e in zip(data.lines, q[:, j], r1[:, k], err)])
            a.hline(0)
            ticks(a, x=False, n=4)
            ticks(a, y=False, n=3, least=3)
            if j == 0:
                a.ylabel = f"{name} residual (mm)"
        ax[-1][j].xlabel = f"q{j + 1} ({unit})"
    return fig
