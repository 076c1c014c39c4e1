"""Stage ``solve_parameters``: the solve, the robust loss's noise scale, and what the fit tells apart.

With the robust loss the noise scale is re-estimated from the residuals
until it settles (:func:`solve_robust`; full pose: both scales, which weigh
the position and orientation parts, with either loss). A parameter the
nominal model confounds with others but the fitted terms tell apart
(:func:`separated`) is freed and the problem solved again.

A large calibration (:data:`LARGE_POSES` poses or more) takes the same
steps with fewer linearisations of every pose (each costs about 0.7 s at
200,000 poses): every solve starts warm, the first from the solution of
the same solve on a subsample of the poses (:data:`SUBSAMPLE_POSES`, every
k-th), each later one from the last solution (IPOPT with the small barrier
of the hand-over from Levenberg-Marquardt; Levenberg-Marquardt with little
damping, stopped once its next step is below a hundredth of every
parameter's standard error). Only the starts differ: the answer is the
full procedure's to the solvers' tolerance (:func:`solve_robust`;
``tests/calibration/test_large.py`` compares the two procedures).
"""

from __future__ import annotations

import math
from dataclasses import fields, replace

import numpy as np

from ..errors import ConvergenceWarning, IdentifiabilityError, SolverError
from ..problem import CalibrationProblem, measured_points
from ..runtime._chunks import pose_chunks
from ..solvers import Ipopt, SolverResult, make_solver
from ..solvers._ipopt import HANDOVER
from ..stats._identifiability import Identifiability, triangular_factor
from ..terms._geometric import Geometric
from ..terms._tool_orientation import ToolOrientation
from ._state import CalibrationRun

#: re-estimates of the robust loss's noise scale at most
ROBUST_LOOPS = 6
#: from this many poses the noise-scale loop starts on a subsample and later solves start IPOPT warm (module
#: docstring); below it every solve is as it was, so that smaller calibrations give their results to the bit
LARGE_POSES = 50_000
#: the subsample's size (every k-th pose): its robust loop costs about as much as one linearisation of
#: 200,000 poses, and its solution is within a few of the full fit's standard errors of it
SUBSAMPLE_POSES = 10_000
#: Levenberg-Marquardt's initial damping from a warm start (its default: 1e-5)
WARM_LAM0 = 1e-10
#: a warm Levenberg-Marquardt solve stops once its next step is below this share of every parameter's standard
#: error (``LevenbergMarquardt.std_tol``): near the optimum its Gauss-Newton step is the distance to it
STD_TOL = 0.01
#: settings IPOPT shares with Levenberg-Marquardt, passed on by ``solver="auto"``
IPOPT_FIELDS = {f.name for f in fields(Ipopt) if not f.name.startswith("_")}
#: a structural combination of the nominal model is identified when its std is below this share of its scale
SEPARATED_STD = 0.1


def _solve(problem: CalibrationProblem, x0: np.ndarray, solver: str, opts: dict, warm: bool = False):
    """One solve from ``x0``: the result and the solver's name (``auto``: LM, then IPOPT if a bound is crossed).

    ``warm``: ``x0`` is near the solution (a solution of a subsample, or of the same problem at another noise
    scale or with fewer parameters free): IPOPT starts with the small barrier of :data:`HANDOVER` (the user's
    own IPOPT options win); the other solvers start from ``x0`` in any case."""
    if warm and solver == "ipopt":
        opts = {**opts, "options": {**HANDOVER, **opts.get("options", {})}}
    elif warm and solver in ("lm", "auto"):
        # near the solution Levenberg-Marquardt's first steps should be Gauss-Newton's: its default damping
        # (1e-5 of the diagonal) held the parameters freed by the separation check (nearly collinear with
        # others) to steps of a few standard errors, 8 linearisations of every pose instead of 3
        opts = {"lam0": WARM_LAM0, "std_tol": STD_TOL, **opts}
    elif warm and solver == "gn":
        opts = {"std_tol": STD_TOL, **opts}
    if solver == "auto":
        res = make_solver("lm", **opts).solve(problem, x0)
        lo, hi = problem.bounds_x()
        if np.any(res.x < lo) or np.any(res.x > hi):
            lm_time = res.solve_time_s
            shared = {k: v for k, v in opts.items() if k in IPOPT_FIELDS}   # --max-iter holds for both
            # from LM's solution only the bounds are left to do: a small barrier (3-5 iterations, not 10-16)
            res = make_solver("ipopt", **{"options": dict(HANDOVER), **shared}).solve(problem, res.x)
            res.solve_time_s += lm_time
            return res, "levenberg-marquardt+ipopt"
        return res, "levenberg-marquardt"
    s = make_solver(solver, **opts)
    return s.solve(problem, x0), s.name


