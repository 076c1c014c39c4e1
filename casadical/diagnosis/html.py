"""A self-contained HTML report of a diagnosis, with inline SVG plots (no plotting library)."""

from __future__ import annotations

import html
import math

import numpy as np

from .run import DiagnosisReport

W, H, PAD, TOP = 560, 300, 58, 34


def _scale(v, lo, hi, a, b):
    return a + (b - a) * (v - lo) / (hi - lo if hi > lo else 1.0)


def _ticks(lo: float, hi: float, n: int = 5) -> list[float]:
    if not (math.isfinite(lo) and math.isfinite(hi)) or hi <= lo:
        return [lo]
    step = 10 ** math.floor(math.log10((hi - lo) / n))
    for m in (1, 2, 5, 10):
        if (hi - lo) / (step * m) <= n:
            step *= m
            break
    return list(np.arange(math.ceil(lo / step) * step, hi + step * 1e-9, step))


def _axes(xlo, xhi, ylo, yhi, xlabel, ylabel, title, xticks: bool = True) -> list[str]:
    out = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{W}" height="{H}" font-family="sans-serif" '
           f'font-size="11"><rect width="{W}" height="{H}" fill="white"/>',
           f'<text x="{W / 2}" y="14" text-anchor="middle" font-weight="bold">{html.escape(title)}</text>',
           f'<line x1="{PAD}" y1="{H - PAD}" x2="{W - 10}" y2="{H - PAD}" stroke="black"/>',
           f'<line x1="{PAD}" y1="{H - PAD}" x2="{PAD}" y2="{TOP}" stroke="black"/>',
           f'<text x="{W / 2}" y="{H - 10}" text-anchor="middle">{html.escape(xlabel)}</text>',
           f'<text x="12" y="{H / 2}" text-anchor="middle" transform="rotate(-90 12 {H / 2})">'
           f'{html.escape(ylabel)}</text>']
    for t in _ticks(xlo, xhi) if xticks else []:
        x = _scale(t, xlo, xhi, PAD, W - 10)
        out.append(f'<text x="{x:.1f}" y="{H - PAD + 14}" text-anchor="middle">{t:.4g}</text>')
    for t in _ticks(ylo, yhi):
        y = _scale(t, ylo, yhi, H - PAD, TOP)
        out.append(f'<text x="{PAD - 4}" y="{y + 4:.1f}" text-anchor="end">{t:.4g}</text>'
                   f'<line x1="{PAD}" y1="{y:.1f}" x2="{W - 10}" y2="{y:.1f}" stroke="#eee"/>')
    return out


def scatter(series: list[tuple[list, list, str, str]], xlabel: str, ylabel: str, title: str,
            lines: bool = False, lines_for: tuple[int, ...] = ()) -> str:
    """SVG scatter plot of ``(x, y, colour, legend)`` series; ``lines`` (or series in ``lines_for``) as lines."""
    xs = np.concatenate([np.asarray(s[0], float) for s in series])
    ys = np.concatenate([np.asarray(s[1], float) for s in series])
    xlo, xhi = float(xs.min()), float(xs.max())
    ylo, yhi = float(min(ys.min(), 0)), float(max(ys.max(), 0))
    if xhi == xlo:
        xlo, xhi = xlo - 1, xhi + 1
    out = _axes(xlo, xhi, ylo, yhi, xlabel, ylabel, title)
    for k, (x, y, colour, legend) in enumerate(series):
        pts = [(_scale(a, xlo, xhi, PAD, W - 10), _scale(b, ylo, yhi, H - PAD, TOP)) for a, b in zip(x, y)]
        if lines or k in lines_for:
            out.append(f'<polyline fill="none" stroke="{colour}" stroke-width="1.5" points="'
                       + " ".join(f"{a:.1f},{b:.1f}" for a, b in pts) + '"/>')
        else:
            out += [f'<circle cx="{a:.1f}" cy="{b:.1f}" r="2.2" fill="{colour}" fill-opacity="0.7"/>'
                    for a, b in pts]
        out.append(f'<rect x="{W - 170}" y="{26 + 14 * k}" width="10" height="10" fill="{colour}"/>'
                   f'<text x="{W - 155}" y="{35 + 14 * k}">{html.escape(legend)}</text>')
    return "\n".join(out + ["</svg>"])


def bars(labels: list[str], values: list[float], ylabel: str, title: str, colours: list[str]) -> str:
    hi = max(values) if values else 1.0
    out = _axes(0, len(values), 0, hi, "", ylabel, title, xticks=False)
    bw = (W - 10 - PAD) / max(len(values), 1)
    for k, (lab, v, c) in enumerate(zip(labels, values, colours)):
        x = PAD + k * bw + 4
        y = _scale(v, 0, hi, H - PAD, TOP)
        out.append(f'<rect x="{x:.1f}" y="{y:.1f}" width="{bw - 8:.1f}" height="{H - PAD - y:.1f}" fill="{c}"/>'
                   f'<text x="{x + (bw - 8) / 2:.1f}" y="{y - 3:.1f}" text-anchor="middle">{v:.3f}</text>'
                   f'<text x="{x + (bw - 8) / 2:.1f}" y="{H - PAD + 12}" text-anchor="end" font-size="9" '
                   f'transform="rotate(-35 {x + (bw - 8) / 2:.1f} {H - PAD + 12})">{html.escape(lab[:24])}</text>')
    return "\n".join(out + ["</svg>"])


