"""Can a periodic error be named? Resolution against neighbours and geometry, stability over halves.

A sine of harmonic ``h`` of a joint's reading is a gear (transmission)
error only if the data can tell it apart:

- from its neighbours ``h - 1`` and ``h + 1``: over a joint range of R
  degrees two harmonics drift apart by ``R / 360`` cycles per unit of
  ``h``, and over a short range they fit much the same residual. The data
  resolve ``h`` when they prefer it to each neighbour by a likelihood
  ratio of at least 100 (the drop of the weighted residual sum of squares,
  in units of the residual variance, exceeds ``2 ln 100``): a strong,
  clean gear error is resolved over a short range, a weak one only over a
  long one;
- from geometry: a low harmonic over a short range is a smooth curve that
  the link parameters (offset, scale) reproduce; at least half of its
  columns must lie outside what the current model spans;
- and its amplitude and phase must agree when fitted on the lower and the
  upper half of the joint's range (a gear is the same over the whole
  turn; a flexible fit of session structure is not). The halves in time
  are reported beside them.

What does not pass is not named as a gear: the diagnosis reports it as
``unexplained`` structure, with where it lives and its size.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import special

from ..data._measurements import Measurements
from ..parameters import READING, Parameter
from ..terms._periodic import phase
from ._screening import LinearFit, Screen, periodic_columns

#: the data must prefer a harmonic to each neighbour by this log-likelihood-ratio (x2): 2 ln 100
NEIGHBOUR_MARGIN = 2 * math.log(100.0)
#: at least this fraction of a harmonic's column must lie outside the current model's span
OUTSIDE_GEOMETRY = 0.5
#: neighbours looked at on each side, at most, for the band of harmonics not told apart
MAX_BAND = 5


@dataclass
class Resolution:
    """How well the data resolve harmonic ``h`` of joint ``j``.

    Attributes
    ----------
    outside_geometry : float
        Fraction (0..1) of the harmonic's columns not reproduced by the current model.
    neighbour_margin : float
        How much better ``h`` fits than its better neighbour: drop of the
        weighted residual sum of squares over the residual variance
        (twice the log-likelihood ratio).
    band : (int, int)
        The harmonics the data cannot tell from ``h``.
    range_deg : float
        The joint's range in the data.
    """

    outside_geometry: float
    neighbour_margin: float
    band: tuple[int, int]
    range_deg: float
    #: a linear axis' travel in the data (mm; its ``range_deg`` is 360 per metre); None: a revolute joint
    range_mm: float | None = None

    @property
    def covered(self) -> str:
        """``the 118 deg the joint covers``, ``the 3800 mm the axis covers``."""
        if self.range_mm is not None:
            return f"the {self.range_mm:.0f} mm the axis covers"
        return f"the {self.range_deg:.0f} deg the joint covers"

    @property
    def resolved(self) -> bool:
        return self.outside_geometry >= OUTSIDE_GEOMETRY and self.neighbour_margin >= NEIGHBOUR_MARGIN

    def to_dict(self) -> dict:
        return {"outside_geometry": round(self.outside_geometry, 4),
                "neighbour_margin": round(self.neighbour_margin, 3),
                "band": list(self.band), "range_deg": round(self.range_deg, 2), "resolved": self.resolved,
                **({"range_mm": round(self.range_mm, 1)} if self.range_mm is not None else {})}

    def text(self) -> str:
        lo, hi = self.band
        if self.resolved:
            return (f"resolved over {self.covered} (preferred to its neighbours by "
                    f"a likelihood ratio of {math.exp(min(self.neighbour_margin, 1400) / 2):.3g})")
        why = []
        if self.outside_geometry < OUTSIDE_GEOMETRY:
            why.append(f"only {100 * self.outside_geometry:.0f}% of it lies outside what the geometry "
                       "already fits")
        if self.neighbour_margin < NEIGHBOUR_MARGIN:
            why.append(f"harmonics {lo}..{hi} fit about as well over {self.covered}")
        return "not resolved: " + "; ".join(why)


def resolution(screen: Screen, joint: int, harmonic: int, session: str | None = None) -> Resolution:
    """Resolution of harmonic ``harmonic`` of ``joint`` in the round's data, given the current model (of one
    session's own error: over that session's poses)."""
    at = np.ones(len(screen.w)) if session is None else (screen.cal.sessions == session).astype(float)
    sw, Q, r_perp = screen.projection()
    sigma2 = float(r_perp @ r_perp) / max(len(r_perp) - Q.shape[1], 1)
    direction = screen.angle_dir[joint] * at[:, None]
    q = phase(screen.model.robot, joint, screen.cal.q[:, joint - 1])     # 2 pi per metre on a linear axis

    def drop(h: int) -> float:
        C = periodic_columns(direction, q, h).reshape(-1, 2) * sw[:, None]
        U, sv, _ = np.linalg.svd(C - Q @ (Q.T @ C), full_matrices=False)
        keep = sv > 1e-9 * max(np.linalg.norm(C), 1e-300)
        proj = U[:, keep].T @ r_perp
        return float(proj @ proj)

    C = periodic_columns(direction, q, harmonic).reshape(-1, 2) * sw[:, None]
    outside = float(np.linalg.norm(C - Q @ (Q.T @ C)) / max(np.linalg.norm(C), 1e-300))
    d0 = drop(harmonic)

    def margin(h: int) -> float:
        return (d0 - drop(h)) / max(sigma2, 1e-300)

    neighbours = [h for h in (harmonic - 1, harmonic + 1) if h >= 1]
    lo = hi = harmonic
    while lo - 1 >= 1 and harmonic - lo < MAX_BAND and margin(lo - 1) < NEIGHBOUR_MARGIN:
        lo -= 1
    while hi - harmonic < MAX_BAND and margin(hi + 1) < NEIGHBOUR_MARGIN:
        hi += 1
    linear = screen.model.robot.joints[joint - 1].prismatic
    return Resolution(outside, min(margin(h) for h in neighbours), (lo, hi), float(np.degrees(np.ptp(q[at > 0]))),
                      float(np.ptp(screen.cal.q[at > 0, joint - 1]) * 1000) if linear else None)


@dataclass
class Halves:
    """A periodic term fitted on two disjoint halves of the data.

    Attributes
    ----------
    split : str
        ``joint`` (lower and upper half of the joint's readings) or ``time``
        (first and second half of the measurement order).
    amplitude_arcsec, phase_deg : (float, float)
        On each half.
    chi2 : float
        Of the difference of the two (s, c) estimates against their
        standard errors (2 degrees of freedom).
    agree : bool
        ``chi2`` below the chi-square(2) quantile at ``1 - alpha`` (``limit``): the two halves' estimates
        cannot be told apart within their errors (whatever their signs).
    limit : float
        That quantile.
    decides : bool
        This split is the one the acceptance tests (the joint's range for a function of a joint's reading,
        time for a drift); the other is reported only.
    """

    split: str
    amplitude_arcsec: tuple[float, float]
    phase_deg: tuple[float, float]
    chi2: float
    agree: bool
    unit: str = ""     # a one-parameter term: its value on each half, in this unit
    #: a linear axis' periodic error: its amplitudes in mm (``amplitude_arcsec`` holds them), with their phases
    linear: bool = False
    limit: float = math.nan
    decides: bool = True

    def to_dict(self) -> dict:
        test = {"chi2": round(self.chi2, 3), "agree": self.agree, "chi2_limit": round(self.limit, 3),
                "decides": self.decides}
        if self.linear:
            return {"split": self.split, "amplitude_mm": [round(a, 5) for a in self.amplitude_arcsec],
                    "phase_deg": [round(a, 2) for a in self.phase_deg], **test}
        if self.unit:
            return {"split": self.split, "values": list(self.amplitude_arcsec), "unit": self.unit, **test}
        return {"split": self.split, "amplitude_arcsec": [round(a, 3) for a in self.amplitude_arcsec],
                "phase_deg": [round(a, 2) for a in self.phase_deg], **test}

    def text(self) -> str:
        what = "lower / upper half of the joint's range" if self.split == "joint" else "first / second half in time"
        a, b = self.amplitude_arcsec
        pa, pb = self.phase_deg
        unit, factor = READING.get(self.unit, (self.unit, 1.0))      # a relative scale in ppm, not "1"
        values = (f"{a:.3g} / {b:.3g} mm, phase {pa:.0f} / {pb:.0f} deg" if self.linear else
                  f"{a * factor:.4g} / {b * factor:.4g} {unit}" if self.unit else
                  f"{a:.1f} / {b:.1f} arcsec, phase {pa:.0f} / {pb:.0f} deg")
        return f"{what}: {values} ({verdict(self.agree, self.chi2, self.limit, self.decides)})"


def verdict(agree: bool, chi2: float, limit: float, decides: bool = True) -> str:
    """The halves' test in words: "the same within their errors" says what the test can say (their difference
    is below what their standard errors allow; two uncertain halves may even differ in sign), never "agree"; a
    split the acceptance does not test is "reported only"."""
    than = f" {limit:.1f}" if math.isfinite(limit) else " the limit"
    words = (f"the same within their errors, chi2 = {chi2:.1f} below{than}" if agree else
             f"differ, chi2 = {chi2:.1f} above{than}")
    return words + ("" if decides else "; reported only, the acceptance tests the halves of the range")


def halves(fit: LinearFit, params: list[Parameter], data: Measurements, joint: int | None,
           alpha: float, session: str | None = None) -> list[Halves]:
    """A term fitted on the joint's range halves and on the time halves (only the latter without a joint).

    ``params`` are the term's parameters: ``(s, c)`` of a periodic error
    (amplitude and phase are reported) or others (the first one's value in
    display units is reported as the "amplitude", phase 0). Each half is
    refitted by one Gauss-Newton step from ``fit``. A term of one
    ``session``: the halves of that session's poses.
    """
    lin = fit.lin
    names = [p.name for p in params]
    cols = [lin.names.index(n) for n in names]
    base = np.array([fit.values[n] for n in names])
    within = np.arange(len(data)) if session is None else np.flatnonzero(data.sessions == session)
    others = np.setdiff1d(np.arange(len(data)), within)
    order_t = within[np.argsort(data.rows[within], kind="stable")]
    splits = [("time", order_t)]
    if joint is not None:
        splits.insert(0, ("joint", within[np.argsort(data.q[within, joint - 1], kind="stable")]))
    n = len(order_t)
    crit = float(special.chdtri(len(names), alpha))  # chi-square quantile at 1 - alpha
    out = []
    for split, order in splits:
        est, cov = [], []
        for rows in (order[: n // 2], order[n // 2:]):
            # (a session's own term: the other sessions' poses with each half, for what the robot shares)
            d, C = lin.refit(np.sort(np.concatenate([others, rows])), rel=0.0)
            s = lin.scale[cols]
            est.append(base + s * d[cols])
            cov.append(C[np.ix_(cols, cols)] * np.outer(s, s))
        diff = est[0] - est[1]
        chi2 = float(diff @ np.linalg.solve(cov[0] + cov[1], diff))
        linear = len(names) == 2 and params[0].unit == "m"     # a linear axis' periodic error (m)
        if len(names) == 2:
            amp = tuple(math.hypot(*e) * (1000.0 if linear else math.degrees(1.0) * 3600) for e in est)
            ph = tuple(math.degrees(math.atan2(e[1], e[0])) for e in est)
            unit = ""
        else:
            amp, ph, unit = tuple(float(params[0].to_display(e[0])) for e in est), (0.0, 0.0), params[0].display_unit
        out.append(Halves(split, amp, ph, chi2, chi2 < crit, unit, linear, crit, decides=not out))
    return out
