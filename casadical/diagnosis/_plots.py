"""The data behind each finding's figure: the residual against the variable its cause depends on."""

from __future__ import annotations

from typing import Callable

import numpy as np

from ..data._measurements import Measurements
from ..result import CalibrationResult
from ._candidates import Candidate
from ._periodogram import joint_errors

ARCSEC = np.degrees(1.0) * 3600


def residual_plot(cand: Candidate, before: CalibrationResult, after: CalibrationResult, d: Measurements,
                  view: Callable[[], tuple] | None = None) -> dict:
    """Joint causes: the partial residual (what the fit leaves plus the fitted effect, as the joint's
    angle error) with the fitted effect as a curve. Thermal expansion, drift and warm-up: the residual before and
    after. What a figure plots against is its cause's (:meth:`~casadical.terms._cause.Cause.figure`).

    ``view``: a function giving :func:`joint_view` of ``after`` on ``d`` (shared by the figures of one model).
    """
    m, p = after.model, after.parameters
    linear = cand.joint is not None and m.robot.joints[cand.joint - 1].prismatic
    fig = cand.kind.figure(cand, d, m, p, linear)
    if fig is None:             # a cause of one's own that acts on no joint: the errors before and after
        ys = [np.linalg.norm(r.residuals(d), axis=1) * 1000 for r in (before, after)]
        return {"x": np.asarray(d.rows, float).tolist(), "before": ys[0].tolist(), "after": ys[1].tolist(),
                "xlabel": "row (measurement order)", "ylabel": "position error (mm)", **_hover(after, d)}
    x = fig["x"]
    if "effect" not in fig:     # the residual before and after: its norm, or along the cause's direction
        if fig["along"] is None:
            ys = [np.linalg.norm(r.residuals(d), axis=1) * 1000 for r in (before, after)]
            ylabel = "position error (mm)"
        else:
            v = np.array([p[n].value for n in cand.parameter_names()])
            u = v / max(np.linalg.norm(v), 1e-300)
            ys = [r.residuals(d) @ u * 1000 for r in (before, after)]
            ylabel = f"residual along the {fig['along']} (mm)"
        return {"x": np.asarray(x, float).tolist(), "before": ys[0].tolist(), "after": ys[1].tolist(),
                "xlabel": fig["xlabel"], "ylabel": ylabel, **_hover(after, d)}
    j, effect = cand.joint, fig["effect"]
    resid, directions = view() if view else joint_view(after, d)
    s, _ = joint_errors(resid, directions[:, :, j - 1])
    order = np.argsort(x)
    if linear:      # a linear axis: its error along it (mm) against its position (mm)
        return {"x": np.asarray(x, float).tolist(), "partial": ((s + effect) * 1000.0).tolist(),
                "curve_x": np.asarray(x, float)[order].tolist(), "curve_y": (effect[order] * 1000.0).tolist(),
                "xlabel": fig["xlabel"], "ylabel": f"axis {j} position error: residual + fitted effect (mm)"}
    return {"x": np.asarray(x, float).tolist(), "partial": ((s + effect) * ARCSEC).tolist(),
            "curve_x": np.asarray(x, float)[order].tolist(), "curve_y": (effect[order] * ARCSEC).tolist(),
            "xlabel": fig["xlabel"], "ylabel": f"joint {j} angle error: residual + fitted effect (arcsec)",
            "lines": d.lines.tolist(), "error_mm": (np.linalg.norm(resid, axis=1) * 1000).tolist()}


def _hover(res: CalibrationResult, d: Measurements) -> dict:
    """What a figure's hover titles give of each pose: its CSV line and the position error of ``res`` (mm)."""
    return {"lines": d.lines.tolist(), "error_mm": (np.linalg.norm(res.residuals(d), axis=1) * 1000).tolist()}


def joint_view(res: CalibrationResult, d: Measurements) -> tuple[np.ndarray, np.ndarray]:
    """Residuals of ``res`` on ``d`` (measured minus predicted, (N, 3)) and how the tool point moves with
    each joint's angle ((N, 3, n): the exact direction of a joint angle error, as the periodograms use it); rows
    that touch: from what they touched (:mod:`casadical.rows`)."""
    m, p = res.model, res.parameters
    xyz, _, directions = m.predict_angle_jacobian(d.q, p.values, m.covariates(d), res.base0)
    return -d.layout.residuals(xyz), directions
