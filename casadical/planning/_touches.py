"""Planning rows that touch: which candidate configurations in a socket tell most (the Ds criterion).

A candidate file may say what each configuration touches (``point``, ``plane``; ``session``; a fixture file's
points: docs/formats.md section 11): the user records many configurations with the ball in a socket (by hand
guiding, say) and the planner says which M of them to keep or to measure. Unlike a tracker row, a touch row does
not add its information on its own: the thing it touches is an unknown of its session (a socket's point, a
plane, a fixture's pose), estimated with the robot's parameters, and for touches alone the whole robot's turn is
not seen either (:class:`casadical.rows._layout.Projection`). Those unknowns are nuisance parameters.

The criterion
-------------
Row ``i`` has the ``r x p`` block ``A_i`` over the robot's identifiable parameters (scaled columns, as
:func:`~casadical.planning._observability.design_problem`; a plane's or a pivot's row its model point's change
along its one measured direction: the kind's ``row_map``) and the block ``N_i`` over the nuisance: its group's
unknowns (the kind's ``basis``, an orthonormal basis of it) and, for touches alone, the turn ``e_k x r_i`` of its
residual. With weights ``w`` the augmented information matrix is

    M(w) = sum_i w_i [A_i N_i]^T [A_i N_i] = [[M_aa, M_an], [M_na, M_nn]],

and the information about the robot's parameters once every nuisance parameter is estimated too is its Schur
complement ``S(w) = M_aa - M_an M_nn^+ M_na``. The criterion is

    f(w) = log det S(w) = log det M(w) - log det M_nn(w)

(Ds-optimality, ``s = p`` parameters of interest). For a 0/1 design ``S`` is exactly ``J_p^T J_p``, the
Gram matrix of the Jacobian the calibration works with (the layout's projection of the selected rows'
Jacobian away from what they touched: ``A^T (I - P_N) A`` is the Schur complement), so the criterion judges a
selection by the information of the calibration it will give. It is NOT additive: one row in a socket nobody
else touches tells nothing (its three equations fix the socket's point), a second row in it tells the
difference of the two.

``f`` is concave in ``w``: ``S(w) = min_X B_X^T M(w) B_X`` (Loewner order, ``B_X = [I; -X]``) is the
pointwise minimum of linear functions, hence concave, and log det is concave and increasing.

The certificate
---------------
Take any feasible ``w`` (``0 <= w_i <= 1``, ``sum w_i = M``) with ``S(w)`` positive definite and
``X = M_nn(w)^+ M_na(w)``, so that ``S(w) = B^T M(w) B``. For every feasible ``w'``,
``S(w') <= B^T M(w') B`` (the minimum over X), and concavity of log det at ``Y = S(w) / t`` gives, for all
``t > 0``,

    f(w') <= log det(B^T M(w') B) <= f(w) - p log t - p + t trace(S(w)^-1 B^T M(w') B)
           = f(w) - p log t - p + t sum_i w'_i d_i(w),

with ``d_i(w) = trace(S^-1 B^T H_i B)``: the Ds variance function, the full variance of row ``i`` less what
its nuisance takes, ``d_i = trace(C_i M^-1 C_i^T) - trace(N_i M_nn^-1 N_i^T)`` (``C_i = [A_i N_i]``). The
largest ``sum_i w'_i d_i`` over the box-constrained simplex is ``S_M(w)``, the sum of the ``M`` largest
``d_i``; at the best ``t = p / S_M`` the bound is

    f(w') <= U(w) = f(w) + p log(S_M(w) / p)          for every feasible w',

so no M candidates, and no relaxed weights, reach more than ``U(w)``: the Kiefer-Wolfowitz bound of
:mod:`~casadical.planning._doptimal` with the Ds variance function in place of the D one (the Ds equivalence
theorem: at the optimum ``d_i`` is equal on fractional weights, at least that on weights at 1, at most on weights
at 0, and ``S_M = p``). The gap ``log(S_M / p)`` per parameter is certified whatever stopped the solver; the
Ds-efficiency of a selection is at least ``exp((f(selection) - U) / p)``. A calibration needs at least
:data:`~casadical.data._measurements.MIN_TOUCH_ROWS` rows of a session at each point it touches; the exact
design keeps every group at none or that many (a constraint of the 0/1 designs alone: the relaxation's bound
holds for the constrained designs a fortiori).

What the rows cannot see (the base pose; without a known distance the scale of every length; the parameters
that only move the whole robot: :mod:`casadical.calibration._unobservable`) is held: those parameters are not
among the ``p``, as in the calibration. The relaxation, bound and exchange are those of
:mod:`casadical.planning._augment` (a question of ``p`` parameters among ``p`` plus the nuisance), which
also plans, with the measured rows' information ``M0``, from a report's open questions.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..calibration._unobservable import unseen, whole_robot
from ..data._measurements import MIN_TOUCH_ROWS, Measurements
from ..errors import IdentifiabilityError, IdentifiabilityWarning, InputError
from ..rows._tracker import TRACKER_POINT
from ..runtime._threads import limited_threads
from ..stats._identifiability import analyse
from ._observability import pool_jacobian

#: the multiplicative step's exponent of the relaxation (:func:`casadical.planning._augment.relax_ds`): on the truth's
#: touch candidates (240 rows, 19 parameters) 5 converges in 160-190 iterations with a fixture or without, 2 in
#: 200-1100
EXPONENT = 5.0


@dataclass
class Nuisance:
    """The nuisance columns of a set of rows: each touch group's unknowns and, for touches alone, the turn.

    Attributes
    ----------
    N : ndarray, shape (n, 3, k)
        Each row's block over the ``k`` nuisance columns.
    groups : ndarray of int, shape (n,)
        Each row's group (index into ``group_names``); -1 for a measured (tracker) row.
    group_names : list of str
        ``"point s0 of session P1"`` and the like.
    row_map : ndarray, shape (n, 3, 3)
        How each row's residual moves with its model point (the identity for a point, ``n n^T`` on a plane).
    turn : bool
        The last 3 columns are the whole robot's turn (touches alone).
    """

    N: np.ndarray
    groups: np.ndarray
    group_names: list[str]
    row_map: np.ndarray
    turn: bool


def nuisance(data: Measurements, P: np.ndarray) -> Nuisance:
    """The nuisance columns of ``data``'s rows at the model points ``P`` (n, 3): the kinds' bases of their
    groups' unknowns (each made orthonormal: a fixture of points on one line has 5, not 6) and, for touches alone,
    the whole robot's turn as :class:`~casadical.rows._layout.Projection` takes it (``e_k x r_i``, mapped as the
    row's residual is)."""
    lay = data.layout
    n = len(data)
    groups = np.full(n, -1)
    names: list[str] = []
    row_map = np.broadcast_to(np.eye(3), (n, 3, 3)).copy()
    r = np.zeros((n, 3))
    blocks = []
    for g in lay.groups:
        if g.kind is TRACKER_POINT:
            continue
        Pg = P[g.rows]
        fitted = g.kind.fit(Pg, g)
        r[g.rows] = g.kind.residual(Pg, fitted, g)
        Mg = g.kind.row_map(Pg, fitted, g)
        if Mg is not None:
            row_map[g.rows] = Mg
        U, sv, _ = np.linalg.svd(g.kind.basis(Pg, fitted, g), full_matrices=False)
        U = U[:, sv > 1e-9 * max(sv.max(initial=0.0), 1e-300)]
        groups[g.rows] = len(names)
        names.append(f"{g.kind.name} {g.name}" + (f" of session {g.session}" if g.session else ""))
        blocks.append((g.rows, U.reshape(len(g.rows), 3, -1)))
    k = sum(b.shape[2] for _, b in blocks)
    turn = lay.touches and not lay.tracked.any()
    N = np.zeros((n, 3, k + 3 * turn))
    at = 0
    for rows, b in blocks:
        N[rows, :, at:at + b.shape[2]] = b
        at += b.shape[2]
    if turn:
        N[:, :, k:] = np.einsum("nij,njk->nik", row_map, np.stack([np.cross(e, r) for e in np.eye(3)], axis=2))
    return Nuisance(N, groups, names, row_map, bool(turn))


