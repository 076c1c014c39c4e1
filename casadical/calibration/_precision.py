"""Stage ``estimate_precision``: how well the poses determine each parameter, and what is not significant.

Standard errors from sigma^2 A^-1 at the solution (A: the loss's
Gauss-Newton matrix; :func:`casadical.stats._uncertainty.from_normal`), with notes
on strong correlations and parameters at a bound
(:func:`casadical.stats._uncertainty.warn_problems`) and on terms whose parameters
the poses do not determine (:func:`casadical.stats._significance.warn_not_significant`).
"""

from __future__ import annotations

import math
import warnings

import numpy as np

from ..stats._significance import warn_not_significant
from ..stats._uncertainty import from_normal, warn_problems
from ._state import CalibrationRun


def estimate_precision(run: CalibrationRun) -> None:
    """Sets ``lin``, ``norms`` (each pose's residual, m), ``uncertainty`` and every parameter's std."""
    problem, params = run.problem, run.params
    lin = problem.linearize(problem.values_from_x(run.solution.x))
    norms = np.linalg.norm(lin.r, axis=1)
    # full pose: the orientation rows count as equations, in position units (weighted by k)
    unc = from_normal(lin.A, float(lin.weights @ (lin.u2 if run.full_pose else norms ** 2)),
                      run.equations, problem.scale, [params.names[i] for i in problem.free])
    for n, s in zip(unc.names, unc.std):
        params[n].std = float(s)
    for i in np.flatnonzero(~params.free):
        p = params.items[i]
        if p.name not in run.kept:
            p.std = 0.0 if p.identifiable is not False else math.nan
    with warnings.catch_warnings():
        if not run.options.warn:
            warnings.simplefilter("ignore")
        run.notes += warn_problems(unc, params, expected=run.expected)
        run.notes += warn_not_significant(run.model, params, unc.dof)   # a term the poses do not determine
    run.lin, run.norms, run.uncertainty = lin, norms, unc
