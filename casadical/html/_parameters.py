"""The parameter table and the correlation figure, shared by both reports."""

from __future__ import annotations

import math

import numpy as np

from ..result import CalibrationResult
from ._figures import figure
from ._page import Page, esc, sig
from ._svg import RDBU


def base_reference(page: Page, result: CalibrationResult) -> None:
    """What the ``base_*`` rows are relative to: each session's reference pose, and the base pose they give."""
    sessions = result.sessions

    def pose(xyz, rpy) -> str:
        return (f"xyz {', '.join(f'{v * 1000:.3f}' for v in xyz)} mm, roll, pitch, yaw "
                f"{', '.join(f'{math.degrees(v):.4f}' for v in rpy)} deg")

    entries = []
    for s in sessions or [None]:
        at = "" if s is None or s == sessions[0] else f"@{s}"
        name = "<code>base0</code>" if not at else f"the reference of session {esc(s)}"
        entries.append((f"session {esc(s)}: " if s else "") + f"<code>base_x{at}</code> .. <code>base_yaw{at}</code> "
                       f"deviate from {name}: {pose(*result.base_reference(s))}; the base pose they give: "
                       f"<b>{pose(*result.base_pose(s))}</b>")
    lead = ("The base parameters are deviations from a reference pose of the robot base in the measurement frame "
            "(kept in the calibration JSON: the closed-form alignment the fit started from), never from the "
            "robot file's base. ")
    if len(entries) == 1:
        page.para(lead + entries[0] + ".")
    else:
        page.para(lead + "One per session:")
        page.items(entries)


def parameter_table_html(page: Page, result: CalibrationResult, fold: bool = False) -> None:
    """Every parameter: nominal, identified, deviation, std, its test against nominal, unit, and status.

    The test (:meth:`CalibrationResult.significance`): relative std, t and
    the 95 % interval (the p-values are in the JSON); a row that is not significant is highlighted and
    says so in its status. First the reference pose the ``base_*`` rows deviate from (:func:`base_reference`);
    ``fold``: the long table folded under a one-line summary (a click opens it).
    """
    base_reference(page, result)
    tests = result.significance()
    rows, classes = [], []
    for p in result.parameters:
        f = p.to_reading
        t = tests.get(p.name)
        if not p.fixed:
            status = "identified" if t is None or t.significant else "identified; not significant"
        elif p.identifiable is False:
            status = "not identifiable: " + (p.reason or "no reason recorded")
        else:
            status = "held" + (f": {p.reason}" if p.reason else "")
        rows.append([p.name, "" if p.joint is None else str(p.joint), sig(f(p.nominal), 6),
                     sig(f(p.value), 6), sig(f(p.value - p.nominal), 3) if not p.fixed else "",
                     sig(f(p.std), 2) if math.isfinite(p.std) else "", *_test_cells(t, f), p.reading_unit, status])
        classes.append("off" if p.fixed else "weak" if t is not None and not t.significant else "")
    header = ["parameter", "joint", "nominal", "identified", "deviation", "std", "rel. std", "t", "95 % interval",
              "unit", "status"]
    if fold:
        with page.folded(f"All {len(rows)} parameters: nominal, identified, deviation, std, test against nominal"):
            page.table(header, rows, text_columns=(0, 9), wrap_columns=(10,), row_classes=classes)
    else:
        page.table(header, rows, text_columns=(0, 9), wrap_columns=(10,), row_classes=classes)
    stiff = result.stiffness()
    if stiff:
        intervals = result.stiffness_intervals()
        page.para("Joint stiffness k = 1/c, from the identified compliance; its interval is 1/c over the "
                  "compliance's (unbounded above when that reaches 0):")
        srows, sclasses = [], []
        for j, (k, sk) in stiff.items():
            t = tests.get(f"c{j}")
            iv = intervals.get(j)
            srows.append([str(j), sig(k, 4) if math.isfinite(k) else "not positive", sig(sk, 2),
                          "\u2013" if iv is None else f"{sig(iv[0], 3)} \u2013 "
                          + (sig(iv[1], 3) if math.isfinite(iv[1]) else "unbounded"),
                          "" if t is None else "yes" if t.significant else "no"])
            sclasses.append("weak" if t is not None and not t.significant else "")
        page.table(["joint", "k (N m/rad)", "std (N m/rad)", "95 % interval (N m/rad)", "significant"], srows,
                   row_classes=sclasses)


def _test_cells(t, f) -> list[str]:
    """Relative std, t and the interval of one parameter's test (display units); empty when not tested."""
    if t is None:
        return ["", "", ""]
    rel = f"{100 * t.relative_std:.0f} %" if t.relative_std < 10 else "> 999 %"
    return [rel, f"{t.t:.2f}", f"{sig(f(t.ci[0]), 6)} \u2013 {sig(f(t.ci[1]), 6)}"]


def strongest_pairs(result: CalibrationResult, n: int = 12, floor: float = 0.5) -> list[tuple[str, str, float]]:
    """The ``n`` most correlated pairs of free parameters with |r| >= ``floor``, strongest first."""
    unc = result.uncertainty
    if unc is None or len(unc.names) < 2:
        return []
    c = unc.correlation
    i, j = np.triu_indices(len(c), 1)
    order = np.argsort(-np.abs(c[i, j]))
    return [(unc.names[i[k]], unc.names[j[k]], float(c[i[k], j[k]])) for k in order[:n]
            if abs(c[i[k], j[k]]) >= floor]


def correlation_figure(result: CalibrationResult):
    """Heat map of the correlation matrix of the free parameters (hover a cell: the pair and its correlation)."""
    unc = result.uncertainty
    n = len(unc.names)
    size = min(max(3.6, 0.16 * n + 1.8), 9.5)
    fig, ax = figure(size + 0.9, size)
    ax = ax[0][0]
    c = np.asarray(unc.correlation, float)
    edges = np.arange(n + 1, dtype=float)
    ax.cells(edges, edges, c, RDBU, -1.0, 1.0,
             titles=[[f"{unc.names[i]} and {unc.names[j]}: {c[i, j]:+.3f}" for j in range(n)] for i in range(n)])
    ax.row_names, ax.rotate, ax.square = list(unc.names), 90.0, True
    ax.tick_size = 8 if n <= 30 else 6.5
    ax.colorbar = (RDBU, -1.0, 1.0, "correlation")
    return fig