@dataclass
class TouchProblem:
    """The design problem of rows that touch: the robot's identifiable parameters and the nuisance.

    Attributes
    ----------
    A : ndarray, shape (N, 3, p + k)
        Each candidate's block: the ``p`` robot parameters (columns scaled by each parameter's typical deviation,
        metres; a row's model point mapped as its residual is), then the ``k`` nuisance columns.
    names : list of str
        The ``p`` robot parameters (in model order).
    nuisance : Nuisance
    sets : ndarray of int, shape (N,)
        Each candidate's touched set (:func:`touched_sets`: the rows of a session at one point or plane), -1 for
        a measured row; ``set_names`` name them.
    M0 : ndarray, shape (p + k, p + k)
        The augmented information of the rows measured already (zero: none).
    unobservable : list of dict
        What the rows cannot see, held (``what``, ``why``, ``parameters``), as a calibration says it.
    missing : list of str
        Free parameters of the model that these rows identify not at all (beyond what they cannot see).
    model_spec : str
    least : ndarray of int
        Per touched set, the fewest rows a selection may hold of it if it holds any
        (:data:`~casadical.data._measurements.MIN_TOUCH_ROWS` less the rows measured already; 0 when those are
        enough).
    """

    A: np.ndarray
    names: list[str]
    nuisance: Nuisance
    sets: np.ndarray
    set_names: list[str]
    M0: np.ndarray
    unobservable: list[dict] = field(default_factory=list)
    missing: list[str] = field(default_factory=list)
    model_spec: str = ""
    least: np.ndarray = field(default_factory=lambda: np.zeros(0, int))

    @property
    def n_candidates(self) -> int:
        return self.A.shape[0]

    @property
    def n_parameters(self) -> int:
        return len(self.names)

    @property
    def interest(self) -> np.ndarray:
        return np.arange(self.n_parameters)

    def criterion(self):
        """The Ds criterion of :mod:`casadical.planning._augment`: the robot's parameters, the nuisance's rest."""
        from ._augment import Criterion

        return Criterion(self.A, self.M0, self.interest)

    def held_text(self) -> list[str]:
        """What the rows cannot see, one line each (as ``inspect --poses`` says it)."""
        return [f"not seen by these rows: {u['what']} ({u['why']}): {', '.join(u['parameters'])} held"
                for u in self.unobservable if u["parameters"]]


