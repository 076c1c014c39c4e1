"""Fitting an RBF or MLP compensator with a cross-validation guard.

A network trained on 20-50 residuals can learn noise as readily as
structure. Before the final fit, k-fold cross-validation on the training
poses compares the compensator (or each candidate size of it) with no
compensation; the best candidate is kept only if it lowers the held-out
error, otherwise the method equals its model-based part and the reason is
recorded. When the network is trained on a separate pose set, the
calibration poses (which the network never saw) give a second check.
Nothing of the validation set is used.
"""

from __future__ import annotations

from typing import Callable

import numpy as np

from ..errors import CasadicalError

Factory = Callable[[], object]


def cv_sse(factory: Factory, X: np.ndarray, Y: np.ndarray, parts: list[np.ndarray], **fit_kwargs) -> float:
    """Held-out sum of squared residual errors of ``factory()`` over the folds ``parts``."""
    n = len(X)
    sse = 0.0
    for part in parts:
        train = np.setdiff1d(np.arange(n), part)
        comp = factory().fit(X[train], Y[train], **fit_kwargs)
        sse += float(np.sum((Y[part] - comp.predict(X[part])) ** 2))
    return sse


def fit_guarded(factory: Factory | dict[str, Factory], X: np.ndarray, Y: np.ndarray, *, guard: bool = True,
                folds: int = 5, seed: int = 0, margin: float = 0.0,
                holdout: tuple[np.ndarray, np.ndarray] | None = None, **fit_kwargs) -> tuple[object | None, dict]:
    """Fit a compensator ``X -> Y`` unless cross-validation shows no gain.

    Parameters
    ----------
    factory : callable or dict of str to callable
        Returns an unfitted compensator (``fit(X, Y, **fit_kwargs)``,
        ``predict(X)``); a dict gives candidates (e.g. network sizes), the
        one with the lowest cross-validated error is chosen.
    X, Y : ndarray
        Features (n, d) and residuals (n, 3), metres.
    guard : bool
        Compare with no compensation (default True). Without it the best
        candidate (by cross-validation) is fitted whatever its score.
    folds : int
        Folds of the cross-validation (at most n).
    margin : float
        Keep the compensator only if its held-out RMS is below ``(1 - margin)``
        times the uncompensated one.
    holdout : (X, Y), optional
        Poses not used for training (e.g. the calibration poses when the
        network trains on a separate set): the fitted compensator must not
        raise their RMS error either.

    Returns
    -------
    compensator or None, info dict
        ``info`` holds ``cv_rms_mm`` (compensated, held out), ``cv_rms_zero_mm``
        (uncompensated), ``chosen``, ``kept`` and ``reason``.
    """
    cands = factory if isinstance(factory, dict) else {"": factory}
    n = len(X)
    info: dict = {"n_train": n}
    if not guard and len(cands) == 1:
        label, fac = next(iter(cands.items()))
        info.update(kept=True, reason="no guard", chosen=label or None)
        return fac().fit(X, Y, **fit_kwargs), info
    k = min(folds, n)
    rng = np.random.default_rng(seed)
    parts = np.array_split(rng.permutation(n), k)
    scores = {}
    for label, fac in cands.items():
        try:
            scores[label] = cv_sse(fac, X, Y, parts, **fit_kwargs)
        except CasadicalError:   # too few samples for this candidate
            continue
    if not scores:
        info.update(kept=False, reason="dropped: too few training poses for a cross-validation")
        return None, info
    label = min(scores, key=scores.get)
    sse, sse0 = scores[label], float(np.sum(Y ** 2))
    info.update(chosen=label or None, cv_rms_mm=float(np.sqrt(sse / n)) * 1e3,
                cv_rms_zero_mm=float(np.sqrt(sse0 / n)) * 1e3)
    if len(scores) > 1:
        info["cv_rms_mm_by_candidate"] = {c: float(np.sqrt(s / n)) * 1e3 for c, s in scores.items()}
    if not guard:
        info.update(kept=True, reason="no guard (candidate chosen by cross-validation)")
        return cands[label]().fit(X, Y, **fit_kwargs), info
    if not sse < (1.0 - margin) ** 2 * sse0:
        info.update(kept=False, reason=(f"dropped: {k}-fold cross-validation on the training poses gives "
                                        f"{info['cv_rms_mm']:.4f} mm RMS with the compensator against "
                                        f"{info['cv_rms_zero_mm']:.4f} mm without"))
        return None, info
    comp = cands[label]().fit(X, Y, **fit_kwargs)
    if holdout is not None:
        Xh, Yh = holdout
        after = float(np.sqrt(np.mean(np.sum((Yh - comp.predict(Xh)) ** 2, axis=1)))) * 1e3
        before = float(np.sqrt(np.mean(np.sum(Yh ** 2, axis=1)))) * 1e3
        info.update(holdout_rms_mm=after, holdout_rms_zero_mm=before)
        if not after < before:
            info.update(kept=False, reason=(f"dropped: on the {len(Yh)} poses it was not trained on it gives "
                                            f"{after:.4f} mm RMS against {before:.4f} mm without"))
            return None, info
    info.update(kept=True, reason=f"{k}-fold cross-validation gain ({info['cv_rms_zero_mm']:.4f} -> "
                                  f"{info['cv_rms_mm']:.4f} mm RMS)")
    return comp, info
