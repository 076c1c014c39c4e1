"""Is a fitted term a physical cause? The rules a named cause must pass.

A better fit is not yet a cause. A term of the model (compliance, backlash,
a gear error, ...) is physics only when, in the fitted model:

- **bounds**: each of its parameters lies inside, not at or beyond, its
  bounds (a negative compliance, a negative half play, an encoder scale of
  30 % are not the things their names say);
- **geometry**: it can be told apart from the geometry: no geometric
  parameter was fixed as a combination of it (a "backlash" whose sign
  never changes is a joint offset), and its Jacobian column is not all but
  a combination of the geometric parameters' columns (variance inflation
  against the free geometric parameters below :data:`MAX_VIF`);
- **significance**: its parameters are jointly non-zero given everything
  else the model fits, the geometry included (Wald test at ``alpha`` with
  the fit's covariance);
- **physics**: its effect makes physical sense over the data: a
  progressive spring keeps its deflection increasing with the load over
  the torques the data reach (it may stiffen or soften, never turn back);
  backlash needs its sign source (the joint's gravity torque, or the
  direction of its last move) to change sign in the data, or it is a
  constant joint offset.

The rules are plain functions of a fitted
:class:`~casadical.result.CalibrationResult` and its data (statsmodels
style diagnostics): :func:`violations` checks the parameters of one cause,
:func:`term_causes` lists the causes of a model, and the diagnosis and
``calibrate``'s notes both use them.

Sign conventions (docs/diagnosis.md): a compliant joint and backlash with
the torque as sign source deflect the joint *with* its gravity torque
(``+c tau``, ``+b sign(tau)``, ``c, b >= 0``); backlash with the last move
as sign source makes the output trail its motor: after a move in the
positive direction the joint stands ``b`` short (``-b sign(move)``,
``b >= 0``). A fit that needs the opposite sign (the output *leading* its
motor) is not play, and is reported as such.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from ..runtime._chunks import pose_chunks
from ..terms import REGISTRY
from ..terms._backlash import MIN_SIDE_POSES, MIN_SIDE_SHARE, sign_changes  # noqa: F401 (their home was here)
from ..terms._compliance import JointCompliance
from ..terms._geometric import Geometric

if TYPE_CHECKING:      # a type only: the data layer stands above the statistics
    from ..data._measurements import Measurements

#: a term's parameter whose column is this much a combination of the geometric columns (variance inflation
#: factor, 1 / (1 - R^2)) cannot be told from the geometry: R^2 above 0.999. Below that a strong effect can
#: still be well determined (an encoder scale over 40 deg of its joint: R^2 = 0.995 and a clear gain), which
#: the significance test (with the geometry free) judges
MAX_VIF = 1000.0
#: significance level of the Wald test of a cause's parameters
ALPHA = 0.001


@dataclass
class Violation:
    """A rule a cause breaks.

    Attributes
    ----------
    rule : {"bounds", "geometry", "significance", "physics"}
    parameters : tuple of str
    text : str
        What is wrong, in words, with the values.
    """

    rule: str
    parameters: tuple[str, ...]
    text: str


@dataclass
class Cause:
    """The parameters of one cause in a model: a term on one joint (one harmonic for a gear error).

    Attributes
    ----------
    term : str
        The term's name (``joint_compliance``, ``backlash``, ...).
    joint : int or None
    parameters : list of str
    label : str
        In words, for messages.
    """

    term: str
    joint: int | None
    parameters: list[str]
    label: str


def term_causes(result) -> list[Cause]:
    """The causes of a fitted model: every term other than the geometry, the probe's mounting, the sessions'
    frames and the compensators (:attr:`~casadical.terms._base.ErrorTerm.is_cause`), split by joint (and harmonic:
    :meth:`~casadical.terms._base.ErrorTerm.fitted_causes`); a term of one session says which."""
    out = []
    for t in result.model.terms:
        inner = getattr(t, "inner", t)          # a term of one session (SessionLocal)
        if not inner.is_cause:
            continue
        names = [p.name for p in t.parameters(result.model.robot)]
        where = f" in session {t.session_name}" if inner is not t else ""
        out += [Cause(t.name, j, ns, label) for j, ns, label in
                inner.fitted_causes(names, lambda n: result.parameters[n].joint, where)]
    return out


def violations(result, data: Measurements, parameters: list[str], *, alpha: float = ALPHA,
               max_vif: float = MAX_VIF) -> list[Violation]:
    """The rules of the module the cause of ``parameters`` breaks in the fitted model ``result``.

    Parameters
    ----------
    result : CalibrationResult
        The fitted model (its values, standard errors, covariance and
        identifiability).
    data : Measurements
        The poses it was fitted on (torque range, sign sources).
    parameters : list of str
        The cause's parameters (e.g. ``["c2"]``, ``["gear2_s17", "gear2_c17"]``;
        a progressive spring: ``["cubic2"]``, judged with ``c2`` if present).
    alpha : float
        Level of the Wald test of significance.
    max_vif : float
        Largest variance inflation against the geometric parameters.

    Returns
    -------
    list of Violation
        Empty when the cause is physics.
    """
    P = result.parameters
    names = [n for n in parameters if n in P]
    out: list[Violation] = []
    fixed = [n for n in names if P[n].fixed]
    if fixed:
        out.append(Violation("geometry", tuple(fixed), "; ".join(
            f"{n} could not be identified from these poses" + (f" ({P[n].reason})" if P[n].reason else "")
            for n in fixed)))
    free = [n for n in names if not P[n].fixed]
    m = result.model
    out += value_violations(P, free, lambda: m.torques(data.q, P.values, m.covariates(data)), data.moves)
    out += separable_from_geometry(result, free, max_vif)
    if free and not out:
        out += significant(result, free, alpha)
    return out


def value_violations(params, names: list[str], torques, moves: np.ndarray) -> list[Violation]:
    """The rules a cause's values alone can break (bounds, physics): what a one-step fit is checked for.

    Parameters
    ----------
    params : Parameters or dict of str to Parameter
        The parameters with their values (and those of a progressive
        spring's linear part, ``c<j>``, where present).
    names : list of str
    torques : ndarray (N, n) or callable
        The gravity torques of the poses (a callable is called once, when needed).
    moves : ndarray (N, n)
        The sign of each joint's last move.
    """
    out = inside_bounds(params, names)
    cache: list = []

    def tau() -> np.ndarray:
        if not cache:
            cache.append(torques() if callable(torques) else np.asarray(torques))
        return cache[0]

    for n in names:
        p = params[n]
        kind = REGISTRY.get(p.term)         # a user term's parameters: no rule beyond their bounds
        if kind is not None:
            out += [Violation("physics", ns, text) for ns, text in kind.value_rules(p, params, tau, moves)]
    return out


def inside_bounds(params, names: list[str]) -> list[Violation]:
    """Parameters at or beyond a bound (``tol``: a millionth of the span, or of the scale if unbounded)."""
    out = []
    for n in names:
        p = params[n]
        span = p.upper - p.lower
        tol = 1e-6 * (span if math.isfinite(span) else p.scale)
        side = "lower" if p.value <= p.lower + tol else ("upper" if p.value >= p.upper - tol else None)
        if side is None:
            continue
        bound = p.lower if side == "lower" else p.upper
        where = "at" if abs(p.value - bound) <= tol else ("below" if side == "lower" else "above")
        kind = REGISTRY.get(p.term)
        meaning = (kind.bound_meaning if kind is not None else {}).get(_kind(n), {}).get(side, "")
        out.append(Violation("bounds", (n,), f"{n} = {_show(p, p.value)} is {where} its {side} bound "
                                             f"{_show(p, bound)}{meaning}"))
    return out


def _kind(name: str) -> str:
    """A parameter's name without its session and joints: ``c2@B`` -> ``c``, ``cpl5_4`` -> ``cpl``."""
    return re.sub(r"[0-9][0-9_]*$", "", name.split("@")[0])


def significant(result, names: list[str], alpha: float = ALPHA) -> list[Violation]:
    """Wald test that the parameters' deviations from nominal are jointly non-zero, at level ``alpha``."""
    unc = result.uncertainty
    if unc is None or not names:
        return []
    idx = [unc.names.index(n) for n in names if n in unc.names]
    if len(idx) != len(names):
        return []
    P = result.parameters
    v = np.array([P[n].value - P[n].nominal for n in names])
    C = unc.covariance[np.ix_(idx, idx)]
    scale = np.array([P[n].scale for n in names])
    Cs = C / np.outer(scale, scale)
    if not np.all(np.isfinite(Cs)) or np.max(np.diag(Cs)) <= 0:
        return [Violation("significance", tuple(names), "the standard errors of " + ", ".join(names)
                          + " are not defined")]
    from scipy import special  # here, not at import: 0.13 s of every calibrate's start-up
    w = float((v / scale) @ np.linalg.pinv(Cs) @ (v / scale))
    p = float(special.chdtrc(len(names), w))
    if p < alpha:
        return []
    if len(names) == 1:
        std = math.sqrt(C[0, 0])
        text = (f"{names[0]} = {_show(P[names[0]], P[names[0]].value)} is not significant (std "
                f"{_show(P[names[0]], std)}, |t| = {abs(v[0]) / std:.2f}, p = {p:.2g})")
    else:
        text = f"{', '.join(names)} are not jointly significant (Wald chi2 = {w:.3g}, {len(names)} dof, p = {p:.2g})"
    return [Violation("significance", tuple(names), text)]


def separable_from_geometry(result, names: list[str], max_vif: float = MAX_VIF) -> list[Violation]:
    """A cause the geometry reproduces: a geometric parameter fixed as a combination of it, or a column
    whose variance inflation against the free geometric columns exceeds ``max_vif``."""
    out = []
    ident = result.identifiability
    if ident is not None:
        for u in ident.unidentifiable:
            partners = [n for n in names if n in u.confounded_with]
            if partners and result.parameters[u.name].term == Geometric.name:
                out.append(Violation("geometry", tuple(partners),
                                     f"{u.name} was fixed as a combination of {', '.join(partners)}: together "
                                     "they are one geometric parameter here, not a cause"))
    unc = result.uncertainty
    if unc is None or not names:
        return out
    P = result.parameters
    geo = [k for k, n in enumerate(unc.names) if P[n].term == Geometric.name]
    A = np.linalg.pinv(unc.covariance / np.outer(unc.std, unc.std).clip(1e-300))   # information, normalised
    for n in names:
        if n not in unc.names or not geo:
            continue
        k = unc.names.index(n)
        sub = geo + [k]
        try:
            vif = float(A[k, k] * np.linalg.inv(A[np.ix_(sub, sub)])[-1, -1])
        except np.linalg.LinAlgError:
            vif = math.inf
        if not vif < max_vif:
            out.append(Violation("geometry", (n,), f"{n} is {1 - 1 / vif:.4f} explained by the geometric "
                                                  f"parameters (variance inflation {vif:.3g}): the geometry "
                                                  "reproduces it"))
    return out


def _show(p, v: float) -> str:
    return f"{p.to_display(v):.4g} {p.display_unit}"


@dataclass
class Sag:
    """How far a compliant joint gives way at the data's poses, and what the model's first order leaves of it.

    Attributes
    ----------
    joint : int
    sag_rad : float
        Its largest fitted deflection (``c tau + k3 tau^3``).
    leaves_m : float
        The largest effect on the measured point of the second-order term the model leaves out for it (m).
    """

    joint: int
    sag_rad: float
    leaves_m: float


def first_order_sag(result, data: Measurements) -> tuple[list[Sag], float]:
    """What the model's first-order compliance leaves out at the poses of ``data``.

    The model takes each drive's gravity torque at the undeflected arm: its joints give way by ``d = K(tau(q))``
    (``K``: ``c tau + k3 tau^3`` of each compliant joint). A real arm gives way until it is in equilibrium,
    ``d = K(tau(q + d))``; to second order the model leaves out ``K'(tau) (dtau/dq) d`` of each joint's angle,
    which moves the point by the angle Jacobian times it. Negligible for realistic stiffness (a sag of 1 mrad
    leaves about 1e-3 of its effect); an arm made soft sags ten times more and it reaches tenths of a mm.

    Returns
    -------
    sags : list of Sag
        One per joint the fitted model holds compliant (a compliance ``c<j>`` above 0).
    leaves_m : float
        The largest effect on the point of the whole neglected term (every joint together), m.
    """
    P, m = result.parameters, result.model
    n = m.robot.n
    c = np.array([P[f"c{j}"].value if f"c{j}" in P else 0.0 for j in range(1, n + 1)])
    k3 = np.array([P[f"cubic{j}"].value if f"cubic{j}" in P else 0.0 for j in range(1, n + 1)])
    joints = [j for j in range(1, n + 1) if c[j - 1] > 0]
    if not joints or len(data) == 0:
        return [], 0.0
    q, cov = data.q, m.covariates(data)
    sag, each, whole = np.zeros(n), np.zeros(n), 0.0
    for s in pose_chunks(len(data)):   # chunk by chunk: the angle Jacobian of every pose is never held at once
        tau, dtau = m.torque_jacobian(q[s], P.values, cov[s])
        d = c * tau + k3 * tau ** 3
        second = (c + 3 * k3 * tau ** 2) * np.einsum("kij,kj->ki", dtau, d)
        _, _, JA = m.predict_angle_jacobian(q[s], P.values, cov[s], result.base0)
        moved = JA * second[:, None, :]                   # (n_s, 3, n): each joint's part
        sag = np.maximum(sag, np.abs(d).max(axis=0))
        each = np.maximum(each, np.linalg.norm(moved, axis=1).max(axis=0))
        whole = max(whole, float(np.linalg.norm(moved.sum(axis=2), axis=1).max()))
    return [Sag(j, float(sag[j - 1]), float(each[j - 1])) for j in joints], whole


def sag_note(result, data: Measurements) -> str | None:
    """A note when the first-order compliance leaves more than half the noise scale (per axis) at some pose of
    ``data`` (:func:`first_order_sag`); None otherwise, or without a compliance or a noise scale."""
    if result.uncertainty is None or not any(isinstance(getattr(t, "inner", t), JointCompliance)
                                             for t in result.model.terms):
        return None
    sags, leaves = first_order_sag(result, data)
    sigma = result.uncertainty.sigma
    if not sags or leaves <= 0.5 * sigma:
        return None
    worst = max(sags, key=lambda s: s.leaves_m)
    which = ", ".join(f"joint {s.joint} sags up to {s.sag_rad * 1000:.3g} mrad" for s in sags)
    return (f"{which}; the model's torques are those of the undeflected arm, which leaves up to "
            f"{leaves * 1000:.3g} mm at these poses (joint {worst.joint}: {worst.leaves_m * 1000:.3g} mm; noise "
            f"{sigma * 1000:.3g} mm per axis): a progressive spring or another cause of the joint may stand for it, "
            "and the stiffness is the one of the undeflected arm")