def held_parameters(model, data: Measurements, P: np.ndarray, J: np.ndarray, cov: np.ndarray, params=None):
    """What ``data``'s rows cannot see (held, in words) and the parameters they identify.

    Returns ``(unobservable, identifiable, missing)``: the entries of
    :func:`~casadical.calibration._unobservable.unseen` (with the parameters that only move the whole robot, for
    touches alone), the names the rows identify (the layout's projection of ``J``, as the calibration analyses
    it) and the parameters that rows spread over the joint ranges would identify and they do not.
    """
    from ..calibration._identify import generic_identifiable

    params = (params or model.parameters).copy()
    unobservable = unseen(data, params)
    for u in unobservable:
        params.fix(u["parameters"], f"{u['what']}: {u['why']}")
    moving = {n for n, m in zip(params.names, np.linalg.norm(J, axis=(0, 1)) > 0) if m}
    ident = analyse(data.layout.project(P, J)[1], params)
    whole = whole_robot(ident, moving, unobservable) if data.touching.all() else set()
    generic = set(generic_identifiable(model, params, cov))
    missing = [u.name for u in ident.unidentifiable if u.name not in whole and u.name in generic]
    return unobservable, list(ident.identifiable), missing


@limited_threads()
def touch_problem(model, data: Measurements, *, values: np.ndarray | None = None, cov: np.ndarray | None = None,
                  base0: np.ndarray | None = None, names: list[str] | None = None,
                  measured: int = 0) -> TouchProblem:
    """The design problem of ``data``'s rows (candidates that touch, measured rows before them).

    Parameters
    ----------
    model : casadical.model._symbolic.Model
    data : Measurements
        The rows, with ``point``/``plane`` columns (and its fixtures); the first ``measured`` of them are rows
        measured already, the others the candidates (they share the groups they touch).
    values : ndarray, optional
        Parameter values the Jacobian is taken at (default: the model's).
    names : list of str, optional
        The robot parameters of the criterion (default: those the rows identify, what they cannot see held).
    measured : int
        Rows at the start of ``data`` measured already: they count towards each group's
        :data:`~casadical.data._measurements.MIN_TOUCH_ROWS`.

    Raises
    ------
    IdentifiabilityError
        The rows identify no parameter.
    """
    cov = model.covariates(data) if cov is None else cov
    params = model.parameters
    p_values = params.values if values is None else np.asarray(values, float)
    P, J = _jacobian(model, data.q, p_values, cov, base0)
    unobservable, ident, missing = held_parameters(model, data, P, J, cov)
    if names is None:
        names = ident
        if not names:
            raise IdentifiabilityError(f"the candidates identify no parameter of model {model.spec}")
    idx = np.array([params.index(n) for n in names], dtype=int)
    nu = nuisance(data, P)
    A = np.einsum("nij,njp->nip", nu.row_map, J[:, :, idx] * params.scales[idx])
    sets, set_names = touched_sets(data)
    have = np.bincount(sets[:measured][sets[:measured] >= 0], minlength=len(set_names))
    least = np.where(have >= MIN_TOUCH_ROWS, 0, MIN_TOUCH_ROWS - have)
    A = np.concatenate([A, nu.N], axis=2)
    B = A[:measured].reshape(-1, A.shape[2])
    return TouchProblem(np.ascontiguousarray(A[measured:]), list(names), nu, sets[measured:], set_names,
                        B.T @ B, unobservable, missing, model.spec, least.astype(int))


