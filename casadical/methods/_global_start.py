"""Metaheuristics as global initialisers of IPOPT (multi-start).

A metaheuristic (CA, GA or TLBO) explores the stiffnesses (and optionally a
few other parameters over wide boxes); its best distinct points start IPOPT
on the full simultaneous problem, and the best local solution wins. The user
gets the metaheuristic's reach and the local solver's precision.

1. Least squares with rigid joints gives the kinematic start (and the
   identifiable set).
2. The metaheuristic minimises the error left after the kinematic least
   squares: linearised in the compliances (:class:`~._search.Linearised`)
   when only stiffnesses are searched, one Gauss-Newton step per candidate
   (:class:`~._search.OneStep`) when other parameters are searched too.
3. The ``n_starts`` best distinct points of the final population start IPOPT
   with every identifiable parameter free.

The outcome also keeps the metaheuristic's own answer (its best point with
the kinematics of the least-squares step, "alone"), so its accuracy can be
compared with the polished one.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from ..calibration import calibrate
from ..errors import InputError, SolverError
from ..model._symbolic import Model
from ..optim import Box, OptimResult
from ..result import CalibrationResult, ErrorStats
from ._base import Inputs, Method, MethodResult, compliance_model, compliant_joints, new_result
from ._search import K_BOUNDS, Linearised, OneStep, Variable, distinct_best, make_optimizer, stiffness_box


@dataclass
class GlobalOutcome:
    """What :func:`global_start` found.

    Attributes
    ----------
    best : CalibrationResult
        Best IPOPT solution over the starts.
    alone : CalibrationResult
        The metaheuristic's best point with the kinematics of its least-squares step.
    optim : OptimResult
    starts : list of dict
        Per start: the point, the IPOPT status, iterations, mean error.
    time_s : dict
        ``start`` (rigid least squares), ``search`` (metaheuristic), ``ipopt`` (all starts).
    """

    best: CalibrationResult
    alone: CalibrationResult
    optim: OptimResult
    starts: list[dict] = field(default_factory=list)
    time_s: dict = field(default_factory=dict)


def global_start(inputs: Inputs, optimizer: str, joints: list[int], *, model: Model | str | None = None,
                 params_box: dict[str, tuple[float, float]] | None = None, k_bounds=K_BOUNDS,
                 n_starts: int = 3, pop_size: int = 20, generations: int = 100,
                 stall_generations: int | None = 10, ftol_mm: float = 1e-4, fitness: str = "mean",
                 start: dict[str, float] | None = None, solver_options: dict | None = None) -> GlobalOutcome:
    """Metaheuristic over stiffnesses (and ``params_box``), then IPOPT from its best points.

    Parameters
    ----------
    inputs : Inputs
    optimizer : {"CA", "GA", "TLBO"}
    joints : list of int
        Compliant joints; the model must contain their compliances.
    model : Model or str, optional
        Default ``kinematic+compliance[joints]``. Pass a Model built with a
        wider geometric box to search joint offsets far from nominal.
    params_box : dict, optional
        Further parameters to search, name -> (lower, upper) in SI units.
    k_bounds : (float, float)
        Stiffness search range (N m/rad), log-uniform.
    n_starts : int
        IPOPT starts from the best distinct points.
    start : dict, optional
        Start values (SI) of other parameters (default nominal).
    """
    t0 = time.perf_counter()
    robot, data = inputs.robot, inputs.calibration
    if model is None:
        model = compliance_model(joints)
    if isinstance(model, str):
        model = Model(robot, model)
    cnames = [f"c{j}" for j in joints]
    params_box = dict(params_box or {})
    for name in list(cnames) + list(params_box):
        if name not in model.parameters:
            raise InputError(f"the model {model.spec} has no parameter {name!r}")
    st = dict(start or {})
    st.update({c: 0.0 for c in cnames})
    fixed = tuple(cnames) + tuple(params_box)
    first = calibrate(robot, data, model, "lm", fix=fixed, start=st, warn=False, position_only=True)
    params = first.parameters
    q, xyz, cov = data.q, data.xyz, model.covariates(data)
    klo, khi = stiffness_box(params, cnames, k_bounds)
    variables = [Variable(c, params.index(c), True, a, b) for c, a, b in zip(cnames, klo, khi)]
    for name, (a, b) in params_box.items():
        p = params[name]
        a, b = max(a, p.lower), min(b, p.upper)
        if not a < b:
            raise InputError(f"empty search box for {name}: [{a:g}, {b:g}] within its bounds "
                             f"[{p.lower:g}, {p.upper:g}]")
        variables.append(Variable(name, params.index(name), False, a, b))
    box = Box([v.lower for v in variables], [v.upper for v in variables])
    t1 = time.perf_counter()

    if params_box:
        # far from the start the rigid least squares above is no guide (it fitted with the searched
        # parameters at their start values): every candidate steps from the start values instead
        p0 = params.copy()
        v0 = model.parameters.values.copy()
        for name, value in st.items():
            v0[model.parameters.index(name)] = value
        p0.values = v0
        objective = OneStep(model, p0, q, xyz, cov, variables, fitness)
    else:
        objective = Linearised(model, params, q, xyz, cov, first.base0, cnames, fitness)
    algo = make_optimizer(optimizer, pop_size, generations, stall_generations, ftol_mm * 1e-3)
    x0 = np.array([v.coordinate(params[v.name].value) for v in variables])
    x0 = np.clip(x0, box.lower, box.upper)
    opt = algo.minimize(objective, box, seed=inputs.seed, x0=x0)
    t2 = time.perf_counter()

    def point(z) -> tuple[np.ndarray, np.ndarray]:
        if params_box:
            return objective.point(z)
        return objective.values(z), first.base0

    def as_result(values, base0, name) -> CalibrationResult:
        ps = params.copy()
        ps.values = values
        for v in variables:
            ps[v.name].fixed, ps[v.name].reason = False, f"searched by the {optimizer.upper()}"
        e = np.linalg.norm(model.predict(q, values, cov, base0) - xyz, axis=1)
        return CalibrationResult(model, ps, base0, None, name, first.identifiability, None, ErrorStats.of(e))

    alone = as_result(*point(opt.x), optimizer.lower())
    pts = np.vstack([opt.x[None, :], opt.population])
    fs = np.concatenate([[opt.fun], opt.population_fun])
    starts, best, best_cost = [], None, np.inf
    for z in distinct_best(pts, fs, box, n_starts):
        values, _ = point(z)
        sv = {n: float(values[i]) for i, n in enumerate(params.names) if params[n].group != "base"}
        entry = {"start": {v.name: (10.0 ** z[k] if v.log_stiffness else float(z[k]))
                           for k, v in enumerate(variables)}, "fitness_mm": None}
        try:
            res = calibrate(robot, data, model, "ipopt", start=sv, solver_options=solver_options, warn=False,
                            position_only=True)
        except SolverError as e:
            entry.update(status=f"failed: {e}")
            starts.append(entry)
            continue
        entry.update(status=res.solver.status, iterations=res.solver.iterations,
                     mean_mm=res.calibration.mean_mm, cost=res.solver.cost)
        starts.append(entry)
        if res.solver.cost < best_cost:
            best, best_cost = res, res.solver.cost
    if best is None:
        raise SolverError(f"IPOPT failed from every start of the {optimizer.upper()}")
    best.solver_name = f"{optimizer.lower()}+ipopt"
    t3 = time.perf_counter()
    return GlobalOutcome(best, alone, opt, starts,
                         {"start": t1 - t0, "search": t2 - t1, "ipopt": t3 - t2, "total": t3 - t0})


class GlobalStartMethod(Method):
    """Base of SKCM-IPOPT-CA/-GA/-TLBO.

    Settings
    --------
    joints : sequence of int
        Compliant joints (default 2-5 on a six-axis arm, 2..n-1 on others).
    params_box : dict
        Further parameters to search, name -> (lower, upper) in SI units
        (e.g. ``{"theta3": (-3.1, 3.1)}``); needs a model whose bounds admit it.
    model : Model or str, optional
        Model to identify (default ``kinematic+compliance[joints]``).
    k_bounds, pop_size, generations, stall_generations, ftol_mm, fitness
        As SKCM-CA.
    n_starts : int
        IPOPT starts (default 3).
    """

    optimizer = "CA"
    joints = None
    params_box = None
    model = None
    k_bounds = K_BOUNDS
    pop_size = 20
    generations = 100
    stall_generations = 10
    ftol_mm = 1e-4
    fitness = "mean"
    n_starts = 3
    start = None

    def fit(self, inputs: Inputs) -> MethodResult:
        joints = compliant_joints(inputs.robot, self.joints)
        o = global_start(inputs, self.optimizer, joints, model=self.model, params_box=self.params_box,
                         k_bounds=self.k_bounds, n_starts=self.n_starts, pop_size=self.pop_size,
                         generations=self.generations, stall_generations=self.stall_generations,
                         ftol_mm=self.ftol_mm, fitness=self.fitness, start=self.start)
        return new_result(o.best, info={"optimizer": self.optimizer, "nfev": o.optim.nfev,
                                        "generations": o.optim.nit, "alone_mean_mm": o.alone.calibration.mean_mm,
                                        "starts": o.starts, "time_split_s": o.time_s, "joints": joints})
