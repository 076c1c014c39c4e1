"""Choose M calibration poses out of a candidate pool: D-optimal, GA or random.

All selectors judge a set by the scaled identification Jacobian of the
parameters the pool can identify (:func:`~casadical.planning._observability.design_problem`)
and report the same summary: O1..O5, ``log det(J^T J)``, and a certificate
(the relaxation's upper bound and the D-efficiency against it), so that the
GA's or a random set's distance from the optimum is known, not guessed.
"""

from __future__ import annotations

import time
import warnings
from dataclasses import dataclass, field

import numpy as np

from ..errors import IdentifiabilityWarning, InputError, listing
from ..runtime._threads import limited_threads
from ._doptimal import (
    DOptimalDesign,
    RelaxationSettings,
    _check_m,
    d_efficiency,
    d_optimal_design,
    relax_multiplicative,
)
from ._observability import DesignProblem, Observability, design_problem, log_det_information, o1_batch, observability

METHODS = ("d-optimal", "ga", "random")


@dataclass
class PlanSettings:
    """Settings of :func:`select_poses`.

    Parameters
    ----------
    relaxation : {"first-order", "cvxpy"}
        Relaxation solver of the D-optimal method.
    relaxation_settings : RelaxationSettings
        Tolerance etc. of the first-order solver.
    certify : bool
        Also compute the certificate for GA and random selections (one
        relaxation solve).
    ga_generations : int
        Generations of the GA (the paper: 100).
    """

    relaxation: str = "first-order"
    relaxation_settings: RelaxationSettings = field(default_factory=RelaxationSettings)
    certify: bool = True
    ga_generations: int = 100


@dataclass
class PlanResult:
    """A selection of poses and how good it is.

    Attributes
    ----------
    indices : ndarray of int
        Selected candidate rows (0-based), in candidate order.
    method : str
    n_candidates : int
    parameters : list of str
        Identifiable parameters the criterion counts.
    observability : Observability
        O1..O5 of the selection.
    log_det : float
        ``log det(J^T J)`` of the scaled Jacobian of the selection.
    upper_bound : float or None
        Certified upper bound on ``log det`` over all M-subsets of the pool
        (None if not computed).
    d_efficiency : float or None
        ``exp((log_det - upper_bound) / p)``, a lower bound on the D-efficiency
        of the selection relative to the best M-subset.
    relaxation_gap : float or None
        Gap per parameter of the relaxation behind the bound.
    time_s : float
        Selection time (without the Jacobian of the pool).
    jacobian_time_s : float
        Time to evaluate and analyse the pool's Jacobian.
    seed : int or None
    details : dict
        Method-specific figures (iterations, swaps, generations, ...).
    missing_parameters : list of str
        Parameters that poses across the joint ranges identify but the pool
        does not (:attr:`DesignProblem.missing`); when any, no certificate is
        given: every choice from the pool leaves them uncalibrated.
    duplicates : int
        Candidate rows identical to an earlier one (same Jacobian block):
        offered once, so the M poses are distinct.
    criterion : {"D", "Ds"}
        ``Ds`` for rows that touch (:mod:`casadical.planning._touches`): ``log_det`` is that of the information
        about the robot's parameters once what the rows touch is fitted (the Schur complement), the bound and
        the efficiency are of it.
    unobservable : list of dict
        What rows that touch cannot see, held (``what``, ``why``, ``parameters``), as a calibration says it.
    """

    indices: np.ndarray
    method: str
    n_candidates: int
    parameters: list[str]
    observability: Observability
    log_det: float
    upper_bound: float | None
    d_efficiency: float | None
    relaxation_gap: float | None
    time_s: float
    jacobian_time_s: float = 0.0
    seed: int | None = None
    details: dict = field(default_factory=dict)
    missing_parameters: list[str] = field(default_factory=list)
    duplicates: int = 0
    criterion: str = "D"
    unobservable: list[dict] = field(default_factory=list)

    @property
    def m(self) -> int:
        return len(self.indices)

    @property
    def O1(self) -> float:
        return self.observability.O1

    def summary(self) -> str:
        """Human-readable summary (printed by ``casadical plan-poses``)."""
        o = self.observability
        p = len(self.parameters)
        ds = self.criterion == "Ds"
        what = "rows" if ds else "poses"
        lines = [
            f"selected {self.m} of {self.n_candidates} candidate {what} by {self.method}"
            + (f" (seed {self.seed})" if self.seed is not None and self.method != "d-optimal" else ""),
            (f"criterion (Ds): log det = {self.log_det:.6g} of the information about {p} robot parameters once "
             "every point, plane or fixture the rows touch is fitted too (the Jacobian projected away from them; "
             "columns scaled by each parameter's typical deviation, metres)" if ds else
             f"criterion: log det(J^T J) = {self.log_det:.6g} over {p} identifiable parameters "
             "(Jacobian columns scaled by each parameter's typical deviation, metres)"),
            "indices: " + "  ".join(f"{k} = {v:.6g}" for k, v in o.as_dict().items()),
        ]
        for u in self.unobservable:
            if u["parameters"]:
                lines.append(f"not seen by these rows: {u['what']} ({u['why']}): {', '.join(u['parameters'])} "
                             "held")
        if self.upper_bound is not None:
            lines.append(f"certificate: no {self.m}-{what[:-1]} subset of the pool exceeds log det "
                         f"{self.upper_bound:.6g} (relaxation bound, gap {self.relaxation_gap:.2g} per "
                         f"parameter); {self.criterion}-efficiency of this selection >= {self.d_efficiency:.4f}")
        elif self.missing_parameters:
            lines.append("no certificate: " + degenerate_message(self.missing_parameters, p))
        if self.duplicates:
            lines.append(f"note: {self.duplicates} candidate rows repeat earlier ones; each pose was "
                         "offered once")
        for k, v in self.details.items():
            if k.startswith("_"):
                continue
            lines.append(f"  {k}: {v}")
        lines.append(f"time: {self.time_s:.3g} s selection + {self.jacobian_time_s:.3g} s Jacobian of the pool")
        return "\n".join(lines)

    def to_dict(self) -> dict:
        """JSON-ready summary."""
        return {"method": self.method, "m": self.m, "n_candidates": self.n_candidates,
                "indices": [int(i) for i in self.indices], "parameters": self.parameters,
                "observability": self.observability.as_dict(), "log_det": self.log_det,
                "upper_bound": self.upper_bound, "d_efficiency": self.d_efficiency,
                "relaxation_gap": self.relaxation_gap, "time_s": self.time_s,
                "jacobian_time_s": self.jacobian_time_s, "seed": self.seed,
                "missing_parameters": self.missing_parameters, "duplicate_rows": self.duplicates,
                "criterion": self.criterion, **({"unobservable": self.unobservable} if self.unobservable else {}),
                "details": {k: v for k, v in self.details.items() if not k.startswith("_")}}


