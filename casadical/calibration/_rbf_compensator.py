"""Stage ``add_rbf_compensator`` (``+rbf_compensator``): an RBF network fitted to what the model leaves.

The network maps sin q, cos q and the gravity torques to the residual in the
robot base frame (:func:`rbf_compensator_data`); it is added to the model as a
``rbf_compensator`` term only if it lowers the cross-validated error
(:func:`fit_rbf_compensator`).
"""

from __future__ import annotations

import warnings
from dataclasses import replace

import numpy as np

from ..data._measurements import Measurements
from ..errors import CasadicalWarning
from ..model._symbolic import Model
from ..result import CalibrationResult, learning_mask, rebuilt
from ..terms import make_term
from ..terms._rbf_compensator import features
from ._state import CalibrationRun


def rbf_compensator_data(result: CalibrationResult, data: Measurements) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """What a residual compensator of ``result`` learns from: features, residuals, poses to train on.

    Features are sin q, cos q and the gravity torques; residuals (measured
    minus predicted) are expressed in the robot base frame; poses the robust
    loss set aside are left out of the training (mask).
    """
    m = result.model
    X = features(data.q, m.torques(data.q, result.parameters.values, m.covariates(data)))
    Y = result.residuals(data) @ result.base_matrix()[:3, :3]   # rows: R^T r, the robot base frame
    return X, Y, learning_mask(result, data)


def with_rbf_compensator(result: CalibrationResult, network, data: Measurements, note: str) -> CalibrationResult:
    """``result`` with a fitted network added to its model as a ``rbf_compensator`` term."""
    m = result.model
    model = Model(m.robot, list(m.terms if m.geometric_free else m.terms[1:])
                  + [make_term("rbf_compensator", network=network)], jit=m.jit)
    return rebuilt(result, model, data, note)


def fit_rbf_compensator(result: CalibrationResult, data: Measurements, seed: int = 0,
                    warn: bool = True) -> CalibrationResult:
    """``result`` with an RBF network fitted to its residuals added as a ``rbf_compensator`` term.

    The network maps sin q, cos q and the gravity torques to the residual in
    the robot base frame; its size and width are chosen by cross-validation
    on ``data``, and it is added only if it lowers the cross-validated
    error (otherwise ``result`` comes back with a note saying so). Poses the
    robust loss set aside do not train the network.
    """
    from ..compensators._guard import fit_guarded  # here, not at import: 9 ms of every command's start-up

    X, Y, keep = rbf_compensator_data(result, data)
    net, info = fit_guarded(rbf_candidates(int(keep.sum()), seed), X[keep], Y[keep], seed=seed)
    if net is None:
        out = replace(result, notes=list(result.notes))
        out.notes.append(f"rbf_compensator not added: {info['reason']}")
        if warn:
            warnings.warn(out.notes[-1], CasadicalWarning, stacklevel=2)
        return out
    return with_rbf_compensator(result, net, data, f"rbf_compensator: {net.n_centers_} Gaussian units fitted to "
                                               f"the residuals of {int(keep.sum())} poses ({info['reason']})")


def rbf_candidates(n: int, seed: int = 0) -> dict:
    """RBF networks to choose from by cross-validation: 2 .. n/3 units, width the mean distance between
    centres (the GA paper's rule; choosing it by a nested cross-validation too costs five times more)."""
    from ..compensators import RBFNetwork

    def make(k):
        return lambda: RBFNetwork(n_centers=k, width=None, seed=seed)
    top = max(2, n // 3)
    return {f"{k} units": make(k) for k in sorted({int(round(k)) for k in np.geomspace(2, top, 5)})}


def add_rbf_compensator(run: CalibrationRun) -> None:
    """With ``+rbf_compensator``: replaces ``result`` by one with the network fitted to its residuals (or a note
    that it was not added)."""
    if run.want_rbf:
        run.result = fit_rbf_compensator(run.result, run.data, warn=run.options.warn)
