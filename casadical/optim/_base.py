"""Problem, algorithm and result pieces shared by the population optimisers.

The split follows pymoo: a :class:`Problem` (objective on a :class:`Box`)
knows nothing about the search, an :class:`Algorithm` holds only settings
and the search logic, and every run returns an :class:`OptimResult`.

Objectives are evaluated a whole population at a time: ``fun`` receives an
array of shape ``(pop, d)`` and returns ``(pop,)`` values.  Non-finite values
(NaN, +-inf) are treated as ``+inf`` so that a failed evaluation never wins.
"""

from __future__ import annotations

import math
import time
from abc import ABC, abstractmethod
from dataclasses import dataclass
from typing import Callable, ClassVar, Optional

import numpy as np

from casadical.errors import InputError, SolverError

__all__ = [
    "Algorithm",
    "Box",
    "Callback",
    "Objective",
    "OptimResult",
    "Population",
    "Problem",
]

#: Vectorised objective: ``(pop, d)`` array -> ``(pop,)`` values.
Objective = Callable[[np.ndarray], np.ndarray]
#: Progress hook ``callback(generation, best_x, best_f)``; returning ``True``
#: stops the run after the current generation.
Callback = Callable[[int, np.ndarray, float], Optional[bool]]


@dataclass
class OptimResult:
    """Outcome of one optimisation run.

    Attributes
    ----------
    x : numpy.ndarray
        Best point found, shape ``(d,)`` (for subset searches: the sorted
        item indices, shape ``(m,)``).
    fun : float
        Objective value at `x` (``inf`` if no finite value was ever seen).
    nfev : int
        Number of points evaluated (rows passed to the objective).
    nit : int
        Number of generations completed.
    history : numpy.ndarray
        Best-so-far objective value after each generation, shape
        ``(nit + 1,)``; ``history[0]`` is the best of the initial population.
    time_s : float
        Wall-clock time of the run in seconds.
    population : numpy.ndarray
        Final population, shape ``(pop, d)``.
    population_fun : numpy.ndarray
        Objective values of the final population, shape ``(pop,)``.
    message : str
        Why the run stopped.
    """

    x: np.ndarray
    fun: float
    nfev: int
    nit: int
    history: np.ndarray
    time_s: float
    population: np.ndarray
    population_fun: np.ndarray
    message: str = ""


def _as_vector(values, name: str) -> np.ndarray:
    try:
        arr = np.array(values, dtype=float)
    except (TypeError, ValueError) as exc:
        raise InputError(f"{name} must be numeric: {exc}") from None
    arr = np.atleast_1d(arr)
    if arr.ndim != 1:
        raise InputError(f"{name} must be 1-D, got shape {arr.shape}")
    if arr.size == 0:
        raise InputError(f"{name} must not be empty")
    return arr


@dataclass(frozen=True, eq=False)
class Box:
    """Axis-aligned search box ``lower <= x <= upper``.

    Parameters
    ----------
    lower, upper : array_like
        Bounds, 1-D, same length, finite, with ``lower < upper`` everywhere.
        Scalars give a 1-D box.

    Raises
    ------
    InputError
        If the bounds are not finite, differ in shape or are not increasing.
    """

    lower: np.ndarray
    upper: np.ndarray

    def __post_init__(self) -> None:
        lower = _as_vector(self.lower, "Box lower")
        upper = _as_vector(self.upper, "Box upper")
        if lower.shape != upper.shape:
            raise InputError(f"Box lower and upper differ in shape: "
                             f"{lower.shape} vs {upper.shape}")
        if not (np.all(np.isfinite(lower)) and np.all(np.isfinite(upper))):
            raise InputError("Box bounds must be finite (the optimisers sample "
                             "the whole box)")
        bad = np.flatnonzero(~(lower < upper))
        if bad.size:
            j = int(bad[0])
            raise InputError(f"Box needs lower < upper; dimension {j} has "
                             f"lower={lower[j]!r}, upper={upper[j]!r}")
        # frozen dataclass: write the validated copies, then freeze them too
        lower.flags.writeable = False
        upper.flags.writeable = False
        object.__setattr__(self, "lower", lower)
        object.__setattr__(self, "upper", upper)

    @classmethod
    def cube(cls, low: float, high: float, dim: int) -> "Box":
        """Return the box ``[low, high]^dim``."""
        if int(dim) != dim or dim < 1:
            raise InputError(f"Box dimension must be a positive integer, got {dim!r}")
        return cls(np.full(int(dim), low, dtype=float),
                   np.full(int(dim), high, dtype=float))

    @property
    def dim(self) -> int:
        """Number of variables."""
        return int(self.lower.size)

    @property
    def width(self) -> np.ndarray:
        """``upper - lower``."""
        return self.upper - self.lower

    def clip(self, X: np.ndarray) -> np.ndarray:
        """Project points onto the box (returns a new array)."""
        return np.clip(X, self.lower, self.upper)

    def contains(self, X: np.ndarray) -> np.ndarray:
        """Whether each point (last axis = variables) lies inside the box."""
        X = np.asarray(X, dtype=float)
        return np.all((X >= self.lower) & (X <= self.upper), axis=-1)

    def sample(self, rng: np.random.Generator, n: int) -> np.ndarray:
        """Latin-hypercube sample of `n` points, shape ``(n, dim)``.

        Stratifying each axis spreads a small population (20 points) over the
        box better than independent uniform draws.
        """
        strata = np.argsort(rng.random((n, self.dim)), axis=0)
        u = (strata + rng.random((n, self.dim))) / n
        return self.lower + u * self.width


