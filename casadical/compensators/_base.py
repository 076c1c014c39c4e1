"""The interface the RBF and MLP compensators share: standardised regression from features to residuals
(:class:`Compensator`), and the column standardisation it uses (:class:`Standardizer`)."""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from ..errors import InputError


@dataclass(frozen=True)
class Standardizer:
    """Per-column affine map ``z = (x - mean) / scale``.

    Columns that are constant (or pure round-off, e.g. the gravity torque of
    a vertical first axis) get ``scale = 1`` so they map to zero instead of
    amplifying noise.
    """

    mean: np.ndarray
    scale: np.ndarray

    @classmethod
    def fit(cls, A: np.ndarray) -> "Standardizer":
        """Standardiser of the columns of `A` (n, k)."""
        mean = A.mean(axis=0)
        std = A.std(axis=0)
        flat = std <= 1e-12 * np.maximum(1.0, np.max(np.abs(A), axis=0))
        return cls(mean=mean, scale=np.where(flat, 1.0, std))

    def transform(self, A: np.ndarray) -> np.ndarray:
        """Map to standard units."""
        return (A - self.mean) / self.scale

    def inverse(self, Z: np.ndarray) -> np.ndarray:
        """Map back from standard units."""
        return Z * self.scale + self.mean


def _as_matrix(A, name: str) -> np.ndarray:
    try:
        arr = np.asarray(A, dtype=float)
    except (TypeError, ValueError) as exc:
        raise InputError(f"{name} must be numeric: {exc}") from None
    if arr.ndim != 2:
        hint = " (use .reshape(-1, 1) for a single column)" if arr.ndim == 1 else ""
        raise InputError(f"{name} must be a 2-D array (n_samples, n_columns), got "
                         f"shape {arr.shape}{hint}")
    if arr.shape[1] == 0:
        raise InputError(f"{name} has no columns")
    bad = ~np.isfinite(arr)
    if bad.any():
        i, j = np.argwhere(bad)[0]
        raise InputError(f"{name} contains NaN or inf (first at row {i}, column {j})")
    return arr


class Compensator(ABC):
    """Common interface: standardised regression from features to residuals.

    Subclasses implement :meth:`_fit` and :meth:`_predict` on standardised
    data; this class validates shapes, rejects NaN/inf and too few samples,
    and handles the scaling.

    Attributes (after :meth:`fit`)
    ------------------------------
    n_features_in_ : int
        Number of input columns.
    n_outputs_ : int
        Number of output columns.
    x_scaler_, y_scaler_ : Standardizer
        Input and output standardisation.
    """

    #: fewest samples :meth:`fit` accepts (standardisation needs two)
    min_samples: ClassVar[int] = 2

    def fit(self, X, Y, **options) -> "Compensator":
        """Fit the compensator.

        Parameters
        ----------
        X : array_like, shape (n, d)
            Features, e.g. effective joint torques or joint angles.
        Y : array_like, shape (n, k)
            Targets, e.g. residual position errors (k = 3).
        **options
            Passed to the subclass' training (see its ``fit``).

        Returns
        -------
        self

        Raises
        ------
        InputError
            Wrong shapes, NaN/inf, mismatched lengths or too few samples.
        """
        X = _as_matrix(X, "X")
        Y = _as_matrix(Y, "Y")
        if X.shape[0] != Y.shape[0]:
            raise InputError(f"X has {X.shape[0]} rows but Y has {Y.shape[0]}")
        need = self._min_samples_for(X.shape[0], **options)
        if X.shape[0] < need:
            raise InputError(f"{type(self).__name__} needs at least {need} samples, "
                             f"got {X.shape[0]}")
        self.x_scaler_ = Standardizer.fit(X)
        self.y_scaler_ = Standardizer.fit(Y)
        self.n_features_in_ = X.shape[1]
        self.n_outputs_ = Y.shape[1]
        self._fit(self.x_scaler_.transform(X), self.y_scaler_.transform(Y), **options)
        return self

    def predict(self, X) -> np.ndarray:
        """Predict the targets for features `X` (n, d); returns (n, k)."""
        self._check_fitted()
        X = _as_matrix(X, "X")
        if X.shape[1] != self.n_features_in_:
            raise InputError(f"X has {X.shape[1]} columns but the compensator was "
                             f"fitted with {self.n_features_in_}")
        return self.y_scaler_.inverse(self._predict(self.x_scaler_.transform(X)))

    @property
    def is_fitted(self) -> bool:
        """Whether :meth:`fit` has run."""
        return hasattr(self, "n_features_in_")

    def _check_fitted(self) -> None:
        if not self.is_fitted:
            raise InputError(f"{type(self).__name__} is not fitted; call fit(X, Y) "
                             f"first")

    def _min_samples_for(self, n: int, **options) -> int:
        """Fewest samples needed with these settings (override if more)."""
        return self.min_samples

    @abstractmethod
    def _fit(self, Xs: np.ndarray, Ys: np.ndarray, **options) -> None:
        """Fit on standardised data."""

    @abstractmethod
    def _predict(self, Xs: np.ndarray) -> np.ndarray:
        """Predict standardised targets from standardised features."""
