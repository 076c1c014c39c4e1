"""Population-based optimisers used by casadical's calibration methods.

Box-constrained minimisation of a vectorised objective (``(pop, d)`` array
in, ``(pop,)`` values out):

- :class:`CulturalAlgorithm` -- Reynolds' cultural algorithm (CA paper:
  stiffness identification, population 20);
- :class:`GeneticAlgorithm` -- real-coded GA (the CA paper's GA baseline);
- :class:`TLBO` -- teaching-learning-based optimisation (TLBO paper: weights
  of the 6-5-3 compensation network).

Subset selection (choose ``m`` distinct items of a pool of ``n``):

- :class:`SubsetGeneticAlgorithm` -- the GA paper's optimal-pose selection
  (population 35, crossover 85 %, mutation 35 %, rate 0.1, 100 generations).

All runs return an :class:`OptimResult` and are reproducible with ``seed``.

Examples
--------
>>> import numpy as np
>>> from casadical.optim import Box, CulturalAlgorithm
>>> box = Box.cube(-5.0, 5.0, 4)
>>> res = CulturalAlgorithm(generations=150).minimize(
...     lambda X: np.sum((X - 1.0) ** 2, axis=1), box, seed=1)
>>> bool(np.allclose(res.x, 1.0, atol=1e-4))
True
"""

from casadical.optim._base import Algorithm, Box, OptimResult, Problem
from casadical.optim._cultural import CulturalAlgorithm
from casadical.optim._genetic import GeneticAlgorithm, SubsetGeneticAlgorithm
from casadical.optim._tlbo import TLBO

__all__ = [
    "Algorithm",
    "Box",
    "CulturalAlgorithm",
    "GeneticAlgorithm",
    "OptimResult",
    "Problem",
    "SubsetGeneticAlgorithm",
    "TLBO",
]