class Problem:
    """Objective `fun` on `box`, evaluated by populations.

    Counts evaluations and keeps the best point ever evaluated, so a result
    can never be worse than any point the algorithm looked at (in particular
    the injected ``x0``).

    Parameters
    ----------
    fun : callable
        ``fun(X) -> f`` with ``X`` of shape ``(pop, d)`` and ``f`` of shape
        ``(pop,)``.
    box : Box
        Search box.
    """

    def __init__(self, fun: Objective, box: Box):
        if not callable(fun):
            raise InputError(f"objective must be callable, got {type(fun).__name__}")
        self.fun = fun
        self.box = box
        self.nfev = 0
        self.best_x = box.lower + 0.5 * box.width
        self.best_f = math.inf

    def evaluate(self, X: np.ndarray) -> np.ndarray:
        """Evaluate the rows of `X`; non-finite values become ``+inf``."""
        X = np.ascontiguousarray(X, dtype=float)
        if X.shape[0] == 0:
            return np.empty(0)
        f = np.asarray(self.fun(X.copy()), dtype=float)
        if f.shape == (X.shape[0], 1):
            f = f[:, 0]
        if f.shape != (X.shape[0],):
            raise InputError(f"objective returned shape {f.shape} for a population "
                             f"of shape {X.shape}; it must return ({X.shape[0]},)")
        f = np.where(np.isfinite(f), f, np.inf)
        self.nfev += X.shape[0]
        i = int(np.argmin(f))
        if f[i] < self.best_f:
            self.best_f = float(f[i])
            self.best_x = X[i].copy()
        return f


@dataclass
class Population:
    """Current population ``X`` (pop, d) with objective values ``F`` (pop,).

    Algorithms that carry more state between generations (e.g. the belief
    space of the cultural algorithm) subclass it.
    """

    X: np.ndarray
    F: np.ndarray


def _check_int(value, name: str, minimum: int) -> None:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) \
            or value < minimum:
        raise InputError(f"{name} must be an integer >= {minimum}, got {value!r}")


def _check_fraction(value, name: str, *, low_open: bool = False) -> None:
    ok = isinstance(value, (int, float, np.floating)) and not isinstance(value, bool)
    if ok:
        ok = (0.0 < value <= 1.0) if low_open else (0.0 <= value <= 1.0)
    if not ok:
        rng_txt = "(0, 1]" if low_open else "[0, 1]"
        raise InputError(f"{name} must be in {rng_txt}, got {value!r}")


def _check_positive(value, name: str) -> None:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.number)) \
            or not (value > 0) or not np.isfinite(value):
        raise InputError(f"{name} must be a finite number > 0, got {value!r}")


