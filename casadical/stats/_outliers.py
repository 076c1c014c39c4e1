"""Are the poses a robust fit set aside bad measurements, or structure the model lacks?

A robust loss weighs down the poses whose residual is far beyond the noise.
Bad measurements (a beam break, a probe knocked, a wrong row) fall on poses
that have nothing in common: any session, any time, any joint reading,
their errors in any direction. Poses that share something are not bad
data: they are where the model is wrong (one session's own gear error,
the warm-up at the start of a session, the most loaded poses of a joint
whose compliance is not modelled). Each test here asks one such question
of the set-aside poses (statsmodels style: a plain function returning a
typed result with its statistic, p-value and where):

- :func:`session_test`: are they concentrated in one session (hypergeometric
  tail of the count in each session)?
- :func:`order_test`: at the start or at the end of their sessions, in
  measurement order or in time (hypergeometric tail of the count among the
  first (last) poses, scanned over how many)?
- :func:`region_test`: in one region of a joint's reading (the same, over
  runs of bins of the reading fixed beforehand)?
- :func:`load_test`: among the poses of largest gravity torque of a joint
  (needs the link masses)?
- :func:`direction_test`: are their errors angle errors of one joint (the
  error along the direction the tool point moves when that joint turns;
  Fisher's combination of each pose's alignment, against errors of any
  direction)?

:func:`set_aside_structure` runs every test, with a Bonferroni correction
over the tests and, in a scan, over the regions scanned; a pose that no
significant structure holds is still a likely bad measurement.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from ..errors import listing
from ..runtime._chunks import pose_chunks

if TYPE_CHECKING:      # a type only: the data layer stands above the statistics
    from ..data._measurements import Measurements

#: family-wise level of the tests together: below it, set-aside poses share structure
ALPHA = 0.001
#: below this family-wise p-value (but above ALPHA) the strongest test is mentioned as a hint
HINT = 0.05
#: a pose's error is along a joint's direction when the angle between them is below this (degrees): the
#: poses a direction structure holds
ALONG_DEG = 25.0


@dataclass
class StructureTest:
    """One test of shared structure among the set-aside poses.

    Attributes
    ----------
    kind : {"session", "order", "region", "load", "direction"}
    where : str
        Where the structure lives, in words (``session s3``, ``the first 21
        poses of session A in time``, ``joint 2 from 80 to 120 deg``).
    statistic : float
        The test's statistic (a count of set-aside poses for the
        hypergeometric tests; Fisher's chi-square for the direction).
    p_value : float
        Corrected for the regions (or sessions, or harmonics) the test
        scanned; not for the other tests (:class:`SetAsideStructure` does).
    poses : ndarray of int
        The set-aside poses (indices into the data) the structure holds.
    joint : int or None
    session : str or None
    """

    kind: str
    where: str
    statistic: float
    p_value: float
    poses: np.ndarray
    joint: int | None = None
    session: str | None = None

    def to_dict(self) -> dict:
        d = {"kind": self.kind, "where": self.where, "statistic": round(float(self.statistic), 4),
             "p_value": float(f"{self.p_value:.3g}"), "poses": int(len(self.poses))}
        if self.joint is not None:
            d["joint"] = self.joint
        if self.session is not None:
            d["session"] = self.session
        return d


@dataclass
class SetAsideStructure:
    """Every test of the set-aside poses, and what they say together.

    Attributes
    ----------
    n_poses, n_set_aside : int
    tests : list of StructureTest
        Every test run, smallest p-value first.
    alpha : float
        Family-wise level over the tests (Bonferroni).
    lines : list of str
        Each set-aside pose as ``file:line`` (or line), in index order.
    index : ndarray of int
        The set-aside poses (indices into the data).
    accounted : ndarray of int
        Set-aside poses that structure found elsewhere accounts for (the largest misses of the structure the
        diagnosis' structure screen reports): never called bad measurements.
    """

    n_poses: int
    n_set_aside: int
    tests: list[StructureTest] = field(default_factory=list)
    alpha: float = ALPHA
    lines: list[str] = field(default_factory=list)
    index: np.ndarray = field(default_factory=lambda: np.zeros(0, int))
    accounted: np.ndarray = field(default_factory=lambda: np.zeros(0, int))

    @property
    def significant(self) -> list[StructureTest]:
        """The tests that find structure at the family-wise level."""
        m = max(len(self.tests), 1)
        return [t for t in self.tests if t.p_value * m < self.alpha]

    @property
    def structured(self) -> bool:
        return bool(self.significant)

    def held(self) -> np.ndarray:
        """Set-aside poses some significant structure holds (indices into the data)."""
        sig = self.significant
        return np.unique(np.concatenate([t.poses for t in sig])) if sig else np.zeros(0, int)

    def bad(self) -> np.ndarray:
        """Set-aside poses no significant structure holds (nor accounts for): the likely bad measurements."""
        return np.setdiff1d(self.index, np.union1d(self.held(), self.accounted))

    def _lines(self, poses: np.ndarray) -> list[str]:
        at = {int(i): k for k, i in enumerate(self.index)}
        return [self.lines[at[int(i)]] for i in poses if int(i) in at]

    def text(self) -> str:
        """The verdict in words: structure with where, and which poses still look like bad measurements."""
        if not self.n_set_aside:
            return ""
        sig = self.significant
        bad = self.bad()
        if len(self.accounted) and not len(bad) and not sig:
            return ""
        if len(self.accounted) and not sig:      # the rest of the set-aside poses, with nothing of their own
            return (f"the other {len(bad)} (rows " + listing(self._lines(bad), 10) + ") share no structure: "
                    "likely bad measurements")
        if self.n_set_aside < 2:
            return "likely a bad measurement (a single pose: no structure to test)"
        if not sig:
            p = min(self.tests[0].p_value * len(self.tests), 1.0) if self.tests else 1.0
            hint = f"; the strongest hint, {self.tests[0].where}, p = {p:.2g}" if p < HINT else ""
            return ("likely bad measurements (they share no session, no start or end of the measurements, no region "
                    f"of a joint or of its load, and their errors no joint's direction{hint})")
        m = len(self.tests)
        parts = [f"{t.where} ({len(t.poses)} of them, p = {max(t.p_value * m, 1e-300):.2g})" for t in sig]
        text = "not bad measurements but structure the model lacks: " + "; ".join(parts)
        if len(bad):
            text += (f"; the other {len(bad)} (rows " + listing(self._lines(bad), 10)
                     + ") share none of it: likely bad measurements")
        return text

    def to_dict(self) -> dict:
        m = max(len(self.tests), 1)
        return {"set_aside": self.n_set_aside, "poses": self.n_poses, "alpha": self.alpha,
                "structured": self.structured, "tests_run": len(self.tests),
                "structure": [{**t.to_dict(), "p_family": float(f"{min(t.p_value * m, 1.0):.3g}")}
                              for t in self.significant],
                "bad_measurements": self._lines(self.bad())}


# --- the tests ------------------------------------------------------------------------

def _tail(k: int, n_total: int, n_in: int, n_flagged: int) -> float:
    """P(at least ``k`` of ``n_flagged`` poses drawn at random fall among ``n_in`` of ``n_total``)."""
    return float(hypergeom_tail(k, n_total, n_in, n_flagged))


def hypergeom_tail(k, n_total: int, n_in, n_drawn: int) -> np.ndarray:
    """P(X >= ``k``) for X hypergeometric: ``n_drawn`` drawn from ``n_total`` of which ``n_in`` are marked
    (``k`` and ``n_in`` may be arrays). scipy.stats.hypergeom.sf(k - 1, ...) to rounding (tested), summed in
    log space with scipy.special's gammaln: importing scipy.stats costs 0.5-0.6 s, paid by every calibration
    that sets two poses aside. Every tail at once (in blocks of about a million terms): a scan asks for
    hundreds, and a call per tail cost 0.35 s of the README job's diagnosis."""
    from scipy.special import gammaln

    def log_comb(a, b):
        return gammaln(a + 1.0) - gammaln(b + 1.0) - gammaln(a - b + 1.0)

    k, n_in = np.broadcast_arrays(np.asarray(k, int), np.asarray(n_in, int))
    shape = k.shape
    k, n_in = k.ravel(), n_in.ravel()
    lo = np.maximum(np.maximum(k, 0), n_drawn - (n_total - n_in))
    hi = np.minimum(n_in, n_drawn)
    out = np.zeros(k.shape)
    some = np.flatnonzero(lo <= hi)
    if not len(some):
        return out.reshape(shape)
    total = log_comb(n_total, n_drawn)
    width = int((hi[some] - lo[some]).max()) + 1
    rows = max(1, (1 << 20) // width)
    for start in range(0, len(some), rows):
        at = some[start:start + rows]
        i = lo[at, None] + np.arange(width)
        inside = i <= hi[at, None]
        i = np.minimum(i, hi[at, None]).astype(float)   # beyond hi: a valid term, masked out below
        a = n_in[at, None].astype(float)
        terms = np.where(inside, log_comb(a, i) + log_comb(n_total - a, n_drawn - i), -np.inf)
        top = terms.max(axis=1)
        log_p = np.log(np.exp(terms - top[:, None]).sum(axis=1)) + top - total
        out[at] = np.minimum(np.exp(log_p), 1.0)
    return out.reshape(shape)


def session_test(sessions: np.ndarray, flagged: np.ndarray) -> StructureTest | None:
    """Are the set-aside poses concentrated in one session? The hypergeometric tail of the count in each
    session, Bonferroni over the sessions; None with one session."""
    names = list(dict.fromkeys(sessions.tolist()))
    if len(names) < 2:
        return None
    N, n = len(sessions), len(flagged)
    best = None
    for s in names:
        at = sessions == s
        k = int(at[flagged].sum())
        p = min(_tail(k, N, int(at.sum()), n) * len(names), 1.0)
        if best is None or p < best[0]:
            best = (p, s, k, int(at.sum()))
    p, s, k, size = best
    return StructureTest("session", f"session {s} ({k} of the {n} set-aside poses; {size} of {N} poses)", k, p,
                         flagged[sessions[flagged] == s], session=s)


def _scan(x: np.ndarray, flagged: np.ndarray, anchored: str):
    """The interval of ``x`` from its smallest value to the j-th smallest set-aside pose (``anchored="low"``), or
    from the j-th largest to its largest (``"high"``), whose count of set-aside poses is least likely by chance:
    (p corrected for the j scanned, lo, hi, the set-aside poses in it), or None.

    For each j the count is the tail of an order statistic (the j-th set-aside pose lies among the first m
    poses exactly when at least j of them do): exact, and Bonferroni over j."""
    N, n = len(x), len(flagged)
    v = np.sort(x[flagged])
    if anchored == "low":
        lo, hi = np.full(n, -np.inf), v
    else:
        lo, hi = v, np.full(n, np.inf)
    xs = np.sort(x)
    n_in = np.searchsorted(xs, hi, side="right") - np.searchsorted(xs, lo, side="left")
    k = np.searchsorted(v, hi, side="right") - np.searchsorted(v, lo, side="left")
    ok = k >= 2
    if not ok.any():
        return None
    p = np.where(ok, hypergeom_tail(k, N, n_in, n), 1.0)
    b = int(np.argmin(p))
    held = flagged[(x[flagged] >= lo[b]) & (x[flagged] <= hi[b])]
    return min(float(p[b]) * len(p), 1.0), max(lo[b], xs[0]), min(hi[b], xs[-1]), held


def order_test(data: Measurements, flagged: np.ndarray) -> list[StructureTest]:
    """Are the set-aside poses at the start or at the end of their sessions? In time (``time_s``, from each
    session's first pose) where the data have times, else in measurement order (the rows)."""
    t = data.get("time_s")
    sessions = data.sessions if data.sessions is not None else np.full(len(data), "", dtype=object)
    x = np.zeros(len(data))
    for s in dict.fromkeys(sessions.tolist()):
        at = np.flatnonzero(sessions == s)
        if t is not None:
            x[at] = t[at] - t[at].min()
        else:
            x[at] = np.argsort(np.argsort(data.rows[at], kind="stable"), kind="stable")
    several = len(set(sessions.tolist())) > 1
    out = []
    for side, first in (("low", "start"), ("high", "end")):
        scan = _scan(x, flagged, side)
        if scan is None:
            continue
        p, lo, hi, held = scan
        span = np.sum((x >= lo) & (x <= hi))
        where_s = " of each session" if several else ""
        if t is not None:
            when = (f"the first {hi:.4g} s{where_s}" if first == "start" else
                    f"after {lo:.4g} s{where_s} (the end)")
        else:
            when = (f"the first {int(hi) + 1} poses{where_s} in measurement order" if first == "start" else
                    f"the poses from the {int(lo) + 1}th on{where_s} in measurement order (the end)")
        out.append(StructureTest("order", f"the {first}: {when} ({span} poses)", len(held), p, held))
    return out


#: bins of equal pose counts a joint's range is cut into for the region test
REGION_BINS = 10


def region_test(q: np.ndarray, flagged: np.ndarray, joint: int) -> StructureTest | None:
    """Are the set-aside poses in one region of joint ``joint``'s reading (rad)?

    The readings are cut into :data:`REGION_BINS` bins of equal pose counts
    (fixed before the set-aside poses are looked at); every run of
    neighbouring bins is a region, its count of set-aside poses tested by
    the hypergeometric tail, Bonferroni over the regions."""
    if np.ptp(q) <= 0 or len(flagged) < 2:
        return None
    edges = np.quantile(q, np.linspace(0, 1, REGION_BINS + 1))
    edges[-1] = np.inf
    N, n = len(q), len(flagged)
    i, j = np.triu_indices(REGION_BINS)
    lo, hi = edges[i], edges[j + 1]
    xs = np.sort(q)
    n_in = np.searchsorted(xs, hi, side="left") - np.searchsorted(xs, lo, side="left")
    v = np.sort(q[flagged])
    k = np.searchsorted(v, hi, side="left") - np.searchsorted(v, lo, side="left")
    ok = (k >= 2) & (n_in < N)
    if not ok.any():
        return None
    p = np.where(ok, hypergeom_tail(k, N, n_in, n), 1.0)
    b = int(np.argmin(p))
    inside = (q[flagged] >= lo[b]) & (q[flagged] < hi[b])
    held = flagged[inside]
    top = float(np.max(q[(q >= lo[b]) & (q < hi[b])]))
    return StructureTest("region", f"joint {joint} from {math.degrees(lo[b]):.1f} to {math.degrees(top):.1f} deg "
                                   f"({int(n_in[b])} of {N} poses)", len(held), min(float(p[b]) * len(p), 1.0), held,
                         joint=joint)


def load_test(tau: np.ndarray, flagged: np.ndarray, joint: int) -> StructureTest | None:
    """Are the set-aside poses among those of largest gravity torque (N m) of joint ``joint``?"""
    a = np.abs(tau)
    if np.ptp(a) <= 0:
        return None
    scan = _scan(a, flagged, "high")
    if scan is None:
        return None
    p, lo, _, held = scan
    span = int(np.sum(a >= lo))
    return StructureTest("load", f"the most loaded poses of joint {joint} (gravity torque above {lo:.4g} N m: "
                                 f"{span} of {len(a)} poses)", len(held), p, held, joint=joint)


def direction_test(residuals: np.ndarray, direction: np.ndarray, flagged: np.ndarray,
                   joint: int) -> StructureTest | None:
    """Are the set-aside poses' errors angle errors of joint ``joint``?

    ``residuals`` (N, 3) of the fit; ``direction`` (N, 3): how the tool
    point moves when the joint turns. Against errors of any direction (a
    bad measurement's), the squared cosine between a pose's error and the
    direction is Beta(1/2, 1): ``p_i = 1 - |cos|``; Fisher's
    ``-2 sum ln p_i`` is chi-square with ``2 n`` degrees of freedom.
    """
    r, d = residuals[flagged], direction[flagged]
    nr, nd = np.linalg.norm(r, axis=1), np.linalg.norm(d, axis=1)
    ok = (nr > 0) & (nd > 1e-9 * max(float(nd.max(initial=0.0)), 1e-300))
    if ok.sum() < 2:
        return None
    cos = np.abs(np.einsum("ij,ij->i", r[ok], d[ok])) / (nr[ok] * nd[ok])
    p_i = np.clip(1.0 - cos, 1e-300, 1.0)
    chi2 = float(-2.0 * np.log(p_i).sum())
    from scipy import special
    p = float(special.chdtrc(2 * len(p_i), chi2))
    along = flagged[ok][cos >= math.cos(math.radians(ALONG_DEG))]
    return StructureTest("direction", f"their errors are angle errors of joint {joint} (along the tool point's "
                                      f"motion when it turns: {len(along)} of {int(ok.sum())} within "
                                      f"{ALONG_DEG:.0f} deg)", chi2, p, along, joint=joint)


def set_aside_structure(data: Measurements, set_aside: np.ndarray, residuals: np.ndarray,
                        directions: np.ndarray | None = None, torques: np.ndarray | None = None,
                        alpha: float = ALPHA) -> SetAsideStructure:
    """Every test of shared structure among the set-aside poses of ``data``.

    Parameters
    ----------
    data : Measurements
        The poses of the fit (sessions, rows, times, joint readings).
    set_aside : ndarray
        A mask, or the indices, of the poses the robust loss set aside.
    residuals : ndarray (N, 3)
        Position residuals of the fit (m).
    directions : ndarray (N, 3, n), optional
        ``d xyz / d theta_j`` of each pose: how the tool point moves when
        each joint turns (the direction tests).
    torques : ndarray (N, n), optional
        Gravity torques of the poses (N m); None when the robot file gives
        no masses (no load test).
    alpha : float
        Family-wise level over every test run.
    """
    idx = np.flatnonzero(set_aside) if np.asarray(set_aside).dtype == bool else np.sort(np.asarray(set_aside, int))
    lines = [f"{data.file(i)}:{data.line(i)}" if data.sources is not None else str(data.line(i)) for i in idx]
    out = SetAsideStructure(len(data), len(idx), alpha=alpha, lines=lines, index=idx)
    if len(idx) < 2:
        return out
    tests: list[StructureTest | None] = []
    if data.sessions is not None:
        tests.append(session_test(data.sessions, idx))
    tests += order_test(data, idx)
    q = data.q
    for j in range(1, data.n_joints + 1):
        tests.append(region_test(q[:, j - 1], idx, j))
        if torques is not None:
            tests.append(load_test(torques[:, j - 1], idx, j))
        if directions is not None:
            tests.append(direction_test(residuals, directions[:, :, j - 1], idx, j))
    out.tests = sorted((t for t in tests if t is not None), key=lambda t: t.p_value)
    return out


def of_fit(result, data: Measurements, set_aside: np.ndarray | None = None,
           alpha: float = ALPHA) -> SetAsideStructure:
    """:func:`set_aside_structure` of a fitted :class:`~casadical.result.CalibrationResult` on its data: its
    set-aside poses (``result.downweighted``, or ``set_aside``), its residuals, directions and gravity torques
    (none when the robot file gives no masses and the data no payload)."""
    if set_aside is None:
        keys = {(d.get("file"), d["line"]) for d in result.downweighted}
        files = data.sources if data.sources is not None else np.full(len(data), None, dtype=object)
        set_aside = np.array([(f if data.sources is not None else None, int(ln)) in keys
                              for f, ln in zip(files, data.lines)], dtype=bool)
    return of_model(result.model, result.parameters.values, result.base0, data, set_aside, alpha=alpha)


def of_model(model, values: np.ndarray, base0: np.ndarray, data: Measurements, set_aside: np.ndarray,
             cov: np.ndarray | None = None, alpha: float = ALPHA) -> SetAsideStructure:
    """:func:`set_aside_structure` of a model (:class:`~casadical.model._symbolic.Model`) at ``values`` on ``data``:
    its residuals, the directions of its joints' angles and its gravity torques (none when every torque is
    zero: the robot file gives no masses and the data no payload)."""
    if not np.any(set_aside):
        return SetAsideStructure(len(data), 0, alpha=alpha)
    cov = model.covariates(data) if cov is None else cov
    # the residuals and directions of the set-aside poses alone (the only ones the tests read); every pose's torque
    idx = np.flatnonzero(set_aside) if np.asarray(set_aside).dtype == bool else np.sort(np.asarray(set_aside, int))
    q = data.q
    residuals, directions = np.zeros((len(data), 3)), np.zeros((len(data), 3, data.n_joints))
    xyz, _, directions[idx] = model.predict_angle_jacobian(q[idx], values, cov[idx], base0)
    residuals[idx] = data.xyz[idx] - xyz
    tau = np.concatenate([model.torques(q[s], values, cov[s]) for s in pose_chunks(len(data))])
    return set_aside_structure(data, idx, residuals, directions, tau if np.any(np.abs(tau) > 0) else None, alpha)
