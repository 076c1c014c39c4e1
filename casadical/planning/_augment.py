"""Ds-optimal augmentation: the M candidate poses that, added to those measured, best determine some parameters.

A question (:mod:`casadical.planning._questions`) is a model and the
parameters it asks about (``s`` of its ``p``, the others are nuisance). Pose
``i`` of the pool adds ``H_i = A_i^T A_i`` to the information matrix (scaled
Jacobian blocks, as in :mod:`casadical.planning._doptimal`); the poses
already measured give ``M0``. With ``M(w) = M0 + sum_i w_i H_i`` the
Ds-criterion of a question is the log determinant of the information about
its own parameters once the nuisance is estimated too,

    f(w) = log det M(w) - log det M_nn(w) = -log det [M(w)^-1]_ss,

the log of the inverse generalised variance of the estimate of those ``s``
parameters. Several questions are planned together by
``F(w) = sum_q f_q(w) / s_q`` (each question's log det per parameter: a
geometric mean of how much each question's confidence region shrinks).

The bound
---------
``f`` is concave. Its gradient is the Ds variance function
``d_i = trace(A_i G A_i^T)``, ``G = M^-1 - [0, 0; 0, M_nn^-1]`` (the full
variance less the nuisance's). With ``B = [I; -M_nn^-1 M_ns]``,
``log det Schur(w') <= log det(B^T M(w') B)`` for every ``w'``, and the
concavity of log det at ``Y = t Schur(w)^-1`` gives, for every feasible
``w'`` (``0 <= w' <= 1``, ``sum w' = M``) and ``t > 0``,

    f(w') <= f(w) - s log t - s + t (c0 + S(w)),

with ``c0 = trace(G M0)`` and ``S`` the sum of the ``M`` largest ``d_i``.
At ``t = s / (c0 + S)`` this is ``U = f(w) + s log((c0 + S) / s)``: the
bound of :mod:`~casadical.planning._doptimal` (``M0 = 0``, ``s = p``) for a
design that augments measured poses and asks about part of the model. It
is zero exactly at the optimum of the relaxation. For several questions
every ``t_q`` gives a bound ``sum_q (f_q - log t_q - 1 + t_q c0_q / s_q) +
top_M(sum_q t_q d_iq / s_q)``; a few rounds choose the ``t_q``.
The Ds-efficiency of a set is ``exp((F(set) - U) / Q)`` for ``Q``
questions: the geometric mean over the questions of each one's
``(det Schur_set / det Schur_best)^(1/s)``.

Solvers: the capped multiplicative algorithm with an exact line search on
``F`` (:func:`relax_ds`), or the conic program with cvxpy for one question
(:func:`relax_ds_cvxpy`: ``max log det X`` subject to
``[[M_ss - X, M_sn], [M_ns, M_nn]] >= 0``), then rounding and Fedorov
exchange on the swap ratios of both determinants (:func:`ds_design`).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np

from ..errors import InputError
from ..runtime._threads import limited_threads
from ._doptimal import _cap_project, _Pool, _swap_ratios, _top, solve_in_turn


@dataclass
class Criterion:
    """One question's part of the design problem.

    Attributes
    ----------
    A : ndarray, shape (N, r, p)
        Scaled Jacobian blocks of the candidates, over the question model's
        identifiable parameters.
    M0 : ndarray, shape (p, p)
        Information of the poses already measured (same scaling).
    interest : ndarray of int
        Columns of the parameters the question asks about (``s`` of them).
    """

    A: np.ndarray
    M0: np.ndarray
    interest: np.ndarray

    def __post_init__(self) -> None:
        self.A = np.ascontiguousarray(self.A, dtype=float)
        self.M0 = np.asarray(self.M0, dtype=float)
        self.interest = np.asarray(self.interest, dtype=int).ravel()
        N, r, p = self.A.shape
        if self.M0.shape != (p, p):
            raise InputError(f"the measured information must be {p} x {p}, got {self.M0.shape}")
        if not len(self.interest) or len(np.unique(self.interest)) != len(self.interest) \
                or self.interest.min() < 0 or self.interest.max() >= p:
            raise InputError(f"the parameters of interest must be distinct columns of 0..{p - 1}")
        self.nuisance = np.setdiff1d(np.arange(p), self.interest)

    @property
    def s(self) -> int:
        return len(self.interest)


class _Question:
    """Working state of one criterion over a candidate pool: scaled pools of the full and the nuisance blocks."""

    def __init__(self, crit: Criterion, m: int):
        self.c = crit
        self.full = _Pool(crit.A, m)
        self.nn = _Pool(crit.A[:, :, crit.nuisance], m) if len(crit.nuisance) else None
        cs = self.full.c
        self.M0 = crit.M0 * np.outer(cs, cs)
        p = crit.A.shape[2]
        # a tiny ridge keeps the criterion finite when the measured poses leave a direction unseen
        self.ridge = 1e-10 * max(float(np.trace(self.M0)) / p, 1.0) * np.eye(p)
        self.s = crit.s
        self.weight = 1.0 / crit.s
        # log dets in the criterion's own (unscaled) units: the scaling depends on M
        self.offset = 2.0 * float(np.sum(np.log(cs[crit.interest])))

    def matrices(self, idx: np.ndarray, w: np.ndarray) -> tuple[np.ndarray, np.ndarray | None]:
        """Scaled ``M`` and ``M_nn`` of weights ``w`` on rows ``idx``."""
        M = self.M0 + self.ridge + (self.full.info(idx, w) if len(idx) else 0.0)
        return M, (M[np.ix_(self.c.nuisance, self.c.nuisance)] if self.nn is not None else None)

    def value(self, M: np.ndarray, Mnn: np.ndarray | None) -> float:
        """``log det M - log det M_nn`` in the criterion's units (the scaling taken out)."""
        out = _logdet(M) - self.offset
        return out - _logdet(Mnn) if Mnn is not None else out

    def inverse_factors(self, M: np.ndarray, Mnn: np.ndarray | None):
        T = np.linalg.inv(np.linalg.cholesky(M))
        Tn = np.linalg.inv(np.linalg.cholesky(Mnn)) if Mnn is not None else None
        return T, Tn

    def variances(self, T: np.ndarray, Tn: np.ndarray | None, idx: np.ndarray | None = None) -> np.ndarray:
        """Ds variance function ``d_i`` (full variance less the nuisance's) at every candidate (or ``idx``)."""
        d = self.full.variances(T, idx)
        if Tn is not None:
            d = d - self.nn.variances(Tn, idx)
        return np.clip(d, 0.0, None)

    def c0(self, T: np.ndarray, Tn: np.ndarray | None) -> float:
        """``trace(G M0)``: what the measured poses already contribute to the variance function's sum."""
        Minv = T.T @ T
        G = Minv.copy()
        if Tn is not None:
            G[np.ix_(self.c.nuisance, self.c.nuisance)] -= Tn.T @ Tn
        return float(np.sum(G * (self.M0 + self.ridge)))


