"""Stages ``note_set_aside`` and ``assemble_result``: the poses the robust loss set aside, and the result.

A pose whose robust weight falls below :data:`DOWNWEIGHT_REPORT` is named by
its file line: a likely bad measurement, unless the poses set aside share
structure the model lacks (:mod:`casadical.stats._outliers`); the result holds the model, the
parameters, the errors overall and per session, the coverage of the joint
ranges and the fit statistics.
"""

from __future__ import annotations

import math

import numpy as np

from ..data._measurements import session_index
from ..errors import listing
from ..result import CalibrationResult, ErrorStats, touch_stats
from ..stats import _outliers as set_aside
from ..stats._coverage import Coverage
from ..stats._significance import FitStatistics
from ._state import CalibrationRun

#: a pose whose robust weight falls below this is reported as set aside
DOWNWEIGHT_REPORT = 0.5


def note_set_aside(run: CalibrationRun) -> None:
    """Sets ``down`` (file, line, residual and weight of each pose set aside, worst first) and notes them."""
    if not run.loss.robust:
        return
    data, lin, norms, full_pose, loss = run.data, run.lin, run.norms, run.full_pose, run.problem.loss
    down = run.down
    for i in np.argsort(-(lin.u2 if full_pose else norms)):
        if lin.weights[i] >= DOWNWEIGHT_REPORT:
            break
        down.append({"line": int(data.lines[i]), "residual_mm": float(norms[i] * 1000),
                     "weight": float(lin.weights[i]),
                     **({"file": data.file(i)} if data.sources is not None else {})})
        if full_pose:
            down[-1]["orientation_deg"] = math.degrees(float(np.linalg.norm(lin.r_rot[i])))
    if down:
        scale = (f"{loss.sigma * 1000:.4f} mm" if not full_pose else
                 f"{loss.sigma * 1000:.4f} mm and {math.degrees(loss.sigma_rot):.4f} deg")
        # bad measurements, or poses that share structure the model lacks (casadical.stats._outliers)
        shared = set_aside.of_model(run.model, run.params.values, run.base0, data, lin.weights < DOWNWEIGHT_REPORT,
                                    run.cov) if not data.touches else None
        run.notes.append(f"the robust loss set aside {len(down)} pose(s) of {data.path} whose residual exceeds "
                         f"{math.sqrt(DOWNWEIGHT_REPORT ** -2 - 1) * run.loss.c:.1f} times the noise scale of "
                         f"{scale} (rows "
                         + listing([f"{d['file']}:{d['line']}" if "file" in d else d["line"] for d in down], 10)
                         + "): " + (shared.text() + "; diagnose looks for its cause" if shared is not None and
                                    shared.structured else (shared.text() + "; " if shared is not None else "")
                                    + "check them, or pass --robust none to fit them anyway"))


def assemble_result(run: CalibrationRun) -> None:
    """Sets ``result``: the calibration, its errors on the poses (overall, per session, orientation)."""
    data, norms, unc = run.data, run.norms, run.uncertainty
    by_session = {s: ErrorStats.of(norms[idx]) for s, idx in session_index(data).items()} \
        if len(data.session_names) > 1 else {}
    coverage = Coverage.of(data.q_deg, units=run.model.robot.units)
    touch = touch_stats(data.layout, run.model.predict(data.q, run.params.values, run.cov, run.base0)) \
        if data.touches else {}
    result = CalibrationResult(run.model, run.params, run.base0, run.solution, run.solver_name, run.ident, unc,
                               ErrorStats.of(norms, touch), run.notes, run.problem.loss, run.down, coverage,
                               by_session=by_session, statistics=FitStatistics.of(unc),
                               tool0=run.tool0 if run.model.orientation else None)
    result.unobservable = list(run.unobservable)
    # touches alone: nothing measures the robot against the world; its points are in its base frame
    result.frame = "base" if data.touches and data.touching.all() else "measurement"
    if result.has_orientation and data.has_orientation:
        result.orientation = result.orientation_stats(data)
    result.full_pose = run.full_pose
    run.result = result
