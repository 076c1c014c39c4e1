"""The CA paper's two-phase identification: kinematic least squares alternated
with a metaheuristic over the joint stiffnesses.

1. Phase 1: with the stiffnesses fixed (rigid joints at first), the
   kinematic parameters by iterative least squares (Levenberg-Marquardt; the
   paper's eq. 4).
2. Phase 2: the metaheuristic (CA, or GA for the paper's baseline) searches
   the stiffness vector in a log-uniform box; a candidate's fitness is the
   mean position error left after the kinematic least squares (A15),
   computed by variable projection (:class:`~._search.Linearised`).
3. Repeat with the new stiffnesses until the mean error after phase 1 gains
   less than ``tol_mm`` or the stiffnesses change by less than ``ktol``
   (relative); the previous best is injected into the next population, so
   the loop never gets worse.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..calibration import calibrate
from ..optim import Box, OptimResult
from ..problem import CalibrationProblem
from ..result import CalibrationResult, ErrorStats
from ..solvers import make_solver
from ..stats._uncertainty import estimate
from ._base import Inputs, Method, MethodResult, compliance_model, compliant_joints, new_result
from ._search import K_BOUNDS, Linearised, make_optimizer, stiffness_box


@dataclass
class TwoPhaseOutcome:
    result: CalibrationResult
    rounds: list[dict] = field(default_factory=list)
    nfev: int = 0
    optimizer_time_s: float = 0.0
    last: OptimResult | None = None


def two_phase(inputs: Inputs, optimizer: str, joints: list[int], *, k_bounds=K_BOUNDS, pop_size: int = 20,
              generations: int = 100, stall_generations: int | None = 10, ftol_mm: float = 1e-4,
              max_rounds: int = 10, tol_mm: float = 1e-4, ktol: float = 1e-3,
              fitness: str = "mean") -> TwoPhaseOutcome:
    """Alternate kinematic least squares and a metaheuristic over the stiffnesses (see module doc)."""
    robot, data = inputs.robot, inputs.calibration
    cnames = [f"c{j}" for j in joints]
    spec = compliance_model(joints)
    # phase 1 with rigid joints; also settles the base pose and what is identifiable
    first = calibrate(robot, data, spec, "lm", fix=tuple(cnames), start={c: 0.0 for c in cnames}, warn=False,
                      position_only=True)
    model, params, base0 = first.model, first.parameters.copy(), first.base0
    q, xyz, cov = data.q, data.xyz, model.covariates(data)
    lo, hi = stiffness_box(params, cnames, k_bounds)
    box = Box(lo, hi)
    algo = make_optimizer(optimizer, pop_size, generations, stall_generations, ftol_mm * 1e-3)
    lm = make_solver("lm")
    out = TwoPhaseOutcome(first)
    z_best = None
    err_prev = float(np.mean(np.linalg.norm(model.predict(q, params.values, cov, base0) - xyz, axis=1)))
    sres = first.solver
    for k in range(max_rounds):
        lin = Linearised(model, params, q, xyz, cov, base0, cnames, fitness)
        opt = algo.minimize(lin, box, seed=inputs.seed + 1000 * k, x0=z_best)
        out.nfev += opt.nfev
        out.optimizer_time_s += opt.time_s
        out.last = opt
        for c, zi in zip(cnames, opt.x):
            params[c].value = 10.0 ** (-zi)
        problem = CalibrationProblem(model, params, q, xyz, cov, base0)
        sres = lm.solve(problem, problem.x_from_values(params.values))
        params.values = problem.values_from_x(sres.x)
        err = float(np.mean(np.linalg.norm(model.predict(q, params.values, cov, base0) - xyz, axis=1)))
        dk = math.inf if z_best is None else float(np.max(np.abs(opt.x - z_best))) * math.log(10)
        out.rounds.append({"round": k + 1, "stiffness": (10.0 ** opt.x).tolist(), "mean_mm": err * 1e3,
                           "generations": opt.nit, "nfev": opt.nfev})
        z_best = opt.x.copy()
        if err_prev - err < tol_mm * 1e-3 and k > 0 or dk < ktol:
            break
        err_prev = err
    # report: compliances as identified (free for the uncertainty estimate), stds from the local LS
    for c in cnames:
        params[c].fixed = False
        params[c].reason = f"identified by the {optimizer.upper()} (two-phase)"
    problem = CalibrationProblem(model, params, q, xyz, cov, base0)
    r, J = problem.residuals_jacobian(params.values)
    unc = estimate(r, J, problem.scale, [params.names[i] for i in problem.free])
    for n, s in zip(unc.names, unc.std):
        params[n].std = float(s)
    errors = np.linalg.norm(r.reshape(-1, 3), axis=1)
    out.result = CalibrationResult(model, params, base0, sres, f"levenberg-marquardt+{optimizer.lower()}",
                                   first.identifiability, unc, ErrorStats.of(errors), list(first.notes))
    return out


class TwoPhaseMethod(Method):
    """Base of SKCM-CA and SKCM-GA; ``optimizer`` names the metaheuristic.

    Settings
    --------
    joints : sequence of int
        Compliant joints (default 2-5 on a six-axis arm, 2..n-1 on others).
    k_bounds : (float, float)
        Stiffness search range, N m/rad (default 1e4..1e8, log-uniform), cut
        to what the compliance bounds allow.
    pop_size, generations : int
        Population (20, the CA paper) and generation limit (100).
    stall_generations, ftol_mm : int, float
        Stop a search when its best gains < ``ftol_mm`` in that many generations.
    max_rounds, tol_mm, ktol
        Outer loop: at most ``max_rounds``; stop when the error after the
        least squares gains < ``tol_mm`` or the stiffness moves < ``ktol``.
    fitness : {"mean", "rms"}
        Mean position error (A15) or RMS (the least-squares criterion).
    """

    optimizer = "CA"
    joints = None
    k_bounds = K_BOUNDS
    pop_size = 20
    generations = 100
    stall_generations = 10
    ftol_mm = 1e-4
    max_rounds = 10
    tol_mm = 1e-4
    ktol = 1e-3
    fitness = "mean"

    def fit(self, inputs: Inputs) -> MethodResult:
        joints = compliant_joints(inputs.robot, self.joints)
        o = two_phase(inputs, self.optimizer, joints, k_bounds=self.k_bounds, pop_size=self.pop_size,
                      generations=self.generations, stall_generations=self.stall_generations,
                      ftol_mm=self.ftol_mm, max_rounds=self.max_rounds, tol_mm=self.tol_mm,
                      ktol=self.ktol, fitness=self.fitness)
        return new_result(o.result, info={"rounds": o.rounds, "optimizer": self.optimizer, "nfev": o.nfev,
                                          "optimizer_time_s": o.optimizer_time_s, "joints": joints})