def _logdet(M: np.ndarray) -> float:
    sign, ld = np.linalg.slogdet(M)
    return float(ld) if sign > 0 else -math.inf


@dataclass
class DsRelaxation:
    """The relaxed (continuous) design: weights, criterion, certified bound."""

    weights: np.ndarray = field(repr=False)
    value: float
    upper_bound: float
    method: str
    status: str
    iterations: int
    time_s: float

    @property
    def gap(self) -> float:
        return self.upper_bound - self.value


@dataclass
class DsDesign:
    """An exact augmentation of M distinct candidates and its certificate.

    Attributes
    ----------
    indices : ndarray of int
        Sorted candidate rows.
    value : float
        ``F`` of the measured poses plus these (log dets in the parameters' scaled units, as the bound).
    upper_bound : float
        No M candidates added to the measured poses reach a larger ``F``.
    efficiency : float
        ``exp((value - upper_bound) / Q)``: the set's Ds-efficiency against the
        best possible, at least (geometric mean over the ``Q`` questions).
    measured_value : float
        ``F`` of the measured poses alone.
    relaxation : DsRelaxation
    swaps, starts : int
    time_s : float
    """

    indices: np.ndarray
    value: float
    upper_bound: float
    efficiency: float
    measured_value: float
    relaxation: DsRelaxation
    swaps: int
    starts: int
    time_s: float


