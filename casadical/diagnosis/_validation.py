"""Validation that can tell: cross-validation folds that must extrapolate.

Poses drawn at random from one measurement session share its structure, so
random folds reward any flexible term that fits the session. A cause that
is really there also predicts where the model has to extrapolate:

- ``random``: k random folds (interpolation, the usual check);
- ``time``: k contiguous blocks of the row order (what was measured later
  is predicted from what was measured before and after);
- ``joint<j>``: k contiguous blocks of joint j's reading (a range of the
  joint left out, for every joint);
- ``session``, with data of several measurement sessions: each session
  left out in turn (what holds for the robot predicts a session it was
  not fitted on; the left-out session's own base pose, which the others
  cannot tell, is estimated on its own poses with the robot's values
  held). With several sessions the time blocks are cut within each
  session.

Each fold is refitted by one Gauss-Newton step from the fit on all poses,
with the training poses only (exact for a linear model, and the
calibration problem is nearly linear at its solution): the whole set of
schemes costs a few small linear solves, not a calibration per fold.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from ..data._measurements import Measurements
from ..data._poses import first_rows, pose_index
from ..model._symbolic import Model
from ..robot import Robot
from ..runtime._threads import evaluation_pool, evaluation_threads


@dataclass
class Scheme:
    """A cross-validation scheme: each pose is held out in exactly one fold."""

    name: str
    folds: list[np.ndarray]

    @property
    def kind(self) -> str:
        return "joint" if self.name.startswith("joint") else self.name


def random_scheme(n: int, k: int, seed: int) -> Scheme:
    idx = np.random.default_rng(seed).permutation(n)
    return Scheme("random", [np.sort(idx[i::k]) for i in range(k)])


def time_scheme(rows: np.ndarray, k: int, sessions: np.ndarray | None = None) -> Scheme:
    """Contiguous blocks of the measurement order (``rows``: each pose's original row); with ``sessions``,
    fold i holds block i of every session."""
    groups = [np.arange(len(rows))] if sessions is None else \
        [np.flatnonzero(sessions == s) for s in dict.fromkeys(sessions.tolist())]
    folds = [[] for _ in range(k)]
    for g in groups:
        order = g[np.argsort(rows[g], kind="stable")]
        for i, b in enumerate(np.array_split(order, k)):
            folds[i].append(b)
    return Scheme("time", [np.sort(np.concatenate(f)) for f in folds])


def session_scheme(sessions: np.ndarray) -> Scheme:
    """Each session left out in turn."""
    return Scheme("session", [np.flatnonzero(sessions == s) for s in dict.fromkeys(sessions.tolist())])


def joint_scheme(q: np.ndarray, j: int, k: int, moving: np.ndarray | None = None) -> Scheme:
    """Contiguous blocks of joint ``j``'s (1-based) reading.

    ``moving``: in a design of one joint at a time, the joint each pose moves
    (:func:`casadical.diagnosis._design.moving_joint`). The blocks are then
    cut in joint ``j``'s own sweep, and the other poses (where joint ``j``
    stands still) are dealt to the folds in turn: a fold leaves out a range
    of the sweep, never the poses the other joints' parameters come from.
    """
    sweep = np.arange(len(q)) if moving is None else np.flatnonzero(moving == j)
    if len(sweep) < 2:
        sweep = np.arange(len(q))
    rest = np.setdiff1d(np.arange(len(q)), sweep)
    order = sweep[np.argsort(q[sweep, j - 1], kind="stable")]
    blocks = np.array_split(order, k)
    return Scheme(f"joint{j}", [np.sort(np.concatenate([b, rest[i::k]])) for i, b in enumerate(blocks)])


def schemes(q: np.ndarray, rows: np.ndarray, k: int, seed: int, lever: np.ndarray | None = None,
            min_lever: float = 0.05, sessions: np.ndarray | None = None, moving: np.ndarray | None = None
            ) -> list[Scheme]:
    """The random, time-blocked and joint-blocked schemes of a data set (and leave-one-session-out with
    ``sessions`` of more than one session).

    A fold leaves a pose out whole: rows of one session with the same readings (a tool of several points
    measured at each, a pose measured again: :func:`casadical.data._poses.pose_index`) are one pose, dealt to the
    folds as one row (its first), so no fold fits a pose it holds out.

    ``moving``: in a design of one joint at a time, the joint each pose moves: the time blocks are cut
    within each joint's sweep (as within each session), the joint-range blocks in the joint's own sweep
    (:func:`joint_scheme`).

    ``lever`` (one per joint): how far the tool point moves when the joint
    turns (e.g. the RMS of ``|d xyz / d q_j|`` over the poses). A joint that
    barely moves the tool point (less than ``min_lever`` of the largest,
    e.g. a flange joint with the probe on its axis) gets no joint-blocked
    scheme: leaving out a range of it tests nothing.
    """
    pose = pose_index(q, sessions)
    first = first_rows(pose)
    if len(first) < len(q):     # the schemes of the poses (their first rows), each pose's rows in its pose's fold
        pick = (lambda a: None if a is None else np.asarray(a)[first])  # noqa: E731
        return [Scheme(s.name, [np.flatnonzero(np.isin(pose, f)) for f in s.folds])
                for s in schemes(q[first], rows[first], k, seed, lever, min_lever, pick(sessions), pick(moving))]
    several = sessions is not None and len(set(sessions.tolist())) > 1
    groups = sessions if several else None
    if moving is not None:
        groups = moving if groups is None else np.array([f"{s}/{m}" for s, m in zip(sessions, moving)])
    out = [random_scheme(len(q), k, seed), time_scheme(rows, k, groups)]
    top = float(np.max(lever)) if lever is not None and len(lever) else 0.0
    out += [joint_scheme(q, j, k, moving) for j in range(1, q.shape[1] + 1)
            if np.ptp(q[:, j - 1]) > 0 and (lever is None or lever[j - 1] >= min_lever * top)]
    if several:
        out.append(session_scheme(sessions))
    return out


def solve_identified(A: np.ndarray, b: np.ndarray, rel: float = 1e-3) -> np.ndarray:
    """``A^-1 b`` on the directions ``A`` determines; the others stay at zero.

    ``A`` is a Gauss-Newton matrix; with its columns normalised, directions
    whose singular value (of the Jacobian) is below ``rel`` of the largest
    are what these poses cannot tell, and a refit would not move them.
    Stacked systems (``A`` of shape (..., p, p), ``b`` (..., p)) are solved
    at once.
    """
    diag = np.diagonal(A, axis1=-2, axis2=-1)
    # a column that is zero here (a session's own parameter, its session left out) stays out: scale 1
    d = np.sqrt(np.where(diag > 0, np.clip(diag, 1e-300, None), 1.0))
    An = A / (d[..., :, None] * d[..., None, :])
    lam, V = _eigh((An + np.swapaxes(An, -1, -2)) / 2)
    keep = lam > np.maximum((rel ** 2) * lam[..., -1:], 1e-300)
    inv = np.where(keep, 1.0 / np.where(keep, lam, 1.0), 0.0)
    x = np.einsum("...ij,...j->...i", V, inv * np.einsum("...ji,...j->...i", V, b / d))
    return x / d


def _eigh(M: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``np.linalg.eigh`` of a stack of matrices, its parts in the evaluation threads (LAPACK lets go of
    the GIL; each matrix is decomposed alone, so the results are the same bits)."""
    k = min(evaluation_threads(), len(M) // 8) if M.ndim == 3 and M.size * M.shape[-1] >= 2e5 else 1
    if k < 2:   # (a small stack: the threads would cost more than they save)
        return np.linalg.eigh(M)
    parts = list(evaluation_pool().map(np.linalg.eigh, np.array_split(M, k)))
    return np.concatenate([p[0] for p in parts]), np.concatenate([p[1] for p in parts])


@dataclass
class CVResult:
    """Held-out errors of one model under each scheme.

    Attributes
    ----------
    errors : dict of str to ndarray
        Scheme name -> held-out position error of every pose (m).
    """

    errors: dict[str, np.ndarray] = field(default_factory=dict)

    def kind_errors(self, kind: str) -> np.ndarray:
        """Held-out error of each pose under one kind of scheme (``joint``: averaged over the joints), m."""
        names = [s for s in self.errors if (s.startswith("joint") if kind == "joint" else s == kind)]
        return np.mean([self.errors[s] for s in names], axis=0)

    def kind_mean_mm(self, kind: str, mask: np.ndarray | None = None) -> float:
        """Mean held-out error over the schemes of one kind (``joint``: all joints)."""
        e = self.kind_errors(kind)
        return float(np.mean(e if mask is None else e[mask]) * 1000)


#: a cause's parameter whose training poses in a fold carry less than this share of what determines it (a
#: warm-up when the start is left out, a session's own cause when its session is) is switched off there
OWN_SHARE = 1e-2


def switch_off(names: list[str], values, scale: np.ndarray) -> np.ndarray:
    """For each column, the step that switches its cause off (NaN for the others): a warm-up's and a cause of
    one session's (``name@S``, not its base pose or tool); :func:`linear_cv` switches them off in a fold that
    leaves out (nearly) all the poses that determine them."""
    return np.array([-values[n] / s if n.startswith("warmup_") or ("@" in n and not n.startswith(("base_", "tool_")))
                     else np.nan for n, s in zip(names, scale)])


def fold_grams(Jw: np.ndarray, folds: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """The normal matrix of weighted columns ``Jw`` (N, 3, p) on all poses, and on the training poses of each
    fold (all poses but the fold's: the matrix minus the fold's part, (n_folds, p, p))."""
    p = Jw.shape[2]
    J2 = Jw.reshape(-1, p)
    A = J2.T @ J2
    AT = np.empty((len(folds), p, p))
    for k, F in enumerate(folds):
        JF = Jw[F].reshape(-1, p)
        AT[k] = A - JF.T @ JF
    return A, AT


def linear_cv(J: np.ndarray, r: np.ndarray, weights: np.ndarray, all_schemes: list[Scheme],
              off: np.ndarray | None = None, prior: tuple[np.ndarray, np.ndarray] | None = None,
              grams: tuple[np.ndarray, np.ndarray] | None = None) -> CVResult:
    """Held-out errors by one Gauss-Newton step per fold from the fit on all poses.

    Parameters
    ----------
    J : ndarray, shape (N, 3, p)
        Jacobian of the predictions w.r.t. the (scaled) free parameters at the fit.
    r : ndarray, shape (N, 3)
        Residuals at the fit (predicted - measured).
    weights : ndarray, shape (N,)
        Pose weights of the fit (robust loss); held fixed.
    all_schemes : list of Scheme
    off : ndarray, optional
        Per column, the step that switches a cause off (:func:`switch_off`; NaN: not a cause of its own poses).
    prior : (ndarray, ndarray), optional
        A prior of each column: its precision (m^2 per scaled unit squared,
        0 for none) and the column's scaled value at the fit (its deviation
        from the prior's mean). Each fold's step is then the most probable
        one (ridge towards the prior's mean): what a fold's training poses
        cannot tell stays at what was known before them (a weak design,
        :mod:`casadical.diagnosis._design`), not at a guess of few poses.
    grams : (ndarray, ndarray), optional
        :func:`fold_grams` of the weighted columns, made already (a round's candidates share the current
        model's block: :meth:`._screening.Screen.fold_grams`).

    Directions the training poses of a fold cannot determine stay at the
    fit on all poses (:func:`solve_identified`). Parameters that only the
    left-out poses inform (a left-out session's own base pose and tool) are
    then estimated on those poses themselves, the rest held: the robot's
    values must come from the other sessions, the session's own from the
    session, as when a calibration is taken to a new session. A cause that
    (nearly: :data:`OWN_SHARE`) only the left-out poses inform (a warm-up
    when the start is left out, a session's own gear error when its session
    is) is switched off there: no fold can predict it, and its fit on those
    very poses would not be held out.
    """
    N, _, p = J.shape
    if p == 0:      # nothing free (touches alone: the nominal model has no base pose to fit)
        out = CVResult()
        out.errors = {s.name: np.linalg.norm(r, axis=1) for s in all_schemes}
        return out
    # pose by pose in memory: the folds gather poses, and a Jacobian whose columns were taken out of a larger
    # one (J[:, :, cols]) keeps each column's poses together, where the gathers took twice as long
    J = np.ascontiguousarray(J)
    sw = np.sqrt(weights)[:, None, None]
    Jw = (J * sw).reshape(N, 3, p)
    rw = r * np.sqrt(weights)[:, None]
    # per-pose contributions summed per fold: A_T = A - A_F, g_T = g - g_F (as matrix products: BLAS)
    J2, r2 = Jw.reshape(-1, p), rw.reshape(-1)
    folds = [F for s in all_schemes for F in s.folds]
    A, AT = fold_grams(Jw, folds) if grams is None else (grams[0], grams[1].copy())
    g = J2.T @ r2
    g_pose = np.einsum("nip,ni->np", Jw, rw)     # each pose's part of g: a fold's is a sum of rows, no gather of J
    owns, offs = [], []
    cause = np.zeros(p, bool) if off is None else np.isfinite(off)
    gT = np.empty((len(folds), p))
    for k, F in enumerate(folds):
        gT[k] = g - g_pose[F].sum(axis=0)
        # what only the left-out poses inform: exactly out of the training system (the subtraction leaves
        # rounding, which the normalisation of solve_identified would blow up)
        share = np.diag(AT[k]) / np.maximum(np.diag(A), 1e-300)
        gone = cause & (share <= OWN_SHARE)          # causes of the left-out poses: switched off
        own = (share <= 1e-9) & ~gone
        if gone.any():      # the training system with them switched off
            gT[k] += AT[k][:, gone] @ off[gone]
        out_ = own | gone
        AT[k][out_, :], AT[k][:, out_], gT[k][out_] = 0.0, 0.0, 0.0
        if prior is not None:     # not on what only the left-out poses inform, nor on what is switched off
            P = np.where(out_, 0.0, prior[0])
            AT[k][np.diag_indices(p)] += P
            gT[k] += P * prior[1]
        owns.append(own)
        offs.append(gone)
    steps = iter(-solve_identified(AT, gT))      # every fold of every scheme in one stacked solve
    owns, offs = iter(owns), iter(offs)
    out = CVResult()
    for s in all_schemes:
        err = np.empty(N)
        for F in s.folds:
            d, own, gone = next(steps), next(owns), next(offs)
            if gone.any():
                d[gone] = off[gone]
            if own.any():   # the left-out poses' own parameters, on those poses
                JF = Jw[F].reshape(-1, p)
                d[own] = np.linalg.lstsq(JF[:, own], -(rw[F].reshape(-1) + JF @ d), rcond=None)[0]
            err[F] = np.linalg.norm(r[F] + J[F] @ d, axis=1)
        out.errors[s.name] = err
    return out


@dataclass
class Linearized:
    """A fit linearised at its solution on some poses: what the fold refits and half fits need.

    Attributes
    ----------
    J : ndarray, shape (N, 3, p)
        Jacobian w.r.t. the scaled free parameters.
    r : ndarray, shape (N, 3)
        Residuals (predicted - measured, m).
    weights : ndarray, shape (N,)
        Robust weights at the fit.
    names : list of str
        The free parameters, in column order.
    scale : ndarray
        Their scales (a unit step of a column is ``scale`` in SI).
    """

    J: np.ndarray
    r: np.ndarray
    weights: np.ndarray
    names: list[str]
    scale: np.ndarray
    off: np.ndarray | None = None
    x0: np.ndarray | None = None
    #: the fold matrices of the weighted columns made by someone who shares them (:func:`fold_grams`; called
    #: with the folds), or None: made here
    grams: Callable[[list[np.ndarray]], tuple[np.ndarray, np.ndarray]] | None = None

    @classmethod
    def of(cls, res, data) -> "Linearized":
        m, p = res.model, res.parameters
        f = np.flatnonzero(p.free)
        xyz, J = m.predict_jacobian(data.q, p.values, m.covariates(data), res.base0, columns=f)
        proj = data.layout.projection(xyz)      # touch rows: from what they touched (casadical.rows)
        r = proj.r
        w = res.loss.weight(np.einsum("ij,ij->i", r, r))
        names = [p.names[i] for i in f]
        return cls(proj(J * p.scales[f]), r, w, names, p.scales[f],
                   switch_off(names, {n: p[n].value for n in names}, p.scales[f]),
                   ((p.values - p.nominal) / p.scales)[f])

    def cv(self, all_schemes: list[Scheme], prior: dict[str, float] | None = None) -> CVResult:
        """Held-out errors of every fold (:func:`linear_cv`); ``prior``: the precision (m^2 per scaled unit
        squared) of the columns that have a prior at their nominal value, by name."""
        pr = None
        if prior and self.x0 is not None:
            pr = (np.array([prior.get(n, 0.0) for n in self.names]), self.x0)
        grams = None if self.grams is None else self.grams([F for s in all_schemes for F in s.folds])
        return linear_cv(self.J, self.r, self.weights, all_schemes, self.off, pr, grams)

    def refit(self, rows: np.ndarray, rel: float = 1e-3) -> tuple[np.ndarray, np.ndarray]:
        """One Gauss-Newton step on ``rows`` only: the change of the scaled parameters and its covariance.

        ``rel``: see :func:`solve_identified` (0: every direction moves).
        """
        J, r, w = self.J[rows], self.r[rows], self.weights[rows]
        p = J.shape[2]
        Jw = (J * np.sqrt(w)[:, None, None]).reshape(-1, p)
        A = Jw.T @ Jw
        g = Jw.T @ (r * np.sqrt(w)[:, None]).reshape(-1)
        d = -solve_identified(A, g, rel)
        res = r + J @ d
        dof = max(3 * len(rows) - p, 1)
        sigma2 = float(np.sum(w[:, None] * res ** 2)) / dof
        return d, sigma2 * np.linalg.pinv(A)


# --- held-out means by kind of fold, as the diagnosis judges them ----------------------

#: the kinds of fold, in the order reports show them (``session`` only with several sessions)
KINDS = ("random", "time", "joint", "session")
#: the kinds of fold where a model must extrapolate: a step may not make them worse
EXTRAPOLATING = ("time", "joint", "session")


def kinds(cv: CVResult | dict) -> list[str]:
    """The kinds of fold a result holds."""
    names = cv.errors if isinstance(cv, CVResult) else cv
    return [k for k in KINDS if any(n == k or (k == "joint" and n.startswith("joint")) for n in names)]


def by_kind(cv: CVResult, mask: np.ndarray) -> dict:
    """Held-out mean error (mm) by kind of fold, over the poses of ``mask``."""
    return {k: cv.kind_mean_mm(k, mask) for k in kinds(cv)}


def not_better(cv0: dict, cv1: dict) -> list[str]:
    """Kinds of fold on which the held-out mean error does not drop."""
    return [k for k in cv0 if not cv1[k] < cv0[k]]


def cv_record(cv0: dict, cv1: dict) -> dict:
    """The held-out means before and after, for the report."""
    return {**{f"{k}_before": cv0[k] for k in cv0}, **{k: cv1[k] for k in cv0}}


def cv_text(cv0: dict, cv1: dict) -> str:
    return ", ".join(f"{k} {cv0[k]:.4f} -> {cv1[k]:.4f} mm" for k in cv0)


def cv_failure(worse: list[str], cv0: dict, cv1: dict) -> str:
    return ("held-out mean does not drop where it must " + ("interpolate" if worse == ["random"] else "extrapolate")
            + ": " + ", ".join(f"{k} {cv0[k]:.4f} -> {cv1[k]:.4f} mm" for k in worse))


def extrapolation_gain(cv0: dict, cv1: dict) -> float:
    """How much a step lowers the held-out mean where the model must extrapolate (time and joint folds)."""
    return 0.5 * ((cv0["time"] - cv1["time"]) + (cv0["joint"] - cv1["joint"]))


def joint_levers(robot: Robot, data: Measurements) -> np.ndarray:
    """How far the tool point moves per radian of each joint (RMS over the poses, m)."""
    m = Model(robot, "nominal", jit=False)
    _, J = m.predict_jacobian(data.q, cov=m.covariates(data))
    return np.array([np.sqrt(np.mean(np.sum(J[:, :, m.parameters.index(f"theta{j}")] ** 2, axis=1)))
                     for j in range(1, robot.n + 1)])