def touched_sets(data: Measurements) -> tuple[np.ndarray, list[str]]:
    """Each row's touched set, the rows of a session touching one point or plane (a calibration needs at least
    :data:`~casadical.data._measurements.MIN_TOUCH_ROWS` of each; a fixture's points each apart), and their names;
    -1 for a measured row."""
    point, plane = (np.array(["" if v is None else str(v).strip() for v in data.columns[c]], dtype=object)
                    if c in data.columns else np.full(len(data), "", dtype=object) for c in ("point", "plane"))
    sessions = data.sessions if data.sessions is not None else np.full(len(data), "", dtype=object)
    keys: dict = {}
    out = np.full(len(data), -1)
    for i, (s, a, b) in enumerate(zip(sessions.tolist(), point.tolist(), plane.tolist())):
        if a or b:
            key = (s, "point" if a else "plane", a or b)
            out[i] = keys.setdefault(key, len(keys))
    names = [("plane " if kind == "plane" else "") + name + (f" of session {s}" if s else "") for s, kind, name in keys]
    return out, names


def _jacobian(model, q, values, cov, base0):
    """Model points and their Jacobian at ``values`` (the model's values are restored after)."""
    old = model.parameters.values
    model.parameters.values = values
    try:
        return model.predict_jacobian(q, cov=cov, base0=base0) if len(q) <= 4096 else (
            model.predict(q, cov=cov, base0=base0), pool_jacobian(model, q, cov, base0))
    finally:
        model.parameters.values = old


