"""Genetic algorithms: real-coded on a box, and subset selection from a pool.

:class:`GeneticAlgorithm`
    Real-coded GA for box-constrained minimisation (the "SKCM-C by GA"
    baseline of the CA paper): tournament selection, SBX or blend (BLX-alpha)
    crossover with a probability, Gaussian mutation with a per-gene rate and
    a step that shrinks geometrically over the run, elitism.

:class:`SubsetGeneticAlgorithm`
    GA choosing ``m`` distinct items out of a pool of ``n`` (the GA paper's
    optimal-pose selection: 20 poses out of 70 maximising the observability
    index).  Its defaults are the GA paper's settings: population 35,
    crossover 85 %, mutation 35 %, mutation rate 0.1, 100 generations.  The
    generation scheme is the common "percentage" GA those numbers come from:
    ``2 * round(0.85 * 35 / 2) = 30`` children by crossover,
    ``round(0.35 * 35) = 12`` mutants of random members, then parents,
    children and mutants are merged, sorted and truncated to 35 (which keeps
    the best: elitist).
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Callable, ClassVar, Optional

import numpy as np

from casadical.errors import InputError, SolverError
from casadical.optim._base import (
    Algorithm,
    OptimResult,
    Population,
    Problem,
    _check_fraction,
    _check_int,
    _check_positive,
)

__all__ = ["GeneticAlgorithm", "SubsetGeneticAlgorithm", "SubsetObjective"]

#: Vectorised subset objective: ``(pop, m)`` int array -> ``(pop,)`` values.
SubsetObjective = Callable[[np.ndarray], np.ndarray]


@dataclass
class GeneticAlgorithm(Algorithm):
    """Real-coded genetic algorithm on a box.

    Parameters
    ----------
    pop_size : int
        Population size, default 40 (even sizes pair up fully).
    generations : int
        Number of generations, default 100; each costs ``pop_size``
        evaluations.
    crossover : {"sbx", "blend"}
        Simulated binary crossover (Deb and Agrawal 1995) or BLX-alpha.
    crossover_prob : float
        Probability that a pair of parents is crossed, default 0.9.
    eta_c : float
        SBX distribution index (larger: children closer to the parents).
    blend_alpha : float
        BLX-alpha extension of the parents' interval, default 0.5.
    mutation_rate : float, optional
        Probability that a gene is mutated; ``None`` means ``1 / d``.
    mutation_scale : float
        Standard deviation of the Gaussian mutation at the first generation,
        as a fraction of the box width, default 0.1.
    mutation_scale_final : float
        The same at the last generation, default 1e-4; the step shrinks
        geometrically in between so the GA can refine its best point.
    tournament_size : int
        Individuals per selection tournament, default 2.
    n_elite : int
        Best individuals copied unchanged into the next generation, default 2.
    stall_generations, ftol
        Optional early stop, see :class:`~casadical.optim._base.Algorithm`.
    """

    pop_size: int = 40
    generations: int = 100
    crossover: str = "sbx"
    crossover_prob: float = 0.9
    eta_c: float = 15.0
    blend_alpha: float = 0.5
    mutation_rate: Optional[float] = None
    mutation_scale: float = 0.1
    mutation_scale_final: float = 1e-4
    tournament_size: int = 2
    n_elite: int = 2

    _crossovers: ClassVar[tuple[str, ...]] = ("sbx", "blend")

    def _validate(self) -> None:
        if self.crossover not in self._crossovers:
            raise InputError(f"crossover must be one of {self._crossovers}, "
                             f"got {self.crossover!r}")
        _check_fraction(self.crossover_prob, "crossover_prob")
        _check_positive(self.eta_c, "eta_c")
        if not (isinstance(self.blend_alpha, (int, float)) and self.blend_alpha >= 0):
            raise InputError(f"blend_alpha must be >= 0, got {self.blend_alpha!r}")
        if self.mutation_rate is not None:
            _check_fraction(self.mutation_rate, "mutation_rate")
        _check_positive(self.mutation_scale, "mutation_scale")
        _check_positive(self.mutation_scale_final, "mutation_scale_final")
        _check_int(self.tournament_size, "tournament_size", 1)
        _check_int(self.n_elite, "n_elite", 0)
        if self.n_elite >= self.pop_size:
            raise InputError(f"n_elite ({self.n_elite}) must be smaller than "
                             f"pop_size ({self.pop_size})")

    def _initialize(self, problem: Problem, pop: Population,
                    rng: np.random.Generator) -> Population:
        return pop

    def _step(self, problem: Problem, state: Population,
              rng: np.random.Generator, generation: int) -> Population:
        box = problem.box
        X, F = state.X, state.F
        p, d = X.shape

        # tournament selection of p parents (ties -> lower index, harmless)
        entrants = rng.integers(0, p, size=(p, self.tournament_size))
        parents = X[entrants[np.arange(p), np.argmin(F[entrants], axis=1)]]

        # pair parents (0,1), (2,3), ...; an odd last parent is copied
        n_pairs = p // 2
        a, b = parents[0:2 * n_pairs:2], parents[1:2 * n_pairs:2]
        cross = rng.random(n_pairs) < self.crossover_prob
        ca, cb = self._cross(a, b, rng)
        ca = np.where(cross[:, None], ca, a)
        cb = np.where(cross[:, None], cb, b)
        children = np.vstack([ca, cb, parents[2 * n_pairs:]])

        # Gaussian mutation, step annealed from mutation_scale to _final
        frac = (generation - 1) / max(self.generations - 1, 1)
        scale = self.mutation_scale * (self.mutation_scale_final
                                       / self.mutation_scale) ** frac
        rate = self.mutation_rate if self.mutation_rate is not None else 1.0 / d
        hit = rng.random(children.shape) < rate
        children = children + hit * rng.standard_normal(children.shape) \
            * (scale * box.width)
        children = box.clip(children)
        children_f = problem.evaluate(children)

        # elitism: the best n_elite parents replace the worst children
        elite = np.argsort(F, kind="stable")[: self.n_elite]
        keep = np.argsort(children_f, kind="stable")[: p - self.n_elite]
        return Population(np.vstack([X[elite], children[keep]]),
                          np.concatenate([F[elite], children_f[keep]]))

    def _cross(self, a: np.ndarray, b: np.ndarray,
               rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
        if self.crossover == "blend":
            lo, hi = np.minimum(a, b), np.maximum(a, b)
            span = hi - lo
            low = lo - self.blend_alpha * span
            size = (1.0 + 2.0 * self.blend_alpha) * span
            return (low + rng.random(a.shape) * size,
                    low + rng.random(a.shape) * size)
        # SBX; each variable crossed with probability 0.5 (as in pymoo/NSGA-II)
        u = rng.random(a.shape)
        e = 1.0 / (self.eta_c + 1.0)
        beta = np.where(u <= 0.5, (2.0 * u) ** e, (0.5 / (1.0 - u)) ** e)
        beta = np.where(rng.random(a.shape) < 0.5, beta, 1.0)
        mean, half = 0.5 * (a + b), 0.5 * (b - a)
        return mean - beta * half, mean + beta * half


@dataclass
class SubsetGeneticAlgorithm:
    """GA choosing ``m`` distinct items from a pool of ``n``.

    An individual is a set of ``m`` distinct pool indices (stored sorted).
    Defaults are the GA paper's settings for choosing calibration poses.

    Parameters
    ----------
    pop_size : int
        Population size, default 35.
    generations : int
        Number of generations, default 100.
    crossover_frac : float
        Children by crossover per generation as a fraction of the population
        (rounded to an even number), default 0.85.
    mutation_frac : float
        Mutants per generation as a fraction of the population, default 0.35.
    mutation_rate : float
        Probability that a gene (an index) of a mutant is replaced by a
        random unused pool item, default 0.1; at least one gene changes.
    tournament_size : int
        Individuals per parent-selection tournament, default 2.
    stall_generations : int, optional
        Stop when the best value has not changed for this many generations.

    Notes
    -----
    Crossover aligns the two parents so that shared items occupy the same
    positions, then takes each position from either parent (uniform
    crossover): shared items are always inherited and no duplicate can
    appear.  As the GA paper prescribes, any duplicate in an individual
    (possible in injected ``x0`` rows) is replaced by a random unused pool
    item.  Identical sets are dropped when the merged population is
    truncated, which keeps diversity in small pools.
    """

    pop_size: int = 35
    generations: int = 100
    crossover_frac: float = 0.85
    mutation_frac: float = 0.35
    mutation_rate: float = 0.1
    tournament_size: int = 2
    stall_generations: Optional[int] = None

    def maximize(self, fun: SubsetObjective, n_pool: int, m: int, *, seed=None,
                 x0=None, callback=None) -> OptimResult:
        """Find the ``m``-subset of ``range(n_pool)`` maximising `fun`.

        Parameters
        ----------
        fun : callable
            ``fun(S) -> values`` with ``S`` an int array ``(pop, m)`` of
            distinct indices per row (sorted) and values of shape ``(pop,)``.
            NaN counts as the worst value.
        n_pool : int
            Pool size ``n``.
        m : int
            Subset size, ``1 <= m <= n_pool``.
        seed : int or numpy.random.Generator, optional
            Seed for :func:`numpy.random.default_rng`.
        x0 : array_like of int, optional
            Subsets ``(m,)`` or ``(k, m)`` put into the initial population.
        callback : callable, optional
            ``callback(generation, best_subset, best_value)``; return ``True``
            to stop.

        Returns
        -------
        OptimResult
            ``x`` is the best subset (sorted indices), ``fun`` its value
            (maximised, not negated), ``history`` the best value per
            generation.
        """
        return self._run(fun, n_pool, m, -1.0, seed, x0, callback)

    def minimize(self, fun: SubsetObjective, n_pool: int, m: int, *, seed=None,
                 x0=None, callback=None) -> OptimResult:
        """Find the ``m``-subset of ``range(n_pool)`` minimising `fun`.

        Same parameters and result as :meth:`maximize`.
        """
        return self._run(fun, n_pool, m, 1.0, seed, x0, callback)

    # -- internals ------------------------------------------------------
    def _validate(self, n_pool, m) -> None:
        _check_int(self.pop_size, "pop_size", 2)
        _check_int(self.generations, "generations", 0)
        _check_fraction(self.crossover_frac, "crossover_frac")
        _check_fraction(self.mutation_frac, "mutation_frac")
        _check_fraction(self.mutation_rate, "mutation_rate")
        _check_int(self.tournament_size, "tournament_size", 1)
        if self.stall_generations is not None:
            _check_int(self.stall_generations, "stall_generations", 1)
        _check_int(n_pool, "n_pool", 1)
        _check_int(m, "m", 1)
        if m > n_pool:
            raise InputError(f"cannot choose m={m} distinct items from a pool "
                             f"of {n_pool}")

    def _run(self, fun, n_pool, m, sign, seed, x0, callback) -> OptimResult:
        self._validate(n_pool, m)
        if not callable(fun):
            raise InputError(f"objective must be callable, got {type(fun).__name__}")
        n_pool, m = int(n_pool), int(m)
        rng = np.random.default_rng(seed)
        t0 = time.perf_counter()
        nfev = 0

        def evaluate(S: np.ndarray) -> np.ndarray:
            nonlocal nfev
            if S.shape[0] == 0:
                return np.empty(0)
            v = np.asarray(fun(S.copy()), dtype=float)
            if v.shape == (S.shape[0], 1):
                v = v[:, 0]
            if v.shape != (S.shape[0],):
                raise InputError(f"subset objective returned shape {v.shape} for "
                                 f"{S.shape[0]} subsets; it must return "
                                 f"({S.shape[0]},)")
            nfev += S.shape[0]
            # internally always minimise sign * fun; NaN/inf are the worst
            c = sign * v
            return np.where(np.isfinite(c), c, np.inf)

        # initial population: random subsets (argsort of noise = permutations)
        P = np.sort(np.argsort(rng.random((self.pop_size, n_pool)), axis=1)[:, :m],
                    axis=1)
        starts = self._check_x0(x0, n_pool, m, rng)
        if starts is not None:
            P[: starts.shape[0]] = starts
        C = evaluate(P)
        P, C = _truncate(P, C, self.pop_size)

        history = [C[0]]
        nit = 0
        message = f"completed {self.generations} generations"
        stop = callback is not None and callback(0, P[0].copy(), sign * C[0]) is True
        if stop:
            message = "stopped by callback"
        n_children = 2 * int(round(self.crossover_frac * self.pop_size / 2))
        n_mutants = int(round(self.mutation_frac * self.pop_size))
        # with m == n_pool (or a single possible set) there is nothing to search
        searchable = m < n_pool
        while searchable and not stop and nit < self.generations:
            nit += 1
            p = P.shape[0]
            # children by crossover of tournament-selected parents
            k = n_children // 2
            if k:
                entrants = rng.integers(0, p, size=(2 * k, self.tournament_size))
                winners = entrants[np.arange(2 * k), np.argmin(C[entrants], axis=1)]
                kids = _crossover(P[winners[:k]], P[winners[k:]], rng)
            else:
                kids = np.empty((0, m), dtype=int)
            # mutants of uniformly drawn members
            mutants = _mutate(P[rng.integers(0, p, size=n_mutants)],
                              n_pool, self.mutation_rate, rng)
            new = np.vstack([kids, mutants])
            P, C = _truncate(np.vstack([P, new]),
                             np.concatenate([C, evaluate(new)]), self.pop_size)
            history.append(C[0])
            if callback is not None and callback(nit, P[0].copy(), sign * C[0]) is True:
                message = "stopped by callback"
                break
            s = self.stall_generations
            if s is not None and nit >= s and not history[-1 - s] > history[-1]:
                message = f"no improvement in {s} generations"
                break
        if not searchable:
            message = "the pool holds a single subset"

        if not np.isfinite(C[0]):
            raise SolverError(f"the subset objective was NaN/inf at all {nfev} "
                              f"evaluated subsets")
        hist = sign * np.asarray(history, dtype=float)
        return OptimResult(x=P[0].copy(), fun=float(sign * C[0]), nfev=nfev, nit=nit,
                           history=hist, time_s=time.perf_counter() - t0,
                           population=P.copy(), population_fun=sign * C,
                           message=message)

    def _check_x0(self, x0, n_pool, m, rng) -> Optional[np.ndarray]:
        if x0 is None:
            return None
        try:
            raw = np.array(x0)
        except (TypeError, ValueError) as exc:
            raise InputError(f"x0 must be integer indices: {exc}") from None
        if raw.ndim == 1:
            raw = raw[None, :]
        if raw.ndim != 2 or raw.shape[1] != m:
            raise InputError(f"x0 must have shape ({m},) or (k, {m}), got {raw.shape}")
        if raw.size and not np.issubdtype(raw.dtype, np.integer):
            raise InputError(f"x0 must hold integer indices, got dtype {raw.dtype}")
        if raw.shape[0] > self.pop_size:
            raise InputError(f"x0 has {raw.shape[0]} subsets but pop_size is "
                             f"{self.pop_size}")
        if raw.size and (raw.min() < 0 or raw.max() >= n_pool):
            raise InputError(f"x0 indices must lie in [0, {n_pool - 1}]")
        return np.sort(_repair(raw.astype(int), n_pool, rng), axis=1)


def _repair(S: np.ndarray, n_pool: int, rng: np.random.Generator) -> np.ndarray:
    """Replace repeated indices in each row by random unused pool items."""
    S = S.copy()
    for row in S:
        _, first = np.unique(row, return_index=True)
        if first.size == row.size:
            continue
        dup = np.setdiff1d(np.arange(row.size), first)
        unused = np.setdiff1d(np.arange(n_pool), row)
        row[dup] = rng.choice(unused, size=dup.size, replace=False)
    return S


def _crossover(A: np.ndarray, B: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Uniform crossover after aligning shared items; two children per pair."""
    kids = []
    for a, b in zip(A, B):
        shared = np.intersect1d(a, b)
        only_a = np.setdiff1d(a, shared)
        only_b = rng.permutation(np.setdiff1d(b, shared))
        # shared items first in both, then the private ones: no duplicates
        pa = np.concatenate([shared, only_a])
        pb = np.concatenate([shared, only_b])
        mask = rng.random(a.size) < 0.5
        kids.append(np.where(mask, pa, pb))
        kids.append(np.where(mask, pb, pa))
    return np.sort(np.asarray(kids, dtype=int), axis=1)


