"""One round's linearisation: every candidate cause scored and fitted at once.

One model holding the current terms and every candidate is linearised at
the current fit (robust weights held fixed). From that single Jacobian:

- the **score test** of each candidate: the drop of the weighted residual
  sum of squares its columns would bring, after the directions the current
  model spans are removed;
- each candidate's **fit**: one Gauss-Newton step on the current columns
  plus the candidate's, from the current fit (the calibration problem is
  nearly linear at its solution, and a candidate adds a small effect), with
  everything the acceptance needs: the residual, the F-test, the held-out
  errors of every fold (:mod:`._validation`), the halves (:mod:`._periodic`)
  and the validation errors (judge only).

Only the accepted candidate is then fitted for real.
"""

from __future__ import annotations

import copy
import math
from dataclasses import dataclass, replace

import numpy as np

from ..calibration._for_data import model_for
from ..data._measurements import Measurements
from ..result import CalibrationResult
from ._candidates import Candidate, compose_terms, tell_apart
from ._statistics import NestedTest, nested_test, set_aside_share
from ._validation import Linearized, fold_grams, solve_identified, switch_off


@dataclass
class Scored:
    """A candidate's score: the linearised F-test, and the residual its columns would explain."""

    log10_p: float
    candidate: Candidate
    test: NestedTest
    fitted: np.ndarray
    basis: np.ndarray | None = None     # orthonormal columns of the candidate, the current model's removed
    base: tuple | None = None           # (residual with the current model's directions removed, p0, equations)


@dataclass
class LinearFit:
    """A model (the current columns, plus a candidate's) fitted by one step from the current fit.

    Attributes
    ----------
    lin : Linearized
        Jacobian of its free columns, residual after the step, weights: what
        cross-validation and the halves need.
    values : dict
        The SI values of its parameters after the step.
    ssr : float
        Weighted residual sum of squares (m^2).
    n_free : int
    step : ndarray
        The change of the scaled free parameters from the current fit.
    cols : list of int
        Its columns in the screen.
    """

    lin: Linearized
    values: dict
    ssr: float
    n_free: int
    step: np.ndarray
    cols: list[int]


