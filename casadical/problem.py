"""The identification problem: model + data + which parameters are free.

Solvers see scaled variables ``x = (p_free - nominal_free) / scale_free``
and residuals ``r = predicted - measured`` (m, stacked per pose as x, y, z).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .data import Measurements
from .model import Model
from .parameters import Parameters


@dataclass
class CalibrationProblem:
    """Everything a solver needs; built by :func:`casadical.calibration.calibrate`.

    Attributes
    ----------
    model : Model
    params : Parameters
        Working copy: values are the start, ``fixed`` flags say what is free.
    q, xyz, cov : ndarray
        Readings (rad, (N, n)), measured positions (m, (N, 3)), covariates.
    base0 : ndarray
        Reference base pose (12 numbers).
    """

    model: Model
    params: Parameters
    q: np.ndarray
    xyz: np.ndarray
    cov: np.ndarray
    base0: np.ndarray

    @classmethod
    def from_data(cls, model: Model, data: Measurements, params: Parameters | None = None,
                  base0: np.ndarray | None = None) -> "CalibrationProblem":
        return cls(model, (params or model.parameters).copy(), data.q, data.xyz,
                   model.covariates(data), model.base0_nominal() if base0 is None else base0)

    @property
    def n_poses(self) -> int:
        return len(self.q)

    @property
    def free(self) -> np.ndarray:
        return np.flatnonzero(self.params.free)

    @property
    def scale(self) -> np.ndarray:
        return self.params.scales[self.free]

    def x_from_values(self, values: np.ndarray) -> np.ndarray:
        f = self.free
        return (values[f] - self.params.nominal[f]) / self.params.scales[f]

    def values_from_x(self, x: np.ndarray) -> np.ndarray:
        v = self.params.values.copy()
        f = self.free
        v[f] = self.params.nominal[f] + self.params.scales[f] * x
        return v

    def bounds_x(self) -> tuple[np.ndarray, np.ndarray]:
        f = self.free
        nom, s = self.params.nominal[f], self.params.scales[f]
        return (self.params.lower[f] - nom) / s, (self.params.upper[f] - nom) / s

    def residuals(self, values: np.ndarray) -> np.ndarray:
        """Stacked residuals (m), shape (3N,)."""
        return (self.model.predict(self.q, values, self.cov, self.base0) - self.xyz).ravel()

    def residuals_jacobian(self, values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Residuals (3N,) and their Jacobian w.r.t. the scaled free variables (3N, n_free)."""
        xyz, J = self.model.predict_jacobian(self.q, values, self.cov, self.base0)
        f = self.free
        return (xyz - self.xyz).ravel(), J[:, :, f].reshape(-1, len(f)) * self.params.scales[f]