def _short(step) -> str:
    """Bar label: what the step added."""
    c = step.candidate
    if c is None or c.cause == "geometric":
        return step.model
    abbrev = {"joint_compliance": "compliance", "joint_periodic": "periodic", "encoder_scale": "encoder",
              "backlash": "backlash", "thermal_expansion": "thermal", "drift": "drift",
              "unexplained": "black box"}[c.cause]
    parts = [abbrev] + ([f"j{c.joint}"] if c.joint else []) + ([f"h{c.harmonic}"] if c.harmonic else [])
    return "+" + " ".join(parts)


def render(report: DiagnosisReport) -> str:
    """The whole report as one HTML document."""
    esc = html.escape
    parts = ["<!DOCTYPE html><html><head><meta charset='utf-8'>",
             f"<title>casadical diagnosis: {esc(report.robot)}</title>",
             "<style>body{font-family:sans-serif;max-width:1200px;margin:auto;padding:1em}"
             "table{border-collapse:collapse}td,th{border:1px solid #ccc;padding:3px 8px;text-align:right}"
             "td:first-child{text-align:left}.no{color:#999}.fig{display:inline-block;margin:4px}</style>",
             "</head><body>", f"<h1>Diagnosis of {esc(report.robot)}</h1>",
             f"<p>Final model <b>{esc(report.final_model)}</b>: validation mean "
             f"{report.final_validation.mean_mm:.4f} mm, max {report.final_validation.max_mm:.4f} mm, "
             f"rms {report.final_validation.rms_mm:.4f} mm. Every number below is measured on validation "
             f"poses that were never fitted ({report.final_validation.n_poses} poses); run time "
             f"{report.time_s:.1f} s.</p>", "<h2>Steps</h2><table><tr><th>model</th><th>calibration rms mm</th>"
             "<th>validation mean mm</th><th>max mm</th><th>rms mm</th><th>accepted</th><th>why not</th></tr>"]
    for s in report.steps:
        cls = "" if s.accepted else " class='no'"
        parts.append(f"<tr{cls}><td>{esc(s.model)}</td><td>{s.calibration.rms_mm:.4f}</td>"
                     f"<td>{s.validation.mean_mm:.4f}</td><td>{s.validation.max_mm:.4f}</td>"
                     f"<td>{s.validation.rms_mm:.4f}</td><td>{'yes' if s.accepted else 'no'}</td>"
                     f"<td style='text-align:left'>{esc(s.reason)}</td></tr>")
    parts.append("</table>")
    acc = [s for s in report.steps if s.accepted]
    parts.append("<div class='fig'>" + bars([_short(s) for s in acc],
                                           [s.validation.mean_mm for s in acc], "validation mean (mm)",
                                           "validation mean error along the accepted steps",
                                           ["#4477aa"] * len(acc)) + "</div>")
    e0, e1 = report.plots["val_errors_nominal_mm"], report.plots["val_errors_final_mm"]
    idx = list(range(len(e0)))
    parts.append("<div class='fig'>" + scatter([(idx, e0, "#cc6677", "nominal"), (idx, e1, "#4477aa", "final")],
                                               "validation pose", "position error (mm)",
                                               "per-pose error before and after") + "</div>")
    parts.append("<h2>Findings</h2>")
    if not report.findings:
        parts.append("<p>No finding: the nominal model explains the data down to the noise.</p>")
    for f in report.findings:
        parts.append(f"<h3>{esc(f.candidate.label())}: validation mean &minus;{f.gain_mm:.4f} mm</h3>"
                     f"<p>{esc(f.evidence)}</p>")
        for a in f.ambiguous_with:
            parts.append(f"<p><i>Ambiguous with {esc(a['label'])}</i> (same residual, similarity "
                         f"{a['similarity']}): {esc(a['tell_apart'])}.</p>")
        if f.plot:
            pl = f.plot
            if "partial" in pl:
                fig = scatter([(pl["x"], pl["partial"], "#4477aa", "partial residual"),
                               (pl["curve_x"], pl["curve_y"], "#cc3311", "fitted effect")],
                              pl["xlabel"], pl["ylabel"], "calibration residual against its cause",
                              lines_for=(1,))
            else:
                fig = scatter([(pl["x"], pl["before"], "#cc6677", "before"),
                               (pl["x"], pl["after"], "#4477aa", "after")],
                              pl["xlabel"], pl["ylabel"], "calibration residual against its cause")
            parts.append("<div class='fig'>" + fig + "</div>")
    if report.periodograms:
        parts.append("<h2>Periodograms of the last residual</h2><p>Fraction of each joint's projected "
                     "residual explained by one harmonic of its reading.</p>")
        colours = ["#4477aa", "#ee6677", "#228833", "#ccbb44", "#66ccee", "#aa3377", "#bbbbbb"]
        parts.append("<div class='fig'>" + scatter(
            [(pg.harmonics.tolist(), pg.power.tolist(), colours[k % 7], f"joint {pg.joint}")
             for k, pg in enumerate(report.periodograms)], "harmonic (cycles per turn)",
            "fraction of residual", "periodogram", lines=True) + "</div>")
    if report.notes:
        parts.append("<h2>Notes</h2><ul>" + "".join(f"<li>{esc(n)}</li>" for n in report.notes) + "</ul>")
    parts.append("</body></html>")
    return "\n".join(parts)
