"""``TLBO-NN-SKCM``: the TLBO paper's method (SKCM, then a 6-5-3 network whose
weights and biases are found by teaching-learning-based optimisation)."""

from __future__ import annotations

from ._base import register
from ._nn_skcm import NNSKCM


@register
class TLBONNSKCM(NNSKCM):
    """SKCM, then the 6-5-3 network trained by TLBO on the separate ``extra`` set (Q2).

    All 53 weights and biases form one learner; TLBO's teacher and learner
    phases minimise the mean squared error (eqs. 12-14), 40 learners for
    500 generations by default. Settings as NN-SKCM.
    """

    name = "TLBO-NN-SKCM"
    paper = "TLBO paper (HH800)"
    summary = "SKCM, then a 6-5-3 network on the joint angles trained by TLBO on a separate set"
    order = 51
    trainer = "tlbo"
