"""``NN-SKCM``: SKCM, then a 6-5-3 network on the joint angles trained by back-propagation."""

from __future__ import annotations

from ..calibration import calibrate
from ._base import Inputs, Method, MethodResult, compliance_model, compliant_joints, new_result, register, to_frame


@register
class NNSKCM(Method):
    """SKCM (IPOPT), then an MLP ``q (n) -> residual (3)`` with 5 tanh hidden units.

    On the papers' six-axis arms this is their 6-5-3 network; on an n-axis
    arm the network reads the n joint readings (n-5-3).

    The network reads the joint readings (rad) and learns what SKCM leaves:
    gear errors, unmodelled deflections, anything smooth in the joint angles
    (TLBO paper, eqs. 8-12). It is trained on the ``extra`` pose set when one
    is given (the TLBO paper's separate Q2, so that the network is not fitted
    to residuals that SKCM has already made small), else on the calibration
    poses. A cross-validation guard drops it if it does not lower the held-out
    error (:mod:`casadical.compensators._guard`).

    Settings
    --------
    joints : sequence of int
        Compliant joints of SKCM (default 2-5 on a six-axis arm, 2..n-1 on others).
    hidden : int
        Hidden units (default 5: the 6-5-3 network).
    trainer : {"backprop", "tlbo", "lbfgs"}
        How the weights are found (default "backprop").
    epochs : int, optional
        Adam steps / TLBO generations / L-BFGS iterations (trainer default).
    l2 : float
        Weight decay on the standardised weights (default 0.01; the paper gives
        none, and without it the 53 weights over-fit 50 poses: on simulated
        gear errors it turned networks that raised the validation error into
        ones that lowered it).
    frame : {"joint1", "measurement"}
        Frame of the learnt residual (default "joint1", see GA-RBF).
    train_on : {"extra", "calibration"}
        Training set; "extra" falls back to the calibration poses if none.
    guard, folds
        Cross-validation guard.
    holdout_check : bool
        Also drop a network trained on the extra set if it raises the error of
        the calibration poses (default False: SKCM was fitted to those poses,
        so their residuals are smaller than elsewhere and the check rejected
        networks that helped on new poses).
    """

    name = "NN-SKCM"
    paper = "TLBO paper's baseline (back-propagation network)"
    summary = "SKCM, then a 6-5-3 network on the joint angles (back-propagation)"
    order = 50
    joints = None
    hidden = 5
    trainer = "backprop"
    epochs = None
    l2 = 0.01
    learning_rate = 0.01
    pop_size = 40
    train_on = "extra"
    frame = "joint1"
    guard = True
    folds = 5
    holdout_check = False

    def fit(self, inputs: Inputs) -> MethodResult:
        joints = compliant_joints(inputs.robot, self.joints)
        sk = calibrate(inputs.robot, inputs.calibration, compliance_model(joints), "ipopt", warn=False,
                       position_only=True)
        use_extra = self.train_on == "extra" and inputs.extra is not None
        train = inputs.extra if use_extra else inputs.calibration
        X, Y = train.q, to_frame(sk, train, self.frame, sk.residuals(train))
        kw = {"method": self.trainer, "epochs": self.epochs, "l2": self.l2}
        if self.trainer == "backprop":
            kw["learning_rate"] = self.learning_rate
        if self.trainer == "tlbo":
            kw["pop_size"] = self.pop_size
        holdout = None
        if use_extra and self.holdout_check:   # the calibration poses are unseen by the network
            cal = inputs.calibration
            holdout = (cal.q, to_frame(sk, cal, self.frame, sk.residuals(cal)))
        from ..compensators import MLP  # here, not at import: 9 ms of every command's start-up
        from ..compensators._guard import fit_guarded

        comp, info = fit_guarded(lambda: MLP(hidden=self.hidden, seed=inputs.seed), X, Y, guard=self.guard,
                                 folds=self.folds, seed=inputs.seed, holdout=holdout, **kw)
        info["trained_on"] = "extra" if use_extra else "calibration"
        info["trainer"] = self.trainer
        info["frame"] = self.frame
        if comp is not None:
            info["final_loss"] = float(comp.training_.final_loss)
            info["epochs"] = int(comp.training_.epochs)
        return new_result(sk, compensator=comp, features="angles", frame=self.frame,
                          info={"compensator": info, "joints": joints, "stiffness_solver": sk.solver_name})
