"""The identification problem: model + data + which parameters are free + the loss.

Solvers see scaled variables ``x = (p_free - nominal_free) / scale_free``
and residuals ``r = predicted - measured`` (m, per pose x, y, z). The loss
is a sum over poses of ``rho(|r_i|^2)``: half the squared norm for plain
least squares, or a pseudo-Huber loss that grows only linearly beyond a few
noise standard deviations (:class:`RobustLoss`), so that one bad tracker
shot cannot pull the model.

Full pose (:attr:`CalibrationProblem.rot` given, a model with the probe's
orientation): each pose also has an orientation residual ``r_o`` (rad, the
rotation vector of ``R_meas^T R_pred``), weighted into position units by
``k = sigma / sigma_rot`` (m/rad), the ratio of the two noise scales
estimated from the data: the loss is ``rho(|r_p|^2 + k^2 |r_o|^2)``, i.e.
``rho`` of ``sigma^2 (|r_p|^2 / sigma^2 + |r_o|^2 / sigma_rot^2)``, one
pseudo-Huber per pose on both parts together.

Large data sets are linearised in chunks of poses: the normal equations
``sum w_i J_i^T J_i`` and ``sum w_i J_i^T r_i`` are accumulated, and the
Jacobian of all poses is never held in memory at once.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from .data._measurements import Measurements
from .errors import CasadicalError
from .model._symbolic import Model
from .parameters import Parameters
from .rows import Layout
from .runtime._chunks import pose_chunks
from .stats._identifiability import triangular_factor

#: median of the norm of a 3-vector of independent N(0, 1) components (sqrt of chi2(3)'s median)
CHI3_MEDIAN = 1.5381722544550522
#: a problem keeps the model's Jacobian at the last parameter values it was asked for when it holds at most this
#: many numbers (2,000 full poses of a 84-parameter model: 1.0 M, 8 MB): see CalibrationProblem.model_jacobian
MEMO_NUMBERS = 2_000_000


@dataclass(frozen=True)
class RobustLoss:
    """Loss of one pose as a function of its squared residual norm ``u2`` (m^2).

    ``kind="huber"``: the pseudo-Huber loss ``rho = u2 / (sqrt(1 + delta u2) + 1)``
    with ``delta = 1 / (c sigma)^2``: ``u2 / 2`` for small residuals, ``c sigma |r|``
    (linear) for large ones, smooth everywhere. ``kind="none"``: ``u2 / 2``,
    plain least squares (``delta = 0``).

    Parameters
    ----------
    kind : {"huber", "none"}
    c : float
        Transition, in noise standard deviations per axis (3: a pose
        whose residual norm is 5 sigma keeps half its weight, one of 50
        sigma a tenth).
    sigma : float
        Noise standard deviation per axis (m); estimated from the data by
        :meth:`with_sigma_from` (median of the residual norms).
    sigma_rot : float
        Full pose only: noise standard deviation of the orientation per axis
        (rad), estimated with ``sigma`` by :meth:`with_scales_from`; the
        orientation residual weighs :attr:`rot_weight` = ``sigma / sigma_rot``
        metres per radian (also for plain least squares).
    """

    kind: str = "none"
    c: float = 3.0
    sigma: float = math.nan
    sigma_rot: float = math.nan

    def __post_init__(self) -> None:
        if self.kind not in ("huber", "none"):
            raise CasadicalError(f"unknown robust loss {self.kind!r}: use 'huber' or 'none'")
        if not self.c > 0:
            raise CasadicalError(f"robust loss: c must be positive, got {self.c}")

    @property
    def robust(self) -> bool:
        return self.kind != "none"

    @property
    def delta(self) -> float:
        """``1 / (c sigma)^2``; 0 for plain least squares (or before sigma is known)."""
        if not self.robust or not self.sigma > 0:
            return 0.0
        return 1.0 / (self.c * self.sigma) ** 2

    @property
    def rot_weight(self) -> float:
        """``sigma / sigma_rot`` (m/rad): the orientation residual in position units; nan before both are known."""
        return self.sigma / self.sigma_rot if self.sigma > 0 and self.sigma_rot > 0 else math.nan

    def rho(self, u2: np.ndarray) -> np.ndarray:
        return u2 / (np.sqrt(1.0 + self.delta * u2) + 1.0)

    def weight(self, u2: np.ndarray) -> np.ndarray:
        """IRLS weight ``d rho / d(u2/2)`` of each pose (1 for plain least squares)."""
        return 1.0 / np.sqrt(1.0 + self.delta * u2)

    def with_sigma_from(self, residual_norms: np.ndarray) -> "RobustLoss":
        """The same loss with ``sigma`` estimated robustly from residual norms (m)."""
        med = float(np.median(residual_norms)) if len(residual_norms) else 0.0
        return replace(self, sigma=max(med / CHI3_MEDIAN, 1e-12))

    def with_scales_from(self, position_norms: np.ndarray, rotation_norms: np.ndarray) -> "RobustLoss":
        """Full pose: ``sigma`` (m) and ``sigma_rot`` (rad) each from its own kind's residual norms (median)."""
        med = float(np.median(rotation_norms)) if len(rotation_norms) else 0.0
        return replace(self.with_sigma_from(position_norms), sigma_rot=max(med / CHI3_MEDIAN, 1e-15))


