"""Screening every candidate cause at once: the score (Lagrange multiplier) test.

One model holding every candidate is linearised at the current fit; the
drop of the (robustly weighted) residual sum of squares each candidate's
parameters would bring is its projection on the residual, after the
directions the current model already spans are removed. One Jacobian
evaluation scores all candidates.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..data import Measurements
from ..model import Model
from ..problem import CalibrationProblem
from ..result import CalibrationResult
from .candidates import Candidate, compose_spec
from .statistics import NestedTest, nested_test


@dataclass
class Scored:
    """A candidate's score: the linearised F-test, and the residual its columns would explain."""

    log10_p: float
    candidate: Candidate
    test: NestedTest
    fitted: np.ndarray


def screen(current: CalibrationResult, accepted: list[Candidate], cands: list[Candidate], geometric: bool,
           data: Measurements) -> list[Scored]:
    """Score test of every candidate at the current fit, best (smallest p) first."""
    robot = current.model.robot
    big = Model(robot, compose_spec(accepted + cands, geometric), jit=False)
    params = big.parameters.copy()
    for p in params:
        if p.name in current.parameters:
            src = current.parameters[p.name]
            p.value, p.fixed = src.value, src.fixed
        else:
            p.fixed = False
    prob = CalibrationProblem(big, params, data.q, data.xyz, big.covariates(data), current.base0)
    r, Jx = prob.residuals_jacobian(params.values)
    # the robust loss's weights at the current fit
    R = r.reshape(-1, 3)
    sw = np.repeat(np.sqrt(current.loss.weight(np.einsum("ij,ij->i", R, R))), 3)
    r, Jx = r * sw, Jx * sw[:, None]
    free_names = [params.names[i] for i in prob.free]
    cur = [k for k, n in enumerate(free_names) if n in current.parameters and not current.parameters[n].fixed]
    Qc, _ = np.linalg.qr(Jx[:, cur])
    r_perp = r - Qc @ (Qc.T @ r)
    ssr0 = float(r_perp @ r_perp)
    p0 = len(cur)
    n_eq = len(r)
    scored = []
    for c in cands:
        cols = [free_names.index(n) for n in c.parameter_names() if n in free_names]
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
        test = nested_test(ssr0, p0, ssr0 - drop, p0 + int(keep.sum()), n_eq)
        scored.append(Scored(test.log10_p, c, test, U[:, keep] @ proj))
    scored.sort(key=lambda t: t.log10_p)
    return scored
