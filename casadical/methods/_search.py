"""Pieces shared by the metaheuristic methods: search boxes, objectives, optimisers.

The papers' metaheuristics search the joint stiffnesses; the kinematic
parameters come from least squares with the stiffness fixed. The objective
of a candidate is therefore "the position error left after the kinematic
least squares", evaluated two ways:

- :class:`Linearised` (variable projection): at a kinematic solution the
  residual is linear in the compliances to first order (a deflection is
  ~1e-3 rad), and the least squares over the kinematic parameters is the
  projection onto the orthogonal complement of their Jacobian. A whole
  population costs two small matrix products; the outer loop re-linearises.
- :class:`OneStep`: for searches over parameters whose effect is far from
  linear (a joint offset tens of degrees off): per candidate, the base pose
  is re-aligned in closed form, one Gauss-Newton step is taken over the
  other parameters, and the residual is evaluated with the full model.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import CasadicalError, InputError
from ..model._symbolic import Model, pose_to_base0
from ..optim import TLBO, Box, CulturalAlgorithm, GeneticAlgorithm
from ..parameters import Parameters
from ..stats._alignment import align

#: Stiffness search range of the CA paper reproduction (docs/papers.md, A15), N m/rad.
K_BOUNDS = (1e4, 1e8)
OPTIMIZERS = ("CA", "GA", "TLBO")
_EYE = pose_to_base0(np.eye(4))


def make_optimizer(kind: str, pop_size: int = 20, generations: int = 100,
                   stall_generations: int | None = 10, ftol: float = 1e-7):
    """CA, GA or TLBO with the reproduction's settings (A15: population 20, at most
    100 generations, stop when the best changes by < ``ftol`` (m, 1e-4 mm) in 10)."""
    kind = kind.upper()
    common = dict(pop_size=pop_size, generations=generations, stall_generations=stall_generations, ftol=ftol)
    if kind == "CA":
        return CulturalAlgorithm(**common)
    if kind == "GA":
        return GeneticAlgorithm(**common)
    if kind == "TLBO":
        return TLBO(**common)
    raise InputError(f"unknown optimiser {kind!r}; choose from {', '.join(OPTIMIZERS)}")


def stiffness_box(params: Parameters, cnames: list[str], k_bounds=K_BOUNDS) -> tuple[np.ndarray, np.ndarray]:
    """Search box in log10(stiffness): ``k_bounds`` within what the compliance bounds allow.

    A compliance ``c`` bounded to ``[0, 1/k_min]`` allows stiffness
    ``[k_min, inf)``; the box is that range cut to ``k_bounds``.
    """
    lo, hi = [], []
    for c in cnames:
        p = params[c]
        k_min = 1.0 / p.upper if p.upper > 0 and math.isfinite(p.upper) else 0.0
        k_max = 1.0 / p.lower if p.lower > 0 else math.inf
        a, b = max(k_bounds[0], k_min), min(k_bounds[1], k_max)
        if not (0 < a < b):
            raise InputError(f"empty stiffness search box for {c}: [{a:g}, {b:g}] N m/rad")
        lo.append(math.log10(a))
        hi.append(math.log10(b))
    return np.array(lo), np.array(hi)


def mean_or_rms(norms: np.ndarray, kind: str) -> np.ndarray:
    """Per-candidate objective from per-pose error norms (..., N): ``mean`` (A15) or ``rms``."""
    if kind == "mean":
        return norms.mean(axis=-1)
    if kind == "rms":
        return np.sqrt((norms ** 2).mean(axis=-1))
    raise InputError(f"unknown fitness {kind!r}; use 'mean' or 'rms'")


class Linearised:
    """Residual after the kinematic least squares, linearised in the compliances.

    Parameters
    ----------
    model, params : Model, Parameters
        ``params`` holds the linearisation point; its free parameters are the
        kinematic ones solved by least squares (the compliances are fixed).
    q, xyz, cov, base0 : ndarray
        The data and the base pose reference.
    cnames : list of str
        Compliance parameters being searched.
    """

    def __init__(self, model: Model, params: Parameters, q, xyz, cov, base0, cnames: list[str],
                 fitness: str = "mean"):
        values = params.values
        pred, J = model.predict_jacobian(q, values, cov, base0)
        self.N = len(q)
        free = np.flatnonzero(params.free)
        self.cidx = np.array([params.index(c) for c in cnames])
        if np.intersect1d(free, self.cidx).size:
            raise InputError("the searched compliances must be fixed in the least-squares problem")
        self.free = free
        self.scales = params.scales[free]
        self.r0 = (pred - xyz).ravel()
        Jx = J[:, :, free].reshape(-1, len(free)) * self.scales
        U, s, Vt = np.linalg.svd(Jx, full_matrices=False)
        keep = s > s[0] * 1e-10
        self.U, self.s, self.Vt = U[:, keep], s[keep], Vt[keep]
        self.Jc = J[:, :, self.cidx].reshape(-1, len(cnames))
        self.c0 = values[self.cidx]
        self.values0 = values
        self.fitness = fitness

    def residuals(self, C: np.ndarray) -> np.ndarray:
        """Projected residuals (pop, 3N) for compliance rows ``C`` (pop, nc)."""
        R = self.r0[:, None] + self.Jc @ (np.atleast_2d(C) - self.c0).T
        R -= self.U @ (self.U.T @ R)
        return R.T

    def __call__(self, Z: np.ndarray) -> np.ndarray:
        """Objective of log10-stiffness rows ``Z`` (pop, nc)."""
        R = self.residuals(10.0 ** (-np.asarray(Z)))
        norms = np.linalg.norm(R.reshape(len(R), self.N, 3), axis=2)
        return mean_or_rms(norms, self.fitness)

    def values(self, z: np.ndarray) -> np.ndarray:
        """All parameter values after the (linear) least-squares step for log10 stiffness ``z``."""
        c = 10.0 ** (-np.asarray(z, float))
        r = self.r0 + self.Jc @ (c - self.c0)
        dx = -self.Vt.T @ ((self.U.T @ r) / self.s)
        v = self.values0.copy()
        v[self.free] += self.scales * dx
        v[self.cidx] = c
        return v


@dataclass
class Variable:
    """One searched variable: a parameter, in log10(1/c) for compliances or SI otherwise."""

    name: str
    index: int
    log_stiffness: bool
    lower: float
    upper: float

    def value(self, z: float) -> float:
        return 10.0 ** (-z) if self.log_stiffness else z

    def coordinate(self, v: float) -> float:
        if self.log_stiffness:
            return -math.log10(v) if v > 0 else self.upper
        return v


class OneStep:
    """Residual after one Gauss-Newton step over the other parameters, per candidate.

    For each candidate the searched parameters are set, the base pose is
    re-aligned in closed form, the free parameters take one (linear least
    squares) Gauss-Newton step, clipped to their bounds, and the full model
    gives the residual. Slower than :class:`Linearised` (three model
    evaluations per candidate), but valid far from the start.
    """

    def __init__(self, model: Model, params: Parameters, q, xyz, cov, variables: list[Variable],
                 fitness: str = "mean"):
        self.model, self.q, self.xyz, self.cov = model, q, xyz, cov
        self.variables = variables
        searched = {v.index for v in variables}
        self.base_idx = np.array([i for i, p in enumerate(params) if p.group == "base"])
        self.rest = np.array([i for i in np.flatnonzero(params.free) if i not in searched])
        self.scales = params.scales[self.rest]
        self.lower, self.upper = params.lower[self.rest], params.upper[self.rest]
        self.values0 = params.values
        self.fitness = fitness

    def point(self, z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Parameter values and base0 after the step, for candidate ``z``."""
        v = self.values0.copy()
        for var, zi in zip(self.variables, z):
            v[var.index] = var.value(zi)
        v[self.base_idx] = 0.0
        T = align(self.model.predict(self.q, v, self.cov, _EYE), self.xyz)
        b0 = pose_to_base0(T)
        pred, J = self.model.predict_jacobian(self.q, v, self.cov, b0)
        r = (pred - self.xyz).ravel()
        Jf = J[:, :, self.rest].reshape(-1, len(self.rest)) * self.scales
        dx = np.linalg.lstsq(Jf, -r, rcond=1e-10)[0]
        v[self.rest] = np.clip(v[self.rest] + self.scales * dx, self.lower, self.upper)
        return v, b0

    def norms(self, z: np.ndarray) -> np.ndarray:
        v, b0 = self.point(z)
        return np.linalg.norm(self.model.predict(self.q, v, self.cov, b0) - self.xyz, axis=1)

    def __call__(self, Z: np.ndarray) -> np.ndarray:
        out = np.empty(len(Z))
        for i, z in enumerate(Z):
            try:
                out[i] = mean_or_rms(self.norms(z), self.fitness)
            except (CasadicalError, np.linalg.LinAlgError, FloatingPointError):
                out[i] = np.inf  # a degenerate candidate (e.g. alignment failure) never wins
        return out


def distinct_best(X: np.ndarray, F: np.ndarray, box: Box, n: int, min_distance: float = 0.02) -> np.ndarray:
    """Up to ``n`` best rows of ``X`` at least ``min_distance`` apart (box-normalised)."""
    order = np.argsort(F)
    chosen: list[np.ndarray] = []
    for i in order:
        if not np.isfinite(F[i]):
            break
        u = (X[i] - box.lower) / box.width
        if all(np.max(np.abs(u - (c - box.lower) / box.width)) >= min_distance for c in chosen):
            chosen.append(X[i])
        if len(chosen) == n:
            break
    return np.array(chosen)