@dataclass
class Linearization:
    """The problem linearised at one point (scaled free variables).

    Attributes
    ----------
    r : ndarray, shape (N, 3)
        Residuals, predicted minus measured (m).
    weights : ndarray, shape (N,)
        IRLS weight of each pose under the loss.
    cost : float
        Sum of the pose losses (m^2; half the SSR for plain least squares).
    A : ndarray, shape (n_free, n_free)
        The Gauss-Newton matrix of the loss: ``sum J_i^T (w_i I - delta w_i^3 r_i r_i^T) J_i``
        (``sum J_i^T J_i`` for least squares).
    g : ndarray, shape (n_free,)
        ``sum w_i J_i^T r_i``, the gradient of ``cost``.
    r_rot : ndarray, shape (N, 3), or None
        Full pose: orientation residuals (rad); ``r_i`` above is then the
        6-vector ``(r_p, k r_o)`` of each pose and ``J_i`` its Jacobian.
    u2 : ndarray, shape (N,)
        Squared residual norm of each pose (``|r_p|^2 + k^2 |r_o|^2`` for full pose; m^2).
    """

    r: np.ndarray
    weights: np.ndarray
    cost: float
    A: np.ndarray
    g: np.ndarray
    r_rot: np.ndarray | None = None
    u2: np.ndarray | None = None


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
    loss : RobustLoss
        Plain least squares by default.
    rot : ndarray, shape (N, 3, 3), or None
        Full pose: the measured probe rotations times the transpose of the
        reference mounting R0 (the model's :meth:`~casadical.model._symbolic.Model.probe_rotation`
        is compared with them); the loss then weighs both parts by
        ``loss.rot_weight``. None: positions only.
    layout : Layout or None
        Rows that say what the tool point touched (:mod:`casadical.rows`): each row's residual is made from the
        model's points of its group (the touched point fitted to them), the Jacobian projected away from the
        groups' unknowns. None: every row measured (``xyz``), as before.
    """

    model: Model
    params: Parameters
    q: np.ndarray
    xyz: np.ndarray
    cov: np.ndarray
    base0: np.ndarray
    loss: RobustLoss = field(default_factory=RobustLoss)
    rot: np.ndarray | None = None
    layout: Layout | None = None
    _memo: tuple | None = field(default=None, init=False, repr=False, compare=False)
    _last: tuple | None = field(default=None, init=False, repr=False, compare=False)

    @classmethod
    def from_data(cls, model: Model, data: Measurements, params: Parameters | None = None,
                  base0: np.ndarray | None = None, loss: RobustLoss | None = None) -> "CalibrationProblem":
        return cls(model, (params or model.parameters).copy(), data.q, measured_points(data),
                   model.covariates(data), model.base0_nominal() if base0 is None else base0,
                   loss or RobustLoss(), layout=data.layout if data.touches else None)

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
        if self.layout is not None:
            return self.layout.residuals(self.model.predict(self.q, values, self.cov, self.base0)).ravel()
        out = np.empty((self.n_poses, 3))
        for s in pose_chunks(self.n_poses):
            out[s] = self.model.predict(self.q[s], values, self.cov[s], self.base0) - self.xyz[s]
        return out.ravel()

    @property
    def full_pose(self) -> bool:
        """True when the loss has the orientation residuals."""
        return self.rot is not None

    @property
    def equations_per_pose(self) -> int:
        return 6 if self.full_pose else 3

    @property
    def equations(self) -> int:
        """The independent equations of the loss: ``equations_per_pose`` a pose; rows that touch, their
        layout's (:attr:`casadical.rows.Layout.equations`)."""
        return self.layout.equations if self.layout is not None else self.equations_per_pose * self.n_poses

    def residual_norms(self, values: np.ndarray) -> tuple[np.ndarray, np.ndarray | None]:
        """Position residual norms (m) and, for full pose, orientation residual norms (rad), per pose."""
        if not self.full_pose:
            return np.linalg.norm(self.residuals(values).reshape(-1, 3), axis=1), None
        rp, ro = np.empty(self.n_poses), np.empty(self.n_poses)
        for s in pose_chunks(self.n_poses):
            xyz, r = self.model.pose_residuals(self.q[s], self.rot[s], values, self.cov[s], self.base0)
            rp[s], ro[s] = np.linalg.norm(xyz - self.xyz[s], axis=1), np.linalg.norm(r, axis=1)
        return rp, ro

    def cost(self, values: np.ndarray) -> float:
        """The loss at ``values`` (m^2) without the Jacobian: :attr:`Linearization.cost`, to the bit (the same
        residuals, each pose's ``u2`` formed as :meth:`linearize` forms it, one sum over every pose)."""
        if self.layout is not None:
            r = self.residuals(values).reshape(-1, 3)
            return float(self.loss.rho(np.einsum("ij,ij->i", r, r)).sum())
        u2 = np.empty(self.n_poses)
        for s in pose_chunks(self.n_poses):
            if self.full_pose:
                xyz, ro = self.model.pose_residuals(self.q[s], self.rot[s], values, self.cov[s], self.base0)
                r = np.concatenate([xyz - self.xyz[s], self.loss.rot_weight * ro], axis=1)
            else:
                r = self.model.predict(self.q[s], values, self.cov[s], self.base0) - self.xyz[s]
            u2[s] = np.einsum("ij,ij->i", r, r)
        return float(self.loss.rho(u2).sum())

    def weighted_jacobian(self, values: np.ndarray, s: slice) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
        """Residual rows and their Jacobian (full parameter vector, SI) of the poses ``s``, in position units.

        Returns ``r`` (n, m), ``J`` (n, m, P) and the orientation residuals
        (rad) or None: m = 3 (positions), or 6 for full pose, whose rows
        3-5 are the orientation's times ``loss.rot_weight``.
        """
        if not self.full_pose:
            if self.layout is not None:     # every row at once: a group's rows make each one's residual
                r, J = self.layout.project(*self.model_jacobian(values, slice(0, self.n_poses)))
                return r[s], J[s], None
            xyz, J = self.model_jacobian(values, s)
            return xyz - self.xyz[s], J, None
        k = self.loss.rot_weight
        xyz, J, ro, Jo = self.model_jacobian(values, s)
        return (np.concatenate([xyz - self.xyz[s], k * ro], axis=1), np.concatenate([J, k * Jo], axis=1), ro)

    def model_jacobian(self, values: np.ndarray, s: slice, columns: np.ndarray | None = None) -> tuple:
        """The model's outputs and Jacobian at the poses ``s``: ``Model.predict_jacobian`` (positions; with
        ``columns``, those columns alone) or ``Model.pose_jacobian`` (full pose), read-only.

        A small problem keeps them at the last ``values`` it was asked for (:data:`MEMO_NUMBERS`): the
        robust loss's re-weighting, the precision and the separation check linearise again where the
        solver stopped, with another loss but the same model (on 2,000 full poses, 43 of 289
        evaluations of a diagnosis were such repeats)."""
        def evaluate():
            if self.full_pose:
                return self.model.pose_jacobian(self.q[s], self.rot[s], values, self.cov[s], self.base0)
            return self.model.predict_jacobian(self.q[s], values, self.cov[s], self.base0, columns=columns)

        if self.n_poses * self.equations_per_pose * len(values) > MEMO_NUMBERS:
            return evaluate()
        inputs = (self.model, self.q, self.cov, self.base0, self.rot)
        memo = self._memo
        if memo is None or any(a is not b for a, b in zip(memo[0], inputs)) or memo[1] != values.tobytes():
            memo = self._memo = (inputs, values.tobytes(), {})
        key = (s.start, s.stop, None if columns is None or self.full_pose else columns.tobytes())
        out = memo[2].get(key)
        if out is None:
            out = memo[2][key] = evaluate()
            for a in out:
                a.flags.writeable = False
        return out

    def linearize(self, values: np.ndarray) -> Linearization:
        """Residuals, weights, loss and normal equations at ``values``, accumulated over chunks of poses.

        A problem too large to keep its Jacobian (:data:`MEMO_NUMBERS`) keeps its last linearisation instead
        (the same values, loss and free set give the same object, to the bit): the precision linearises
        where the solver stopped, which the solver's last iterate did (0.7 s at 200,000 poses)."""
        if self.n_poses * self.equations_per_pose * len(values) <= MEMO_NUMBERS:
            return self._linearize(values)
        key = (values.tobytes(), self.loss, self.free.tobytes(), self.model, self.q, self.xyz, self.cov,
               self.base0, self.rot)
        last = self._last
        if last is None or len(last[0]) != len(key) or any(
                a != b if isinstance(a, (bytes, RobustLoss)) else a is not b for a, b in zip(last[0], key)):
            last = self._last = (key, self._linearize(values))
        return last[1]

    def _linearize(self, values: np.ndarray) -> Linearization:
        if self.full_pose:
            return self._linearize_pose(values)
        if self.layout is not None:
            return self._linearize_touch(values)
        f = self.free
        scale = self.params.scales[f]
        nf = len(f)
        A = np.zeros((nf, nf))
        g = np.zeros(nf)
        r_all = np.empty((self.n_poses, 3))
        u2_all, w_all = np.empty(self.n_poses), np.empty(self.n_poses)
        for s in pose_chunks(self.n_poses):
            xyz, J = self.model_jacobian(values, s, f)
            r = xyz - self.xyz[s]
            r_all[s] = r
            Jx = J * scale                                # (n, 3, nf), scaled variables
            u2_all[s] = np.einsum("ij,ij->i", r, r)
            w = w_all[s] = self.loss.weight(u2_all[s])
            Jw = Jx * np.sqrt(w)[:, None, None]
            Jw2 = Jw.reshape(-1, nf)
            A += Jw2.T @ Jw2
            v = np.einsum("nkp,nk->np", Jx, r)            # J_i^T r_i per pose
            g += v.T @ w
            if self.loss.delta:
                # the loss's own curvature along each residual (Triggs' correction of IRLS): the matrix
                # stays positive semi-definite, w^3 along r_i, and LM converges as fast as for least squares
                A -= self.loss.delta * (v * (w ** 3)[:, None]).T @ v
        return Linearization(r_all, w_all, float(self.loss.rho(u2_all).sum()), A, g, None, u2_all)

    def _linearize_touch(self, values: np.ndarray) -> Linearization:
        """:meth:`linearize` of rows some of which say what they touched: every row at once (a group's unknowns
        are fitted to all its rows), the Jacobian projected away from them (:meth:`Layout.project`)."""
        f = self.free
        scale = self.params.scales[f]
        nf = len(f)
        xyz, J = self.model_jacobian(values, slice(0, self.n_poses))
        r, Jp = self.layout.project(xyz, J[:, :, f])
        Jx = Jp * scale
        u2 = np.einsum("ij,ij->i", r, r)
        w = self.loss.weight(u2)
        Jw2 = (Jx * np.sqrt(w)[:, None, None]).reshape(-1, nf) if nf else np.zeros((3 * len(r), 0))
        v = np.einsum("nkp,nk->np", Jx, r)
        A = Jw2.T @ Jw2
        if self.loss.delta:
            A -= self.loss.delta * (v * (w ** 3)[:, None]).T @ v
        return Linearization(r, w, float(self.loss.rho(u2).sum()), A, v.T @ w, None, u2)

    def _linearize_pose(self, values: np.ndarray) -> Linearization:
        """:meth:`linearize` of the full-pose loss: each pose's 6-vector (r_p, k r_o)."""
        f = self.free
        scale = self.params.scales[f]
        nf = len(f)
        A = np.zeros((nf, nf))
        g = np.zeros(nf)
        r_all, ro_all = np.empty((self.n_poses, 3)), np.empty((self.n_poses, 3))
        u2_all, w_all = np.empty(self.n_poses), np.empty(self.n_poses)
        for s in pose_chunks(self.n_poses):
            r, J, ro = self.weighted_jacobian(values, s)
            r_all[s], ro_all[s] = r[:, :3], ro
            Jx = J[:, :, f] * scale                       # (n, 6, nf), scaled variables
            u2_all[s] = np.einsum("ij,ij->i", r, r)
            w = w_all[s] = self.loss.weight(u2_all[s])
            Jw2 = (Jx * np.sqrt(w)[:, None, None]).reshape(-1, nf)
            A += Jw2.T @ Jw2
            v = np.einsum("nkp,nk->np", Jx, r)
            g += v.T @ w
            if self.loss.delta:
                A -= self.loss.delta * (v * (w ** 3)[:, None]).T @ v
        return Linearization(r_all, w_all, float(self.loss.rho(u2_all).sum()), A, g, ro_all, u2_all)

    def residuals_jacobian(self, values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Residuals (3N,) and their Jacobian w.r.t. the scaled free variables (3N, n_free).

        Holds the whole Jacobian: for small problems (screening, global
        search); solvers use :meth:`linearize`.
        """
        xyz, J = self.model.predict_jacobian(self.q, values, self.cov, self.base0)
        f = self.free
        if self.layout is not None:
            r, Jp = self.layout.project(xyz, J[:, :, f])
            return r.ravel(), Jp.reshape(-1, len(f)) * self.params.scales[f]
        return (xyz - self.xyz).ravel(), J[:, :, f].reshape(-1, len(f)) * self.params.scales[f]


#: full pose, before the noise scales are known (identifiability): an orientation residual of 1 rad weighs
#: like a position residual of this many metres (an angle's effect at one metre)
ROT_WEIGHT_PRIOR = 1.0


def jacobian_factor(model: Model, q: np.ndarray, values: np.ndarray, cov: np.ndarray,
                    base0: np.ndarray, rot: np.ndarray | None = None, rot_weight: float = ROT_WEIGHT_PRIOR,
                    layout: Layout | None = None) -> np.ndarray:
    """Triangular factor ``R`` (P x P) with ``R^T R = J^T J`` of the full identification Jacobian.

    Computed chunk by chunk (a tall-skinny QR), so that any number of poses
    fits in memory; column inner products, hence every identifiability
    question, are those of ``J``. With ``rot`` (full pose, as
    :attr:`CalibrationProblem.rot`) ``J`` also has the orientation rows,
    times ``rot_weight`` (m/rad). With ``layout`` (rows that say what they touched) ``J`` is projected away from
    the touched things' unknowns, all rows at once.
    """
    if layout is not None:
        P, J = model.predict_jacobian(q, values, cov, base0)
        return triangular_factor([layout.project(P, J)[1]], len(values))
    if rot is None:
        blocks = (model.predict_jacobian(q[s], values, cov[s], base0)[1] for s in pose_chunks(len(q)))
    else:
        blocks = (np.concatenate([J, rot_weight * Jo], axis=1) for J, Jo in
                  (model.pose_jacobian(q[s], rot[s], values, cov[s], base0)[1::2] for s in pose_chunks(len(q))))
    return triangular_factor(blocks, len(values))


def measured_points(data: Measurements) -> np.ndarray:
    """The measured points of ``data`` (m, (N, 3)): NaN at rows that say what they touched, all NaN where no row
    was measured."""
    if data.has_positions:
        return data.xyz
    return np.full((len(data), 3), np.nan)