@limited_threads()
def select_poses(model, q_candidates: np.ndarray | None, m: int, method: str = "d-optimal", *,
                 seed: int | None = None, cov: np.ndarray | None = None,
                 settings: PlanSettings | None = None,
                 problem: DesignProblem | None = None) -> PlanResult:
    """Select M of the candidate poses.

    Parameters
    ----------
    model : casadical.model._symbolic.Model
        E.g. ``Model(robot, "kinematic+compliance")``.
    q_candidates : ndarray, shape (N, n_joints)
        Candidate joint readings (rad). Ignored if ``problem`` is given.
    m : int
        Number of poses to select.
    method : {"d-optimal", "ga", "random"}
        ``d-optimal``: relaxation + rounding + Fedorov exchange (certified);
        ``ga``: the GA paper's selector (population 35, crossover 85 %,
        mutation 35 %, rate 0.1, 100 generations, fitness O1);
        ``random``: a uniformly random M-subset, for comparison.
    seed : int, optional
        For ``ga`` and ``random``.
    cov : ndarray, optional
        Per-candidate covariates (``model.covariates(data)``), e.g. payload.
    settings : PlanSettings, optional
    problem : DesignProblem, optional
        A precomputed :func:`design_problem` of the pool (saves the Jacobian
        when selecting repeatedly from the same pool).

    Returns
    -------
    PlanResult

    Raises
    ------
    InputError
        Unknown method, M larger than the number of distinct candidates.
    IdentifiabilityError
        M too small to identify the parameters the pool can identify.

    Notes
    -----
    Identical candidates (same Jacobian block) are offered once. A pool that
    identifies fewer parameters than poses across the joint ranges do gets
    no certificate (``upper_bound`` and ``d_efficiency`` None) and an
    :class:`~casadical.errors.IdentifiabilityWarning`: the bound would only
    cover the parameters the pool happens to identify, e.g. 3 for a pool of
    one repeated pose, where every selection is "optimal".
    """
    if method not in METHODS:
        raise InputError(f"unknown selection method {method!r}; choose one of {', '.join(METHODS)}")
    st = settings or PlanSettings()
    t0 = time.perf_counter()
    if problem is None:
        problem = design_problem(model, np.asarray(q_candidates, dtype=float), cov)
    t_jac = time.perf_counter() - t0
    N, p = problem.n_candidates, problem.n_parameters
    rows = distinct_rows(problem.A)
    if len(rows) < m:
        k = len(rows)
        raise InputError(f"M={m} distinct poses asked for, but the {N} candidates hold only {k} distinct "
                         f"pose{'s' if k != 1 else ''} ({N - k} rows repeat earlier ones)")
    A = problem.A[rows] if len(rows) < N else problem.A
    _check_m(A, m)
    if problem.missing:
        warnings.warn(degenerate_message(problem.missing, p), IdentifiabilityWarning, stacklevel=3)
    t1 = time.perf_counter()
    details: dict = {}
    ub = gap = None
    if method == "d-optimal":
        des: DOptimalDesign = d_optimal_design(A, m, relaxation=st.relaxation,
                                               settings=st.relaxation_settings)
        idx = des.indices
        ub, gap = des.upper_bound, des.relaxation.gap_per_parameter
        rel = des.relaxation
        details = {"relaxation": f"{rel.method}, {rel.status}, {rel.iterations} iterations, "
                                 f"{rel.time_s:.3g} s, log det {rel.log_det:.6g}, "
                                 f"{rel.n_at_one} weights at 1 and {rel.n_support - rel.n_at_one} fractional",
                   "exchange": f"best of {des.exchange.starts} rounded starts, {des.exchange.swaps} swaps in all, "
                               f"{des.exchange.time_s:.3g} s",
                   "_design": des}
    elif method == "ga":
        from ..optim._genetic import SubsetGeneticAlgorithm

        ga = SubsetGeneticAlgorithm(generations=st.ga_generations)
        res = ga.maximize(lambda S: o1_batch(A, S), len(A), m, seed=seed)
        idx = np.sort(np.asarray(res.x, dtype=int))
        details = {"ga": f"{res.nit} generations, {res.nfev} sets evaluated, best O1 {res.fun:.6g}, "
                         f"{res.time_s:.3g} s ({res.message})", "_result": res}
    else:
        rng = np.random.default_rng(seed)
        idx = np.sort(rng.choice(len(A), size=m, replace=False))
    t_sel = time.perf_counter() - t1
    ld = log_det_information(A, idx)
    if problem.missing:
        ub = gap = None  # a bound over the parameters a degenerate pool identifies is no certificate
    elif ub is None and st.certify:
        rel = relax_multiplicative(A, m, st.relaxation_settings)
        ub, gap = rel.upper_bound, rel.gap_per_parameter
        details["certificate"] = (f"first-order relaxation, {rel.iterations} iterations, "
                                  f"{rel.time_s:.3g} s")
    eff = d_efficiency(ld, ub, p) if ub is not None else None
    return PlanResult(rows[idx], method, N, list(problem.names), observability(A, idx), ld, ub, eff,
                      gap, t_sel, t_jac, seed, details, list(problem.missing), N - len(rows))


def distinct_rows(A: np.ndarray) -> np.ndarray:
    """Sorted first occurrences of the distinct per-pose blocks ``A[i]`` (bitwise equality)."""
    flat = np.ascontiguousarray(A).reshape(len(A), -1)
    keys = flat.view(np.dtype((np.void, flat.dtype.itemsize * flat.shape[1]))).ravel()
    return np.sort(np.unique(keys, return_index=True)[1])


def degenerate_message(missing: list[str], p: int) -> str:
    """Why a pool that misses parameters gets no certificate."""
    shown = listing(missing)
    return (f"the candidates identify only {p} parameters; {len(missing)} more that poses across the "
            f"joint ranges identify ({shown}) stay uncalibrated whatever is chosen from them: add "
            "candidates that move them (other poses, loads)")


@limited_threads()
def random_o1(A: np.ndarray, m: int, n_sets: int, seed: int | None = None) -> np.ndarray:
    """O1 of ``n_sets`` uniformly random M-subsets of the pool (the GA paper's Fig. 6 baseline)."""
    rng = np.random.default_rng(seed)
    N = A.shape[0]
    sets = np.sort(np.argsort(rng.random((n_sets, N)), axis=1)[:, :m], axis=1)
    return o1_batch(A, sets)