def criterion_value(criteria: list[Criterion], subset=None, weights: np.ndarray | None = None) -> float:
    """``F = sum_q f_q / s_q`` of the measured poses plus ``subset`` (or relaxed ``weights``)."""
    qs = [_Question(c, 1) for c in criteria]     # F does not depend on the working scaling (set by M)
    return _value(qs, *_as_weights(len(criteria[0].A), subset, weights))


def _as_weights(N: int, subset, weights):
    if weights is not None:
        w = np.asarray(weights, dtype=float)
        idx = np.flatnonzero(w > 0)
        return idx, w[idx]
    idx = np.zeros(0, int) if subset is None else np.asarray(subset, dtype=int)
    return idx, np.ones(len(idx))


def _value(qs: list[_Question], idx: np.ndarray, w: np.ndarray) -> float:
    return float(sum(q.weight * q.value(*q.matrices(idx, w)) for q in qs))


def _check(criteria: list[Criterion], m: int) -> int:
    if not criteria:
        raise InputError("no question to plan for")
    N = criteria[0].A.shape[0]
    if any(c.A.shape[0] != N for c in criteria):
        raise InputError("every question must be over the same candidates")
    if not isinstance(m, (int, np.integer)) or m < 1:
        raise InputError(f"the number of poses M must be a positive integer, got {m!r}")
    if m > N:
        raise InputError(f"cannot choose M={m} distinct poses from a pool of {N}")
    return N


def _bound(qs: list[_Question], state: list, m: int) -> float:
    """Certified bound on ``F`` over every feasible design, from the state (M, T, Tn, f, d) of each question."""
    fs = np.array([st[3] for st in state])
    ds = [st[4] for st in state]
    c0 = np.array([q.c0(st[1], st[2]) for q, st in zip(qs, state)])
    s = np.array([q.s for q in qs], dtype=float)
    if len(qs) == 1:
        S = float(np.sum(_top(ds[0], m)))
        return float(fs[0] / s[0] + math.log(max(c0[0] + S, 1e-300) / s[0]))

    def B(t):
        g = sum(tq * d / sq for tq, d, sq in zip(t, ds, s))
        return float(np.sum(fs / s - np.log(t) - 1 + t * c0 / s) + np.sum(_top(g, m)))
    t = np.ones(len(qs))
    best = B(t)
    for _ in range(20):        # t_q = s_q / (c0_q + the top-M set's sum of d_q): any t bounds, the least is kept
        g = sum(tq * d / sq for tq, d, sq in zip(t, ds, s))
        top = np.argpartition(-g, m - 1)[:m] if m < len(g) else np.arange(len(g))
        t = np.array([sq / max(c + float(np.sum(d[top])), 1e-300) for sq, c, d in zip(s, c0, ds)])
        b = B(t)
        if b >= best - 1e-12:
            best = min(best, b)
            break
        best = b
    return best


def _state(qs: list[_Question], idx: np.ndarray, w: np.ndarray) -> list:
    out = []
    for q in qs:
        M, Mnn = q.matrices(idx, w)
        T, Tn = q.inverse_factors(M, Mnn)
        out.append((M, T, Tn, q.value(M, Mnn), q.variances(T, Tn)))
    return out


def _line_search(qs: list[_Question], Ms: list, Ds: list) -> float:
    """argmax over t in [0, 1] of F along the segment ``M_q + t D_q`` (concave: bisection on the derivative)."""
    def slope(t):
        g = 0.0
        for q, (M, Mnn), (D, Dnn) in zip(qs, Ms, Ds):
            try:
                g += q.weight * float(np.sum(np.linalg.inv(M + t * D) * D))
                if Mnn is not None:
                    g -= q.weight * float(np.sum(np.linalg.inv(Mnn + t * Dnn) * Dnn))
            except np.linalg.LinAlgError:
                return -math.inf
        return g
    if slope(1.0) >= 0:
        return 1.0
    lo, hi = 0.0, 1.0
    for _ in range(40):
        mid = 0.5 * (lo + hi)
        if slope(mid) > 0:
            lo = mid
        else:
            hi = mid
    return lo


