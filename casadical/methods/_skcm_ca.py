"""``SKCM-CA``: the CA paper's method (kinematic least squares alternated with a cultural algorithm)."""

from __future__ import annotations

from ._base import register
from ._two_phase import TwoPhaseMethod


@register
class SKCMCA(TwoPhaseMethod):
    """Two-phase SKCM with Reynolds' cultural algorithm over the 4 stiffnesses (population 20).

    The paper's "SKCM-C CA"; see :mod:`casadical.methods._two_phase` for the loop
    and :class:`~casadical.methods._two_phase.TwoPhaseMethod` for the settings.
    """

    name = "SKCM-CA"
    paper = "CA paper (YS100)"
    summary = "kinematic LS alternated with a cultural algorithm over the stiffnesses"
    order = 30
    optimizer = "CA"
