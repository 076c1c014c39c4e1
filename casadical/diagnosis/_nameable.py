"""Can a cause be named? The checks a candidate passes beyond the statistics, by its kind.

- a function of a joint's reading (periodic error, encoder scale; a
  coupling: of its source joint's reading) is the same over the lower and
  the upper half of that joint's range, and a
  periodic error is resolved from its neighbouring harmonics and from the
  geometry (:mod:`._periodic`);
- a drift (a velocity) is the same over the first and the second half of
  the measurement time;
- a warm-up (an offset that dies away) is told from a drift: the data
  prefer its decay to a straight line in time by the same likelihood ratio
  a harmonic must win over its neighbours by (:data:`._periodic.NEIGHBOUR_MARGIN`);
- a progressive spring's cubic part is told from a periodic error of the
  same joint: the data prefer it to every harmonic of the joint the round
  screens by that likelihood ratio (over a joint's range a harmonic and the
  cubic of a load that follows the reading can fit the same residual; where
  the poses cannot tell, neither linear from progressive is named, and the
  structure is reported as the joint's unexplained structure).

A cause of one session is checked on that session's poses.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..data._measurements import Measurements
from ._candidates import Candidate
from ._periodic import NEIGHBOUR_MARGIN, halves, resolution
from ._screening import LinearFit, Screen


def unjudged(cand: Candidate) -> set[str]:
    """The kinds of fold that cannot judge ``cand``: the session folds a cause of one session (no other session
    has it), the time folds a warm-up (no later pose shows the start); :func:`._validation.linear_cv` switches
    such a cause off where it leaves out the poses that determine it, and its acceptance does not ask those
    folds."""
    return ({"session"} if cand.session is not None else set()) | set(cand.kind.unjudged_folds)


@dataclass
class VersusDrift:
    """How much better a warm-up's decay fits than a drift of the same session.

    Attributes
    ----------
    margin : float
        Drop of the weighted residual sum of squares by the warm-up minus
        the drop by the drift, over the residual variance (twice the
        log-likelihood ratio); infinite when a drift is in the model already.
    """

    margin: float

    @property
    def resolved(self) -> bool:
        return self.margin >= NEIGHBOUR_MARGIN

    def to_dict(self) -> dict:
        return {"margin_vs_drift": round(self.margin, 3) if np.isfinite(self.margin) else None,
                "resolved": self.resolved}

    def text(self) -> str:
        if self.resolved:
            return ("told from a drift (its decay preferred to a straight line in time by a likelihood ratio of "
                    f"{np.exp(min(self.margin, 1400) / 2):.3g})" if np.isfinite(self.margin) else
                    "beyond the drift already in the model")
        return "not told from a drift: a straight line in time fits these poses about as well"


def versus_drift(screen: Screen, cand: Candidate) -> VersusDrift:
    """A warm-up against a drift of the same scope (a translation growing in time), both beyond the current
    model; infinite margin when the model holds that drift already."""
    if any(a.cause == cand.kind.rival and a.session == cand.session for a in screen.accepted):
        return VersusDrift(np.inf)
    t = screen.cal.get("time_s")
    at = np.ones(len(t)) if cand.session is None else (screen.cal.sessions == cand.session).astype(float)
    drift = np.einsum("i,jk->ijk", t * at, np.eye(3))          # (N, 3, 3): d xyz / d (v_x, v_y, v_z)
    drop, sigma2 = drops(screen)
    return VersusDrift((drop(screen.J[:, :, screen.columns(cand)]) - drop(drift)) / max(sigma2, 1e-300))


@dataclass
class VersusHarmonics:
    """How much better a progressive spring's cubic part fits than the best harmonic of the same joint's angle.

    Attributes
    ----------
    margin : float
        Drop of the weighted residual sum of squares by the cubic part minus
        the drop by the best harmonic screened, over the residual variance.
    harmonic : int or None
        That harmonic (None: none screened).
    """

    margin: float
    harmonic: int | None

    @property
    def resolved(self) -> bool:
        return self.margin >= NEIGHBOUR_MARGIN

    def to_dict(self) -> dict:
        return {"margin_vs_harmonic": round(self.margin, 3) if np.isfinite(self.margin) else None,
                "harmonic": self.harmonic, "resolved": self.resolved}

    def text(self) -> str:
        if self.resolved:
            return ("told from a periodic error of the joint" + (f" (preferred to harmonic {self.harmonic} by a "
                    f"likelihood ratio of {np.exp(min(self.margin, 1400) / 2):.3g})" if self.harmonic else ""))
        return (f"these poses cannot tell a progressive spring from harmonic {self.harmonic} of the joint's angle "
                "(it fits about as well or better): linear or progressive is not told, and not named")


def drops(screen: Screen):
    """``drop(C)``: the weighted residual sum of squares columns ``C`` (N, 3, k) remove beyond the current
    model, and the residual variance."""
    sw, Q, r_perp = screen.projection()     # the round's basis, made once per linearisation
    sigma2 = float(r_perp @ r_perp) / max(len(r_perp) - Q.shape[1], 1)

    def drop(C: np.ndarray) -> float:
        C = C.reshape(len(sw), -1) * sw[:, None]
        U, sv, _ = np.linalg.svd(C - Q @ (Q.T @ C), full_matrices=False)
        keep = sv > 1e-9 * max(float(np.linalg.norm(C)), 1e-300)
        proj = U[:, keep].T @ r_perp
        return float(proj @ proj)

    return drop, sigma2


def versus_harmonics(screen: Screen, cand: Candidate) -> VersusHarmonics:
    """A progressive spring's cubic part against every harmonic of its joint the round screens (same scope)."""
    drop, sigma2 = drops(screen)
    mine = drop(screen.J[:, :, screen.columns(cand)])
    best, h = -np.inf, None
    for c, cols in screen.cols_of.items():
        if c.harmonic is not None and c.joint == cand.joint and c.session == cand.session:
            d = drop(screen.J[:, :, cols])
            if d > best:
                best, h = d, c.harmonic
    return VersusHarmonics((mine - best) / max(sigma2, 1e-300) if h is not None else np.inf, h)


