"""Cultural algorithm (CA) for box-constrained real-valued minimisation.

Reynolds (1994) "An introduction to cultural algorithms"; the real-valued
version follows Chung and Reynolds (1998) "CAEP: an evolution-based tool for
real-valued function optimization using cultural algorithms", which is the
form the CA paper (YS100 compliance identification, population 20) sketches:

    generate and evaluate the initial population; initialise the belief space
    repeat
        update the belief space with the accepted individuals
        apply variation under the influence of the belief space
        evaluate the children
        select the next population
    until the end condition

Belief space
    *situational knowledge*: the best individual found so far (``s``);
    *normative knowledge*: per variable an interval ``[l_j, u_j]`` and the
    scores ``L_j``, ``U_j`` of the individuals that set its ends.  An accepted
    individual ``x`` with value ``f`` moves ``l_j`` to ``x_j`` if
    ``x_j <= l_j`` or ``f < L_j`` (and likewise ``u_j`` if ``x_j >= u_j`` or
    ``f < U_j``), so the interval follows the good region and shrinks as the
    accepted individuals cluster.

Acceptance
    The best ``accept_frac`` of the population (at least one individual).

Influence
    Each parent makes one child; per variable the step size comes from the
    normative interval and the direction from the situational knowledge
    (CAEP's normative-size / situational-direction variant):
    ``x_j + |w_j N(0,1)|`` if ``x_j < s_j``, ``x_j - |w_j N(0,1)|`` if
    ``x_j > s_j``, ``x_j + w_j N(0,1)`` otherwise, with
    ``w_j = step_scale * (u_j - l_j)``, clipped to the box.

Selection
    ``"tournament"`` (CAEP): parents and children together; each meets
    ``n_opponents`` random rivals, and the ``pop_size`` with most wins survive
    (the best always survives).  ``"plus"``: (mu + lambda) truncation.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar, Optional

import numpy as np

from casadical.errors import InputError
from casadical.optim._base import Algorithm, Population, Problem, _check_fraction, _check_int, _check_positive

__all__ = ["BeliefSpace", "CulturalAlgorithm"]


@dataclass
class BeliefSpace(Population):
    """Population plus belief space (situational and normative knowledge).

    Attributes
    ----------
    s, s_f : numpy.ndarray, float
        Situational knowledge: best individual so far and its value.
    lower, upper : numpy.ndarray
        Normative intervals ``[l_j, u_j]``.
    lower_f, upper_f : numpy.ndarray
        Scores ``L_j``, ``U_j`` of the individuals that set the interval ends.
    """

    s: Optional[np.ndarray] = None
    s_f: float = np.inf
    lower: Optional[np.ndarray] = None
    upper: Optional[np.ndarray] = None
    lower_f: Optional[np.ndarray] = None
    upper_f: Optional[np.ndarray] = None


@dataclass
class CulturalAlgorithm(Algorithm):
    """Cultural algorithm with situational and normative knowledge.

    Parameters
    ----------
    pop_size : int
        Population size, default 20 (the CA paper's N = 20).
    generations : int
        Number of generations, default 100; each costs ``pop_size``
        evaluations.
    accept_frac : float
        Fraction of the population accepted into the belief space each
        generation, default 0.2.
    step_scale : float
        Factor on the normative interval width used as mutation step,
        default 1.0.
    min_width : float
        Floor on the normative width as a fraction of the box width
        (default 1e-9), so a collapsed interval cannot freeze a variable.
    selection : {"tournament", "plus"}
        Survivor selection, see the module docstring.  Default "tournament".
    n_opponents : int
        Rivals per individual in the tournament, default 10 (capped at
        ``2 * pop_size - 1``).
    stall_generations, ftol
        Optional early stop, see :class:`~casadical.optim._base.Algorithm`.
    """

    pop_size: int = 20
    generations: int = 100
    accept_frac: float = 0.2
    step_scale: float = 1.0
    min_width: float = 1e-9
    selection: str = "tournament"
    n_opponents: int = 10

    _selections: ClassVar[tuple[str, ...]] = ("tournament", "plus")

    def _validate(self) -> None:
        _check_fraction(self.accept_frac, "accept_frac", low_open=True)
        _check_positive(self.step_scale, "step_scale")
        _check_positive(self.min_width, "min_width")
        if self.selection not in self._selections:
            raise InputError(f"selection must be one of {self._selections}, "
                             f"got {self.selection!r}")
        _check_int(self.n_opponents, "n_opponents", 1)

    def _initialize(self, problem: Problem, pop: Population,
                    rng: np.random.Generator) -> BeliefSpace:
        box = problem.box
        d = box.dim
        # the normative intervals start as the whole box with unknown scores,
        # so the first accepted individuals set both ends
        state = BeliefSpace(X=pop.X, F=pop.F, s=pop.X[np.argmin(pop.F)].copy(),
                            s_f=float(np.min(pop.F)),
                            lower=box.lower.copy(), upper=box.upper.copy(),
                            lower_f=np.full(d, np.inf), upper_f=np.full(d, np.inf))
        return state

    def _step(self, problem: Problem, state: BeliefSpace,
              rng: np.random.Generator, generation: int) -> BeliefSpace:
        box = problem.box
        X, F = state.X, state.F
        p, d = X.shape

        self._update_beliefs(state)

        # influence: normative step size, situational direction
        width = np.maximum(state.upper - state.lower, self.min_width * box.width)
        step = self.step_scale * width * rng.standard_normal((p, d))
        direction = np.sign(state.s - X)
        children = np.where(direction == 0, X + step, X + direction * np.abs(step))
        children = box.clip(children)
        children_f = problem.evaluate(children)

        pool = np.vstack([X, children])
        pool_f = np.concatenate([F, children_f])
        keep = self._select(pool_f, p, rng)
        state.X, state.F = pool[keep], pool_f[keep]
        return state

    def _update_beliefs(self, state: BeliefSpace) -> None:
        """Acceptance function followed by the belief-space update."""
        p = state.X.shape[0]
        n_accept = max(1, int(round(self.accept_frac * p)))
        order = np.argsort(state.F, kind="stable")[:n_accept]

        best = order[0]
        if state.F[best] < state.s_f:
            state.s, state.s_f = state.X[best].copy(), float(state.F[best])

        # sequential on purpose: the order of the accepted individuals
        # (best first) decides which one owns an interval end
        for i in order:
            x, f = state.X[i], state.F[i]
            move = (x <= state.lower) | (f < state.lower_f)
            state.lower[move] = x[move]
            state.lower_f[move] = f
            move = (x >= state.upper) | (f < state.upper_f)
            state.upper[move] = x[move]
            state.upper_f[move] = f

    def _select(self, pool_f: np.ndarray, p: int,
                rng: np.random.Generator) -> np.ndarray:
        if self.selection == "plus":
            return np.argsort(pool_f, kind="stable")[:p]
        n = pool_f.size
        c = min(self.n_opponents, n - 1)
        # rivals drawn among the others (offset trick avoids self-matches)
        rivals = (np.arange(n)[:, None] + rng.integers(1, n, size=(n, c))) % n
        wins = np.sum(pool_f[:, None] <= pool_f[rivals], axis=1)
        # most wins first, ties broken by the objective value
        return np.lexsort((pool_f, -wins))[:p]
