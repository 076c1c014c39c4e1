"""A Gaussian process on the residual: the accuracy layer that knows where it holds.

What the named causes leave is learnt as a function of the joint readings
by a Gaussian process with one length scale per joint (automatic relevance
determination) and a white-noise part:

    k(x, x') = s^2 exp(-1/2 sum_j ((x_j - x'_j) / l_j)^2) + sigma_n^2 [x = x']

Its hyperparameters are fitted by maximum marginal likelihood with
scikit-learn's :class:`~sklearn.gaussian_process.GaussianProcessRegressor`
(a well-kept implementation with the gradient of the likelihood and
L-BFGS-B; GPyTorch would do the same at the cost of importing PyTorch). The
fitted process is then held as plain numbers (training poses, residuals,
hyperparameters) and evaluated here with numpy, and symbolically in the
model (:class:`~casadical.terms.gp_compensator.GPCompensator`), so that
``predict`` and ``compensate`` do not import scikit-learn; a test checks the
two agree with scikit-learn's own prediction.

Unlike a network, the process says where it knows: its predictive standard
deviation is small near the poses it learnt from and returns to its prior
far from them. :meth:`ResidualGP.knows` marks the poses where it is below
``max_std_ratio`` of the prior; elsewhere the compensator does nothing and
the physical model stands alone.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.linalg import cho_factor, cho_solve

from ..errors import InputError

#: a pose is one where the process knows when its predictive std is below this share of its prior std
MAX_STD_RATIO = 0.8
#: bounds of the length scales (rad) and of the noise share of the variance in the fit
LENGTH_BOUNDS = (0.05, 100.0)


@dataclass
class ResidualGP:
    """A fitted Gaussian process from joint readings (rad) to a residual (3 components).

    Attributes
    ----------
    X : ndarray, shape (N, n)
        The training poses (rad).
    Y : ndarray, shape (N, 3)
        Their residuals (m).
    length_scales : ndarray, shape (n,)
        One per joint (rad); a joint whose scale reaches the upper bound does not matter.
    signal_var : float
        ``s^2``, in standardised units of the residual.
    noise_var : float
        ``sigma_n^2``, in standardised units.
    y_mean, y_std : ndarray, shape (3,)
        The standardisation of ``Y`` (scikit-learn's ``normalize_y``).
    max_std_ratio : float
        Where the predictive std exceeds this share of the prior std the
        process does not know (:meth:`knows`).
    """

    X: np.ndarray
    Y: np.ndarray
    length_scales: np.ndarray
    signal_var: float
    noise_var: float
    y_mean: np.ndarray
    y_std: np.ndarray
    max_std_ratio: float = MAX_STD_RATIO

    def __post_init__(self) -> None:
        self.X, self.Y = np.asarray(self.X, float), np.asarray(self.Y, float)
        self.length_scales = np.asarray(self.length_scales, float)
        self.y_mean, self.y_std = np.asarray(self.y_mean, float), np.asarray(self.y_std, float)
        K = self.kernel(self.X, self.X) + self.noise_var * np.eye(len(self.X))
        self._chol = cho_factor(K, lower=True)
        self.alpha = cho_solve(self._chol, (self.Y - self.y_mean) / self.y_std)

    # --- fitting ------------------------------------------------------------------

    @classmethod
    def fit(cls, X: np.ndarray, Y: np.ndarray, max_std_ratio: float = MAX_STD_RATIO, seed: int = 0) -> "ResidualGP":
        """Hyperparameters by maximum marginal likelihood (scikit-learn), one length scale per joint.

        Parameters
        ----------
        X : ndarray, shape (N, n)
            Joint readings (rad).
        Y : ndarray, shape (N, 3)
            Residuals (m).
        """
        from sklearn.gaussian_process import GaussianProcessRegressor
        from sklearn.gaussian_process.kernels import RBF, ConstantKernel, WhiteKernel

        X, Y = np.asarray(X, float), np.asarray(Y, float)
        if len(X) < 10:
            raise InputError(f"a Gaussian process of the residual needs 10 poses or more, got {len(X)}")
        kernel = (ConstantKernel(1.0, (1e-4, 1e2)) * RBF(np.ones(X.shape[1]), LENGTH_BOUNDS)
                  + WhiteKernel(0.5, (1e-4, 1.0)))
        gp = GaussianProcessRegressor(kernel, normalize_y=True, random_state=seed).fit(X, Y)
        k = gp.kernel_
        return cls(X, Y, np.atleast_1d(k.k1.k2.length_scale), float(k.k1.k1.constant_value),
                   float(k.k2.noise_level), np.asarray(gp._y_train_mean).reshape(3),
                   np.asarray(gp._y_train_std).reshape(3), max_std_ratio)

    def refit(self, rows: np.ndarray) -> "ResidualGP":
        """The same hyperparameters, conditioned on the training poses ``rows`` only (for held-out folds)."""
        return ResidualGP(self.X[rows], self.Y[rows], self.length_scales, self.signal_var, self.noise_var,
                          self.y_mean, self.y_std, self.max_std_ratio)

    # --- prediction -----------------------------------------------------------------

    def kernel(self, A: np.ndarray, B: np.ndarray) -> np.ndarray:
        """The smooth part of the kernel, ``s^2 exp(-1/2 |(a - b) / l|^2)``."""
        a, b = A / self.length_scales, B / self.length_scales
        d2 = np.sum(a ** 2, 1)[:, None] + np.sum(b ** 2, 1)[None, :] - 2 * a @ b.T
        return self.signal_var * np.exp(-0.5 * np.clip(d2, 0.0, None))

    def predict(self, X: np.ndarray) -> np.ndarray:
        """The residual the process expects at poses ``X`` (m, (N, 3))."""
        return (self.kernel(np.asarray(X, float), self.X) @ self.alpha) * self.y_std + self.y_mean

    def std_ratio(self, X: np.ndarray) -> np.ndarray:
        """Predictive std of the smooth part over its prior std at each pose (0: known exactly, 1: unknown)."""
        Ks = self.kernel(np.asarray(X, float), self.X)
        v = cho_solve(self._chol, Ks.T)
        var = self.signal_var - np.einsum("ij,ji->i", Ks, v)
        return np.sqrt(np.clip(var, 0.0, None) / self.signal_var)

    def knows(self, X: np.ndarray) -> np.ndarray:
        """Poses where the process knows the residual (predictive std below ``max_std_ratio`` of the prior)."""
        return self.std_ratio(X) < self.max_std_ratio

    def casadi(self, x):
        """The expected residual as a CasADi expression of the joint readings ``x`` (n x 1), m."""
        import casadi as ca
        z = (x / ca.DM(self.length_scales)).T                       # 1 x n
        Z = ca.DM(self.X / self.length_scales)                        # N x n
        d2 = ca.sum2((ca.repmat(z, Z.shape[0], 1) - Z) ** 2)          # N x 1
        k = self.signal_var * ca.exp(-0.5 * d2)
        return ca.mtimes(ca.DM(self.alpha).T, k).T * ca.DM(self.y_std) + ca.DM(self.y_mean)

    # --- files ------------------------------------------------------------------------

    def to_dict(self) -> dict:
        return {"kind": "gaussian_process", "length_scales_rad": self.length_scales.tolist(),
                "signal_var": self.signal_var, "noise_var": self.noise_var, "y_mean_m": self.y_mean.tolist(),
                "y_std_m": self.y_std.tolist(), "max_std_ratio": self.max_std_ratio,
                "q_rad": self.X.tolist(), "residual_m": self.Y.tolist()}

    @classmethod
    def from_dict(cls, d: dict) -> "ResidualGP":
        """Read :meth:`to_dict`'s form back.

        Raises
        ------
        InputError
            A key missing, or numbers of the wrong shape or not finite.
        """
        try:
            X, Y = np.asarray(d["q_rad"], float), np.asarray(d["residual_m"], float)
            ls = np.asarray(d["length_scales_rad"], float)
            mean, std = np.asarray(d["y_mean_m"], float), np.asarray(d["y_std_m"], float)
            sv, nv, ratio = float(d["signal_var"]), float(d["noise_var"]), float(d.get("max_std_ratio", MAX_STD_RATIO))
        except (KeyError, TypeError, ValueError) as e:
            raise InputError(f"not a Gaussian process written by casadical ({e})") from e
        n = ls.shape[0] if ls.ndim == 1 else -1
        if (X.ndim != 2 or X.shape[1] != n or Y.shape != (len(X), 3) or mean.shape != (3,) or std.shape != (3,)
                or not all(np.all(np.isfinite(a)) for a in (X, Y, ls, mean, std))):
            raise InputError("a Gaussian process needs q_rad (N x n), residual_m (N x 3), n length scales and "
                             "3-vector y_mean_m, y_std_m, all finite")
        if not (np.all(ls > 0) and np.all(std > 0) and sv > 0 and nv > 0 and 0 < ratio <= 1
                and math.isfinite(sv) and math.isfinite(nv)):
            raise InputError("a Gaussian process needs positive length scales, variances and y_std_m, and "
                             "max_std_ratio in (0, 1]")
        return cls(X, Y, ls, sv, nv, mean, std, ratio)