def _mutate(S: np.ndarray, n_pool: int, rate: float,
            rng: np.random.Generator) -> np.ndarray:
    """Replace each gene with probability `rate` by a random unused item."""
    S = S.copy()
    m = S.shape[1]
    for row in S:
        genes = np.flatnonzero(rng.random(m) < rate)
        if genes.size == 0:
            genes = rng.integers(0, m, size=1)   # a mutant must differ
        unused = np.setdiff1d(np.arange(n_pool), row)
        take = min(genes.size, unused.size)
        row[genes[:take]] = rng.choice(unused, size=take, replace=False)
    return np.sort(S, axis=1)


def _truncate(P: np.ndarray, C: np.ndarray, size: int) -> tuple[np.ndarray, np.ndarray]:
    """Sort by cost, drop repeated sets (kept only if needed), keep `size`."""
    order = np.argsort(C, kind="stable")
    P, C = P[order], C[order]
    _, first = np.unique(P, axis=0, return_index=True)
    unique = np.zeros(P.shape[0], dtype=bool)
    unique[first] = True
    # np.unique returns the first occurrence, i.e. the best copy of each set
    keep = np.concatenate([np.flatnonzero(unique), np.flatnonzero(~unique)])[:size]
    keep.sort()
    return P[keep], C[keep]