class Screen:
    """The current fit and every candidate, linearised together on the calibration poses.

    The model evaluated holds the current terms and the candidates other
    than periodic errors, joint couplings and warm-ups; a periodic
    candidate's columns are the exact derivative of the tool point w.r.t.
    its joint's angle times ``sin`` and ``cos`` of its harmonic, a
    coupling's that derivative times its source joint's reading, a
    warm-up's a translation times its decay, so screening again with other harmonics or time constants
    (:meth:`with_candidates`) needs no new model and no new evaluation. A
    candidate of one session (``c2@B``, ``joint_periodic j1 h11 @B``) has its
    cause's columns at that session's poses and zeros elsewhere.
    """

    def __init__(self, current: CalibrationResult, accepted: list[Candidate], cands: list[Candidate],
                 geometric: bool, cal: Measurements, val: Measurements, session_tools: bool = False):
        robot = current.model.robot
        self.current, self.cal, self.val, self.accepted = current, cal, val, list(accepted)
        self.physical = {c.carrier for c in cands if not c.kind.analytic}
        # drift and thermal terms referenced to the calibration poses, as in the fits (current's model)
        self.model = big = model_for(robot, compose_terms(accepted + sorted(self.physical, key=str), geometric), cal,
                                     session_tools=session_tools)
        frames = big.term("sessions")
        if frames is not None:      # each session's reference pose: the current fit's
            frames.references = dict(current.model.term("sessions").references)
        params = big.parameters.copy()
        for p in params:
            if p.name in current.parameters:
                src = current.parameters[p.name]
                p.value, p.fixed = src.value, src.fixed
            else:
                p.fixed = False
        self.model_params = params
        self.free = np.flatnonzero(params.free)
        xyz, J, JA = big.predict_angle_jacobian(cal.q, params.values, big.covariates(cal), current.base0)
        # touch rows: residuals from what they touched, every column projected away from its unknowns
        self._proj = cal.layout.projection(xyz)
        self._raw = J[:, :, self.free] * params.scales[self.free]
        self._model_cols = (self._proj(self._raw), [params.names[i] for i in self.free], params.scales[self.free])
        self.angle_dir = {j: JA[:, :, j - 1] for j in range(1, robot.n + 1)}
        self._JA = JA
        self.r = self._proj.r
        self.w = current.loss.weight(np.einsum("ij,ij->i", self.r, self.r))
        # a warm-up starts at the first calibration pose of its session, as in the fits (Warmup.reference_value)
        t = cal.get("time_s")
        sessions = cal.sessions if cal.sessions is not None else np.full(len(cal), "", dtype=object)
        self.t0 = {} if t is None else {None: float(t.min()), **{s: float(t[sessions == s].min())
                                                                 for s in dict.fromkeys(sessions.tolist())}}
        self._val: dict = {}                   # the validation poses' residuals and columns, made on first use
        self._basis: dict = {}                 # projection(), made on first use
        self._grams: dict = {}                 # fold_grams() of the current model's columns, by folds
        self._set_extra(cands)

    def with_candidates(self, cands: list[Candidate]) -> "Screen":
        """The same linearisation screening ``cands`` (other periodic harmonics, warm-up time constants, sessions'
        own causes or laws; no new cause of the model's)."""
        extra = {c.carrier for c in cands if not c.kind.analytic} - self.physical
        if extra:
            raise ValueError(f"not in this screen's model: {sorted(map(str, extra))}")
        new = copy.copy(self)
        new._set_extra(cands)
        return new

    def _set_extra(self, cands: list[Candidate]) -> None:
        """Columns, names, scales and parameters: the model's, then those of each candidate that is not one of
        the model's columns (a periodic error, a warm-up, a cause of one session, a law over a session
        covariate)."""
        J, names, scale = self._model_cols
        n_model = len(names)
        self.params = {p.name: p for p in self.model_params}
        self.extra: list[tuple[Candidate, int]] = []      # the candidate and its parameter, of each extra column
        self.cols_of: dict[Candidate, list[int]] = {}
        cols = [J]
        for c in cands:
            own = c.parameter_names()
            if own[0] in names[:n_model] or c in self.cols_of:
                continue        # in the model already (or given twice)
            if c.kind.analytic:
                ps = self._analytic_parameters(c)
            elif c != c.carrier and all(n in names[:n_model] for n in c.carrier.parameter_names()):
                ps = c.kind.carried(c, [replace(self.params[n], name=local) for n, local in zip(_carried(c), own)])
            else:
                continue        # a cause of the model's (found by its names), or one it cannot screen
            self.cols_of[c] = list(range(len(names), len(names) + len(ps)))
            for k, p in enumerate(ps):
                self.params.setdefault(p.name, p)
                self.extra.append((c, k))
                cols.append(self._proj(self._column(c, k, self.cal, self._raw, self._JA))[:, :, None])
            names = names + [p.name for p in ps]
            scale = np.append(scale, [p.scale for p in ps])
        self.J = np.concatenate(cols, axis=2) if len(cols) > 1 else J
        self.names, self.scale = names, scale
        cur = self.current.parameters
        self.cur = [k for k, n in enumerate(self.names[:n_model]) if n in cur and not cur[n].fixed]

    def _analytic_parameters(self, c: Candidate) -> list:
        ps = c.kind.analytic_term(c).parameters(self.model.robot)
        return [replace(p, name=n) for p, n in zip(ps, c.parameter_names())]

    def _column(self, c: Candidate, k: int, d: Measurements, J: np.ndarray, JA: np.ndarray) -> np.ndarray:
        """Column (N, 3), scaled, of the ``k``-th parameter of candidate ``c`` at the poses of ``d`` (``J``: the
        model's free columns there, ``JA``: the directions of the joints' angles; not projected for touch rows):
        an analytic cause's computed
        (:meth:`~casadical.terms._cause.Cause.analytic_column`: a periodic error, the direction of its joint's angle
        times a sine of its harmonic; a joint coupling, that direction times the source joint's reading: n (n - 1)
        pairs, one column each, need no term in the screen's model; a warm-up, a translation times its decay)."""
        if c.kind.analytic:
            col = c.kind.analytic_column(c, k, d, JA, self.t0, self.model.robot)
            col = col * self.params[c.parameter_names()[k]].scale
        else:       # a session's own or a law: its carrier's column (scaled alike) at its factor
            col = J[:, :, self._model_cols[1].index(_carried(c)[k])]
            factors = c.kind.factors(c, d, self.cal)
            if factors is not None:
                col = col * factors[:, k % factors.shape[1], None]
        if c.session is not None:
            col = col * (d.sessions == c.session).astype(float)[:, None]
        return col

    # -- the score test ----------------------------------------------------------

    def scores(self, cands: list[Candidate]) -> list[Scored]:
        """Score test of every candidate, best (smallest p) first."""
        sw, Qc, r_perp = self.projection()
        r = self.r.ravel() * sw
        Jx = self.J.reshape(len(r), -1) * sw[:, None]
        ssr0 = float(r_perp @ r_perp)
        # the noise scale with the set-aside poses counted by their influence (statistics.set_aside_share)
        u2w = self.w * np.einsum("ij,ij->i", self.r, self.r)
        share = float(u2w @ set_aside_share(self.w)) / max(float(u2w.sum()), 1e-300)
        p0 = len(self.cur)
        scored = []
        for c in cands:
            cols = self.columns(c)
            if not cols:
                continue
            Jk = Jx[:, cols]
            Jk = Jk - Qc @ (Qc.T @ Jk)
            U, sv, _ = np.linalg.svd(Jk, full_matrices=False)
            keep = sv > 1e-6 * max(np.linalg.norm(Jx[:, cols]), 1e-300)
            if not keep.any():
                continue
            proj = U[:, keep].T @ r_perp
            drop = float(proj @ proj)
            test = nested_test(ssr0, p0, ssr0 - drop, p0 + int(keep.sum()), len(r), (ssr0 - drop) * share)
            scored.append(Scored(test.log10_p, c, test, U[:, keep] @ proj, U[:, keep], (r_perp, p0, len(r))))
        scored.sort(key=lambda t: t.log10_p)
        return scored

    def projection(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The square roots of the weights (per equation), an orthonormal basis of the current model's weighted
        columns, and the weighted residual beyond them: made once per linearisation (the screens of other
        candidates share it, as do the resolution checks of every periodic candidate)."""
        if not self._basis:
            sw = np.repeat(np.sqrt(self.w), 3)
            Q, _ = np.linalg.qr(self.J[:, :, self.cur].reshape(len(sw), -1) * sw[:, None])
            rw = self.r.ravel() * sw
            self._basis.update(sw=sw, Q=Q, r_perp=rw - Q @ (Q.T @ rw))
        return self._basis["sw"], self._basis["Q"], self._basis["r_perp"]

    def columns(self, c: Candidate) -> list[int]:
        """The candidate's free columns not already in the current model."""
        if c in self.cols_of:
            return self.cols_of[c]
        n_model = len(self._model_cols[1])
        return [k for k in (self.names.index(n) for n in c.parameter_names() if n in self.names[:n_model])
                if k not in self.cur]

    # -- fits by one step ----------------------------------------------------------

    def fit(self, cand: Candidate | None = None) -> LinearFit:
        """The current columns (plus ``cand``'s) fitted by one weighted Gauss-Newton step."""
        cols = list(self.cur) + (self.columns(cand) if cand is not None else [])
        J = self.J[:, :, cols]
        sw = np.sqrt(self.w)
        Jw = (J * sw[:, None, None]).reshape(-1, len(cols))
        A = Jw.T @ Jw
        g = Jw.T @ (self.r * sw[:, None]).reshape(-1)
        d = -solve_identified(A, g, rel=1e-9)
        r1 = self.r + J @ d
        names = [self.names[k] for k in cols]
        values = {n: self.params[n].value + self.scale[k] * dk for n, k, dk in zip(names, cols, d)}
        lin = Linearized(J, r1, self.w, names, self.scale[cols], switch_off(names, values, self.scale[cols]),
                         np.array([(values[n] - self.params[n].nominal) / self.scale[k] for n, k in zip(names, cols)]),
                         lambda folds: self.fold_grams(cols, folds))
        return LinearFit(lin, values, float(np.sum(self.w[:, None] * r1 ** 2)), len(cols), d, cols)

    def fold_grams(self, cols: list[int], folds: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
        """:func:`._validation.fold_grams` of the weighted columns ``cols`` (the current model's, then a
        candidate's): the current model's block is made once per linearisation and folds, shared by every
        candidate; a candidate adds its own rows and columns, each fold's part summed as one product (a fold's
        indicator times the columns' products, pose by pose): the cost of a candidate's columns, not of the
        model's."""
        p0 = len(self.cur)
        if list(cols[:p0]) != list(self.cur):
            return fold_grams(self.J[:, :, cols] * np.sqrt(self.w)[:, None, None], folds)
        key = tuple(map(id, folds))
        if key not in self._grams:
            sw = np.sqrt(self.w)[:, None, None]
            S = np.zeros((len(folds), len(self.w)))
            for k, F in enumerate(folds):
                S[k, F] = 1.0
            Jb = self.J[:, :, self.cur] * sw
            self._grams[key] = (S, Jb, *fold_grams(Jb, folds))
        S, Jb, A, AT = self._grams[key]
        extra = list(cols[p0:])
        if not extra:
            return A, AT
        Jc = self.J[:, :, extra] * np.sqrt(self.w)[:, None, None]
        n, pb, pc = Jb.shape[0], p0, len(extra)

        def per_fold(X, Y):      # each fold's sum over its poses of X_i^T Y_i: (n_folds, a, b)
            XY = np.einsum("nia,nib->nab", X, Y).reshape(n, -1)
            return (S @ XY).reshape(len(folds), X.shape[2], Y.shape[2]), XY.sum(axis=0).reshape(X.shape[2], Y.shape[2])
        Fbc, Abc = per_fold(Jb, Jc)
        Fcc, Acc = per_fold(Jc, Jc)
        A1 = np.block([[A, Abc], [Abc.T, Acc]])
        AT1 = np.empty((len(folds), pb + pc, pb + pc))
        AT1[:, :pb, :pb] = AT
        AT1[:, :pb, pb:] = Abc - Fbc
        AT1[:, pb:, :pb] = np.swapaxes(AT1[:, :pb, pb:], 1, 2)
        AT1[:, pb:, pb:] = Acc - Fcc
        return A1, AT1

    def validation_errors(self, fit: LinearFit) -> np.ndarray:
        """Position errors (m) on the validation poses of a one-step fit (a judge, never used to decide)."""
        val = self._val      # shared with the screens of other candidates (with_candidates): one evaluation
        if not val:
            big, p = self.model, self.model_params
            xyz, J, JA = big.predict_angle_jacobian(self.val.q, p.values, big.covariates(self.val),
                                                    self.current.base0)
            proj = self.val.layout.projection(xyz)
            raw = J[:, :, self.free] * p.scales[self.free]
            # column by column in memory (p, N, 3): a column is read whole, not every p-th number (6x faster)
            JT = np.ascontiguousarray(proj(raw).transpose(2, 0, 1))
            val.update(r=proj.r, JT=JT, raw=raw, JA=JA, proj=proj, columns={})
        r, JT, raw, JA, proj, columns = val["r"], val["JT"], val["raw"], val["JA"], val["proj"], val["columns"]
        n_model = len(self._model_cols[1])
        # r + J step: the model's columns in one product (the step 0 on those the fit holds; the columns are rows
        # in memory, so none is copied), then the candidate's a column at a time
        step = np.zeros(n_model)
        model = [i for i, k in enumerate(fit.cols) if k < n_model]
        step[[fit.cols[i] for i in model]] = fit.step[model]
        out = r + (step @ JT.reshape(n_model, -1)).reshape(r.shape)
        for k, d in zip(fit.cols, fit.step):
            if k >= n_model:     # each candidate's column made once (a periodic one is a sin or cos of every pose)
                key = self.extra[k - n_model]
                col = columns.get(key)
                if col is None:
                    col = columns[key] = proj(self._column(*key, self.val, raw, JA))
                out += col * d
        return np.linalg.norm(out, axis=1)


def _carried(c: Candidate) -> list[str]:
    """For each parameter of ``c``, its carrier's parameter whose column it is at a factor (a law has several per
    parameter of its carrier: one per polynomial)."""
    base = c.carrier.parameter_names()
    own = c.parameter_names()
    per = len(own) // len(base)
    return [base[k // per] for k in range(len(own))]


def periodic_columns(direction: np.ndarray, q: np.ndarray, h: int) -> np.ndarray:
    """Columns (N, 3, 2) of ``s sin(h q) + c cos(h q)`` added to a joint's angle, ``direction`` its derivative."""
    return np.stack([direction * np.sin(h * q)[:, None], direction * np.cos(h * q)[:, None]], axis=2)


def ambiguous(best: Scored, scored: list[Scored], level: float) -> list[dict]:
    """Candidates whose screening fit explains the same residual as the accepted one."""
    amb = []
    best_drop = float(best.fitted @ best.fitted)
    cand = best.candidate
    for sc in scored:
        other = sc.candidate
        if other == cand or sc.log10_p >= level or (other.kind is cand.kind and other.joint == cand.joint
                                                    and other.harmonic is None and other.session == cand.session):
            continue
        drop = float(sc.fitted @ sc.fitted)
        cos = float(sc.fitted @ best.fitted) / math.sqrt(max(drop * best_drop, 1e-300))
        similar = drop > 0.7 * best_drop and cos > 0.9
        if not (similar or _reading_rivals(cand, other)):
            continue
        told = beyond(best, sc)
        if told is not None and told.log10_p < level:
            continue    # the data need the accepted cause beyond the other
        # the two fit much the same residual; or, an encoder scale and a harmonic of the same joint (over a short
        # range both are a curve of its reading), neither is needed beyond the other (joint 3's first harmonic
        # over 118 deg and its scale: cos 0.84, but the scale beyond the harmonic p = 0.76 and the harmonic
        # beyond the scale p = 0.005, at a level of 1e-5: the scale was named with no doubt)
        back = None if similar or told is None else beyond(sc, best)
        if similar or (back is not None and back.log10_p >= level):
            amb.append({**other.to_dict(), "label": other.label(), "similarity": round(cos, 4),
                        "tell_apart": tell_apart(cand, other),
                        **({"test": {"text": told.text(), "log10_p": told.log10_p, "log10_level": level}}
                           if told is not None else {})})
    return amb


def _reading_rivals(a: Candidate, b: Candidate) -> bool:
    """An encoder scale and a periodic error of one joint (and scope): both functions of the joint's reading."""
    return (a.kind is not b.kind and a.kind.of_own_reading and b.kind.of_own_reading and a.joint == b.joint
            and a.session == b.session)


def beyond(a: Scored, b: Scored) -> NestedTest | None:
    """The F-test of ``a``'s columns with ``b``'s in the model (linearised at the current fit): whether these
    poses tell ``a`` from ``b`` (None without the columns)."""
    if a.basis is None or b.basis is None or a.base is None:
        return None
    r, p0, n = a.base
    Q, R = np.linalg.qr(np.column_stack([b.basis, a.basis]))
    keep = np.abs(np.diag(R)) > 1e-8
    Q = Q[:, keep]
    both = Q.T @ r
    only_b = b.basis.T @ r
    ssr0 = float(r @ r)
    ssr_b, ssr_ab = ssr0 - float(only_b @ only_b), ssr0 - float(both @ both)
    kb = b.basis.shape[1]
    return nested_test(ssr_b, p0 + kb, ssr_ab, p0 + int(keep.sum()), n)