@dataclass
class Algorithm(ABC):
    """Base of the box-constrained population optimisers.

    Subclasses add their own settings as dataclass fields and implement
    :meth:`_initialize` and :meth:`_step`; the generation loop, bookkeeping,
    ``x0`` injection, callback and early stop live here.

    Parameters
    ----------
    pop_size : int
        Population size.
    generations : int
        Maximum number of generations.
    stall_generations : int, optional
        Stop early when the best value improved by less than `ftol` over this
        many generations.  ``None`` (default) always runs all generations.
    ftol : float
        Improvement threshold used with `stall_generations`.
    """

    pop_size: int = 20
    generations: int = 100
    stall_generations: Optional[int] = None
    ftol: float = 0.0

    #: smallest population the algorithm can work with
    _min_pop: ClassVar[int] = 2

    # -- to implement ---------------------------------------------------
    @abstractmethod
    def _initialize(self, problem: Problem, pop: Population,
                    rng: np.random.Generator) -> Population:
        """Build the algorithm state from the evaluated initial population."""

    @abstractmethod
    def _step(self, problem: Problem, state: Population,
              rng: np.random.Generator, generation: int) -> Population:
        """Run one generation and return the new state."""

    def _validate(self) -> None:
        """Check the algorithm-specific settings (raise InputError)."""

    # -- public ---------------------------------------------------------
    def minimize(self, fun: Objective, box: Box, *, seed=None, x0=None,
                 callback: Optional[Callback] = None) -> OptimResult:
        """Minimise `fun` over `box`.

        Parameters
        ----------
        fun : callable
            Vectorised objective ``fun(X) -> f``, ``X`` of shape ``(pop, d)``,
            ``f`` of shape ``(pop,)``.  NaN/inf values count as ``+inf``.
        box : Box or tuple
            Search box, or a ``(lower, upper)`` pair.
        seed : int or numpy.random.Generator, optional
            Seed of :func:`numpy.random.default_rng`; the same seed gives the
            same run.
        x0 : array_like, optional
            Point ``(d,)`` or points ``(k, d)``, ``k <= pop_size``, inside the
            box, that replace members of the random initial population.  The
            result is never worse than the best of them.
        callback : callable, optional
            ``callback(generation, best_x, best_f)`` after the initial
            population (generation 0) and after each generation; return
            ``True`` to stop.

        Returns
        -------
        OptimResult

        Raises
        ------
        InputError
            Bad settings, box, `x0`, or an objective returning the wrong shape.
        SolverError
            The objective never returned a finite value.
        """
        self._check_settings()
        if not isinstance(box, Box):
            try:
                lower, upper = box
            except (TypeError, ValueError):
                raise InputError("box must be a Box or a (lower, upper) pair") from None
            box = Box(lower, upper)
        rng = np.random.default_rng(seed)
        problem = Problem(fun, box)
        t0 = time.perf_counter()

        X = box.sample(rng, self.pop_size)
        starts = self._check_x0(x0, box)
        if starts is not None:
            X[: starts.shape[0]] = starts
        state = self._initialize(problem, Population(X, problem.evaluate(X)), rng)

        history = [problem.best_f]
        message = f"completed {self.generations} generations"
        nit = 0
        stop = callback is not None and callback(0, problem.best_x.copy(),
                                                 problem.best_f) is True
        if stop:
            message = "stopped by callback"
        while not stop and nit < self.generations:
            nit += 1
            state = self._step(problem, state, rng, nit)
            history.append(problem.best_f)
            if callback is not None and callback(nit, problem.best_x.copy(),
                                                 problem.best_f) is True:
                message = "stopped by callback"
                break
            k = self.stall_generations
            if k is not None and nit >= k and \
                    not history[-1 - k] - history[-1] > self.ftol:
                message = f"no improvement > ftol in {k} generations"
                break

        if not math.isfinite(problem.best_f):
            raise SolverError(f"the objective was NaN/inf at all {problem.nfev} "
                              f"evaluated points")
        return OptimResult(
            x=problem.best_x.copy(), fun=float(problem.best_f), nfev=problem.nfev,
            nit=nit, history=np.asarray(history, dtype=float),
            time_s=time.perf_counter() - t0, population=state.X.copy(),
            population_fun=state.F.copy(), message=message)

    # -- helpers --------------------------------------------------------
    def _check_settings(self) -> None:
        _check_int(self.pop_size, "pop_size", self._min_pop)
        _check_int(self.generations, "generations", 0)
        if self.stall_generations is not None:
            _check_int(self.stall_generations, "stall_generations", 1)
        if not (isinstance(self.ftol, (int, float)) and self.ftol >= 0):
            raise InputError(f"ftol must be a number >= 0, got {self.ftol!r}")
        self._validate()

    def _check_x0(self, x0, box: Box) -> Optional[np.ndarray]:
        if x0 is None:
            return None
        try:
            starts = np.array(x0, dtype=float)
        except (TypeError, ValueError) as exc:
            raise InputError(f"x0 must be numeric: {exc}") from None
        if starts.ndim == 1:
            starts = starts[None, :]
        if starts.ndim != 2 or starts.shape[1] != box.dim:
            raise InputError(f"x0 must have shape ({box.dim},) or (k, {box.dim}), "
                             f"got {np.shape(x0)}")
        if starts.shape[0] > self.pop_size:
            raise InputError(f"x0 has {starts.shape[0]} points but pop_size is "
                             f"{self.pop_size}")
        if not np.all(np.isfinite(starts)):
            raise InputError("x0 contains NaN or inf")
        outside = np.flatnonzero(~box.contains(starts))
        if outside.size:
            raise InputError(f"x0 point {int(outside[0])} lies outside the box")
        return starts