@limited_threads()
def relax_ds(criteria: list[Criterion], m: int, tol: float = 1e-4, max_iter: int = 2000,
             exponent: float = 2.0) -> DsRelaxation:
    """The relaxation of the augmentation, by the capped multiplicative algorithm with an exact line search.

    Parameters
    ----------
    criteria : list of Criterion
        One per question, over the same candidates.
    m : int
        Poses to add.
    tol : float
        Stop when the certified gap ``U - F`` per question is at most this.
    """
    N = _check(criteria, m)
    t0 = time.perf_counter()
    qs = [_Question(c, m) for c in criteria]
    w = np.full(N, m / N)
    all_rows = np.arange(N)
    status, it = "iteration limit", 0
    best_ub = math.inf
    for it in range(1, max_iter + 1):
        st = _state(qs, all_rows, w)
        F = float(sum(q.weight * x[3] for q, x in zip(qs, st)))
        best_ub = min(best_ub, _bound(qs, st, m))
        if (best_ub - F) / len(qs) <= tol:
            status = "converged"
            break
        g = sum(q.weight * x[4] for q, x in zip(qs, st))
        if it % 25 == 0:
            # a weight that shrank to nothing grows back too slowly by the multiplicative steps: candidates
            # among the M of largest variance function start again from the uniform weight
            top = g >= np.partition(g, N - m)[N - m] if m < N else np.ones(N, bool)
            revive = top & (w < 1e-6 * m / N)
            if revive.any():
                w[revive] = m / N
                w = _cap_project(w, m)
                continue
        # multiplicative step on the combined variance function, projected onto the capped simplex
        scale = float(np.dot(w, g)) / m
        if not scale > 0:
            status = "no information in the candidates"
            break
        v = _cap_project(w * (np.maximum(g, 0.0) / scale) ** exponent + 1e-300, m)
        if float(np.dot(g, v - w)) <= 1e-14:
            status = "no ascent direction (at the optimum to machine precision)"
            break
        dw = v - w
        Ms = [(x[0], x[0][np.ix_(q.c.nuisance, q.c.nuisance)] if q.nn is not None else None) for q, x in zip(qs, st)]
        Ds = []
        for q in qs:
            D = q.full.info(all_rows, dw)
            Ds.append((D, D[np.ix_(q.c.nuisance, q.c.nuisance)] if q.nn is not None else None))
        w = w + _line_search(qs, Ms, Ds) * dw
        w = np.clip(w, 0.0, 1.0)
    st = _state(qs, all_rows, w)
    F = float(sum(q.weight * x[3] for q, x in zip(qs, st)))
    best_ub = min(best_ub, _bound(qs, st, m))
    return DsRelaxation(w, F, best_ub, "multiplicative", status, it, time.perf_counter() - t0)


