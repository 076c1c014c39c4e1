"""The MLP compensator: a one-hidden-layer perceptron (the TLBO paper's 6-5-3 network).

``y = W2 f(W1 x + b1) + b2`` with a linear output layer, on standardised
inputs and outputs.  The TLBO paper trains a 6-5-3 network (joint angles ->
residual error) by teaching-learning-based optimisation of all weights and
biases (eqs. 10-14) and compares it with back-propagation.  Three trainers
are offered, all minimising

    E(w) = mean over samples and outputs of (y - t)^2 + l2 * (|W1|^2 + |W2|^2)

(the paper's eq. 12 is this mean square error without the penalty):

- ``"lbfgs"`` (default): scipy L-BFGS-B with the analytic gradient -- the
  most accurate for a given budget;
- ``"backprop"``: full-batch gradient descent with Adam steps on the
  analytic (back-propagated) gradient;
- ``"tlbo"``: :class:`casadical.optim.TLBO` over the flattened weight
  vector; every candidate network of the class is evaluated at once with
  ``einsum``.  The initial weights are injected into the first population,
  so the result is never worse than them.

The weight vector is ``[W1 (h, d) row-major, b1 (h), W2 (k, h) row-major,
b2 (k)]``, see :meth:`MLP.get_weights`.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import ClassVar, Optional

import numpy as np

from ..errors import InputError
from ._base import Compensator

__all__ = ["MLP", "TrainingReport"]


@dataclass
class TrainingReport:
    """How an :class:`MLP` was trained.

    Attributes
    ----------
    method : str
        ``"backprop"``, ``"lbfgs"`` or ``"tlbo"``.
    epochs : int
        Epochs / iterations / generations actually run.
    loss_history : numpy.ndarray
        Training loss ``E`` (standardised units, with the l2 term) at the
        initial weights (entry 0) and after each epoch / generation.
        For L-BFGS one entry per iteration.
    initial_loss, final_loss : float
        First and last entries of `loss_history`.
    nfev : int
        Loss evaluations (TLBO: candidate networks evaluated).
    time_s : float
        Training time in seconds.
    message : str
        Stop reason reported by the trainer.
    """

    method: str
    epochs: int
    loss_history: np.ndarray
    initial_loss: float
    final_loss: float
    nfev: int
    time_s: float
    message: str = ""


_ACTIVATIONS = ("tanh", "sigmoid", "relu")


def _act(name: str, Z: np.ndarray) -> np.ndarray:
    if name == "tanh":
        return np.tanh(Z)
    if name == "sigmoid":
        return 0.5 * (1.0 + np.tanh(0.5 * Z))   # overflow-free logistic
    return np.maximum(Z, 0.0)


def _act_grad(name: str, H: np.ndarray, Z: np.ndarray) -> np.ndarray:
    """Derivative of the activation from its output H (and input Z)."""
    if name == "tanh":
        return 1.0 - H ** 2
    if name == "sigmoid":
        return H * (1.0 - H)
    return (Z > 0).astype(float)


@dataclass(eq=False)
class MLP(Compensator):
    """Multilayer perceptron with one hidden layer and a linear output.

    Parameters
    ----------
    hidden : int
        Hidden units, default 5 (the TLBO paper's 6-5-3 network).  Input and
        output sizes come from the data.
    activation : {"tanh", "sigmoid", "relu"}
        Hidden-layer activation, default "tanh" (MATLAB's tan-sigmoid).
    seed : int, optional
        Seed of the weight initialisation and of TLBO.

    Attributes (after fit)
    ----------------------
    training_ : TrainingReport
        Loss history and timing of the last fit.
    n_weights : int
        Length of the flattened weight vector.

    Examples
    --------
    >>> import numpy as np
    >>> rng = np.random.default_rng(1)
    >>> q = rng.uniform(-np.pi, np.pi, (60, 6))
    >>> err = 1e-4 * np.column_stack([np.sin(q[:, 1]), np.cos(q[:, 2]), q[:, 0]])
    >>> net = MLP(seed=0).fit(q, err, method="lbfgs", epochs=300)
    >>> net.n_weights                       # 6*5 + 5 + 5*3 + 3
    53
    """

    hidden: int = 5
    activation: str = "tanh"
    seed: Optional[int] = None

    #: default epochs (backprop), iterations (lbfgs), generations (tlbo)
    default_epochs: ClassVar[dict[str, int]] = {"backprop": 5000, "lbfgs": 2000, "tlbo": 500}

    _shape: Optional[tuple[int, int]] = field(default=None, init=False, repr=False)

    def __post_init__(self) -> None:
        h = self.hidden
        if isinstance(h, bool) or not isinstance(h, (int, np.integer)) or h < 1:
            raise InputError(f"hidden must be a positive integer, got {self.hidden!r}")
        if self.activation not in _ACTIVATIONS:
            raise InputError(f"activation must be one of {_ACTIVATIONS}, "
                             f"got {self.activation!r}")
        self._w = None

    # -- weights ------------------------------------------------------------
    @property
    def n_weights(self) -> int:
        """Number of weights and biases ``h*d + h + k*h + k``."""
        if self._shape is None:
            raise InputError("the network size is unknown until fit() or "
                             "initialize() has set the input/output sizes")
        d, k = self._shape
        return self.hidden * (d + 1) + k * (self.hidden + 1)

    def initialize(self, n_inputs: int, n_outputs: int) -> np.ndarray:
        """Set the sizes and draw Glorot-uniform weights (zero biases).

        Returns the weight vector.  :meth:`fit` calls this unless
        ``warm_start=True``.
        """
        for v, name in ((n_inputs, "n_inputs"), (n_outputs, "n_outputs")):
            if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < 1:
                raise InputError(f"{name} must be a positive integer, got {v!r}")
        self._shape = (int(n_inputs), int(n_outputs))
        rng = np.random.default_rng(self.seed)
        h = self.hidden
        lim1 = np.sqrt(6.0 / (n_inputs + h))
        lim2 = np.sqrt(6.0 / (h + n_outputs))
        W1 = rng.uniform(-lim1, lim1, (h, n_inputs))
        W2 = rng.uniform(-lim2, lim2, (n_outputs, h))
        self._w = np.concatenate([W1.ravel(), np.zeros(h), W2.ravel(),
                                  np.zeros(n_outputs)])
        return self._w.copy()

    def get_weights(self) -> np.ndarray:
        """Copy of the flattened weight vector ``[W1, b1, W2, b2]``."""
        if self._w is None:
            raise InputError("MLP has no weights yet; call fit() or initialize()")
        return self._w.copy()

    def set_weights(self, w) -> None:
        """Set the flattened weight vector (length :attr:`n_weights`)."""
        w = np.asarray(w, dtype=float)
        if w.shape != (self.n_weights,):
            raise InputError(f"weights must have shape ({self.n_weights},), "
                             f"got {w.shape}")
        if not np.all(np.isfinite(w)):
            raise InputError("weights contain NaN or inf")
        self._w = w.copy()

    def _unpack(self, w: np.ndarray):
        """Views W1 (..., h, d), b1 (..., h), W2 (..., k, h), b2 (..., k)."""
        d, k = self._shape
        h = self.hidden
        lead = w.shape[:-1]
        i1, i2, i3 = h * d, h * d + h, h * d + h + k * h
        return (w[..., :i1].reshape(*lead, h, d), w[..., i1:i2],
                w[..., i2:i3].reshape(*lead, k, h), w[..., i3:])

    # -- fitting ------------------------------------------------------------
    def fit(self, X, Y, method: str = "lbfgs", epochs: Optional[int] = None,
            l2: float = 0.0, *, learning_rate: float = 0.01, pop_size: int = 40,
            weight_bound: float = 5.0, tol: float = 1e-12,
            warm_start: bool = False) -> "MLP":
        """Train the network.

        Parameters
        ----------
        X : array_like, shape (n, d)
            Features (e.g. six joint angles or torques).
        Y : array_like, shape (n, k)
            Targets (e.g. three residual errors).
        method : {"lbfgs", "backprop", "tlbo"}
            Trainer, see the module docstring.
        epochs : int, optional
            Gradient steps (backprop), iterations (lbfgs) or generations
            (tlbo); defaults in :attr:`default_epochs`.
        l2 : float
            Weight-decay factor on W1 and W2 (biases not penalised).
        learning_rate : float
            Adam step size (backprop only).
        pop_size : int
            TLBO class size (tlbo only); each generation evaluates
            ``2 * pop_size`` networks.
        weight_bound : float
            TLBO searches every weight and bias in
            ``[-weight_bound, weight_bound]`` (standardised units) (tlbo only).
        tol : float
            L-BFGS-B ``ftol`` (lbfgs only).
        warm_start : bool
            Start from the current weights instead of a fresh initialisation.

        Returns
        -------
        self
        """
        return super().fit(X, Y, method=method, epochs=epochs, l2=l2,
                           learning_rate=learning_rate, pop_size=pop_size,
                           weight_bound=weight_bound, tol=tol, warm_start=warm_start)

    def _fit(self, Xs, Ys, *, method, epochs, l2, learning_rate, pop_size,
             weight_bound, tol, warm_start) -> None:
        if method not in self.default_epochs:
            raise InputError(f"method must be one of {tuple(self.default_epochs)}, "
                             f"got {method!r}")
        if epochs is None:
            epochs = self.default_epochs[method]
        if isinstance(epochs, bool) or not isinstance(epochs, (int, np.integer)) \
                or epochs < 0:
            raise InputError(f"epochs must be an integer >= 0, got {epochs!r}")
        if not (np.isfinite(l2) and l2 >= 0):
            raise InputError(f"l2 must be a finite number >= 0, got {l2!r}")
        d, k = Xs.shape[1], Ys.shape[1]
        if not (warm_start and self._w is not None and self._shape == (d, k)):
            self.initialize(d, k)
        t0 = time.perf_counter()
        if method == "backprop":
            if not (np.isfinite(learning_rate) and learning_rate > 0):
                raise InputError(f"learning_rate must be > 0, got {learning_rate!r}")
            report = self._fit_adam(Xs, Ys, int(epochs), l2, learning_rate)
        elif method == "lbfgs":
            report = self._fit_lbfgs(Xs, Ys, int(epochs), l2, tol)
        else:
            if not (np.isfinite(weight_bound) and weight_bound > 0):
                raise InputError(f"weight_bound must be > 0, got {weight_bound!r}")
            report = self._fit_tlbo(Xs, Ys, int(epochs), l2, pop_size, weight_bound)
        report.time_s = time.perf_counter() - t0
        self.training_ = report

    def _loss_grad(self, w, Xs, Ys, l2):
        """Loss E(w) and its analytic gradient (back-propagation)."""
        W1, b1, W2, b2 = self._unpack(w)
        Z = Xs @ W1.T + b1
        H = _act(self.activation, Z)
        E = H @ W2.T + b2 - Ys
        c = 2.0 / Ys.size
        loss = np.sum(E ** 2) / Ys.size + l2 * (np.sum(W1 ** 2) + np.sum(W2 ** 2))
        G = c * E                                   # dloss/doutput
        gW2 = G.T @ H + 2.0 * l2 * W2
        gb2 = G.sum(axis=0)
        D = (G @ W2) * _act_grad(self.activation, H, Z)
        gW1 = D.T @ Xs + 2.0 * l2 * W1
        gb1 = D.sum(axis=0)
        return loss, np.concatenate([gW1.ravel(), gb1, gW2.ravel(), gb2])

    def population_loss(self, Wpop: np.ndarray, Xs: np.ndarray, Ys: np.ndarray,
                        l2: float = 0.0) -> np.ndarray:
        """Loss of many weight vectors at once (standardised data).

        Parameters
        ----------
        Wpop : numpy.ndarray, shape (p, n_weights)
            Candidate weight vectors.
        Xs, Ys : numpy.ndarray
            Standardised features (n, d) and targets (n, k).
        l2 : float
            Weight-decay factor.

        Returns
        -------
        numpy.ndarray, shape (p,)
        """
        W1, b1, W2, b2 = self._unpack(Wpop)
        H = _act(self.activation, np.einsum("phd,nd->pnh", W1, Xs) + b1[:, None, :])
        out = np.einsum("pkh,pnh->pnk", W2, H) + b2[:, None, :]
        mse = np.mean((out - Ys) ** 2, axis=(1, 2))
        return mse + l2 * (np.sum(W1 ** 2, axis=(1, 2)) + np.sum(W2 ** 2, axis=(1, 2)))

    def _fit_adam(self, Xs, Ys, epochs, l2, lr) -> TrainingReport:
        w = self._w.copy()
        m = np.zeros_like(w)
        v = np.zeros_like(w)
        b1, b2, eps = 0.9, 0.999, 1e-8
        history = np.empty(epochs + 1)
        best_w, best = w.copy(), np.inf
        for t in range(epochs + 1):
            loss, g = self._loss_grad(w, Xs, Ys, l2)
            history[t] = loss
            if loss < best:
                best, best_w = loss, w.copy()
            if t == epochs:
                break
            m = b1 * m + (1 - b1) * g
            v = b2 * v + (1 - b2) * g ** 2
            w = w - lr * (m / (1 - b1 ** (t + 1))) / (np.sqrt(v / (1 - b2 ** (t + 1)))
                                                      + eps)
        # Adam is not monotone: keep the best weights seen
        self._w = best_w
        return TrainingReport("backprop", epochs, history, float(history[0]),
                              float(best), epochs + 1, 0.0,
                              f"{epochs} Adam steps")

    def _fit_lbfgs(self, Xs, Ys, epochs, l2, tol) -> TrainingReport:
        w0 = self._w.copy()
        history = [self._loss_grad(w0, Xs, Ys, l2)[0]]
        if epochs == 0:
            return TrainingReport("lbfgs", 0, np.asarray(history), history[0],
                                  history[0], 1, 0.0, "no iterations requested")

        def record(intermediate_result):
            history.append(float(intermediate_result.fun))

        import scipy.optimize  # here, not at import: it costs 0.3 s of every command's start-up

        res = scipy.optimize.minimize(
            self._loss_grad, w0, args=(Xs, Ys, l2), jac=True, method="L-BFGS-B",
            callback=record, options={"maxiter": epochs, "ftol": tol, "gtol": 1e-10})
        if res.fun <= history[0] and np.all(np.isfinite(res.x)):
            self._w = res.x.copy()
        return TrainingReport("lbfgs", int(res.nit), np.asarray(history, dtype=float),
                              float(history[0]), float(min(res.fun, history[0])),
                              int(res.nfev), 0.0, str(res.message))

    def _fit_tlbo(self, Xs, Ys, generations, l2, pop_size, bound) -> TrainingReport:
        # imported here: casadical.optim does not depend on the compensators
        from casadical.optim import TLBO, Box

        w0 = np.clip(self._w, -bound, bound)
        box = Box.cube(-bound, bound, self.n_weights)
        res = TLBO(pop_size=pop_size, generations=generations).minimize(
            lambda P: self.population_loss(P, Xs, Ys, l2), box,
            seed=self.seed, x0=w0)
        initial = float(self.population_loss(w0[None, :], Xs, Ys, l2)[0])
        self._w = res.x.copy()
        history = np.concatenate([[initial], res.history])
        return TrainingReport("tlbo", res.nit, history, initial, float(res.fun),
                              res.nfev, 0.0, res.message)

    def _predict(self, Xs: np.ndarray) -> np.ndarray:
        W1, b1, W2, b2 = self._unpack(self._w)
        return _act(self.activation, Xs @ W1.T + b1) @ W2.T + b2
