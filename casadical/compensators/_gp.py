"""A Gaussian process on the residual: the GP compensator's regressor, which knows where it holds.

What the named causes leave is learnt as a function of the joint readings,
one Gaussian process per component of the residual (x, y, z in the robot
base frame), each with one length scale per joint (automatic relevance
determination) and a white-noise part:

    k(x, x') = s^2 exp(-1/2 sum_j ((x_j - x'_j) / l_j)^2) + sigma_n^2 [x = x']

Each component has its own hyperparameters: on the UR10 data (series B,
200 calibration poses, kinematic model) three processes of their own
predict the held-out poses to 0.260-0.266 mm where one kernel shared by the
three components gives 0.314-0.324 mm.

The hyperparameters are fitted by maximum marginal likelihood, the
objective and start of scikit-learn's
:class:`~sklearn.gaussian_process.GaussianProcessRegressor` (``normalize_y``,
``ConstantKernel * RBF + WhiteKernel``, its bounds) with its likelihood's
gradient and scipy's L-BFGS-B, on at most :data:`FIT_POSES` poses and
:data:`FIT_ITERATIONS` iterations (UR10, 300 poses, three splits: 20
iterations and 30 give the same held-out error to within 2 um, 150 poses
instead of 200 give 2-7 % more; the cost of each step grows with the cube of
the poses). The likelihood is evaluated here (:func:`log_likelihood`), not by
scikit-learn: its kernel objects build the gradient as an ``N x N x n``
stack and invert ``K`` by a solve for every evaluation and component; the
same numbers from the squared distances of each joint (computed once for the
three components) and ``K``'s inverse from its Cholesky factor cost 0.27 of
its CPU on the README job (``benchmarks/speed/bench_gp_compensator.py``; a test checks the
likelihood, its gradient and the fitted hyperparameters against
scikit-learn's). The fitted process is then held as plain numbers (training poses,
residuals, hyperparameters) conditioned on every pose, and evaluated here
with numpy and symbolically in the model
(:class:`~casadical.terms._gp_compensator.GPCompensator`), so that
``predict`` and ``compensate`` do not import scikit-learn; a test checks the
two agree with scikit-learn's own prediction.

Unlike a network, the process says where it knows: its predictive standard
deviation is small near the poses it learnt from and returns to its prior
far from them. Its correction is bounded by what it knows
(:meth:`ResidualGP.weight`): the posterior mean times

    w(x) = (1 - r(x)^2)^p        (0 where r(x) >= max_std_ratio)

where ``r`` is the predictive std over the prior std (the largest of the
three components) and ``1 - r^2`` the share of the prior's variance the
poses it learnt from explain there. Near them ``r`` is small and the whole
correction applies; as the pose moves away it shrinks smoothly to nothing
at ``r = 1``, where the physical model stands alone. The strength ``p``
(:attr:`ResidualGP.shrink`) is chosen by the diagnosis on the calibration
folds; ``p = 0`` with ``max_std_ratio < 1`` is the on/off support of
earlier versions (:data:`MAX_STD_RATIO`, the default of a process fitted
outside the diagnosis and of files without ``shrink``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import InputError
from ..runtime._kept import Kept, array_key
from ..runtime._threads import limited_threads

#: a pose is one where the process knows when its predictive std is below this share of its prior std (UR10
#: series A, 300 poses, seed 1: 86 % of the series' other poses, none of series B's, whose ratio is 1.000 at
#: every pose; at 0.8 the share in series was 76 % and its held-out mean 0.010 mm worse)
MAX_STD_RATIO = 0.95
#: the 95 % quantile of a chi distribution with 3 degrees of freedom, sqrt(7.8147): the factor of a 95 % interval of
#: a measured point whose three axes are Gaussian alike (:mod:`casadical.prediction`)
CHI3_95 = 2.7955
#: bounds of the length scales (rad)
LENGTH_BOUNDS = (0.05, 100.0)
#: the hyperparameters are fitted on at most this many poses (chosen at random), in at most this many iterations
FIT_POSES = 200
FIT_ITERATIONS = 20
#: added to the kernel's diagonal, as scikit-learn's ``alpha`` does by default
JITTER = 1e-10
#: bounds of the signal and the noise variance (of the standardised residual), as the kernel's start values
SIGNAL_BOUNDS, NOISE_BOUNDS = (1e-4, 1e2), (1e-4, 1.0)
SIGNAL0, LENGTH0, NOISE0 = 1.0, 1.0, 0.5
#: the GP compensator's likelihood: a Student-t of this many degrees of freedom (per pose, its three components
#: together), heavy-tailed so that the few poses both models miss by far do not pull its correction (None: a
#: Gaussian, scikit-learn's); its weights by :data:`ROBUST_ROUNDS` rounds of expectation-maximisation, after the
#: Gaussian fit and after each of :data:`ROBUST_REFITS` fits of its hyperparameters with them, from scikit-learn's
#: start, in at most :data:`ROBUST_ITERATIONS` iterations (to convergence: at 20, a difference of 1e-10 in the
#: residuals, CasADi's JIT or not, changed the README job's choice of likelihood)
ROBUST_NU = 4.0
ROBUST_ROUNDS = 5
ROBUST_REFITS = 2
ROBUST_ITERATIONS = 60


def squared_differences(X: np.ndarray) -> np.ndarray:
    """``D[a, b, j] = (X[a, j] - X[b, j])^2`` (N x N x n): what every kernel of the poses ``X`` is made of."""
    return (X[:, None, :] - X[None, :, :]) ** 2


def log_likelihood(theta: np.ndarray, D: np.ndarray, y: np.ndarray, scale: np.ndarray | None = None
                   ) -> tuple[float, np.ndarray]:
    """Log marginal likelihood of the standardised residual ``y`` and its gradient, at the log hyperparameters
    ``theta = log(s^2, l_1 .. l_n, sigma_n^2)`` (scikit-learn's ``theta`` of ``ConstantKernel * RBF +
    WhiteKernel``, with its ``alpha``); ``D``: :func:`squared_differences` of the poses; ``scale``: each pose's
    noise variance over ``sigma_n^2`` (1 / its robust weight, :func:`robust_weights`; None: 1 at every pose)."""
    from scipy.linalg import cho_factor, cho_solve, lapack  # here: a command whose model has no process needs none
    s2, ls, nv = math.exp(theta[0]), np.exp(theta[1:-1]), math.exp(theta[-1])
    n = len(y)
    # the arithmetic of s^2 exp(-1/2 D l^-2), K^-1's symmetric whole and W = alpha alpha^T - K^-1 in place, each
    # factor worked on where it lies (the same bits with 4 arrays of N x N, not 9: 10 % of the call at N = 200)
    SE = D @ (1.0 / ls ** 2)
    SE *= -0.5
    np.exp(SE, out=SE)
    SE *= s2                                             # s^2 E: the kernel without its noise
    K = SE.copy()
    d = np.ones(n) if scale is None else scale
    K[np.diag_indices(n)] += nv * d + JITTER
    try:
        L = cho_factor(K, lower=True, overwrite_a=True, check_finite=False)
    except np.linalg.LinAlgError:
        return -np.inf, np.zeros_like(theta)
    alpha = cho_solve(L, y, check_finite=False)
    lml = -0.5 * float(y @ alpha) - float(np.log(np.diag(L[0])).sum()) - 0.5 * n * math.log(2 * math.pi)
    inv, info = lapack.dpotri(L[0], lower=1, overwrite_c=1)   # K^-1 from its factor (a third of cho_solve's cost)
    if info != 0:
        return -np.inf, np.zeros_like(theta)
    inv = np.tril(inv)
    inv += np.tril(inv, -1).T
    W = np.outer(alpha, alpha)
    W -= inv
    grad = np.empty_like(theta)
    grad[-1] = 0.5 * nv * float(np.diag(W) @ d)
    W *= SE                                              # M: tr(W dK/dlog s^2) = sum(M); dK/dlog l_j = M's D_j / l_j^2
    grad[0] = 0.5 * W.sum()
    grad[1:-1] = 0.5 * np.tensordot(W, D, axes=([0, 1], [0, 1])) / ls ** 2
    return lml, grad


def robust_weights(Y: np.ndarray, K_signal: list, noise_var: np.ndarray, nu: float,
                   rounds: int = ROBUST_ROUNDS, w: np.ndarray | None = None) -> np.ndarray:
    """Each pose's weight under a Student-t likelihood of ``nu`` degrees of freedom (a Gaussian scale mixture):
    the expectation-maximisation of its noise scale, ``rounds`` times.

    The three components of a pose share one weight (a pose a tracker shot or a transient spoils is spoilt in
    every axis): ``w = (nu + 3) / (nu + q)``, ``q`` the expected squared residual of the pose's three
    standardised components, ``E[(y - f)^2] / sigma_n^2``, under the process conditioned with the current
    weights (its noise variance at the pose ``sigma_n^2 / w``): ``(d alpha)^2 + d - d^2 [K^-1]_ii``, ``d`` that
    noise variance. A pose within the noise keeps about 1; one the process misses by far gets about
    ``(nu + 3) / q`` and pulls the correction by that share.

    Parameters
    ----------
    Y : ndarray, shape (N, 3)
        The standardised residuals.
    K_signal : list of 3 ndarrays (N, N)
        The smooth part of each component's kernel at the poses.
    noise_var : ndarray, shape (3,)
        ``sigma_n^2`` of each component (standardised units).
    """
    from scipy.linalg import cho_factor, cho_solve, lapack

    n = len(Y)
    w = np.ones(n) if w is None else np.asarray(w, float).copy()
    for _ in range(rounds):
        q = np.zeros(n)
        for a in range(3):
            d = noise_var[a] / w
            K = K_signal[a].copy()
            K[np.diag_indices(n)] += d + JITTER
            L = cho_factor(K, lower=True, check_finite=False)
            alpha = cho_solve(L, Y[:, a], check_finite=False)
            inv, _ = lapack.dpotri(L[0], lower=1)
            q += ((d * alpha) ** 2 + d - d ** 2 * np.diag(inv)) / noise_var[a]
        w = (nu + 3.0) / (nu + q)
    return w


@dataclass
class ResidualGP:
    """Fitted Gaussian processes from joint readings (rad) to the 3 components of a residual.

    Attributes
    ----------
    X : ndarray, shape (N, n)
        The training poses (rad).
    Y : ndarray, shape (N, 3)
        Their residuals (m).
    length_scales : ndarray, shape (3, n)
        Per component, one per joint (rad); a joint whose scale reaches the
        upper bound does not matter.
    signal_var, noise_var : ndarray, shape (3,)
        ``s^2`` and ``sigma_n^2`` of each component, in its standardised units.
    y_mean, y_std : ndarray, shape (3,)
        The standardisation of ``Y`` (scikit-learn's ``normalize_y``).
    max_std_ratio : float
        Where the predictive std of a component exceeds this share of its
        prior std the correction is 0 (:meth:`weight`).
    shrink : float
        The strength ``p`` of :meth:`weight`'s shrinkage, ``(1 - r^2)^p``
        (0: the whole correction wherever ``r < max_std_ratio``).
    interval_k : float
        The factor of the 95 % interval of a measured point at the poses of
        its session (:func:`casadical.prediction.prediction_interval`):
        :data:`CHI3_95`, or as the diagnosis calibrates it on its folds.
    pose_weights : ndarray, shape (N,), optional
        Each training pose's robust weight (:func:`robust_weights`; its noise
        variance ``sigma_n^2 / w``); None: 1 at every pose (a Gaussian
        likelihood).
    nu : float, optional
        The Student-t likelihood's degrees of freedom (None: a Gaussian).
    """

    X: np.ndarray
    Y: np.ndarray
    length_scales: np.ndarray
    signal_var: np.ndarray
    noise_var: np.ndarray
    y_mean: np.ndarray
    y_std: np.ndarray
    max_std_ratio: float = MAX_STD_RATIO
    shrink: float = 0.0
    interval_k: float = CHI3_95
    pose_weights: np.ndarray | None = None
    nu: float | None = None

    def __post_init__(self) -> None:
        from scipy.linalg import cho_factor, cho_solve  # here: a command whose model has no process needs none

        self.X, self.Y = np.asarray(self.X, float), np.asarray(self.Y, float)
        self.length_scales = np.atleast_2d(np.asarray(self.length_scales, float))
        self.signal_var, self.noise_var = (np.asarray(v, float).reshape(3) for v in (self.signal_var, self.noise_var))
        self.y_mean, self.y_std = np.asarray(self.y_mean, float), np.asarray(self.y_std, float)
        if self.pose_weights is not None:
            self.pose_weights = np.asarray(self.pose_weights, float).reshape(len(self.X))
        w = np.ones(len(self.X)) if self.pose_weights is None else self.pose_weights
        Z = (self.Y - self.y_mean) / self.y_std
        self._chol, alpha = [], []
        for a in range(3):
            K = self.kernel(self.X, self.X, a) + np.diag(self.noise_var[a] / w + JITTER)
            self._chol.append(cho_factor(K, lower=True))
            alpha.append(cho_solve(self._chol[a], Z[:, a]))
        self.alpha = np.column_stack(alpha)
        self._answers = Kept(4)                   # _posterior's last answers

    # --- fitting ------------------------------------------------------------------

    @classmethod
    @limited_threads()
    def fit(cls, X: np.ndarray, Y: np.ndarray, max_std_ratio: float = MAX_STD_RATIO, seed: int = 0,
            robust_nu: float | None = None, gaussian: "ResidualGP | None" = None) -> "ResidualGP":
        """Hyperparameters by maximum marginal likelihood (scikit-learn's objective: :func:`log_likelihood`), one
        length scale per joint and component, on at most :data:`FIT_POSES` poses; the process conditioned on all
        of them.

        With ``robust_nu`` the likelihood is a Student-t of that many degrees of freedom instead of a Gaussian
        (the GP compensator's: :data:`ROBUST_NU`): the Gaussian fit, then each pose's weight
        (:func:`robust_weights`, on every pose), the hyperparameters fitted again with them and the weights
        again, :data:`ROBUST_REFITS` times (:data:`ROBUST_NU`'s comment).

        Parameters
        ----------
        X : ndarray, shape (N, n)
            Joint readings (rad).
        Y : ndarray, shape (N, 3)
            Residuals (m).
        gaussian : ResidualGP, optional
            With ``robust_nu``: the Gaussian fit of the same ``X``, ``Y``, ``max_std_ratio`` and ``seed``, already
            made (the GP compensator fits both likelihoods): its hyperparameters are the Student-t's first ones,
            the same to the bit, not fitted again.
        """
        from scipy.optimize import minimize

        X, Y = np.asarray(X, float), np.asarray(Y, float)
        if len(X) < 10:
            raise InputError(f"a Gaussian process of the residual needs 10 poses or more, got {len(X)}")
        rows = np.sort(np.random.default_rng(seed).permutation(len(X))[:FIT_POSES])
        D = squared_differences(X[rows])
        n = X.shape[1]
        bounds = np.log([SIGNAL_BOUNDS] + [LENGTH_BOUNDS] * n + [NOISE_BOUNDS])
        theta0 = np.log([SIGNAL0] + [LENGTH0] * n + [NOISE0])
        mean, std = Y.mean(axis=0), Y.std(axis=0)
        std = np.where(std > 0, std, 1.0)

        def hyperparameters(start, scale, iterations=FIT_ITERATIONS):
            thetas = []
            for a in range(3):
                y = Y[rows, a]
                sd = y.std()
                y = (y - y.mean()) / (sd if sd > 0 else 1.0)        # scikit-learn's normalize_y

                def objective(theta):
                    lml, grad = log_likelihood(theta, D, y, scale)
                    return -lml, -grad

                thetas.append(minimize(objective, start[a], method="L-BFGS-B", jac=True, bounds=bounds,
                                       options={"maxiter": iterations}).x)
            return thetas

        def process(thetas, **kw):
            return cls(X, Y, np.array([np.exp(t[1:-1]) for t in thetas]), np.array([math.exp(t[0]) for t in thetas]),
                       np.array([math.exp(t[-1]) for t in thetas]), mean, std, max_std_ratio, **kw)

        if robust_nu is None:
            return process(hyperparameters([theta0] * 3, None))
        # the Gaussian fit's hyperparameters first (the one already made, the same bits), then the weights and the
        # hyperparameters in turn
        g = gaussian if gaussian is not None else process(hyperparameters([theta0] * 3, None))
        w, Z = None, (Y - mean) / std
        for refit in [True] * ROBUST_REFITS + [False]:
            w = robust_weights(Z, [g.kernel(X, X, a) for a in range(3)], g.noise_var, robust_nu, w=w)
            if refit:
                thetas = hyperparameters([theta0] * 3, 1.0 / w[rows], ROBUST_ITERATIONS)
                g = process(thetas)
        return process(thetas, pose_weights=w, nu=robust_nu)

    def refit(self, rows: np.ndarray) -> "ResidualGP":
        """The same hyperparameters, conditioned on the training poses ``rows`` only (for held-out folds)."""
        return ResidualGP(self.X[rows], self.Y[rows], self.length_scales, self.signal_var, self.noise_var,
                          self.y_mean, self.y_std, self.max_std_ratio, self.shrink, self.interval_k,
                          None if self.pose_weights is None else self.pose_weights[rows], self.nu)

    # --- prediction -----------------------------------------------------------------

    def kernel(self, A: np.ndarray, B: np.ndarray, a: int) -> np.ndarray:
        """The smooth part of component ``a``'s kernel, ``s^2 exp(-1/2 |(x - x') / l|^2)``."""
        ls = self.length_scales[a]
        P, Q = A / ls, B / ls
        # |p|^2 + |q|^2 - 2 p.q, clipped at 0, times -1/2, its exp times s^2: the operations of the one expression
        # they were, in its order, in place (the same bits; at 10,000 x 600 poses 2 arrays of 48 MB, not 6, whose
        # page faults cost more than the arithmetic)
        G = P @ Q.T
        G *= 2
        out = np.sum(P ** 2, 1)[:, None] + np.sum(Q ** 2, 1)[None, :]
        np.subtract(out, G, out=out)
        del G
        np.clip(out, 0.0, None, out=out)
        out *= -0.5
        np.exp(out, out=out)
        out *= self.signal_var[a]
        return out

    def predict(self, X: np.ndarray) -> np.ndarray:
        """The residual the processes expect at poses ``X`` (m, (N, 3)); from :meth:`_posterior`'s kept answers
        where the poses were asked for their uncertainty first (the kernel both need is made once)."""
        X = np.ascontiguousarray(X, float)
        got = self._answers.get(array_key(X))
        Z = got[1] if got is not None else np.column_stack([self.kernel(X, self.X, a) @ self.alpha[:, a]
                                                            for a in range(3)])
        return Z * self.y_std + self.y_mean

    def _posterior(self, X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """At poses ``X`` (contiguous), per component: ``|L^-1 k*|^2`` (``L`` the Cholesky factor of the training
        kernel, ``k*`` the kernel of each pose and the training poses; the predictive variance is ``s^2`` minus it)
        and the posterior mean ``k*^T alpha`` (standardised), each (N, 3), from one kernel per component. Read
        them, never write to them.

        The last few answers are kept, by the poses' bytes: a diagnosis asks again for the same poses (the gate of
        every model evaluation, then the model's own prediction there, then its predictive std; a held-out fold its
        std ratios, then its prediction), and at 10,000 poses of a 600-pose process an answer costs 0.35 s.
        """
        from scipy.linalg import solve_triangular  # here: a command whose model has no process needs none

        key = array_key(X)
        got = self._answers.get(key)
        if got is not None:
            return got
        vv, mean = np.empty((len(X), 3)), np.empty((len(X), 3))
        for a in range(3):
            K = self.kernel(X, self.X, a)
            mean[:, a] = K @ self.alpha[:, a]
            # k** - k*^T K^-1 k* = s^2 - |L^-1 k*|^2: one triangular solve (half of cho_solve's two)
            v = solve_triangular(self._chol[a][0], K.T, lower=True, check_finite=False)
            del K
            vv[:, a] = np.einsum("ij,ij->j", v, v)
        self._answers.put(key, (vv, mean))
        return vv, mean

    def std_ratio(self, X: np.ndarray) -> np.ndarray:
        """Predictive std of each pose over the prior std, the largest of the three components (0: known
        exactly, 1: unknown)."""
        vv = self._posterior(np.ascontiguousarray(X, float))[0]
        out = np.zeros(len(vv))
        for a in range(3):
            var = self.signal_var[a] - vv[:, a]
            out = np.maximum(out, np.sqrt(np.clip(var, 0.0, None) / self.signal_var[a]))
        return out

    def noise_std(self) -> float:
        """The white-noise part of the residual, per axis (m): what the joint readings do not predict (the mean of
        the three components' variances; of a Student-t likelihood its variance, ``sigma_n^2 nu / (nu - 2)``: a
        new pose's weight is not known)."""
        t = self.nu / (self.nu - 2.0) if self.nu is not None and self.nu > 2 else 1.0
        return float(np.sqrt(np.mean(self.noise_var * self.y_std ** 2) * t))

    def std_ratio_of(self, X: np.ndarray, a: int) -> np.ndarray:
        """Predictive std of component ``a`` over its prior std at poses ``X``."""
        vv = self._posterior(np.ascontiguousarray(X, float))[0][:, a]
        return np.sqrt(np.clip(1.0 - vv / self.signal_var[a], 0.0, 1.0))

    def predictive_std(self, X: np.ndarray) -> np.ndarray:
        """Standard deviation (m, (N, 3)) of the residual at poses ``X`` that the process leaves once its
        correction, the posterior mean ``m`` times :meth:`weight` ``w``, is applied: under the process's prior
        the residual ``f - w m`` has the variance ``v + (1 - w)^2 (s^2 - v)`` (``v`` the predictive variance,
        ``s^2 - v`` that of ``m``): its predictive std where the whole correction applies, its prior std where
        none does (the residual is then what it would have been)."""
        X = np.ascontiguousarray(X, float)
        out = np.empty((len(X), 3))
        w = self.weight(X)
        vv = self._posterior(X)[0]
        for a in range(3):
            var = np.clip(self.signal_var[a] - vv[:, a], 0.0, self.signal_var[a])
            var = var + (1.0 - w) ** 2 * (self.signal_var[a] - var)
            out[:, a] = np.sqrt(var) * self.y_std[a]
        return out

    def weight(self, X: np.ndarray) -> np.ndarray:
        """The share of its posterior mean the correction applies at each pose: ``(1 - r^2)^p`` with ``r`` the
        :meth:`std_ratio` and ``p`` :attr:`shrink`, 0 where ``r >= max_std_ratio`` (1 near the poses it learnt
        from, 0 where it knows nothing)."""
        r = self.std_ratio(X)
        w = np.clip(1.0 - r ** 2, 0.0, 1.0) ** self.shrink if self.shrink > 0 else np.ones(len(r))
        return np.where(r < self.max_std_ratio, w, 0.0)

    def knows(self, X: np.ndarray) -> np.ndarray:
        """Poses where the process knows the residual: its correction applies at least half of its posterior
        mean (:meth:`weight` >= 0.5; with ``shrink`` 0: every component's predictive std below
        ``max_std_ratio`` of its prior)."""
        return self.weight(X) >= 0.5

    def casadi(self, x):
        """The expected residual as a CasADi expression of the joint readings ``x`` (n x 1), m."""
        import casadi as ca
        out = []
        for a in range(3):
            ls = self.length_scales[a]
            Z = ca.DM(self.X / ls)                                          # N x n
            d2 = ca.sum2((ca.repmat((x / ca.DM(ls)).T, Z.shape[0], 1) - Z) ** 2)
            k = self.signal_var[a] * ca.exp(-0.5 * d2)
            out.append(ca.dot(ca.DM(self.alpha[:, a]), k) * self.y_std[a] + self.y_mean[a])
        return ca.vertcat(*out)

    # --- files ------------------------------------------------------------------------

    def to_dict(self) -> dict:
        return {"kind": "gaussian_process", "length_scales_rad": self.length_scales.tolist(),
                "signal_var": self.signal_var.tolist(), "noise_var": self.noise_var.tolist(),
                "y_mean_m": self.y_mean.tolist(), "y_std_m": self.y_std.tolist(),
                "max_std_ratio": self.max_std_ratio, "shrink": self.shrink, "interval_k": self.interval_k,
                "q_rad": self.X.tolist(),
                "residual_m": self.Y.tolist(),
                **({} if self.pose_weights is None else {"pose_weights": self.pose_weights.tolist()}),
                **({} if self.nu is None else {"student_t_nu": self.nu})}

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
            sv, nv = np.asarray(d["signal_var"], float), np.asarray(d["noise_var"], float)
            mean, std = np.asarray(d["y_mean_m"], float), np.asarray(d["y_std_m"], float)
            ratio = float(d.get("max_std_ratio", MAX_STD_RATIO))
            shrink = float(d.get("shrink", 0.0))
            k = float(d.get("interval_k", CHI3_95))
            pw = None if d.get("pose_weights") is None else np.asarray(d["pose_weights"], float)
            nu = None if d.get("student_t_nu") is None else float(d["student_t_nu"])
        except (KeyError, TypeError, ValueError) as e:
            raise InputError(f"not a Gaussian process written by casadical ({e})") from e
        n = ls.shape[1] if ls.ndim == 2 else -1
        if (ls.shape[0:1] != (3,) or X.ndim != 2 or X.shape[1] != n or len(X) < 1 or Y.shape != (len(X), 3)
                or any(v.shape != (3,) for v in (sv, nv, mean, std))
                or not all(np.all(np.isfinite(a)) for a in (X, Y, ls, sv, nv, mean, std))):
            raise InputError("a Gaussian process needs q_rad (N x n), residual_m (N x 3), 3 x n length scales "
                             "and 3-vectors signal_var, noise_var, y_mean_m, y_std_m, all finite")
        if not (np.all(ls > 0) and np.all(std > 0) and np.all(sv > 0) and np.all(nv > 0) and 0 < ratio <= 1
                and math.isfinite(ratio) and 0 <= shrink < math.inf and 0 < k < math.inf):
            raise InputError("a Gaussian process needs positive length scales, variances and y_std_m, "
                             "max_std_ratio in (0, 1], a finite shrink >= 0 and a finite interval_k > 0")
        if pw is not None and (pw.shape != (len(X),) or not np.all(np.isfinite(pw)) or not np.all(pw > 0)):
            raise InputError("a Gaussian process's pose_weights are one positive finite number per pose of q_rad")
        if nu is not None and not (math.isfinite(nu) and nu > 0):
            raise InputError("a Gaussian process's student_t_nu is a finite number > 0")
        return cls(X, Y, ls, sv, nv, mean, std, ratio, shrink, k, pw, nu)