def schur_singular_values(problem: TouchProblem, subset) -> np.ndarray:
    """Singular values of the candidates ``subset``'s Jacobian projected away from its nuisance (the square roots of
    the eigenvalues of the Schur complement; with rows measured already, of theirs and the subset's together): for
    O1..O5 and the exact Ds value ``2 sum log sigma``."""
    B = problem.A[np.asarray(subset, dtype=int)].reshape(-1, problem.A.shape[2])
    if np.any(problem.M0):
        B = np.vstack([B, _root(problem.M0)])
    p = problem.n_parameters
    Ab, Nb = B[:, :p], B[:, p:]
    if Nb.shape[1]:
        U, sv, _ = np.linalg.svd(Nb, full_matrices=False)
        U = U[:, sv > 1e-9 * max(sv.max(initial=0.0), 1e-300)]
        Ab = Ab - U @ (U.T @ Ab)
    return np.linalg.svd(Ab, compute_uv=False)


def schur_log_det(problem: TouchProblem, subset) -> float:
    """``log det`` of the information about the robot's parameters of the candidates ``subset`` (with the rows
    measured already): the exact Ds value, the Schur complement's; -inf when singular."""
    sv = schur_singular_values(problem, subset)
    if len(sv) < problem.n_parameters or sv.min() <= 1e-12 * sv.max():
        return -np.inf
    return float(2.0 * np.sum(np.log(sv)))


def _root(M: np.ndarray) -> np.ndarray:
    """A matrix ``R`` with ``R^T R = M`` (M symmetric positive semi-definite)."""
    lam, V = np.linalg.eigh((M + M.T) / 2)
    return (V * np.sqrt(np.clip(lam, 0.0, None))).T


def short_sets(problem: TouchProblem, subset) -> list[str]:
    """The touched sets ``subset`` holds too few rows of to fix what they touch (empty: a selection a calibration
    takes)."""
    g = problem.sets[np.asarray(subset, dtype=int)]
    counts = np.bincount(g[g >= 0], minlength=len(problem.least))
    bad = np.flatnonzero((counts > 0) & (counts < problem.least))
    return [f"{problem.set_names[k]} ({counts[k]} of {problem.least[k]} rows)" for k in bad]


def random_rows(sets: np.ndarray, least: np.ndarray, m: int, rng: np.random.Generator) -> np.ndarray:
    """A uniformly random M-subset of the candidates, then each touched set (``sets``: each candidate's, -1 none;
    ``least``: the fewest rows of each if any, :class:`TouchProblem`) it holds too few rows of filled up with
    random rows of it (random rows of the sets with rows to spare leaving) or, where it cannot be, emptied (random
    rows of the others joining): a random selection a calibration takes."""
    N = len(sets)
    X = rng.choice(N, m, replace=False)
    for _ in range(4 * m):
        c = np.bincount(sets[X][sets[X] >= 0], minlength=len(least))
        short = np.flatnonzero((c > 0) & (c < least))
        if not len(short):
            return np.sort(X)
        k = int(rng.choice(short))
        need = int(least[k] - c[k])
        free_k = np.setdiff1d(np.flatnonzero(sets == k), X)
        g = sets[X]
        spare = (g < 0) | ((g != k) & (c[np.maximum(g, 0)] > least[np.maximum(g, 0)]))
        if len(free_k) >= need and spare.sum() >= need:
            drop = rng.choice(np.flatnonzero(spare), need, replace=False)
            X = np.concatenate([np.delete(X, drop), rng.choice(free_k, need, replace=False)])
            continue
        mine = sets[X] == k
        X = X[~mine]
        c = np.bincount(sets[X][sets[X] >= 0], minlength=len(least))
        rest = np.setdiff1d(np.arange(N), X)
        g = sets[rest]
        open_ = rest[(g < 0) | (c[np.maximum(g, 0)] + 1 >= least[np.maximum(g, 0)])]
        if len(open_) < int(mine.sum()):
            break
        X = np.concatenate([X, rng.choice(open_, int(mine.sum()), replace=False)])
    raise InputError(f"cannot choose {m} of the {N} candidates so that each point touched has none or at least "
                     f"{MIN_TOUCH_ROWS} rows: change M")


