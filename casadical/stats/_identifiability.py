"""Which parameters a set of poses can identify, and with which others they are confounded.

The identification Jacobian is scaled by each parameter's typical deviation
and its columns normalised, then taken column by column in a priority order
(base pose, tool, non-geometric terms, links from base to tip): a column
that adds nothing to the span of the accepted ones (relative residual below
``tol``) is not identifiable and is fixed at nominal. Its expansion in the
accepted columns names the parameters it is confounded with.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Iterable

import numpy as np

from ..parameters import Parameters
from ..terms._geometric import Geometric

_GROUP_PRIORITY = {"base": 0, "tool": 1, "link": 3, "loop": 3}


@dataclass
class Unidentifiable:
    """A parameter the poses cannot identify."""

    name: str
    reason: str
    confounded_with: list[str] = field(default_factory=list)


@dataclass
class Identifiability:
    """Result of :func:`analyse`.

    Attributes
    ----------
    identifiable : list of str
        Parameters kept free, in model order.
    unidentifiable : list of Unidentifiable
    singular_values : ndarray
        Of the scaled, column-normalised Jacobian of the identifiable set.
    condition_number : float
    n_equations : int
    """

    identifiable: list[str]
    unidentifiable: list[Unidentifiable]
    singular_values: np.ndarray
    condition_number: float
    n_equations: int

    def apply(self, params: Parameters) -> None:
        """Fix the unidentifiable parameters (at their current values) with the reason."""
        for u in self.unidentifiable:
            params[u.name].fixed = True
            params[u.name].identifiable = False
            params[u.name].reason = u.reason
        for n in self.identifiable:
            params[n].identifiable = True

    def free(self, names: list[str], params: Parameters) -> None:
        """Count ``names`` as identifiable after all (see :func:`casadical.calibration._solve.separated`); free them."""
        self.unidentifiable = [u for u in self.unidentifiable if u.name not in names]
        self.identifiable = [n for n in params.names if n in set(self.identifiable) | set(names)]
        for n in names:
            params[n].fixed, params[n].identifiable, params[n].reason = False, True, ""

    def report(self) -> str:
        lines = [f"identifiable: {len(self.identifiable)} parameters from {self.n_equations} equations, "
                 f"condition number {self.condition_number:.3g} (scaled, column-normalised Jacobian)"]
        for u in self.unidentifiable:
            lines.append(f"  {u.name}: not identifiable, {u.reason}")
        return "\n".join(lines)


def _priority(params: Parameters, i: int) -> tuple[int, int]:
    p = params.items[i]
    group = _GROUP_PRIORITY.get(p.group, 2) if p.term == Geometric.name else 2
    return group, i


def triangular_factor(blocks: Iterable[np.ndarray], P: int) -> np.ndarray:
    """``R`` (at most P x P) with ``R^T R = J^T J`` of the rows of ``J`` given block by block (tall-skinny QR).

    Memory stays that of one block; pass ``R`` to :func:`analyse` with
    ``n_equations`` = the rows of ``J``.
    """
    R = np.zeros((0, P))
    for block in blocks:
        R = np.linalg.qr(np.vstack([R, block.reshape(-1, P)]), mode="r")
    return R


def analyse(J: np.ndarray, params: Parameters, tol: float = 1e-6,
            effect_tol: float = 1e-9, n_equations: int | None = None) -> Identifiability:
    """Identifiability of the free parameters from an identification Jacobian.

    Parameters
    ----------
    J : ndarray, shape (N, 3, P) or (3N, P)
        Jacobian of the positions w.r.t. the full parameter vector (SI).
    params : Parameters
        The model's parameters; only free ones are analysed.
    tol : float
        Relative residual under which a normalised column counts as a
        combination of the accepted ones.
    effect_tol : float
        RMS position change (m) per unit of scale below which a parameter
        has no effect at these poses.
    n_equations : int, optional
        Rows of the Jacobian ``J`` stands for: pass it when ``J`` is a
        triangular factor with the same ``J^T J``
        (:func:`casadical.problem.jacobian_factor`), which answers every
        question here the same way.
    """
    J = J.reshape(-1, J.shape[-1])
    m = J.shape[0] if n_equations is None else int(n_equations)
    free = np.flatnonzero(params.free)
    Js = J[:, free] * params.scales[free]
    norms = np.linalg.norm(Js, axis=0)
    order = sorted(range(len(free)), key=lambda k: _priority(params, free[k]))
    names = params.names
    accepted: list[int] = []
    basis = np.zeros((J.shape[0], 0))
    out: list[Unidentifiable] = []
    for k in order:
        name = names[free[k]]
        if norms[k] / np.sqrt(max(m, 1)) < effect_tol:
            out.append(Unidentifiable(name, "has no effect on the measured point at these poses"))
            continue
        c = Js[:, k] / norms[k]
        r = c - basis @ (basis.T @ c)
        r = r - basis @ (basis.T @ r)  # second Gram-Schmidt pass for accuracy
        rn = float(np.linalg.norm(r))
        if rn < tol or len(accepted) >= min(m, J.shape[0]):
            A = Js[:, accepted] / norms[accepted]
            coef = np.linalg.lstsq(A, c, rcond=None)[0] if accepted else np.zeros(0)
            big = [names[free[accepted[i]]] for i in np.argsort(-np.abs(coef)) if abs(coef[i]) > 0.05][:6]
            reason = ("a combination of " + ", ".join(big)) if big else "not observable at these poses"
            out.append(Unidentifiable(name, reason, big))
            continue
        accepted.append(k)
        basis = np.column_stack([basis, r / rn])
    ident = [names[free[k]] for k in sorted(accepted)]
    if accepted:
        A = Js[:, sorted(accepted)] / norms[sorted(accepted)]
        sv = np.linalg.svd(A, compute_uv=False)
        cond = float(sv[0] / sv[-1]) if sv[-1] > 0 else float("inf")
    else:
        sv, cond = np.zeros(0), float("inf")
    out.sort(key=lambda u: names.index(u.name))
    return Identifiability(ident, out, sv, cond, m)
