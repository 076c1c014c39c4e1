"""``SKCM-IPOPT-CA``, ``-GA``, ``-TLBO``: a metaheuristic's best points start IPOPT (multi-start)."""

from __future__ import annotations

from ._base import register
from ._global_start import GlobalStartMethod


@register
class SKCMIpoptCA(GlobalStartMethod):
    """Cultural algorithm over the stiffnesses, then IPOPT (SKCM) from its best distinct points."""

    name = "SKCM-IPOPT-CA"
    paper = "casadical (CA paper's optimiser as a global start)"
    summary = "cultural algorithm global start, IPOPT multi-start"
    order = 60
    optimizer = "CA"


@register
class SKCMIpoptGA(GlobalStartMethod):
    """Genetic algorithm over the stiffnesses, then IPOPT (SKCM) from its best distinct points."""

    name = "SKCM-IPOPT-GA"
    paper = "casadical (GA as a global start)"
    summary = "genetic algorithm global start, IPOPT multi-start"
    order = 61
    optimizer = "GA"


@register
class SKCMIpoptTLBO(GlobalStartMethod):
    """TLBO over the stiffnesses, then IPOPT (SKCM) from its best distinct points."""

    name = "SKCM-IPOPT-TLBO"
    paper = "casadical (TLBO paper's optimiser as a global start)"
    summary = "TLBO global start, IPOPT multi-start"
    order = 62
    optimizer = "TLBO"
