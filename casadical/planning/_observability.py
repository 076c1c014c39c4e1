"""Observability indices of a pose set and the identification Jacobian they are computed from.

A pose set is judged by the singular values ``sigma_1 >= ... >= sigma_n`` of
its identification Jacobian ``J`` (``3 m x n`` for ``m`` poses and ``n``
identifiable parameters, positions only):

- ``O1 = (sigma_1 ... sigma_n)^(1/n) / sqrt(m)`` (Borm & Menq; the GA paper's
  Eq. 5). ``O1^(2n) m^n = det(J^T J)``: maximising O1 is the D-criterion;
- ``O2 = sigma_min / sigma_max`` (inverse condition number, Driels & Pathre);
- ``O3 = sigma_min`` (minimum singular value, Nahvi);
- ``O4 = sigma_min^2 / sigma_max`` (noise amplification index, Nahvi & Hollerbach);
- ``O5 = 1 / sum(1 / sigma_i)`` (Sun & Hollerbach).

The Jacobian columns are those of the *identifiable* parameters only
(:func:`casadical.stats._identifiability.analyse` on the candidate pool), each
multiplied by the parameter's ``scale`` (its typical deviation, e.g. 1 mm,
1 mrad, or the compliance that deflects a joint 0.1 mrad at full load). The
entries are then metres of tool displacement per typical deviation, and the
indices are in metres. Without that scaling a column in rad/(N m) would
dominate every index by ten orders of magnitude.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field

import numpy as np

from ..errors import IdentifiabilityError, InputError
from ..runtime._threads import limited_threads
from ..stats._identifiability import Identifiability, analyse, triangular_factor

#: poses per Jacobian evaluation of a candidate pool (bounds memory and CasADi's map size)
JACOBIAN_CHUNK = 4096
#: pools from this size on pay for compiling the model (about 1.5 s once, then ~7x faster
#: than CasADi's virtual machine); ``plan-poses`` passes ``jit=`` accordingly
JIT_MIN_CANDIDATES = 60_000


@dataclass(frozen=True)
class Observability:
    """The five observability indices of one pose set.

    Attributes
    ----------
    O1, O2, O3, O4, O5 : float
        See the module docstring; 0 when the set does not identify every
        parameter (``sigma_min = 0``).
    n_poses : int
        ``m``, the number of poses.
    n_parameters : int
        ``n``, the number of identifiable parameters (Jacobian columns).
    singular_values : ndarray
        Descending, shape ``(n,)`` (fewer when ``3 m < n``: the missing ones are 0).
    """

    O1: float
    O2: float
    O3: float
    O4: float
    O5: float
    n_poses: int
    n_parameters: int
    singular_values: np.ndarray = field(repr=False, compare=False)

    def as_dict(self) -> dict[str, float]:
        """``{"O1": ..., ..., "O5": ...}``."""
        d = asdict(self)
        return {k: float(d[k]) for k in ("O1", "O2", "O3", "O4", "O5")}


def indices_from_singular_values(sigma, n_poses: int, n_parameters: int | None = None) -> Observability:
    """O1..O5 from the singular values of a pose set's (scaled) identification Jacobian.

    Parameters
    ----------
    sigma : array_like
        Singular values (any order), at most ``n_parameters`` of them.
    n_poses : int
        Number of poses ``m`` (O1 divides by ``sqrt(m)``).
    n_parameters : int, optional
        Number of parameters ``n``; defaults to ``len(sigma)``. Missing
        singular values (a wide Jacobian) count as zeros.

    Examples
    --------
    >>> o = indices_from_singular_values([3.0, 2.0, 1.0], n_poses=2)
    >>> round(o.O1, 6) == round(6 ** (1 / 3) / 2 ** 0.5, 6), o.O2, o.O3, o.O4
    (True, 0.3333333333333333, 1.0, 0.3333333333333333)
    """
    s = np.sort(np.abs(np.asarray(sigma, dtype=float)).ravel())[::-1]
    n = len(s) if n_parameters is None else int(n_parameters)
    if n < 1 or len(s) > n:
        raise InputError(f"need 1 <= len(sigma) <= n_parameters, got {len(s)} singular values "
                         f"for {n} parameters")
    if n_poses < 1:
        raise InputError(f"the number of poses must be at least 1, got {n_poses}")
    full = np.zeros(n)
    full[:len(s)] = s
    smax, smin = float(full[0]), float(full[-1])
    if smin <= 0.0:
        o1 = o2 = o3 = o4 = o5 = 0.0
    else:
        o1 = math.exp(float(np.mean(np.log(full)))) / math.sqrt(n_poses)
        o2, o3, o4 = smin / smax, smin, smin * smin / smax
        o5 = 1.0 / float(np.sum(1.0 / full))
    return Observability(o1, o2, o3, o4, o5, int(n_poses), n, full)


@limited_threads()
def observability(A: np.ndarray, subset=None) -> Observability:
    """O1..O5 of a pose set from its per-pose Jacobian blocks.

    Parameters
    ----------
    A : ndarray, shape (N, r, n)
        Scaled identification Jacobian of the pool, one ``r x n`` block per
        pose (``r = 3`` for positions).
    subset : array_like of int, optional
        Rows of the pool forming the set (default: all).
    """
    A = _blocks(A)
    B = A if subset is None else A[np.asarray(subset, dtype=int)]
    s = np.linalg.svd(B.reshape(-1, A.shape[2]), compute_uv=False)
    return indices_from_singular_values(s, len(B), A.shape[2])


@limited_threads()
def log_det_information(A: np.ndarray, subset=None) -> float:
    """``log det(J^T J)`` of a pose set (``-inf`` if singular).

    Equals ``2 n log(O1 sqrt(m))``.
    """
    A = _blocks(A)
    B = (A if subset is None else A[np.asarray(subset, dtype=int)]).reshape(-1, A.shape[2])
    sign, ld = np.linalg.slogdet(B.T @ B)
    return float(ld) if sign > 0 else -math.inf


@limited_threads()
def o1_batch(A: np.ndarray, sets: np.ndarray) -> np.ndarray:
    """O1 of many pose sets at once (the GA's fitness).

    Parameters
    ----------
    A : ndarray, shape (N, r, n)
    sets : int ndarray, shape (k, m)
        One pose set per row.

    Returns
    -------
    ndarray, shape (k,)
        O1 of each set, 0 for sets that do not identify every parameter.
    """
    A = _blocks(A)
    sets = np.atleast_2d(np.asarray(sets, dtype=int))
    k, m = sets.shape
    n = A.shape[2]
    B = A[sets].reshape(k, -1, n)
    # log det of the Gram matrix = 2 sum log sigma; O1 = exp(log det / (2 n)) / sqrt(m)
    sign, ld = np.linalg.slogdet(np.einsum("kai,kaj->kij", B, B))
    out = np.zeros(k)
    ok = sign > 0
    out[ok] = np.exp(ld[ok] / (2 * n)) / math.sqrt(m)
    return out


@dataclass
class DesignProblem:
    """The scaled identification Jacobian of a candidate pool.

    Attributes
    ----------
    A : ndarray, shape (N, 3, n)
        Per-pose Jacobian blocks of the identifiable parameters, each column
        multiplied by the parameter's scale (metres per typical deviation).
    names : list of str
        The ``n`` identifiable parameters, in model order.
    identifiability : Identifiability or None
        The analysis of the whole pool that chose them.
    model_spec : str
        The model the Jacobian belongs to.
    scaling : str
        ``"scales"`` (default) or ``"si"`` (unscaled SI columns, for
        comparing with papers that use raw units).
    missing : list of str
        Parameters that poses spread over the joint ranges identify but this
        pool does not (empty when the pool is not degenerate). No choice
        from the pool calibrates them, so no certificate is given for it.
    """

    A: np.ndarray
    names: list[str]
    identifiability: Identifiability | None = None
    model_spec: str = ""
    scaling: str = "scales"
    missing: list[str] = field(default_factory=list)

    @property
    def n_candidates(self) -> int:
        return self.A.shape[0]

    @property
    def n_parameters(self) -> int:
        return self.A.shape[2]

    @property
    def rows_per_pose(self) -> int:
        return self.A.shape[1]

    @property
    def min_poses(self) -> int:
        """Fewest poses whose equations can identify every parameter."""
        return -(-self.n_parameters // self.rows_per_pose)


@limited_threads()
def design_problem(model, q: np.ndarray, cov: np.ndarray | None = None, *,
                   scaling: str = "scales", base0: np.ndarray | None = None,
                   reference: bool = True) -> DesignProblem:
    """Scaled identification Jacobian of the identifiable parameters over a candidate pool.

    Parameters
    ----------
    model : casadical.model._symbolic.Model
    q : ndarray, shape (N, n_joints)
        Candidate joint readings (rad).
    cov : ndarray, optional
        Per-pose covariates (``model.covariates(data)``), e.g. the payload
        that drives the compliance torques; defaults to the robot's.
    scaling : {"scales", "si"}
        Multiply each column by the parameter's scale (default), or keep SI
        units (m per m, m per rad, ...).
    base0 : ndarray, optional
        Reference base pose (12 numbers); defaults to the robot file's.
    reference : bool
        Also compare with the parameters that poses spread over the joint
        ranges identify (:func:`reference_identifiable`, ~0.05 s) and list
        those the pool misses in ``missing``.

    Raises
    ------
    IdentifiabilityError
        The pool identifies no parameter at all.
    """
    if scaling not in ("scales", "si"):
        raise InputError(f"scaling must be 'scales' or 'si', got {scaling!r}")
    J = pool_jacobian(model, q, cov, base0)
    params = model.parameters
    ident = _analyse_pool(J, params)
    if not ident.identifiable:
        raise IdentifiabilityError("the candidate poses identify no parameter of model "
                                   f"{model.spec}")
    idx = np.array([params.index(n) for n in ident.identifiable])
    A = J[:, :, idx]
    if scaling == "scales":
        A = A * params.scales[idx]
    missing: list[str] = []
    if reference:
        ref = reference_identifiable(model, base0)
        if len(ref) > len(ident.identifiable):  # the pool identifies fewer than poses across the joints do
            have = set(ident.identifiable)
            missing = [n for n in ref if n not in have]
    return DesignProblem(np.ascontiguousarray(A), list(ident.identifiable), ident, model.spec, scaling,
                         missing)


def reference_identifiable(model, base0: np.ndarray | None = None, n: int = 200) -> list[str]:
    """Parameters of ``model`` that ``n`` poses drawn uniformly over the joint ranges identify.

    The yardstick of a candidate pool: a pool that identifies fewer is
    degenerate (identical or too similar poses, no load where compliance
    needs one). Covariates are the robot's defaults (its payload).
    """
    from ..data._simulate import sample_poses

    q = sample_poses(model.robot, n, np.random.default_rng(0), floor_z=None)
    J = model.predict_jacobian(q, base0=base0)[1]
    return list(analyse(J, model.parameters).identifiable)


def pool_jacobian(model, q: np.ndarray, cov: np.ndarray | None = None, base0: np.ndarray | None = None,
                  chunk: int = JACOBIAN_CHUNK) -> np.ndarray:
    """``model.predict_jacobian`` over a large pool, ``chunk`` poses at a time.

    Every chunk has the same size (the last one is padded), so CasADi builds
    one map for all of them; building a map for 10^5 poses at once takes
    longer than evaluating it.

    Returns
    -------
    ndarray, shape (N, 3, P)
    """
    q = np.atleast_2d(np.asarray(q, dtype=float))
    N = len(q)
    if cov is not None:
        cov = np.asarray(cov, dtype=float)
        cov = cov[:, None] if cov.ndim == 1 else cov
    if N <= chunk:
        return model.predict_jacobian(q, cov=cov, base0=base0)[1]
    J = np.empty((N, 3, len(model.parameters)))
    for s in range(0, N, chunk):
        qs, cs = q[s:s + chunk], None if cov is None else cov[s:s + chunk]
        n = len(qs)
        if n < chunk:
            qs = np.concatenate([qs, np.repeat(qs[-1:], chunk - n, axis=0)])
            cs = None if cs is None else np.concatenate([cs, np.repeat(cs[-1:], chunk - n, axis=0)])
        J[s:s + n] = model.predict_jacobian(qs, cov=cs, base0=base0)[1][:n]
    return J


def _analyse_pool(J: np.ndarray, params) -> Identifiability:
    """:func:`casadical.stats._identifiability.analyse` of a large pool's Jacobian, on a ``P x P`` factor.

    ``J = Q R`` (Householder QR, in chunks of rows) keeps every angle and
    length between columns, which is all the analysis uses. Saves a
    Gram-Schmidt sweep and the least-squares fits over ``3N`` rows (seconds
    at 10^5 poses).
    """
    rows = J.reshape(-1, J.shape[-1])
    n_rows, P = rows.shape
    if n_rows <= 4 * P:
        return analyse(J, params)
    R = triangular_factor((rows[s:s + 8192] for s in range(0, n_rows, 8192)), P)
    return analyse(R, params, n_equations=n_rows)


def _blocks(A) -> np.ndarray:
    A = np.asarray(A, dtype=float)
    if A.ndim != 3:
        raise InputError(f"expected per-pose Jacobian blocks of shape (N, r, n), got shape {A.shape}")
    return A
