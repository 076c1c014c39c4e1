"""``SKCM-GA``: the CA paper's baseline (kinematic least squares alternated with a genetic algorithm)."""

from __future__ import annotations

from ._base import register
from ._two_phase import TwoPhaseMethod


@register
class SKCMGA(TwoPhaseMethod):
    """Two-phase SKCM with a real-coded GA over the stiffnesses (the CA paper's "SKCM-C GA").

    Same loop and settings as SKCM-CA (population 20, as the paper gives no GA
    settings); see :mod:`casadical.methods._two_phase`.
    """

    name = "SKCM-GA"
    paper = "CA paper (YS100), baseline"
    summary = "kinematic LS alternated with a genetic algorithm over the stiffnesses"
    order = 31
    optimizer = "GA"
