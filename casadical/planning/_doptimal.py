"""Certified D-optimal selection of M distinct poses from a candidate pool.

Pose ``i`` of the pool contributes the rank-3 block ``H_i = A_i^T A_i`` to
the information matrix, with ``A_i`` its ``3 x p`` scaled Jacobian block
(:mod:`casadical.planning._observability`). Choosing ``M`` distinct poses to
maximise ``log det(sum_{i in S} H_i)`` is combinatorial; its continuous
relaxation

    maximise  f(w) = log det M(w),  M(w) = sum_i w_i H_i,
    subject to 0 <= w_i <= 1,  sum_i w_i = M

is concave and gives both a starting point and a bound.

The bound
---------
For any weights ``w`` with ``M(w)`` positive definite, let
``d_i(w) = trace(A_i M(w)^-1 A_i^T)`` (the variance function) and ``S(w)``
the sum of the ``M`` largest ``d_i``. Concavity of log det gives, for every
``Y > 0``, ``log det X <= -log det Y - p + trace(Y X)``; with
``Y = (p / S) M(w)^-1`` and the box constraints,

    f(w') <= f(w) + p log(S(w) / p)    for every feasible w',

so ``U(w) = f(w) + p log(S(w)/p)`` bounds the relaxation and hence every
exact ``M``-pose design. It is the Kiefer-Wolfowitz bound of approximate
design theory (``D-efficiency >= p / max_i d_i``) adapted to the weight
caps: the largest single variance becomes the sum of the ``M`` largest.
``log(S/p)`` is the certified gap per parameter, zero exactly at the
optimum (``d_i`` equal on fractional weights, larger on weights at 1,
smaller on weights at 0). The D-efficiency of any set ``S`` against it is
``exp((log det M_S - U) / p) <= 1``.

Solvers
-------
:func:`relax_multiplicative`
    First-order: the multiplicative algorithm ``w_i <- w_i d_i^gamma``
    projected onto the capped simplex (Kullback-Leibler projection: scale,
    then clip at 1), with an exact line search along the segment (a
    ``p``-dimensional eigenvalue problem) and active-set pruning. It needs
    one pass over the pool per iteration and no ``N x N`` or ``N x p^2``
    storage; 10^5 candidates fit in a few hundred MB.
:func:`relax_cvxpy`
    The same relaxation as a conic program (``cvxpy.log_det``), columns
    scaled so that the information matrix of the uniform design has a unit
    diagonal (otherwise entries of 1e-6 m^2 defeat the solvers' tolerances).
    Accurate but its size grows as ``N p^2``.
:func:`exchange`
    Rounding (the ``M`` largest weights, and random roundings with
    probabilities proportional to the weights) then Fedorov exchange: swap
    the selected/unselected pair with the largest determinant ratio,
    ``det(I_6 + D U^T M^-1 U)``, ``U = [A_in^T, A_out^T]``,
    ``D = diag(I_3, -I_3)``, until no swap improves; the best of the starts
    is kept.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np

from ..errors import IdentifiabilityError, InputError, SolverError
from ..runtime._threads import limited_threads


@dataclass
class RelaxationSettings:
    """Settings of the first-order relaxation solver.

    Parameters
    ----------
    tol : float
        Stop when the certified gap per parameter, ``log(S/p)``, is at most
        this (log det units; 1e-3 = 0.1 % D-efficiency).
    max_iter : int
        Iteration limit.
    time_limit_s : float
        Wall-clock limit; the result is still certified (with a larger gap).
    exponent : float
        ``gamma`` of the multiplicative update ``w_i d_i^gamma``; 1 is the
        classical algorithm, larger values converge faster and the line
        search keeps them monotone (5 takes about 40 % fewer iterations
        than 3 on 2,000-10^5 candidates, the same certificate).
    prune : float
        Weights below this leave the active set (checked back against the
        whole pool before the result is certified). The certificate does not
        depend on it; the speed does: 1e-5 keeps the active set small early.
    check_every : int
        Least iterations between full-pool variance checks (a check is also
        skipped until the active-set work since the last one is as large as
        the pool).
    chunk : int
        Poses per block when sweeping the pool (bounds temporary memory and
        keeps a block in the CPU cache).
    """

    tol: float = 1e-4
    max_iter: int = 20000
    time_limit_s: float = 600.0
    exponent: float = 5.0
    prune: float = 1e-5
    check_every: int = 25
    chunk: int = 2048

    def __post_init__(self) -> None:
        if not self.tol > 0:
            raise InputError(f"tol must be positive, got {self.tol}")
        if not self.exponent > 0:
            raise InputError(f"exponent must be positive, got {self.exponent}")
        if self.max_iter < 1 or self.check_every < 1 or self.chunk < 1:
            raise InputError("max_iter, check_every and chunk must be at least 1")


@dataclass
class Relaxation:
    """Solution of the continuous relaxation.

    Attributes
    ----------
    weights : ndarray, shape (N,)
        In [0, 1], summing to M.
    log_det : float
        ``log det M(w)`` (scaled Jacobian, SI).
    upper_bound : float
        Certified bound ``U(w)`` on the log det of every M-pose design.
    gap_per_parameter : float
        ``(upper_bound - log_det) / p``.
    method : str
        ``"multiplicative"`` or ``"cvxpy:<SOLVER>"``.
    status : str
        Why the solver stopped.
    iterations : int
    time_s : float
    """

    weights: np.ndarray = field(repr=False)
    log_det: float
    upper_bound: float
    gap_per_parameter: float
    method: str
    status: str
    iterations: int
    time_s: float

    @property
    def n_support(self) -> int:
        """Candidates with a weight above 1e-6."""
        return int(np.sum(self.weights > 1e-6))

    @property
    def n_at_one(self) -> int:
        """Candidates with a weight of (almost) 1."""
        return int(np.sum(self.weights > 1 - 1e-6))


@dataclass
class ExactDesign:
    """An exact design of M distinct poses.

    Attributes
    ----------
    indices : ndarray of int
        Sorted pool rows.
    log_det : float
        ``log det`` of its information matrix.
    swaps : int
        Exchanges made after rounding (all starts).
    time_s : float
    starts : int
        Exchange runs (distinct starting sets) behind this design.
    """

    indices: np.ndarray
    log_det: float
    swaps: int
    time_s: float
    starts: int = 1


@dataclass
class DOptimalDesign:
    """Result of :func:`d_optimal_design`.

    Attributes
    ----------
    indices : ndarray of int
        The M selected pool rows, sorted.
    log_det : float
        ``log det(J_S^T J_S)`` of the selection.
    upper_bound : float
        Best certified bound on the log det of any M-pose subset of the pool.
    d_efficiency : float
        ``exp((log_det - upper_bound) / p)``: the selection is at least this
        D-efficient relative to the (unknown) best subset.
    relaxation : Relaxation
    exchange : ExactDesign
    time_s : float
        Relaxation, rounding and exchange.
    """

    indices: np.ndarray
    log_det: float
    upper_bound: float
    d_efficiency: float
    relaxation: Relaxation
    exchange: ExactDesign
    time_s: float


# --- the pool -------------------------------------------------------------------------


class _Pool:
    """Per-pose blocks with a column scaling for well-conditioned linear algebra.

    Work is in scaled coordinates ``A_i C`` with ``C = diag(c)`` chosen so
    that the uniform design ``w = M/N`` has a unit-diagonal information
    matrix; log dets are converted back by ``- 2 sum log c``.

    Sweeps over the pool go in chunks of ``chunk`` poses (small enough to
    stay in the CPU cache); the scaled blocks of one small index set (the
    relaxation's active set, an exchange's candidates) are kept contiguous
    between calls.
    """

    def __init__(self, A: np.ndarray, m: int, chunk: int = 2048):
        A = np.asarray(A, dtype=float)
        if A.ndim != 3:
            raise InputError(f"expected per-pose Jacobian blocks of shape (N, r, p), got shape {A.shape}")
        self.A = A
        self.N, self.r, self.p = A.shape
        self.m = int(m)
        self.chunk = int(chunk)
        sq = np.zeros(self.p)
        for s in range(0, self.N, self.chunk):
            sq += np.einsum("nij,nij->j", A[s:s + self.chunk], A[s:s + self.chunk])
        with np.errstate(divide="ignore"):
            c = 1.0 / np.sqrt(sq / self.N * self.m)
        c[~np.isfinite(c)] = 1.0  # a column without effect anywhere: leave it (M will be singular)
        self.c = c
        self.log_c = float(np.sum(np.log(c)))
        self._kept: tuple[np.ndarray, np.ndarray] | None = None

    def blocks(self, idx: np.ndarray) -> np.ndarray:
        """Scaled blocks of the poses ``idx`` as one ``(len(idx) r, p)`` array (cached for one set)."""
        if self._kept is not None and np.array_equal(self._kept[0], idx):
            return self._kept[1]
        B = (self.A[idx] * self.c).reshape(-1, self.p)
        self._kept = (np.array(idx), B)
        return B

    def _sweep(self, idx: np.ndarray | None):
        """``(start, 2-D blocks, scaled)`` over the pool or ``idx``, in chunks; small sets in one piece.

        Chunks are not scaled (the scaling is applied to the small matrices instead).
        """
        n = self.N if idx is None else len(idx)
        if idx is not None and n <= 4 * self.chunk:
            yield 0, self.blocks(idx), True
            return
        for s in range(0, n, self.chunk):
            blk = self.A[s:s + self.chunk] if idx is None else self.A[idx[s:s + self.chunk]]
            yield s, blk.reshape(-1, self.p), False

    def info(self, idx: np.ndarray, w: np.ndarray) -> np.ndarray:
        """Scaled ``sum_k w_k H_idx[k]`` (weights may be negative: a difference of designs)."""
        out = np.zeros((self.p, self.p))
        raw = np.zeros((self.p, self.p))
        for s, B, scaled in self._sweep(idx):
            n = len(B) // self.r
            part = (B * np.repeat(w[s:s + n], self.r)[:, None]).T @ B
            if scaled:
                out += part
            else:
                raw += part
        out += raw * np.outer(self.c, self.c)
        return 0.5 * (out + out.T)

    def variances(self, T: np.ndarray, idx: np.ndarray | None = None) -> np.ndarray:
        """``d_i = ||T C A_i^T||_F^2`` for ``T = L^-1`` (scaled Cholesky factor of M)."""
        d = np.empty(self.N if idx is None else len(idx))
        TT, TC = T.T, (T * self.c).T
        for s, B, scaled in self._sweep(idx):
            G = B @ (TT if scaled else TC)
            n = len(B) // self.r
            d[s:s + n] = np.einsum("ij,ij->i", G, G).reshape(n, self.r).sum(axis=1)
        return d

    def factor(self, Ms: np.ndarray) -> tuple[np.ndarray, float]:
        """Cholesky factor of a scaled information matrix and its log det in original units."""
        try:
            L = np.linalg.cholesky(Ms)
        except np.linalg.LinAlgError:
            raise IdentifiabilityError("the information matrix is singular: the weighted poses do "
                                       "not identify every parameter") from None
        return L, 2.0 * float(np.sum(np.log(np.diag(L)))) - 2.0 * self.log_c

    def bound_from(self, log_det: float, d: np.ndarray) -> float:
        """``U = log det + p log(S / p)``, ``S`` the sum of the M largest variances."""
        S = float(np.sum(_top(d, self.m)))
        return log_det + self.p * math.log(max(S, self.p) / self.p)


def _top(x: np.ndarray, k: int) -> np.ndarray:
    """The k largest entries (unordered)."""
    if k >= len(x):
        return x
    return np.partition(x, len(x) - k)[len(x) - k:]


def _check_m(A: np.ndarray, m: int) -> None:
    N, r, p = A.shape
    if not isinstance(m, (int, np.integer)) or m < 1:
        raise InputError(f"the number of poses M must be a positive integer, got {m!r}")
    if m > N:
        raise InputError(f"cannot choose M={m} distinct poses from a pool of {N}")
    need = -(-p // r)
    if m < need:
        raise IdentifiabilityError(f"M={m} poses give {m * r} equations, fewer than the {p} "
                                   f"identifiable parameters; choose M >= {need}")


# --- the bound ------------------------------------------------------------------------


@limited_threads()
def upper_bound(A: np.ndarray, m: int, weights: np.ndarray) -> float:
    """Certified upper bound on the log det of every M-pose subset of the pool.

    Parameters
    ----------
    A : ndarray, shape (N, r, p)
        Scaled Jacobian blocks of the pool.
    m : int
        Design size M.
    weights : ndarray, shape (N,)
        Any non-negative weights with ``M(w)`` positive definite (a relaxed
        solution, or a 0/1 exact design); the closer to optimal, the tighter.

    Returns
    -------
    float
        ``log det M(w) + p log(S(w)/p)``.
    """
    A = np.asarray(A, dtype=float)
    _check_m(A, m)
    pool = _Pool(A, m)
    w = np.asarray(weights, dtype=float)
    idx = np.flatnonzero(w > 0)
    L, ld = pool.factor(pool.info(idx, w[idx]))
    return pool.bound_from(ld, pool.variances(np.linalg.inv(L)))


def d_efficiency(log_det: float, bound: float, p: int) -> float:
    """``exp((log_det - bound) / p)``, 0 for a singular design."""
    if not math.isfinite(log_det):
        return 0.0
    return float(math.exp(min(0.0, (log_det - bound) / p)))


# --- first-order relaxation -------------------------------------------------------------


def _cap_project(u: np.ndarray, m: int) -> np.ndarray:
    """``v = min(1, t u)`` with ``sum v = m`` (KL projection onto the capped simplex)."""
    o = np.sort(u)[::-1]
    tail = np.cumsum(o[::-1])[::-1]  # tail[k] = sum of o[k:]
    k = np.arange(min(m, len(o)))
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (m - k) / tail[k]
        ok = (t * o[k] <= 1.0 + 1e-12) & (tail[k] > 0)
    if not ok.any():
        raise SolverError("cannot spread the weights: fewer than M candidates carry information")
    kk = int(k[np.argmax(ok)])
    return np.minimum(1.0, t[kk] * u)


def _line_search(lam: np.ndarray) -> float:
    """argmax over s in [0, 1] of sum log(1 + s lam) (concave; lam from the step's eigenproblem)."""
    lo, hi = 0.0, 1.0
    if lam.min() < 0:
        hi = min(1.0, (1.0 - 1e-12) / -lam.min())
    if np.sum(lam / (1.0 + hi * lam)) >= 0:
        return hi
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        if np.sum(lam / (1.0 + mid * lam)) > 0:
            lo = mid
        else:
            hi = mid
    return lo


@limited_threads()
def relax_multiplicative(A: np.ndarray, m: int, settings: RelaxationSettings | None = None,
                         w0: np.ndarray | None = None) -> Relaxation:
    """Solve the relaxation with the capped multiplicative algorithm (first-order).

    Parameters
    ----------
    A : ndarray, shape (N, r, p)
        Scaled Jacobian blocks of the pool.
    m : int
        Design size M.
    settings : RelaxationSettings, optional
    w0 : ndarray, optional
        Starting weights (default uniform ``M/N``).

    Returns
    -------
    Relaxation
        Certified: ``upper_bound`` holds whatever the stopping reason.

    Raises
    ------
    IdentifiabilityError
        The pool cannot identify every parameter, or M is too small.
    """
    A = np.asarray(A, dtype=float)
    _check_m(A, m)
    st = settings or RelaxationSettings()
    t0 = time.perf_counter()
    pool = _Pool(A, m, st.chunk)
    N, p = pool.N, pool.p
    w = np.full(N, m / N) if w0 is None else _cap_project(np.maximum(np.asarray(w0, float), 1e-300), m)
    act = np.flatnonzero(w > 0)
    Ms = pool.info(act, w[act])
    status = f"iteration limit ({st.max_iter})"
    best_ub, ld, it = math.inf, -math.inf, 0
    last_full, work = 0, 0
    for it in range(1, st.max_iter + 1):
        if it % st.check_every == 0:
            Ms = pool.info(act, w[act])  # drop the rounding drift of the incremental updates
        L, ld = pool.factor(Ms)
        T = np.linalg.inv(L)
        d = pool.variances(T, act)
        work += len(act)
        gap_act = math.log(max(float(np.sum(_top(d, m))), p) / p)
        timeout = time.perf_counter() - t0 > st.time_limit_s
        # a sweep of the whole pool costs N: at most about as often as the active-set work pays for it
        due = it - last_full >= st.check_every and work >= N
        if gap_act <= st.tol or due or timeout or it == st.max_iter:
            # certify against the whole pool; pruned candidates that now matter come back
            last_full, work = it, 0
            d_all = pool.variances(T)
            ub = pool.bound_from(ld, d_all)
            best_ub = min(best_ub, ub)
            if (ub - ld) / p <= st.tol:
                status = "converged"
                break
            if timeout:
                status = f"time limit ({st.time_limit_s:g} s)"
                break
            thresh = np.partition(d_all, N - m)[N - m]
            back = np.setdiff1d(np.flatnonzero(d_all >= thresh), act, assume_unique=True)
            if len(back):
                w[back] = m / N
                act = np.union1d(act, back)
                w[act] = _cap_project(w[act], m)
                Ms = pool.info(act, w[act])
                continue
            d_act = d
        else:
            d_act = d
        wa = w[act]
        # the update direction: KL projection of w d^gamma; d scaled by its mean to avoid overflow
        ds = d_act / (p / m)
        v = None
        for gamma in (st.exponent, 1.0):
            cand = _cap_project(wa * ds ** gamma, m)
            if float(np.dot(d_act, cand - wa)) > 1e-14 * p:
                v = cand
                break
        if v is None:
            status = "no ascent direction (at the optimum to machine precision)"
            break
        Dm = pool.info(act, v - wa)
        lam = np.linalg.eigvalsh(T @ Dm @ T.T)
        s = _line_search(lam)
        w[act] = wa + s * (v - wa)
        Ms = Ms + s * Dm
        keep = w[act] > st.prune
        # prune in batches: each pruning recomputes the information matrix
        if np.count_nonzero(~keep) > len(act) // 50 or (it % st.check_every == 0 and not keep.all()):
            w[act[~keep]] = 0.0
            act = act[keep]
            w[act] = _cap_project(w[act], m)
            Ms = pool.info(act, w[act])
    L, ld = pool.factor(pool.info(act, w[act]))
    best_ub = min(best_ub, pool.bound_from(ld, pool.variances(np.linalg.inv(L))))
    return Relaxation(w, ld, best_ub, (best_ub - ld) / p, "multiplicative", status, it,
                      time.perf_counter() - t0)


# --- conic relaxation -----------------------------------------------------------------


@limited_threads()
def relax_cvxpy(A: np.ndarray, m: int, solver: str | None = None, verbose: bool = False,
                **solver_options) -> Relaxation:
    """Solve the relaxation as a conic program with cvxpy's ``log_det``.

    Parameters
    ----------
    A : ndarray, shape (N, r, p)
    m : int
    solver : str, optional
        A cvxpy solver supporting the exponential and PSD cones. Default:
        CLARABEL (interior point, accurate), and SCS if CLARABEL fails (it
        stalls on pools of ~10^4 candidates, whose constraint matrix holds
        ``N p (p + 1) / 2`` nonzeros).
    verbose : bool
    **solver_options
        Passed to ``Problem.solve``.

    Returns
    -------
    Relaxation
        Weights clipped to [0, 1]; the bound is recomputed from them with
        :func:`upper_bound` so the two solvers are certified the same way.
    """
    import cvxpy as cp

    A = np.asarray(A, dtype=float)
    _check_m(A, m)
    t0 = time.perf_counter()
    pool = _Pool(A, m)
    N, p = pool.N, pool.p
    As = A * pool.c
    H = np.einsum("nri,nrj->nij", As, As).reshape(N, p * p)
    w = cp.Variable(N)
    Mx = cp.reshape(H.T @ w, (p, p), order="F")
    prob = cp.Problem(cp.Maximize(cp.log_det((Mx + Mx.T) / 2)),
                      [w >= 0, w <= 1, cp.sum(w) == m])
    solver, failures = solve_in_turn(prob, w, solver, verbose=verbose, **solver_options)
    wv = np.clip(np.asarray(w.value, dtype=float), 0.0, 1.0)
    idx = np.flatnonzero(wv > 0)
    L, ld = pool.factor(pool.info(idx, wv[idx]))
    ub = pool.bound_from(ld, pool.variances(np.linalg.inv(L)))
    stats = prob.solver_stats
    its = int(stats.num_iters) if stats is not None and stats.num_iters is not None else 0
    status = str(prob.status) + (f" (after: {'; '.join(failures)})" if failures else "")
    return Relaxation(wv, ld, ub, (ub - ld) / p, f"cvxpy:{solver}", status, its,
                      time.perf_counter() - t0)


def solve_in_turn(prob, w, solver: str | None = None, **options) -> tuple[str, list[str]]:
    """Solve a cvxpy problem with ``solver``, or CLARABEL and then SCS if CLARABEL fails; the solver that
    did and the failures before it.

    Raises
    ------
    SolverError
        No solver gave weights ``w`` with an optimal (or optimal-inaccurate) status.
    """
    import cvxpy as cp

    if solver is None:
        installed = cp.installed_solvers()
        chain = [s for s in ("CLARABEL", "SCS") if s in installed] or [None]
    else:
        chain = [solver]
    failures: list[str] = []
    for name in chain:
        try:
            prob.solve(solver=name, **options)
        except cp.error.SolverError as e:
            failures.append(f"{name} failed: {str(e).splitlines()[0]}")
            continue
        if w.value is not None and prob.status in ("optimal", "optimal_inaccurate"):
            return name, failures
        failures.append(f"{name} ended with status {prob.status}")
    raise SolverError(f"cvxpy could not solve the relaxation: {'; '.join(failures)}")


# --- rounding and exchange ------------------------------------------------------------


@limited_threads()
def exchange(A: np.ndarray, m: int, start, *, n_candidates: int | None = None,
             max_swaps: int | None = None, weights: np.ndarray | None = None) -> ExactDesign:
    """Fedorov exchange from a starting set of M distinct poses.

    Parameters
    ----------
    A : ndarray, shape (N, r, p)
    m : int
    start : array_like of int
        M distinct pool rows.
    n_candidates : int, optional
        Unselected poses considered per swap: those of largest variance
        ``d_i`` under the current set (a swap-in gains at most
        ``det(I + A_i M^-1 A_i^T)``, so low-variance poses cannot help much);
        default ``max(100, 2 M)``, capped by the pool.
    max_swaps : int, optional
        Default ``10 M``.
    weights : ndarray, optional
        Relaxed weights: candidates with positive weight are always considered.

    Returns
    -------
    ExactDesign
    """
    A = np.asarray(A, dtype=float)
    _check_m(A, m)
    t0 = time.perf_counter()
    pool = _Pool(A, m)
    X = np.array(start, dtype=int).ravel()
    if len(X) != m or len(np.unique(X)) != m or X.min() < 0 or X.max() >= pool.N:
        raise InputError(f"the starting design must hold {m} distinct pool rows")
    X, swaps = _exchange(pool, X, n_candidates, max_swaps, weights)
    return ExactDesign(X, _exact_log_det(pool, X), swaps, time.perf_counter() - t0)


def _exact_log_det(pool: _Pool, X: np.ndarray) -> float:
    sign, ld = np.linalg.slogdet(pool.info(X, np.ones(len(X))))
    return float(ld) - 2.0 * pool.log_c if sign > 0 else -math.inf


def _exchange(pool: _Pool, X: np.ndarray, n_candidates: int | None, max_swaps: int | None,
              weights: np.ndarray | None) -> tuple[np.ndarray, int]:
    """Fedorov exchange on a pool; returns the sorted design and the number of swaps.

    Each step scores every (candidate in, selected out) pair among the ``nc``
    unselected poses of largest variance (plus the relaxation's support) by
    the determinant ratio ``det(I + A_c M^-1 A_c^T) det(I - A_o M'^-1 A_o^T)``
    (``M' = M + A_c^T A_c``; the same value as ``det(I_2r + D U^T M^-1 U)``),
    all pairs at once from one matrix product. Variances are computed on a
    working list of poses; before stopping, the whole pool is checked and
    the list extended if its ``nc`` largest variances lie outside it, so the
    stopping rule is that of the exchange over the whole pool.
    """
    N, r, p, m = pool.N, pool.r, pool.p, len(X)
    X = X.copy()
    nc = min(N - m, n_candidates or max(100, 2 * m))
    max_swaps = 10 * m if max_swaps is None else max_swaps
    support = np.flatnonzero(weights > 1e-6) if weights is not None else np.zeros(0, int)
    # a tiny ridge keeps the criterion finite for a rank-deficient start; swaps that
    # restore the rank then have huge ratios
    ridge = 1e-10 * np.eye(p)
    I = np.eye(r)
    work: np.ndarray | None = None  # working list of pool rows (sorted)
    selected = np.zeros(N, dtype=bool)
    selected[X] = True
    swaps = 0
    while nc > 0 and swaps < max_swaps:
        L = np.linalg.cholesky(pool.info(X, np.ones(m)) + ridge)
        T = np.linalg.inv(L)
        if work is None:
            work = _top_rows(pool.variances(T), X, min(N - m, 4 * nc), support)
        rows = work[~selected[work]]
        d = pool.variances(T, rows)
        cand = rows[np.argpartition(-d, nc - 1)[:nc]] if nc < len(rows) else rows
        cand = np.union1d(cand, support[~selected[support]])
        ratio = _swap_ratios(pool, T, cand, X, I)
        c, o = np.unravel_index(int(np.argmax(ratio)), ratio.shape)
        if not ratio[c, o] > 1.0 + 1e-10:
            # no swap improves within the working list: check the whole pool before stopping
            top = _top_rows(pool.variances(T), X, nc, np.zeros(0, int))
            new = np.setdiff1d(top, work, assume_unique=True)
            if not len(new):
                break
            work = np.union1d(work, new)
            continue
        selected[X[o]], selected[cand[c]] = False, True
        X[o] = cand[c]
        swaps += 1
    return np.sort(X), swaps


def _top_rows(d: np.ndarray, X: np.ndarray, k: int, extra: np.ndarray) -> np.ndarray:
    """The k unselected rows of largest ``d``, with ``extra`` added (sorted, unique)."""
    d = d.copy()
    d[X] = -np.inf
    top = np.argpartition(-d, k - 1)[:k] if k < len(d) - len(X) else np.flatnonzero(np.isfinite(d))
    return np.union1d(top, extra)


def _swap_ratios(pool: _Pool, T: np.ndarray, cand: np.ndarray, X: np.ndarray, I: np.ndarray) -> np.ndarray:
    """``det(M_new) / det(M)`` for swapping each candidate (rows) in and each selected pose (columns) out.

    With whitened blocks ``a = A T^T`` (``M^-1 = T^T T``) and ``I + a_c a_c^T = R_c R_c^T``, the
    ratio is ``det(R_c)^2 det(I - a_o a_o^T + W^T W)`` with ``W = R_c^-1 a_c a_o^T``: one matrix
    product for all pairs, then closed-form ``r x r`` determinants.
    """
    r, p = pool.r, pool.p
    k, m = len(cand), len(X)
    TC = (T * pool.c).T
    GX = pool.A[X].reshape(m * r, p) @ TC                     # whitened blocks of the design
    GC = (pool.A[cand].reshape(k * r, p) @ TC).reshape(k, r, p)
    R = np.linalg.cholesky(I + np.einsum("kip,kjp->kij", GC, GC))
    det_in = np.prod(np.diagonal(R, axis1=1, axis2=2), axis=1) ** 2
    Q = np.einsum("kij,kjp->kip", np.linalg.inv(R), GC)
    W = (Q.reshape(k * r, p) @ GX.T).reshape(k, r, m, r).transpose(3, 1, 0, 2).copy()  # W[a, j, c, o]
    GX = GX.reshape(m, r, p)
    Boo = np.einsum("oip,ojp->ijo", GX, GX)                   # a_o a_o^T, (r, r, m)
    S = np.empty((r, r, k, m))
    for a in range(r):
        for b in range(a, r):
            acc = W[a, 0] * W[b, 0]
            for j in range(1, r):
                acc += W[a, j] * W[b, j]
            acc += I[a, b] - Boo[a, b]
            S[a, b] = S[b, a] = acc
    return det_in[:, None] * _det_small(S)


def _det_small(S: np.ndarray) -> np.ndarray:
    """Determinants of ``S[:, :, ...]`` (a stack of small matrices, leading axes; closed form up to 3 x 3)."""
    n = S.shape[0]
    if n == 1:
        return S[0, 0]
    if n == 2:
        return S[0, 0] * S[1, 1] - S[0, 1] * S[1, 0]
    if n == 3:
        return (S[0, 0] * (S[1, 1] * S[2, 2] - S[1, 2] * S[2, 1])
                - S[0, 1] * (S[1, 0] * S[2, 2] - S[1, 2] * S[2, 0])
                + S[0, 2] * (S[1, 0] * S[2, 1] - S[1, 1] * S[2, 0]))
    return np.linalg.det(np.moveaxis(S, (0, 1), (-2, -1)))


def round_weights(weights: np.ndarray, m: int, tiebreak: np.ndarray | None = None) -> np.ndarray:
    """The M candidates of largest weight (ties broken by ``tiebreak``, e.g. the variances)."""
    w = np.asarray(weights, dtype=float)
    key = w if tiebreak is None else w + 1e-9 * tiebreak / max(float(np.max(np.abs(tiebreak))), 1e-300)
    return np.sort(np.argsort(-key, kind="stable")[:m])


def _auto_starts(N: int) -> int:
    # exchange costs ~M p^2 (nc + M) per swap: many starts on small pools, a few on huge ones. Twice
    # the starts of the first version (16 / 8 / 3), now that a swap is several times cheaper: the best
    # local optimum depends less on which roundings the relaxation's path leads to
    return 32 if N <= 2000 else 16 if N <= 20000 else 6


@limited_threads()
def round_and_exchange(A: np.ndarray, m: int, weights: np.ndarray, *, n_starts: int | None = None,
                       seed: int = 0, n_candidates: int | None = None) -> ExactDesign:
    """Exact design of M distinct poses from relaxed weights: best of several rounded starts + exchange.

    Parameters
    ----------
    A : ndarray, shape (N, r, p)
    m : int
    weights : ndarray, shape (N,)
        Relaxed weights (:class:`Relaxation` ``.weights``).
    n_starts : int, optional
        Exchange runs: from the M largest weights, then from random roundings
        (M poses drawn without replacement with probabilities proportional
        to the weights). Exchange stops at a local optimum for single swaps;
        several starts escape poor ones, which matters when M is close to
        ``p / 3``. Default 32 for pools up to 2,000, 16 up to 20,000, else 6.
    seed : int
        Seed of the random roundings.
    n_candidates : int, optional
        See :func:`exchange`.
    """
    A = np.asarray(A, dtype=float)
    _check_m(A, m)
    N = A.shape[0]
    w = np.asarray(weights, dtype=float)
    n_starts = _auto_starts(N) if n_starts is None else max(1, int(n_starts))
    rng = np.random.default_rng(seed)
    with np.errstate(divide="ignore"):
        logw = np.log(np.maximum(w, 0.0))
    t0 = time.perf_counter()
    pool = _Pool(A, m)
    first = round_weights(w, m)
    seen = {tuple(first.tolist())}
    best, swaps = _exchange(pool, first, n_candidates, None, w)
    best_ld = _exact_log_det(pool, best)
    for _ in range(n_starts - 1):
        # Gumbel top-M: sampling without replacement, probabilities proportional to w
        start = np.sort(np.argsort(-(logw + rng.gumbel(size=N)))[:m])
        key = tuple(start.tolist())
        if key in seen:
            continue
        seen.add(key)
        X, k = _exchange(pool, start, n_candidates, None, w)
        swaps += k
        ld = _exact_log_det(pool, X)
        if ld > best_ld:
            best, best_ld = X, ld
    return ExactDesign(best, best_ld, swaps, time.perf_counter() - t0, len(seen))


@limited_threads()
def d_optimal_design(A: np.ndarray, m: int, *, relaxation: str = "first-order",
                     settings: RelaxationSettings | None = None,
                     n_candidates: int | None = None, n_starts: int | None = None,
                     seed: int = 0) -> DOptimalDesign:
    """Certified D-optimal choice of M distinct poses.

    Parameters
    ----------
    A : ndarray, shape (N, r, p)
        Scaled Jacobian blocks of the identifiable parameters over the pool.
    m : int
        Number of poses M.
    relaxation : {"first-order", "cvxpy"}
        Relaxation solver.
    settings : RelaxationSettings, optional
        For the first-order solver.
    n_candidates : int, optional
        See :func:`exchange`.
    n_starts, seed : optional
        See :func:`round_and_exchange`.

    Returns
    -------
    DOptimalDesign
    """
    A = np.asarray(A, dtype=float)
    _check_m(A, m)
    t0 = time.perf_counter()
    if relaxation == "first-order":
        rel = relax_multiplicative(A, m, settings)
    elif relaxation == "cvxpy":
        rel = relax_cvxpy(A, m)
    else:
        raise InputError(f"relaxation must be 'first-order' or 'cvxpy', got {relaxation!r}")
    N, _, p = A.shape
    ex = round_and_exchange(A, m, rel.weights, n_starts=n_starts, seed=seed, n_candidates=n_candidates)
    ub = rel.upper_bound
    if math.isfinite(ex.log_det):
        # the exact design is itself a feasible point of the relaxation: its bound holds too
        w = np.zeros(N)
        w[ex.indices] = 1.0
        ub = min(ub, upper_bound(A, m, w))
    return DOptimalDesign(ex.indices, ex.log_det, ub, d_efficiency(ex.log_det, ub, p), rel, ex,
                          time.perf_counter() - t0)
