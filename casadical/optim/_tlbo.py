"""Teaching-learning-based optimisation (TLBO).

Rao, Savsani and Vakharia (2011), "Teaching-learning-based optimization: a
novel method for constrained mechanical design optimization problems",
Computer-Aided Design 43(3), as used by the TLBO paper (Le and Kang 2020,
eqs. 13-14) to train the weights of the 6-5-3 compensation network.

Each generation has two phases, each evaluating the whole class once:

* teacher phase: ``X_new = X + r * (X_teacher - TF * X_mean)`` with ``r``
  uniform in [0, 1] (drawn per learner and per variable) and the teaching
  factor ``TF`` drawn from {1, 2} per learner;
* learner phase: each learner ``i`` meets a random peer ``k != i`` and moves
  away from it if ``i`` is better, towards it otherwise:
  ``X_new = X_i + r * (X_i - X_k)`` or ``X_i + r * (X_k - X_i)``.

New positions are clipped to the box and accepted only if they improve the
learner (greedy).  The learners of one phase move simultaneously (the
original updates them one after another); this lets the objective be
evaluated on the whole class at once.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from casadical.optim._base import Algorithm, Population, Problem

__all__ = ["TLBO"]


@dataclass
class TLBO(Algorithm):
    """Teaching-learning-based optimisation (no algorithm-specific knobs).

    Parameters
    ----------
    pop_size : int
        Class size (number of learners), default 20.
    generations : int
        Number of teacher + learner cycles, default 100.  Each costs
        ``2 * pop_size`` evaluations.
    stall_generations, ftol
        Optional early stop, see :class:`~casadical.optim._base.Algorithm`.

    Examples
    --------
    >>> import numpy as np
    >>> from casadical.optim import TLBO, Box
    >>> res = TLBO(generations=60).minimize(
    ...     lambda X: np.sum((X - 1.0) ** 2, axis=1), Box.cube(-5, 5, 3), seed=0)
    >>> bool(res.fun < 1e-8)
    True
    """

    pop_size: int = 20
    generations: int = 100

    def _initialize(self, problem: Problem, pop: Population,
                    rng: np.random.Generator) -> Population:
        return pop

    def _step(self, problem: Problem, state: Population,
              rng: np.random.Generator, generation: int) -> Population:
        X, F = state.X, state.F
        p, d = X.shape
        box = problem.box

        # teacher phase: pull the class mean towards the best learner
        teacher = X[np.argmin(F)]
        tf = rng.integers(1, 3, size=(p, 1))
        trial = box.clip(X + rng.random((p, d)) * (teacher - tf * X.mean(axis=0)))
        X, F = _greedy(X, F, trial, problem.evaluate(trial))

        # learner phase: learn from a random other learner (k != i)
        peer = (np.arange(p) + rng.integers(1, p, size=p)) % p
        better = (F < F[peer])[:, None]
        direction = np.where(better, X - X[peer], X[peer] - X)
        trial = box.clip(X + rng.random((p, d)) * direction)
        X, F = _greedy(X, F, trial, problem.evaluate(trial))
        return Population(X, F)


def _greedy(X: np.ndarray, F: np.ndarray, trial: np.ndarray,
            trial_f: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Keep each trial point only where it is strictly better."""
    keep = trial_f < F
    return np.where(keep[:, None], trial, X), np.where(keep, trial_f, F)
