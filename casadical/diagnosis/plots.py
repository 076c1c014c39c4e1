"""The data behind each finding's figure: the residual against the variable its cause depends on."""

from __future__ import annotations

from typing import Callable

import numpy as np

from ..data.measurements import Measurements
from ..result import CalibrationResult
from ..terms.mount_compliance import mount_moments
from ..terms.periodic import phase
from .candidates import Candidate
from .periodogram import joint_errors

ARCSEC = np.degrees(1.0) * 3600


def residual_plot(cand: Candidate, before: CalibrationResult, after: CalibrationResult, d: Measurements,
                  view: Callable[[], tuple] | None = None) -> dict:
    """Joint causes: the partial residual (what the fit leaves plus the fitted effect, as the joint's
    angle error) with the fitted effect as a curve. Thermal expansion, drift and warm-up: the residual before and
    after.

    ``view``: a function giving :func:`joint_view` of ``after`` on ``d`` (shared by the figures of one model).
    """
    if cand.cause in ("thermal_expansion", "drift", "warmup", "mount_compliance", "straightness", "carriage_angle"):
        if cand.cause in ("straightness", "carriage_angle"):
            x, xlabel = d.q[:, cand.joint - 1] * 1000.0, f"axis {cand.joint} position (mm)"
            ys = [np.linalg.norm(r.residuals(d), axis=1) * 1000 for r in (before, after)]
            ylabel = "position error (mm)"
        elif cand.cause == "thermal_expansion":
            x, xlabel = d.get("temperature_c"), "temperature (deg C)"
            ys = [np.linalg.norm(r.residuals(d), axis=1) * 1000 for r in (before, after)]
            ylabel = "position error (mm)"
        elif cand.cause == "mount_compliance":
            x = np.linalg.norm(mount_moments(after.model.robot, d.q, d.get("payload_kg"))[:, :2], axis=1)
            xlabel = "moment of the weights about the base, horizontal (N m)"
            ys = [np.linalg.norm(r.residuals(d), axis=1) * 1000 for r in (before, after)]
            ylabel = "position error (mm)"
        else:
            t = d.get("time_s")
            x, xlabel = (t, "time (s)") if t is not None else (d.rows, "row (measurement order)")
            v = np.array([after.parameters[n].value for n in cand.parameter_names()])
            u = v / max(np.linalg.norm(v), 1e-300)
            ys = [r.residuals(d) @ u * 1000 for r in (before, after)]
            ylabel = f"residual along the {'drift' if cand.cause == 'drift' else 'warm-up offset'} (mm)"
        return {"x": np.asarray(x, float).tolist(), "before": ys[0].tolist(), "after": ys[1].tolist(),
                "xlabel": xlabel, "ylabel": ylabel, **_hover(after, d)}
    if cand.joint is None:      # a cause of one's own that acts on no joint: the errors before and after
        ys = [np.linalg.norm(r.residuals(d), axis=1) * 1000 for r in (before, after)]
        return {"x": np.asarray(d.rows, float).tolist(), "before": ys[0].tolist(), "after": ys[1].tolist(),
                "xlabel": "row (measurement order)", "ylabel": "position error (mm)", **_hover(after, d)}
    j, m, p = cand.joint, after.model, after.parameters
    cov = m.covariates(d)
    resid, directions = view() if view else joint_view(after, d)
    s, _ = joint_errors(resid, directions[:, :, j - 1])
    q = d.q[:, j - 1]
    value = p[cand.parameter_names()[0]].value
    if m.robot.joints[j - 1].prismatic:      # a linear axis: its error along it (mm) against its position (mm)
        if cand.cause == "joint_periodic":
            sn, cs = (p[n].value for n in cand.parameter_names())
            arg = phase(m.robot, j, cand.harmonic * q)
            effect = sn * np.sin(arg) + cs * np.cos(arg)
            x = np.degrees(arg) % 360.0
            xlabel = f"phase of {cand.harmonic} cycles per metre of axis {j} (deg)"
        elif cand.cause == "backlash" and cand.source == "motion":
            x = d.moves[:, j - 1]
            effect, xlabel = -value * x, f"direction of the last move of axis {j}"
        elif cand.cause == "backlash":
            x = m.torques(d.q, p.values, cov)[:, j - 1]
            effect, xlabel = value * np.sign(x), f"force of gravity along axis {j} (N)"
        else:
            effect, x, xlabel = value * q, q * 1000.0, f"axis {j} position (mm)"
        order = np.argsort(x)
        return {"x": np.asarray(x, float).tolist(), "partial": ((s + effect) * 1000.0).tolist(),
                "curve_x": np.asarray(x, float)[order].tolist(), "curve_y": (effect[order] * 1000.0).tolist(),
                "xlabel": xlabel, "ylabel": f"axis {j} position error: residual + fitted effect (mm)"}
    if cand.cause == "joint_periodic":
        sn, cs = (p[n].value for n in cand.parameter_names())
        effect = sn * np.sin(cand.harmonic * q) + cs * np.cos(cand.harmonic * q)
        # folded by the harmonic, h cycles per turn line up into one sinusoid
        x = np.degrees(cand.harmonic * q) % 360.0
        xlabel = f"phase of {cand.harmonic} cycles per turn of joint {j} (deg)"
    elif cand.cause == "encoder_scale":
        effect, x, xlabel = value * q, np.degrees(q), f"joint {j} reading (deg)"
    elif cand.cause == "joint_coupling":
        k = cand.source_joint
        effect, x, xlabel = value * d.q[:, k - 1], np.degrees(d.q[:, k - 1]), f"joint {k} reading (deg)"
    elif cand.cause == "backlash" and cand.source == "motion":
        x = d.moves[:, j - 1]
        effect, xlabel = value * x, f"direction of the last move of joint {j}"
    else:
        x = m.torques(d.q, p.values, cov)[:, j - 1]
        xlabel = f"gravity torque at joint {j} (N m)"
        effect = {"joint_compliance": value * x, "nonlinear_stiffness": value * x ** 3}.get(
            cand.cause, value * np.sign(x))
    order = np.argsort(x)
    return {"x": np.asarray(x, float).tolist(), "partial": ((s + effect) * ARCSEC).tolist(),
            "curve_x": np.asarray(x, float)[order].tolist(), "curve_y": (effect[order] * ARCSEC).tolist(),
            "xlabel": xlabel, "ylabel": f"joint {j} angle error: residual + fitted effect (arcsec)",
            "lines": d.lines.tolist(), "error_mm": (np.linalg.norm(resid, axis=1) * 1000).tolist()}


def _hover(res: CalibrationResult, d: Measurements) -> dict:
    """What a figure's hover titles give of each pose: its CSV line and the position error of ``res`` (mm)."""
    return {"lines": d.lines.tolist(), "error_mm": (np.linalg.norm(res.residuals(d), axis=1) * 1000).tolist()}


def joint_view(res: CalibrationResult, d: Measurements) -> tuple[np.ndarray, np.ndarray]:
    """Residuals of ``res`` on ``d`` (measured minus predicted, (N, 3)) and how the tool point moves with
    each joint's angle ((N, 3, n): the exact direction of a joint angle error, as the periodograms use it)."""
    m, p = res.model, res.parameters
    xyz, _, directions = m.predict_angle_jacobian(d.q, p.values, m.covariates(d), res.base0)
    return d.xyz - xyz, directions
