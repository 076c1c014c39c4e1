"""``GA-RBF``: the GA paper's pipeline (kinematic calibration, then an RBF network
from the six effective joint torques to the three residual position errors)."""

from __future__ import annotations

import numpy as np

from ..calibration import calibrate
from ._base import Inputs, Method, MethodResult, compensator_features, new_result, register, to_frame


@register
class GARBF(Method):
    """KM, then a Gaussian RBF network ``tau (n) -> residual (3)`` (GA paper, eqs. 13-20).

    The paper's YS100 has six joints; on an n-axis arm the network reads the
    n joints' torques, and the residual frame turning with joint 1 follows
    the robot file's convention (MDH with or without beta1, or DH).

    The torques are the gravity torques of every joint from the calibrated
    kinematics, the link masses and each pose's payload. The network has
    Gaussian units with k-means centres and a linear output layer; the
    number of centres and the width are chosen by cross-validation inside
    the calibration set (A8), and a further cross-validation guard drops the
    network if it does not lower the held-out error (see
    :mod:`casadical.compensators._guard`).

    The "GA" of the paper's name is its pose selection (the 20 calibration
    poses chosen out of 70 by a genetic algorithm on the observability
    index): that is ``casadical plan-poses --method ga``; this method
    calibrates on the poses it is given.

    Settings
    --------
    n_centers : int or "cv"
        Number of Gaussian units; "cv" (default) chooses among 2 .. n/2 by
        cross-validation on the calibration poses (fewer centres than poses:
        not an interpolant).
    width : float, "cv" or None
        Width of the units (default "cv": chosen per size by cross-validation).
    ridge : float
        Ridge penalty of the output layer (standardised units).
    frame : {"joint1", "measurement"}
        Frame of the learnt residual (default "joint1": the frame turning with
        joint 1, in which the error of the other joints does not depend on q1;
        the torques cannot tell q1, so in the measurement frame the network
        can only learn errors of a cell that hardly turns joint 1).
    guard : bool
        Cross-validation guard (default True).
    solver : str
        KM solver (default "lm").
    """

    name = "GA-RBF"
    paper = "GA paper (YS100)"
    summary = "KM, then RBF network from the 6 effective torques to the residual"
    order = 40
    n_centers = "cv"
    width = "cv"
    ridge = 1e-6
    frame = "joint1"
    guard = True
    folds = 5
    solver = "lm"

    def fit(self, inputs: Inputs) -> MethodResult:
        data = inputs.calibration
        km = calibrate(inputs.robot, data, "kinematic", self.solver, warn=False, position_only=True)
        X = compensator_features(km, data, "torques")
        Y = to_frame(km, data, self.frame, km.residuals(data))
        from ..compensators._guard import fit_guarded  # here, not at import: 9 ms of every command's start-up

        comp, info = fit_guarded(self._candidates(len(X), inputs.seed), X, Y, guard=self.guard,
                                 folds=self.folds, seed=inputs.seed)
        if comp is not None:
            info.update(n_centers=int(comp.n_centers_), width=float(comp.width_))
        info["frame"] = self.frame
        info["features"] = "gravity torques of joints 1..n (N m), calibrated kinematics"
        return new_result(km, compensator=comp, features="torques", frame=self.frame, info={"compensator": info})

    def _candidates(self, n: int, seed: int) -> dict:
        """Networks to choose from: with ``n_centers="cv"``, 2 .. n/2 centres (A8: fewer centres
        than poses, the paper's calibration error is not zero), each with its width by CV."""
        from ..compensators import RBFNetwork  # here, not at import: 9 ms of every command's start-up

        def make(k):
            return lambda: RBFNetwork(n_centers=k, width=self.width, ridge=self.ridge, seed=seed)
        if self.n_centers != "cv":
            return {str(self.n_centers): make(self.n_centers)}
        top = max(2, int(n * (1 - 1 / self.folds)) // 2)
        ks = sorted({int(round(k)) for k in np.geomspace(2, top, 5)})
        return {f"{k} centres": make(k) for k in ks}
