"""The GP compensator (one per session): fitted, applied where it knows, judged on folds.

The named causes make the physical model: what holds for the robot, in
any session. What they leave is partly structure of the session (the
tracker's own errors, the state of the robot that day) that no cause
explains but that predicts other poses of the same session. The GP
compensator learns it with a Gaussian process of the joint readings
(:class:`casadical.compensators._gp.ResidualGP`, one per session), in the
robot base frame of each pose's session, and adds it to the model as a
``gp_compensator`` term (``gp_compensator@<session>`` with several
sessions). Its correction shrinks with its predictive uncertainty
(:meth:`ResidualGP.weight`): whole near the poses it learnt from, nothing
where it knows nothing, and there the physical model stands alone;
:func:`gp_compensator_coverage` says at how many poses it applied (at least
half of its posterior mean).

:func:`gp_compensator_held_out` judges the compensator as the diagnosis
judges every step: on cross-validation folds (random, time-blocked,
joint-blocked, each session left out), with the hyperparameters of the fit
on all poses and the process conditioned on each fold's training poses
only.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

from ..compensators._gp import MAX_STD_RATIO, ROBUST_NU, ResidualGP
from ..data._measurements import Measurements, session_index
from ..model._symbolic import Model
from ..prediction import fold_interval_k
from ..result import CalibrationResult, learning_mask, rebuilt
from ..runtime._threads import limited_threads
from ..terms import SessionLocal, make_term
from ..terms._gp_compensator import fitted_processes

#: a session's process learns from at most this many of its poses (drawn at random): its cost grows with the cube
#: of the poses, in the fit and in every held-out fold, and its size in the model with their number
MAX_POSES = 600


def gp_compensator_data(result: CalibrationResult, data: Measurements) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """What the GP compensator learns from: joint readings (rad), residuals (measured minus predicted, m) in the robot
    base frame of each pose's session, and the poses to learn from (those the robust loss did not set aside)."""
    r = result.residuals(data)
    Y = np.empty_like(r)
    for s, idx in session_index(data).items():
        R = result.base_matrix(s or None)[:3, :3]
        Y[idx] = r[idx] @ R                 # rows: R^T r
    return data.q, Y, learning_mask(result, data)


def fit_gp_compensator(result: CalibrationResult, data: Measurements, max_std_ratio: float = MAX_STD_RATIO,
                       seed: int = 0, progress: Callable[[str], None] | None = None,
                       robust_nu: float | None = ROBUST_NU, gaussian: dict[str | None, ResidualGP] | None = None
                       ) -> tuple[dict[str | None, ResidualGP], dict[str | None, np.ndarray]]:
    """A Gaussian process of the residual per session (key None for data of one session), and the poses of
    ``data`` each learnt from; ``progress`` receives a line per session. ``gaussian``: with ``robust_nu``, the
    processes this function fitted with a Gaussian likelihood on the same ``result``, ``data`` and ``seed``
    (:meth:`ResidualGP.fit`'s ``gaussian``)."""
    X, Y, keep = gp_compensator_data(result, data)
    gps: dict[str | None, ResidualGP] = {}
    rows: dict[str | None, np.ndarray] = {}
    for s, idx in session_index(data).items():
        idx = idx[keep[idx]]
        if len(idx) > MAX_POSES:
            idx = np.sort(np.random.default_rng(seed).choice(idx, MAX_POSES, replace=False))
        if progress is not None:
            progress(f"  hyperparameters of the processes{f' of session {s}' if s else ''}: {len(idx)} poses, "
                     "x, y and z")
        gps[s or None] = ResidualGP.fit(X[idx], Y[idx], max_std_ratio=max_std_ratio, seed=seed,
                                       robust_nu=robust_nu, gaussian=(gaussian or {}).get(s or None))
        rows[s or None] = idx
    return gps, rows


def with_gp_compensator(result: CalibrationResult, gps: dict[str | None, ResidualGP], data: Measurements,
                        note: str) -> CalibrationResult:
    """``result`` with the processes added to its model as ``gp_compensator`` terms (the values kept)."""
    m = result.model
    terms = [t for t in m.terms if t.name != "gp_compensator"]
    for s, gp in gps.items():
        term = make_term("gp_compensator", gp=gp)
        terms.append(term if s is None else SessionLocal(term, s))
    return rebuilt(result, Model(m.robot, terms if m.geometric_free else terms[1:], jit=m.jit), data, note)


def gp_compensator_coverage(result: CalibrationResult, data: Measurements) -> tuple[int, int]:
    """At how many of ``data``'s poses the result's GP compensator applies, of how many it could
    (the poses of the sessions it has a process for); (0, 0) without one."""
    known = total = 0
    for gp, rows in fitted_processes(result.model.terms, data):
        total += len(rows)
        known += int(gp.knows(data.q[rows]).sum())
    return known, total