def subsample(problem: CalibrationProblem, n: int) -> CalibrationProblem:
    """The problem on every k-th pose (at least ``n`` poses): the same model, parameters and loss."""
    s = slice(0, problem.n_poses, max(problem.n_poses // n, 1))
    if problem.layout is not None:      # touches: a group's rows make each one's residual; small data anyway
        return problem
    return replace(problem, params=problem.params.copy(), q=problem.q[s], xyz=problem.xyz[s], cov=problem.cov[s],
                   rot=None if problem.rot is None else problem.rot[s])


def _subsample_fit(problem: CalibrationProblem, x: np.ndarray, solver: str, opts: dict):
    """The solve on a subsample (:data:`SUBSAMPLE_POSES`) at the problem's loss, a start for the same solve on
    every pose (None if it fails: then that solve starts where it would have; a poor start costs iterations,
    never the answer).

    The subsample's problem (and the Jacobians it keeps, :data:`casadical.problem.MEMO_NUMBERS`) goes with
    this call."""
    try:
        res, _ = _solve(subsample(problem, SUBSAMPLE_POSES), x, solver, opts)
    except SolverError:
        return None
    return res if np.all(np.isfinite(res.x)) else None


def _new_scale(problem: CalibrationProblem, x: np.ndarray):
    """The robust loss with its noise scale(s) estimated at ``x`` on every pose, and the largest relative
    change from the problem's."""
    if problem.full_pose:   # each kind's own robust scale: they weigh the two parts
        rp, ro = problem.residual_norms(problem.values_from_x(x))
        new = problem.loss.with_scales_from(rp, ro)
        return new, max(abs(new.sigma / problem.loss.sigma - 1), abs(new.sigma_rot / problem.loss.sigma_rot - 1))
    norms = np.linalg.norm(problem.residuals(problem.values_from_x(x)).reshape(-1, 3), axis=1)
    new = problem.loss.with_sigma_from(norms)
    return new, abs(new.sigma / problem.loss.sigma - 1)


def solve_robust(problem: CalibrationProblem, x: np.ndarray, solver: str, opts: dict, estimate_scale: bool,
                 scale_at: np.ndarray | None = None, warm: bool = False):
    """Solve from ``x``; with ``estimate_scale``, re-estimate the robust loss's noise scale until it settles
    (changes by less than 5 % from one solution to the next; first at ``scale_at``, default ``x``).

    A large problem (:data:`LARGE_POSES`) takes the same steps, each solve on every pose started warm: the
    first from the solution of the same solve on a subsample, each later one from the last solution. Only the
    starts differ, so the solutions, and the noise scales estimated at them, are the full procedure's to the
    solver's tolerance (Levenberg-Marquardt's ``std_tol``: a hundredth of each parameter's standard error).
    A subsample's solution standing for the first solve's would not do: where the model misfits (YS100
    kinematic on a compliant arm, 200,000 poses) the noise scale estimated there differed by 0.5 %, the loop
    then stopped one solve later (a change of 5.2 % against the full procedure's 4.9 %) and the parameters
    moved by up to 1.6 standard errors. ``warm``: ``x`` is already near the solution."""
    res, name, solve_time, setup_time = None, "", 0.0, 0.0
    at = x if scale_at is None else scale_at
    large = problem.n_poses >= LARGE_POSES
    for k in range(ROBUST_LOOPS if estimate_scale else 1):
        if estimate_scale:
            new, change = _new_scale(problem, at)
            if res is not None and change < 0.05:
                break
            problem.loss = new
        if k == 0 and large and not warm:   # a start near the first solve's solution
            first = _subsample_fit(problem, x, solver, opts)
            if first is not None:
                x, warm = first.x, True
                solve_time, setup_time = first.solve_time_s, first.setup_time_s
        res, name = _solve(problem, x, solver, opts, warm)
        warm = warm or large   # the next solve starts from this one's solution
        solve_time += res.solve_time_s
        setup_time += res.setup_time_s
        x = at = res.x
    res.solve_time_s, res.setup_time_s = solve_time, setup_time
    return res, name


def separated(problem: CalibrationProblem, values: np.ndarray, ident: Identifiability) -> list[str]:
    """Parameters fixed as combinations of others at the nominal values that the fit tells apart well.

    The structural analysis runs at nominal values, where every compliance
    is zero; a fitted compliance can break a combination (tilting joint 1
    changes the gravity torques, which moving the base does not). Such a
    parameter is freed when its column, beyond what the free columns span,
    determines it to ``SEPARATED_STD`` of its typical size at the noise of
    the fit.
    """
    model, params = problem.model, problem.params
    cands = [u.name for u in ident.unidentifiable if u.confounded_with]
    if not cands or all(isinstance(t, (Geometric, ToolOrientation)) for t in model.terms):
        return []
    f = problem.free
    cols = np.concatenate([f, [params.index(n) for n in cands]])
    scale = params.scales[cols]
    ssr = [0.0]

    def blocks():   # weighted, scaled Jacobian columns (free ones first), pose chunk by pose chunk
        for s in pose_chunks(problem.n_poses):
            r, J, _ = problem.weighted_jacobian(values, s)
            u2 = np.einsum("ij,ij->i", r, r)
            w = problem.loss.weight(u2)
            ssr[0] += float(w @ u2)
            yield J[:, :, cols] * scale * np.sqrt(w)[:, None, None]

    R = triangular_factor(blocks(), len(cols))
    sigma = math.sqrt(ssr[0] / max(problem.equations - len(f), 1))
    out = []
    for j, name in enumerate(cands):
        perp = float(np.linalg.norm(R[len(f):, len(f) + j]))     # the column beyond the free columns' span
        if perp > 0 and sigma / perp < SEPARATED_STD:
            out.append(name)
    return out


def _free_separated(run: CalibrationRun, problem: CalibrationProblem, res, name: str):
    """Free what the fit tells apart (:func:`separated`) and solve again from the fit; the final solve."""
    values = problem.values_from_x(res.x)
    freed = separated(problem, values, run.ident)
    partners = {u.name: u.confounded_with for u in run.ident.unidentifiable if u.name in freed}
    if not partners:
        return problem, res, name
    params = run.params
    run.expected = frozenset(frozenset((n, c)) for n, cs in partners.items() for c in cs)
    params.values = values
    run.ident.free(list(partners), params)
    fitted = [t.spec() for t in run.model.terms[1:] if not isinstance(t, ToolOrientation)]
    run.notes.append(f"{', '.join(partners)}: a combination of other parameters in the nominal model, but "
                     f"the fitted terms ({', '.join(fitted)}) tell them apart on "
                     "these poses (std below a tenth of the typical size): identified; they stay strongly "
                     f"correlated with {', '.join(sorted({c for cs in partners.values() for c in cs}))}")
    first = res
    problem = CalibrationProblem(run.model, params, run.data.q, measured_points(run.data), run.cov, run.base0,
                                 problem.loss, run.rot, problem.layout)
    res, name = solve_robust(problem, problem.x_from_values(params.values), run.options.solver,
                             run.options.solver_options, False, warm=problem.n_poses >= LARGE_POSES)
    res.solve_time_s += first.solve_time_s
    res.setup_time_s += first.setup_time_s
    return problem, res, name


def solve_parameters(run: CalibrationRun) -> None:
    """Sets ``problem``, ``solution``, ``solver_name``, ``expected`` and the parameters' values; raises when
    no parameter is free or the cost is not finite, notes a solve that did not converge."""
    params, loss, opts = run.params, run.loss, run.options
    problem = CalibrationProblem(run.model, params, run.data.q, measured_points(run.data), run.cov, run.base0, loss,
                                 run.rot, run.data.layout if run.data.touches else None)
    if len(problem.free) == 0 and run.data.touches:
        # touches and the nominal model: its base pose is not seen, nothing is left to fit; judged as it is
        if loss.robust and not math.isfinite(loss.sigma):
            problem = replace(problem, loss=loss.with_sigma_from(problem.residual_norms(params.values)[0]))
        run.problem, run.solver_name = problem, "none"
        run.solution = SolverResult(np.zeros(0), problem.cost(params.values), True, "nothing to fit", 0, 0.0)
        return
    if len(problem.free) == 0:
        raise IdentifiabilityError("no free parameter left to identify")
    estimate = (not (math.isfinite(loss.sigma) and math.isfinite(loss.sigma_rot)) if run.full_pose
                else loss.robust and not math.isfinite(loss.sigma))
    res, name = solve_robust(problem, problem.x_from_values(params.values), opts.solver, opts.solver_options,
                             estimate, None if run.scale_at is None else problem.x_from_values(run.scale_at))
    if run.ident is not None and np.isfinite(res.cost):
        # a combination of other parameters in the nominal model that the fitted terms tell apart (the tilt
        # of joint 1 against gravity once a compliance deflects the arm): identified when these poses
        # determine it well
        problem, res, name = _free_separated(run, problem, res, name)
    if not np.isfinite(res.cost):
        raise SolverError(f"{name} ended with a non-finite cost ({res.status}); check the data for outliers "
                          "and the robot file for wrong units")
    if not res.success:
        run.note(f"{name} did not converge ({res.status} after {res.iterations} iterations); the result "
                 "is the last iterate. Try --solver lm or more iterations", ConvergenceWarning)
    params.values = problem.values_from_x(res.x)
    run.problem, run.solution, run.solver_name = problem, res, name