@limited_threads()
def relax_ds_cvxpy(criterion: Criterion, m: int, solver: str | None = None) -> DsRelaxation:
    """The relaxation of one question as a conic program (cvxpy): ``max log det X`` with
    ``[[M_ss - X, M_sn], [M_ns, M_nn]] >= 0`` (Schur complement), ``M = M0 + sum w_i H_i``.

    Its size grows as ``N p^2``: for pools of a few thousand candidates and models of a few dozen
    parameters; the bound is recomputed from its weights as for :func:`relax_ds`.
    """
    import cvxpy as cp

    N = _check([criterion], m)
    t0 = time.perf_counter()
    q = _Question(criterion, m)
    A = criterion.A * q.full.c
    p = A.shape[2]
    order = np.concatenate([criterion.interest, criterion.nuisance])
    A = A[:, :, order]
    H = np.einsum("nri,nrj->nij", A, A).reshape(N, p * p)
    M0 = (q.M0 + q.ridge)[np.ix_(order, order)]
    w = cp.Variable(N)
    M = cp.reshape(H.T @ w, (p, p), order="F") + M0
    M = (M + M.T) / 2
    s = criterion.s
    X = cp.Variable((s, s), symmetric=True)
    big = cp.bmat([[M[:s, :s] - X, M[:s, s:]], [M[s:, :s], M[s:, s:]]]) if s < p else M - X
    prob = cp.Problem(cp.Maximize(cp.log_det(X)), [w >= 0, w <= 1, cp.sum(w) == m, (big + big.T) / 2 >> 0])
    solver, _ = solve_in_turn(prob, w, solver)
    wv = np.clip(np.asarray(w.value, dtype=float), 0.0, 1.0)
    st = _state([q], np.arange(N), wv)
    return DsRelaxation(wv, st[0][3] / s, _bound([q], st, m), f"cvxpy:{solver}", str(prob.status),
                        int(getattr(prob.solver_stats, "num_iters", 0) or 0), time.perf_counter() - t0)


def _swap_scores(qs: list[_Question], X: np.ndarray, cand: np.ndarray) -> np.ndarray:
    """Change of ``F`` for swapping each candidate (rows) in and each selected pose (columns) out."""
    out = np.zeros((len(cand), len(X)))
    I = np.eye(qs[0].full.r)
    for q in qs:
        M, Mnn = q.matrices(X, np.ones(len(X)))
        T, Tn = q.inverse_factors(M, Mnn)
        with np.errstate(divide="ignore", invalid="ignore"):
            r = np.log(np.clip(_swap_ratios(q.full, T, cand, X, I), 1e-300, None))
            if Tn is not None:
                r -= np.log(np.clip(_swap_ratios(q.nn, Tn, cand, X, I), 1e-300, None))
        out += q.weight * r
    return out


def _exchange(qs: list[_Question], X: np.ndarray, support: np.ndarray, n_candidates: int,
              max_swaps: int, groups: "_Groups | None" = None) -> tuple[np.ndarray, int]:
    N, m = qs[0].full.N, len(X)
    X = X.copy()
    selected = np.zeros(N, bool)
    selected[X] = True
    swaps = 0
    nc = min(N - m, n_candidates)
    while nc > 0 and swaps < max_swaps:
        st = _state(qs, X, np.ones(m))
        g = sum(q.weight * x[4] for q, x in zip(qs, st))
        g[selected] = -np.inf
        cand = np.argpartition(-g, nc - 1)[:nc] if nc < N - m else np.flatnonzero(~selected)
        cand = np.union1d(cand, support[~selected[support]])
        score = _swap_scores(qs, X, cand)
        if groups is not None:
            score[~groups.swaps(X, cand)] = -np.inf
        c, o = np.unravel_index(int(np.argmax(score)), score.shape)
        if not score[c, o] > 1e-10:
            break
        selected[X[o]], selected[cand[c]] = False, True
        X[o] = cand[c]
        swaps += 1
    return np.sort(X), swaps


