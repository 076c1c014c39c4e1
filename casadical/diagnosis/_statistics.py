"""Statistical tests that decide whether an extension of the model is supported."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import special  # not scipy.stats: importing it costs 0.5 s of every diagnosis

from ..calibration._outcome import DOWNWEIGHT_REPORT


@dataclass
class NestedTest:
    """F-test and BIC of a model with ``k`` more parameters than the reference.

    Attributes
    ----------
    f : float
        F statistic.
    dof : (int, int)
    log10_p : float
        log10 of the p-value (p itself underflows for strong effects).
    delta_bic : float
        BIC(extended) - BIC(reference); negative favours the extension.
    """

    f: float
    dof: tuple[int, int]
    log10_p: float
    delta_bic: float

    def text(self) -> str:
        p = f"p = {10 ** self.log10_p:.2g}" if self.log10_p > -300 else "p < 1e-300"
        return f"F = {self.f:.4g} ({self.dof[0]} and {self.dof[1]} dof, {p}), BIC change {self.delta_bic:+.1f}"


def nested_test(ssr0: float, p0: int, ssr1: float, p1: int, n: int, noise_ssr: float | None = None) -> NestedTest:
    """Compare nested least-squares fits: SSR and parameter counts, ``n`` equations.

    ``noise_ssr``: of a robust fit, the extended model's SSR with the set-aside poses counted by their influence
    (:func:`set_aside_share`): the noise scale of the test and of its BIC. The drop ``ssr0 - ssr1`` is the
    fits' own (a set-aside pose's part of it is bounded by its influence already).
    """
    if noise_ssr is not None and noise_ssr > 0:
        ssr0, ssr1 = noise_ssr + (ssr0 - ssr1), noise_ssr
    k = max(p1 - p0, 1)
    dof2 = max(n - p1, 1)
    f = ((ssr0 - ssr1) / k) / (ssr1 / dof2) if ssr1 > 0 else math.inf
    log10_p = _log10(float(special.fdtrc(k, dof2, max(f, 0.0)))) if math.isfinite(f) else -math.inf
    bic = n * (math.log(ssr1 / n) - math.log(ssr0 / n)) + (p1 - p0) * math.log(n)
    return NestedTest(float(f), (k, dof2), log10_p, float(bic))


def set_aside_share(weights: np.ndarray) -> np.ndarray:
    """How much of each pose's term counts in a test's sum of squares: all of it, except for a pose the robust
    loss sets aside (weight below :data:`~casadical.calibration._outcome.DOWNWEIGHT_REPORT`), whose share falls
    with its weight.

    A robust fit's weighted sum of squares grows with a bad shot's distance (``w |r|^2`` and ``2 rho`` are about
    ``c sigma |r|`` far out): three 5 mm shots among 80 poses at 0.02 mm make it ten times the noise's, and every
    F-test's noise scale with it. In the noise scale (``noise_ssr`` of :func:`nested_test`) a set-aside pose
    counts by its influence (``w^2 |r|^2 / 0.5``, at most about ``2 (c sigma)^2``: a pose at 6 sigma), as it
    counts in the fit; the drop a cause brings is the fits' own, so a pose set aside for structure the cause
    explains keeps all its evidence.
    """
    return np.minimum(1.0, np.asarray(weights, float) / DOWNWEIGHT_REPORT)


def noise_ssr(lin) -> float:
    """A linearised fit's (:class:`._validation.Linearized`) weighted SSR with the set-aside poses counted by their
    influence: the noise scale of its tests (:func:`nested_test`)."""
    w = lin.weights
    return float((w * np.einsum("ij,ij->i", lin.r, lin.r)) @ set_aside_share(w))


#: above this many pairs scipy's Wilcoxon test takes its normal approximation, which :func:`paired_gain` computes
ASYMPTOTIC_PAIRS = 50


def paired_gain(before: np.ndarray, after: np.ndarray) -> float:
    """One-sided Wilcoxon signed-rank p-value that ``after`` errors are smaller.

    :func:`scipy.stats.wilcoxon` (``alternative="greater"``, its defaults). Above :data:`ASYMPTOTIC_PAIRS` pairs
    it takes the normal approximation (zeros dropped, average ranks, the ties' correction), computed here from
    ``scipy.special``: the same p-value (a test checks it) without importing ``scipy.stats``, 0.4 s of CPU of
    every diagnosis with the GP compensator.
    """
    d = np.asarray(before, float) - np.asarray(after, float)
    if np.allclose(d, 0):
        return 1.0
    if len(d) <= ASYMPTOTIC_PAIRS:
        from scipy import stats  # the exact or permutation test of few pairs

        return float(stats.wilcoxon(d, alternative="greater").pvalue)
    d = d[d != 0]
    n = len(d)
    values, inverse, counts = np.unique(np.abs(d), return_inverse=True, return_counts=True)
    ranks = (np.cumsum(counts) - (counts - 1) / 2.0)[inverse]      # average ranks of ties
    r_plus = float(ranks[d > 0].sum())
    se = math.sqrt((n * (n + 1.0) * (2.0 * n + 1.0) - float(np.sum(counts ** 3.0 - counts)) / 2.0) / 24.0)
    return float(special.ndtr(-(r_plus - n * (n + 1.0) / 4.0) / se))


def _log10(p: float) -> float:
    return math.log10(p) if p > 0 else -math.inf