@dataclass
class GPCompensatorFolds:
    """Held-out predictions of the GP compensator on every fold: what judging it, and choosing its shrinkage, needs.

    Attributes
    ----------
    before : ndarray, shape (N,)
        Residual norm (m) of each pose of ``keep`` without the compensator.
    folds : dict of str to list of tuples
        By kind: for each fold, its held-out poses (indices into ``keep``'s poses), their residuals (m, (m, 3)),
        the fold's process's prediction there (m), its predictive std over the prior (:meth:`ResidualGP.std_ratio`),
        its predictive and prior variances (m^2, (m, 3)) and its white noise per axis (m, (m,)).
    n_schemes : dict of str to int
        Schemes of each kind (a pose is held out once in each).
    """

    before: np.ndarray
    folds: dict
    n_schemes: dict

    def after(self, kind: str, shrink: float) -> np.ndarray:
        """Residual norm (m) of each pose with the compensator, held out in the folds of ``kind`` (averaged over
        its schemes), its correction shrunk with strength ``shrink`` (:func:`shrink_weight`)."""
        out = np.zeros(len(self.before))
        for at, Y, pred, ratio, *_ in self.folds[kind]:
            out[at] += np.linalg.norm(Y - pred * shrink_weight(ratio, shrink)[:, None], axis=1)
        return out / self.n_schemes[kind]

    def interval_k(self, shrink: float, level: float = 0.95, params_var: np.ndarray | None = None) -> float:
        """The factor of a 95 % interval of a measured point, calibrated on the random folds: the ``level``
        quantile of each held-out pose's error over ``sqrt(std^2 / 3 + sigma^2)`` (``std`` what the fold's
        process leaves, :meth:`ResidualGP.predictive_std`, and the parameters' part ``params_var`` (m^2, one per
        pose of ``keep``; :func:`casadical.prediction.prediction_std`), as the interval adds them;
        ``sigma`` its white noise), never below :data:`CHI3_95`."""
        e, s2, sigma = [np.zeros(0)], [np.zeros(0)], [np.zeros(0)]
        for at, Y, pred, ratio, var, prior, noise in self.folds.get("random", []):
            w = shrink_weight(ratio, shrink)[:, None]
            v = np.sum(var + (1 - w) ** 2 * (prior - var), axis=1)
            s2.append(v if params_var is None else v + params_var[at])
            e.append(np.linalg.norm(Y - pred * w, axis=1))
            sigma.append(noise)
        return fold_interval_k(np.concatenate(e), np.concatenate(s2), np.concatenate(sigma), min(level, 1.0))

    def means_mm(self, shrink: float) -> dict[str, tuple[float, float]]:
        """Held-out mean (mm) without and with the compensator, by kind."""
        b = float(self.before.mean() * 1000)
        return {k: (b, float(self.after(k, shrink).mean() * 1000)) for k in self.folds}

    def worst_mm(self, shrink: float, band: float = np.inf) -> dict[str, tuple[float, float]]:
        """Worst held-out error (mm) without and with the compensator, by kind, like with like: leaving out the
        poses both miss by more than ``band`` (mm; a pose no model of the robot predicts, where a few um either
        way say nothing of the compensator)."""
        out = {}
        for k in self.folds:
            b, a = self.before * 1000, self.after(k, shrink) * 1000
            like = ~((b > band) & (a > band))
            out[k] = (float(b[like].max()), float(a[like].max())) if like.any() else (float(b.max()), float(a.max()))
        return out

    def missed(self, shrink: float, band: float) -> dict[str, int]:
        """By kind, how many poses both models miss by more than ``band`` (mm): left out of :meth:`worst_mm`."""
        return {k: int(((self.before * 1000 > band) & (self.after(k, shrink) * 1000 > band)).sum()) for k in self.folds}


def shrink_weight(ratio: np.ndarray, shrink: float) -> np.ndarray:
    """:meth:`ResidualGP.weight` from the std ratios: ``(1 - r^2)^shrink``, 0 at ``r >= 1``."""
    return np.where(ratio < 1.0, np.clip(1.0 - ratio ** 2, 0.0, 1.0) ** shrink, 0.0)


@limited_threads()
def gp_compensator_held_out(gps: dict[str | None, ResidualGP], learnt: dict[str | None, np.ndarray],
                            data: Measurements, Y: np.ndarray, keep: np.ndarray, schemes,
                            progress: Callable[[str], None] | None = None) -> GPCompensatorFolds:
    """Held-out residuals (m) without and with the GP compensator, by kind of fold, at the poses of ``keep``.

    Each fold's process is the session's process (hyperparameters of the
    fit on all poses) conditioned on the poses it learnt from (``learnt``,
    indices into ``data``) that are among the fold's training poses; where
    it knows nothing it adds nothing (:meth:`GPCompensatorFolds.after`: for any shrinkage).
    ``progress`` receives a line per kind of fold.
    """
    sessions = session_index(data)
    idx_keep = np.flatnonzero(keep)
    folds: dict[str, list] = {}
    n_schemes: dict[str, int] = {}
    for kind in dict.fromkeys(s.kind for s in schemes):
        group = [s for s in schemes if s.kind == kind]
        if progress is not None:
            progress(f"  held-out errors on the {kind} folds ({sum(len(g.folds) for g in group)} folds)")
        folds[kind], n_schemes[kind] = [], len(group)
        for scheme in group:
            for F in scheme.folds:
                test = np.intersect1d(F, idx_keep)
                pred, ratio = np.zeros((len(test), 3)), np.ones(len(test))
                var, prior, noise = np.zeros((len(test), 3)), np.zeros((len(test), 3)), np.zeros(len(test))
                for s, rows in sessions.items():
                    own = learnt[s or None]
                    train = np.setdiff1d(own, F)
                    at = np.isin(test, rows)
                    if len(train) >= 10 and at.any():
                        g = gps[s or None].refit(np.searchsorted(own, train))
                        x = data.q[test[at]]
                        r = np.column_stack([g.std_ratio_of(x, a) for a in range(3)])
                        pred[at], ratio[at] = g.predict(x), r.max(axis=1)
                        prior[at] = g.signal_var * g.y_std ** 2
                        var[at], noise[at] = r ** 2 * prior[at], g.noise_std()
                folds[kind].append((np.searchsorted(idx_keep, test), Y[test], pred, ratio, var, prior, noise))
    return GPCompensatorFolds(np.linalg.norm(Y[idx_keep], axis=1), folds, n_schemes)