class _Groups:
    """Candidates that must come in numbers: each group (a socket of a session) none or at least ``least`` of
    them in a selection (the rows a calibration needs to fix what they touch); group -1 is free."""

    def __init__(self, groups: np.ndarray, least: np.ndarray):
        self.g = np.asarray(groups, dtype=int)
        self.least = np.asarray(least, dtype=int)

    def counts(self, X: np.ndarray) -> np.ndarray:
        g = self.g[X]
        return np.bincount(g[g >= 0], minlength=len(self.least))

    def short(self, X: np.ndarray) -> np.ndarray:
        """The groups ``X`` holds some but too few rows of."""
        c = self.counts(X)
        return np.flatnonzero((c > 0) & (c < self.least))

    def swaps(self, X: np.ndarray, cand: np.ndarray) -> np.ndarray:
        """Which swaps (candidate in: rows, selected out: columns) keep every group at none or enough."""
        c = self.counts(X)
        gi, go = self.g[cand], self.g[X]
        ok_in = (gi < 0) | (c[np.maximum(gi, 0)] + 1 >= self.least[np.maximum(gi, 0)])
        ok_out = (go < 0) | (c[np.maximum(go, 0)] - 1 >= self.least[np.maximum(go, 0)]) | (c[np.maximum(go, 0)] == 1)
        return (gi[:, None] == go[None, :]) & (gi[:, None] >= 0) | ok_in[:, None] & ok_out[None, :]

    def may_add(self, X: np.ndarray, rows: np.ndarray, also: int | None = None) -> np.ndarray:
        """Unselected ``rows`` one of which can join ``X`` and keep its groups at none or enough (``also``: a group
        whose rows may join too)."""
        c = self.counts(X)
        g = self.g[rows]
        gg = np.maximum(g, 0)
        return (g < 0) | ((c[gg] >= self.least[gg]) & (c[gg] > 0)) | (g == also)

    def may_drop(self, X: np.ndarray, keep: int | None = None) -> np.ndarray:
        """Selected rows one of which can leave ``X`` and keep its group at none or enough (``keep``: a group whose
        rows stay)."""
        c = self.counts(X)
        g = self.g[X]
        gg = np.maximum(g, 0)
        return ((g < 0) | (c[gg] - 1 >= self.least[gg]) | (c[gg] < self.least[gg]) | (c[gg] == 1)) & (g != keep)


def _repair(qs: list[_Question], X: np.ndarray, groups: _Groups) -> np.ndarray:
    """``X`` with every group at none or enough rows: each short group filled up (its best rows in, the rows of
    least use out) or emptied (its rows out, the best others in), whichever gives the larger criterion
    (first-order choices by the variance function, the two outcomes compared exactly)."""
    N, m = qs[0].full.N, len(X)
    for _ in range(m + 1):
        short = groups.short(X)
        if not len(short):
            return np.sort(X)
        c = groups.counts(X)
        k = int(short[np.argmax(c[short] / groups.least[short])])
        options = []
        rows_k = X[groups.g[X] == k]
        # empty the group: its rows out, the best others in
        Y = X[groups.g[X] != k]
        Y = _greedy_add(qs, Y, len(rows_k), groups, exclude=k)
        if Y is not None:
            options.append(Y)
        # fill it up: its best rows in, the rows of least use out
        need = int(groups.least[k] - c[k])
        Y = _greedy_add(qs, X, need, groups, only=k)
        if Y is not None:
            Y = _greedy_drop(qs, Y, need, groups, keep=k)
            if Y is not None:
                options.append(Y)
        if not options:
            raise InputError(f"cannot choose {m} of the {N} candidates so that each point touched has none or at "
                             f"least {int(groups.least.max())} rows: change M")
        X = max(options, key=lambda Y: _value(qs, Y, np.ones(len(Y))))
    return np.sort(X)


def _gain(qs: list[_Question], X: np.ndarray) -> np.ndarray:
    """The combined variance function at the selection ``X`` (first order: what a row adds)."""
    st = _state(qs, X, np.ones(len(X)))
    return sum(q.weight * x[4] for q, x in zip(qs, st))


def _greedy_add(qs, X: np.ndarray, n: int, groups: _Groups, only: int | None = None,
                exclude: int | None = None) -> np.ndarray | None:
    """``X`` plus ``n`` rows, one at a time the unselected row of the largest variance function that keeps the
    groups feasible (``only``: rows of that group; ``exclude``: never rows of that group); None if too few."""
    N = qs[0].full.N
    X = np.array(X, dtype=int)
    for _ in range(n):
        out = np.setdiff1d(np.arange(N), X)
        if only is not None:
            out = out[groups.g[out] == only]
        else:
            out = out[groups.may_add(X, out) & (groups.g[out] != exclude)]
        if not len(out):
            return None
        d = _gain(qs, X)[out] if len(X) else np.zeros(len(out))
        X = np.append(X, out[int(np.argmax(d))])
    return X


