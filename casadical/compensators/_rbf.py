"""The RBF compensator: a Gaussian radial-basis-function network (the GA paper's).

The GA paper (eqs. 17-19) maps the six effective joint torques to the three
residual position errors with hidden units ``o = exp(-n^2)``,
``n = ||w_i - p|| b_i`` (MATLAB ``newrb`` notation: centre ``w_i``, input
``p``, bias ``b_i``) and a linear output layer.  Here the same unit is
written ``exp(-||x - c||^2 / (2 s^2))``, i.e. ``b = 1 / (sqrt(2) s)``, and
all units share one width ``s``.

Training (the paper only cites its references for it):

1. standardise inputs and outputs;
2. centres by k-means (k-means++ start, Lloyd iterations) on the inputs;
3. width ``s`` = mean distance between the centres unless given (on smooth
   6-input test functions this beat the nearest-centre distance, which
   makes the units too narrow to generalise from ~50 samples);
4. output weights (and a bias) by ridge least squares.

The number of centres defaults to ``min(n, max(3, n // 3))``; it and a
factor on the width can be chosen by k-fold cross-validation with
``n_centers="cv"`` / ``width="cv"``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar, Optional, Union

import numpy as np

from ..errors import InputError, SolverError
from ._base import Compensator, Standardizer, _as_matrix

__all__ = ["RBFNetwork", "default_n_centers", "kmeans", "mean_center_distance"]


@dataclass(eq=False)
class RBFNetwork(Compensator):
    """Gaussian RBF network with k-means centres and a linear output layer.

    Parameters
    ----------
    n_centers : int, "cv" or None
        Number of hidden units.  ``None``: ``min(n, max(3, n // 3))`` for
        ``n`` training samples.  ``"cv"``: the count among a grid of about
        eight values from 2 to the fold training size with the lowest k-fold
        validation error.
    width : float, "cv" or None
        Gaussian width ``s`` in standardised input units (each input column
        scaled to unit variance).  ``None``: the mean distance between
        centres.  ``"cv"``: that mean distance times the factor among
        (0.25, 0.5, 1, 2) with the lowest k-fold validation error (chosen
        jointly with ``n_centers`` if both are "cv").
    ridge : float
        Ridge penalty on the output weights (standardised units), default
        1e-8; it only guards against nearly collinear units.
    bias : bool
        Add a constant unit to the output layer (not penalised), default True.
    seed : int, optional
        Seed of the k-means initialisation and of the CV folds.
    cv_folds : int
        Folds used by the "cv" options, default 5.

    Attributes (after fit)
    ----------------------
    centers_ : numpy.ndarray, shape (k, d)
        Centres in standardised input units.
    width_ : float
        Width used (standardised units).
    weights_ : numpy.ndarray, shape (k [+ 1], n_outputs)
        Output weights (bias last), standardised units.
    n_centers_ : int
        Number of centres used.
    cv_errors_ : dict[tuple[int, float], float]
        With a "cv" option: mean validation MSE (standardised units) per
        ``(n_centers, width_factor)`` tried (factor ``nan`` for a fixed width).

    Examples
    --------
    >>> import numpy as np
    >>> rng = np.random.default_rng(0)
    >>> tau = 1e3 * rng.standard_normal((80, 6))            # N m
    >>> err = 1e-4 * np.tanh(tau[:, :3] / 1e3)             # m
    >>> model = RBFNetwork(seed=0).fit(tau, err)
    >>> model.predict(tau[:2]).shape
    (2, 3)
    """

    n_centers: Union[int, str, None] = None
    width: Union[float, str, None] = None
    ridge: float = 1e-8
    bias: bool = True
    seed: Optional[int] = None
    cv_folds: int = 5

    #: width factors tried by ``width="cv"``
    cv_width_factors: ClassVar[tuple[float, ...]] = (0.25, 0.5, 1.0, 2.0)

    def __post_init__(self) -> None:
        nc = self.n_centers
        if not (nc is None or (isinstance(nc, str) and nc == "cv") or
                (isinstance(nc, (int, np.integer)) and not isinstance(nc, bool)
                 and nc >= 1)):
            raise InputError(f"n_centers must be a positive integer, 'cv' or None, "
                             f"got {nc!r}")
        w = self.width
        if not (w is None or (isinstance(w, str) and w == "cv") or
                (isinstance(w, (int, float, np.floating)) and not isinstance(w, bool)
                 and np.isfinite(w) and w > 0)):
            raise InputError(f"width must be a number > 0, 'cv' or None, got {w!r}")
        if not (isinstance(self.ridge, (int, float, np.floating))
                and np.isfinite(self.ridge) and self.ridge >= 0):
            raise InputError(f"ridge must be a finite number >= 0, got {self.ridge!r}")
        if isinstance(self.cv_folds, bool) or \
                not isinstance(self.cv_folds, (int, np.integer)) or self.cv_folds < 2:
            raise InputError(f"cv_folds must be an integer >= 2, got {self.cv_folds!r}")

    # -- Compensator hooks -----------------------------------------------
    def _uses_cv(self) -> bool:
        return isinstance(self.n_centers, str) or isinstance(self.width, str)

    def _min_samples_for(self, n: int, **options) -> int:
        need = self.min_samples
        if self._uses_cv():
            # every fold needs a validation sample and >= 2 training samples
            need = max(need, self.cv_folds, 3)
        if isinstance(self.n_centers, (int, np.integer)):
            need = max(need, int(self.n_centers))
        return need

    def _fit(self, Xs: np.ndarray, Ys: np.ndarray, **options) -> None:
        if options:
            raise InputError(f"RBFNetwork.fit takes no options, got {sorted(options)}")
        rng = np.random.default_rng(self.seed)
        n = Xs.shape[0]
        self.cv_errors_ = {}
        factor = 1.0
        if self._uses_cv():
            k, factor = self._choose_by_cv(Xs, Ys, rng)
        elif self.n_centers is None:
            k = default_n_centers(n)
        else:
            k = int(self.n_centers)
        self.centers_ = kmeans(Xs, k, rng)
        self.width_ = self._width(self.centers_, factor)
        self.weights_ = self._output_layer(self._design(Xs, self.centers_,
                                                        self.width_), Ys)
        self.n_centers_ = k

    def _predict(self, Xs: np.ndarray) -> np.ndarray:
        return self._design(Xs, self.centers_, self.width_) @ self.weights_

    # -- a fitted network as data, and as a symbolic expression -----------
    def to_dict(self) -> dict:
        """The fitted network as JSON-ready numbers (what :meth:`from_dict` reads back)."""
        self._check_fitted()
        return {"kind": "rbf", "x_mean": self.x_scaler_.mean.tolist(), "x_scale": self.x_scaler_.scale.tolist(),
                "y_mean": self.y_scaler_.mean.tolist(), "y_scale": self.y_scaler_.scale.tolist(),
                "centers": self.centers_.tolist(), "width": float(self.width_),
                "weights": self.weights_.tolist(), "bias": bool(self.bias)}

    @classmethod
    def from_dict(cls, d: dict) -> "RBFNetwork":
        """A fitted network from :meth:`to_dict`'s numbers.

        Raises
        ------
        InputError
            Missing or inconsistent entries.
        """
        try:
            net = cls(bias=bool(d["bias"]))
            net.x_scaler_ = Standardizer(np.asarray(d["x_mean"], float), np.asarray(d["x_scale"], float))
            net.y_scaler_ = Standardizer(np.asarray(d["y_mean"], float), np.asarray(d["y_scale"], float))
            net.centers_ = np.asarray(d["centers"], float).reshape(-1, len(net.x_scaler_.mean))
            net.width_ = float(d["width"])
            net.weights_ = np.asarray(d["weights"], float).reshape(len(net.centers_) + net.bias,
                                                                    len(net.y_scaler_.mean))
        except (KeyError, TypeError, ValueError) as e:
            raise InputError(f"not a fitted RBF network: {e!r}") from e
        arrays = (net.x_scaler_.mean, net.x_scaler_.scale, net.y_scaler_.mean, net.y_scaler_.scale,
                  net.centers_, net.weights_)
        if not all(np.isfinite(a).all() for a in arrays) or not net.width_ > 0:
            raise InputError("the RBF network holds non-finite numbers or a width <= 0")
        net.n_centers_ = len(net.centers_)
        net.n_features_in_ = len(net.x_scaler_.mean)
        net.n_outputs_ = len(net.y_scaler_.mean)
        return net

    def casadi(self, x):
        """The network's output for a symbolic feature column ``x`` (CasADi, d x 1) -> k x 1.

        The same numbers as :meth:`predict`, as an expression the model can
        differentiate (e.g. with respect to the joint angles).
        """
        import casadi as ca
        self._check_fitted()
        z = (x - ca.DM(self.x_scaler_.mean)) / ca.DM(self.x_scaler_.scale)
        C = ca.DM(self.centers_)
        d2 = ca.sum2((ca.repmat(z.T, C.shape[0], 1) - C) ** 2)           # k x 1
        phi = ca.exp(-d2 / (2.0 * self.width_ ** 2))
        if self.bias:
            phi = ca.vertcat(phi, 1)
        out = ca.mtimes(ca.DM(self.weights_).T, phi)
        return out * ca.DM(self.y_scaler_.scale) + ca.DM(self.y_scaler_.mean)

    # -- pieces -----------------------------------------------------------
    def hidden(self, X) -> np.ndarray:
        """Hidden-layer outputs (n, k) for raw features `X` (n, d)."""
        self._check_fitted()
        X = _as_matrix(X, "X")
        if X.shape[1] != self.n_features_in_:
            raise InputError(f"X has {X.shape[1]} columns, expected "
                             f"{self.n_features_in_}")
        return _gaussian(self.x_scaler_.transform(X), self.centers_, self.width_)

    def _width(self, centers: np.ndarray, factor: float) -> float:
        if isinstance(self.width, (int, float, np.floating)):
            return float(self.width)
        return factor * mean_center_distance(centers)

    def _design(self, Xs: np.ndarray, centers: np.ndarray, width: float) -> np.ndarray:
        Phi = _gaussian(Xs, centers, width)
        if self.bias:
            Phi = np.hstack([Phi, np.ones((Xs.shape[0], 1))])
        return Phi

    def _output_layer(self, Phi: np.ndarray, Ys: np.ndarray) -> np.ndarray:
        # ridge as extra rows [Phi; sqrt(ridge) I] keeps lstsq well conditioned
        # (better than forming Phi^T Phi); the bias column is not penalised
        penal = np.sqrt(self.ridge) * np.eye(Phi.shape[1])
        if self.bias:
            penal[-1, -1] = 0.0
        A = np.vstack([Phi, penal])
        B = np.vstack([Ys, np.zeros((Phi.shape[1], Ys.shape[1]))])
        import scipy.linalg  # here, not at import: start-up time of every command

        try:
            return scipy.linalg.lstsq(A, B)[0]
        except (np.linalg.LinAlgError, ValueError) as exc:
            raise SolverError(f"RBF output-layer least squares failed: {exc}") from None

    def _choose_by_cv(self, Xs, Ys, rng) -> tuple[int, float]:
        n = Xs.shape[0]
        folds = np.array_split(rng.permutation(n), self.cv_folds)
        n_train = n - max(len(f) for f in folds)
        if isinstance(self.n_centers, str):
            grid = np.unique(np.round(np.geomspace(2, max(n_train, 2), 8)).astype(int))
        elif self.n_centers is None:
            grid = np.array([default_n_centers(n_train)])
        else:
            grid = np.array([min(int(self.n_centers), n_train)])
        if isinstance(self.width, str):
            factors = self.cv_width_factors
        else:
            factors = (1.0,) if self.width is None else (np.nan,)
        sse = {(int(k), float(f)): 0.0 for k in grid for f in factors}
        for fold in folds:
            train = np.setdiff1d(np.arange(n), fold)
            for k in grid:
                # centres do not depend on the width: one k-means per (fold, k)
                centers = kmeans(Xs[train], int(k), rng)
                for f in factors:
                    s = self._width(centers, f)
                    W = self._output_layer(self._design(Xs[train], centers, s),
                                           Ys[train])
                    resid = self._design(Xs[fold], centers, s) @ W - Ys[fold]
                    sse[(int(k), float(f))] += float(np.sum(resid ** 2))
        self.cv_errors_ = {key: v / Ys.size for key, v in sse.items()}
        k, f = min(self.cv_errors_, key=self.cv_errors_.get)
        # refit size: scale the chosen count from fold size to the full data
        if isinstance(self.n_centers, str):
            k = min(n, max(1, int(round(k * n / n_train))))
        elif self.n_centers is None:
            k = default_n_centers(n)
        else:
            k = int(self.n_centers)
        return k, (1.0 if np.isnan(f) else f)


def default_n_centers(n: int) -> int:
    """Default number of centres for `n` samples: ``min(n, max(3, n // 3))``."""
    return min(n, max(3, n // 3))


def _gaussian(Xs: np.ndarray, centers: np.ndarray, width: float) -> np.ndarray:
    d2 = _sqdist(Xs, centers)
    return np.exp(-d2 / (2.0 * width ** 2))


def _sqdist(A: np.ndarray, B: np.ndarray) -> np.ndarray:
    """Squared Euclidean distances (len(A), len(B)), clipped at 0."""
    d2 = (np.sum(A ** 2, axis=1)[:, None] + np.sum(B ** 2, axis=1)[None, :]
          - 2.0 * A @ B.T)
    return np.maximum(d2, 0.0)


def mean_center_distance(centers: np.ndarray) -> float:
    """Mean distance between distinct pairs of centres (default width).

    Falls back to 1 (standardised units) for a single centre or coincident
    centres, which would otherwise give a zero width.
    """
    k = centers.shape[0]
    if k < 2:
        return 1.0
    iu = np.triu_indices(k, 1)
    width = float(np.mean(np.sqrt(_sqdist(centers, centers)[iu])))
    return width if width > 1e-8 else 1.0


def kmeans(X: np.ndarray, k: int, rng: np.random.Generator,
           n_iter: int = 100) -> np.ndarray:
    """k-means++ seeding followed by Lloyd iterations.

    Parameters
    ----------
    X : numpy.ndarray, shape (n, d)
        Points.
    k : int
        Number of centres, ``1 <= k <= n``.
    rng : numpy.random.Generator
        Random source for the seeding.
    n_iter : int
        Maximum Lloyd iterations.

    Returns
    -------
    numpy.ndarray, shape (k, d)
        Centres.  An emptied cluster is re-seeded at the point farthest from
        its centre, so all ``k`` centres stay in use.
    """
    n = X.shape[0]
    if not 1 <= k <= n:
        raise InputError(f"k-means needs 1 <= k <= n_samples, got k={k}, n={n}")
    centers = np.empty((k, X.shape[1]))
    centers[0] = X[rng.integers(n)]
    d2 = np.sum((X - centers[0]) ** 2, axis=1)
    for j in range(1, k):
        total = d2.sum()
        # all points already covered (duplicates): any point will do
        i = rng.integers(n) if total <= 0 else rng.choice(n, p=d2 / total)
        centers[j] = X[i]
        d2 = np.minimum(d2, np.sum((X - centers[j]) ** 2, axis=1))

    labels = None
    for _ in range(n_iter):
        dist = _sqdist(X, centers)
        new = np.argmin(dist, axis=1)
        if labels is not None and np.array_equal(new, labels):
            break
        labels = new
        counts = np.bincount(labels, minlength=k)
        sums = np.zeros_like(centers)
        np.add.at(sums, labels, X)
        filled = counts > 0
        centers[filled] = sums[filled] / counts[filled, None]
        for j in np.flatnonzero(~filled):
            far = int(np.argmax(dist[np.arange(n), labels]))
            centers[j] = X[far]
            dist[far, labels[far]] = 0.0   # do not pick it twice
    return centers