@limited_threads()
def select_touches(problem: TouchProblem, m: int, method: str = "d-optimal", *, seed: int | None = None,
                   settings=None):
    """Select M of the candidates that touch: by the Ds criterion (certified, each touched set with none or
    enough rows) or at random (for comparison).

    Returns
    -------
    PlanResult
        ``log_det`` the exact Ds value of the selection (log det of the Schur complement), ``upper_bound`` the
        certificate's bound on it over every M candidates, ``d_efficiency`` the Ds-efficiency against it.

    Raises
    ------
    InputError
        Unknown method (``ga`` judges rows measured alone), M larger than the candidates.
    """
    import time
    import warnings

    from ._augment import ds_design, relax_ds
    from ._observability import indices_from_singular_values
    from ._selectors import PlanResult, PlanSettings, degenerate_message

    if method not in ("d-optimal", "random"):
        raise InputError(f"{method!r} selects rows measured alone; rows that touch are selected by d-optimal "
                         "(the Ds criterion) or random")
    st = settings or PlanSettings()
    N, p = problem.n_candidates, problem.n_parameters
    if m > N:
        raise InputError(f"cannot choose M={m} rows from {N} candidates")
    t0 = time.perf_counter()
    details: dict = {}
    crit = problem.criterion()
    if method == "d-optimal":
        des = ds_design([crit], m, relaxation=st.relaxation, seed=0 if seed is None else seed,
                        groups=problem.sets, least=problem.least, exponent=EXPONENT)
        idx, ub, rel = des.indices, des.upper_bound, des.relaxation
        details = {"relaxation": f"{rel.method}, {rel.status}, {rel.iterations} iterations, {rel.time_s:.3g} s",
                   "exchange": f"best of {des.starts} rounded starts, {des.swaps} swaps in all"}
    else:
        idx = random_rows(problem.sets, problem.least, m, np.random.default_rng(seed))
        ub = None
        if st.certify:
            rel = relax_ds([crit], m, exponent=EXPONENT)
            ub = rel.upper_bound
            details["certificate"] = f"first-order relaxation, {rel.iterations} iterations, {rel.time_s:.3g} s"
    t_sel = time.perf_counter() - t0
    if problem.missing:     # a bound over the parameters a degenerate pool identifies is no certificate
        warnings.warn(degenerate_message(problem.missing, p), IdentifiabilityWarning, stacklevel=3)
        ub = None
    sv = schur_singular_values(problem, idx)
    ld = float(2.0 * np.sum(np.log(sv))) if len(sv) == p and sv.min() > 0 else -np.inf
    # the bound is per parameter (augment's F = f / p): in log det units as the D criterion's
    bound = None if ub is None else ub * p
    eff = None if bound is None else float(np.exp(min(0.0, (ld - bound) / p))) if np.isfinite(ld) else 0.0
    gap = None if ub is None else float(rel.upper_bound - rel.value)
    counts = np.bincount(problem.sets[idx][problem.sets[idx] >= 0], minlength=len(problem.set_names))
    details["rows per point or plane touched"] = ", ".join(f"{n}: {int(c)}" for n, c in zip(problem.set_names, counts)
                                                  if c)
    return PlanResult(np.sort(idx), method, N, list(problem.names), indices_from_singular_values(sv, m, p), ld,
                      bound, eff, gap, t_sel, seed=seed, details=details, missing_parameters=list(problem.missing),
                      criterion="Ds", unobservable=list(problem.unobservable))