def cause_checks(scr: Screen, fit: LinearFit, cand: Candidate, cal: Measurements, alpha: float) -> dict:
    """The checks of :mod:`this module <.nameable>` its cause asks of a candidate fitted by one step
    (:attr:`~casadical.terms._cause.Cause.checks`): ``{"reasons": [...]}`` (empty when it passes) with ``halves``,
    ``resolution``, ``versus_drift`` or ``versus_harmonics`` as they apply; ``{}`` for a cause without checks.

    A function of a joint's reading (``reading_halves``: the cause's :meth:`~casadical.terms._cause.Cause.reading`)
    is the same over either half of that joint's range: compliance, progressive stiffness and backlash follow the
    load, not the reading; on real data their half-range estimates are biased by the structure still unmodelled in
    each half, so the test is not applied to them."""
    asked = cand.kind.checks
    if not asked:
        return {}
    out: dict = {"reasons": []}
    if "versus_harmonics" in asked:
        vh = out["versus_harmonics"] = versus_harmonics(scr, cand)
        if not vh.resolved:
            out["reasons"].append(vh.text())
        return out
    if "versus_drift" in asked:
        vd = out["versus_drift"] = versus_drift(scr, cand)
        if not vd.resolved:
            out["reasons"].append(vd.text())
        return out
    params = [scr.params[n] for n in cand.parameter_names() if n in fit.lin.names]
    if "time_halves" in asked:
        hv = out["halves"] = halves(fit, params, cal, None, alpha, cand.session)
        if not hv[0].agree:
            out["reasons"].append("the first and second half in time differ: " + hv[0].text())
        return out
    # a coupling is a straight line in its source joint's reading: the same slope over either half of that range
    reading = cand.kind.reading(cand)
    hv = out["halves"] = halves(fit, params, cal, reading, alpha, cand.session)
    if "resolution" in asked:
        rs = out["resolution"] = resolution(scr, cand.joint, cand.harmonic, cand.session)
        if not rs.resolved:
            out["reasons"].append(rs.text())
    if not hv[0].agree:
        whose = f"joint {reading}'s" if reading != cand.joint else "the joint's"
        out["reasons"].append(f"the halves of {whose} range differ: " + hv[0].text())
    return out