def _greedy_drop(qs, X: np.ndarray, n: int, groups: _Groups, keep: int) -> np.ndarray | None:
    """``X`` less ``n`` rows, one at a time the row of the smallest variance function whose leaving keeps the groups
    feasible (never rows of group ``keep``); None if too few may leave."""
    X = np.array(X, dtype=int)
    for _ in range(n):
        ok = groups.may_drop(X, keep)
        if not ok.any():
            return None
        d = np.where(ok, _gain(qs, X)[X], np.inf)
        X = np.delete(X, int(np.argmin(d)))
    return X


@limited_threads()
def ds_design(criteria: list[Criterion], m: int, *, relaxation: str = "first-order", tol: float = 1e-4,
              n_starts: int = 8, seed: int = 0, n_candidates: int | None = None, groups: np.ndarray | None = None,
              least: np.ndarray | None = None, exponent: float = 2.0) -> DsDesign:
    """The M candidates that, added to the measured poses, maximise ``F`` (certified).

    Parameters
    ----------
    criteria : list of Criterion
    m : int
    relaxation : {"first-order", "cvxpy"}
        ``cvxpy`` for a single question only.
    n_starts : int
        Exchange runs: from the M largest relaxed weights, then from random
        roundings (probabilities proportional to the weights); the best is kept.
    n_candidates : int, optional
        Unselected candidates considered per swap (largest variance function;
        the relaxation's support always): default ``max(100, 2 M)``.
    groups, least : ndarray of int, optional
        Candidates that count only in numbers (rows touching one point of a session:
        :mod:`casadical.planning._touches`): candidate ``i``'s group ``groups[i]`` (-1: none), and per group the
        fewest rows a selection holds of it if any (``least[g]``). Rounded starts are repaired to hold each
        group none or that many, and the exchange keeps them so; the relaxation and its bound are those of the
        unconstrained problem (a bound of the constrained designs too).
    exponent : float
        Of the first-order relaxation's multiplicative step (:func:`relax_ds`).
    """
    N = _check(criteria, m)
    t0 = time.perf_counter()
    if relaxation == "cvxpy":
        if len(criteria) != 1:
            raise InputError("the cvxpy relaxation plans one question at a time: give --question N")
        rel = relax_ds_cvxpy(criteria[0], m)
    elif relaxation == "first-order":
        rel = relax_ds(criteria, m, tol=tol, exponent=exponent)
    else:
        raise InputError(f"relaxation must be 'first-order' or 'cvxpy', got {relaxation!r}")
    qs = [_Question(c, m) for c in criteria]
    w = rel.weights
    support = np.flatnonzero(w > 1e-6)
    nc = n_candidates or max(100, 2 * m)
    rng = np.random.default_rng(seed)
    grp = None if groups is None else _Groups(groups, least)
    first = np.sort(np.argsort(-w, kind="stable")[:m])
    seen = {tuple(first.tolist())}
    if grp is not None:
        first = _repair(qs, first, grp)
    best, swaps = _exchange(qs, first, support, nc, 10 * m, grp)
    best_v = _value(qs, best, np.ones(m))
    with np.errstate(divide="ignore"):
        logw = np.log(np.maximum(w, 0.0))
    for _ in range(n_starts - 1):
        start = np.sort(np.argsort(-(logw + rng.gumbel(size=N)))[:m])
        if tuple(start.tolist()) in seen:
            continue
        seen.add(tuple(start.tolist()))
        if grp is not None:
            start = _repair(qs, start, grp)
        X, k = _exchange(qs, start, support, nc, 10 * m, grp)
        swaps += k
        v = _value(qs, X, np.ones(m))
        if v > best_v:
            best, best_v = X, v
    ub = rel.upper_bound
    # the exact design is a feasible point of the relaxation: its own bound holds too
    wx = np.zeros(N)
    wx[best] = 1.0
    ub = min(ub, _bound(qs, _state(qs, np.arange(N), wx), m))
    eff = math.exp(min(0.0, (best_v - ub) / len(qs)))
    return DsDesign(best, best_v, ub, eff, _value(qs, np.zeros(0, int), np.zeros(0)), rel, swaps, len(seen),
                    time.perf_counter() - t0)
