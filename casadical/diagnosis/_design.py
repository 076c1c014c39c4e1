"""Is the design of the calibration poses weak, and what question can its folds answer?

A design is weak when it gives the geometry little to go on:

- **few poses**: fewer than :data:`WEAK_EQUATIONS` measured coordinates per free parameter of the kinematic
  model (24 positions for 31 parameters: 2.3);
- **one joint at a time**: most poses (:data:`ONE_AT_A_TIME` of them) differ from a common pose, or from the
  pose before, in one joint only;
- **correlations near 1**: two parameters of the kinematic fit correlated beyond :data:`NEAR_ONE`.

On such a design a fold that leaves out part of a joint's sweep leaves that joint's parameters to a
handful of poses or to none, and a fold refitted on them measures the design, not the geometry: a
kinematic step that predicts the validation poses three times better than the nominal model was
rejected as "does not drop where it must extrapolate" (issue 25). The folds of a weak design therefore
ask what it can answer: every parameter of the geometry (links and tool; the base pose is never known)
has a prior at its nominal value with its nominal tolerance (its scale: 1 mm, 1 mrad), so that what a
fold's training poses cannot tell stays at what was known before them
(:func:`casadical.diagnosis._validation.linear_cv`), as for the nominal model it is compared with. On a
design that is not weak the prior changes nothing that matters and is not applied.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..data._measurements import Measurements
from ..data._poses import first_rows, pose_index
from ..result import CalibrationResult
from ..terms._geometric import Geometric

#: fewer measured coordinates than this per free parameter of the kinematic model make a weak design
WEAK_EQUATIONS = 5.0
#: this share of the poses moving one joint only (from a common pose or from the pose before): one joint at a time
ONE_AT_A_TIME = 0.5
#: a correlation beyond this (absolute) between two parameters of the kinematic fit: near 1
NEAR_ONE = 0.999
#: joint readings closer than this (deg) are the same
SAME_DEG = 1e-3


@dataclass
class Design:
    """What makes a design of calibration poses weak (nothing: not weak).

    Attributes
    ----------
    equations_per_parameter : float
        Measured coordinates per free parameter of the kinematic fit.
    one_joint_share : float
        Share of the poses that move one joint only, from a common pose or from the pose before.
    moving : ndarray of int
        The joint each calibration pose moves (:func:`moving_joint`), in the order of the poses.
    correlated : list of (str, str, float)
        Pairs of parameters of the kinematic fit correlated beyond :data:`NEAR_ONE`.
    reasons : list of str
        Each weakness in words.
    """

    equations_per_parameter: float
    one_joint_share: float
    moving: np.ndarray
    correlated: list[tuple[str, str, float]] = field(default_factory=list)
    reasons: list[str] = field(default_factory=list)

    @property
    def weak(self) -> bool:
        return bool(self.reasons)

    @property
    def one_at_a_time(self) -> bool:
        return self.one_joint_share >= ONE_AT_A_TIME

    def text(self) -> str:
        """The note of the report."""
        return ("the design of the calibration poses is weak: " + "; ".join(self.reasons)
                + ". The folds ask what it can answer: "
                + ("each leaves out part of every joint's sweep, never a whole one (time blocks within each "
                   "sweep, joint-range blocks of the joint's own sweep); " if self.one_at_a_time else "")
                + "each parameter of the geometry stays at its nominal value within its nominal tolerance (1 mm, "
                "1 mrad) where a fold's training poses cannot tell it. More poses, moving several joints at once "
                "over their ranges, would tell more (casadical plan-poses)")


def moving_joint(q_deg: np.ndarray) -> tuple[float, np.ndarray]:
    """Which joint each pose moves, in a design of one joint at a time.

    Returns the share of the poses that differ in one joint at most from a common pose (each joint's most
    frequent reading) or, if more do, from the pose before them (``q_deg`` in the measurement order), and for
    each pose that joint (1-based; 0: none, the common pose or a repeat; -1: several).
    """
    if len(q_deg) < 2:
        return 0.0, np.full(len(q_deg), -1)
    q = np.round(np.asarray(q_deg, float) / SAME_DEG) * SAME_DEG
    common = np.empty(q.shape[1])
    for j in range(q.shape[1]):
        values, counts = np.unique(q[:, j], return_counts=True)
        common[j] = values[np.argmax(counts)]
    out = []
    for moved in (np.abs(q - common) > SAME_DEG, np.r_[np.ones((1, q.shape[1]), bool),
                                                         np.abs(np.diff(q, axis=0)) > SAME_DEG]):
        n = moved.sum(axis=1)
        out.append((float(np.mean(n <= 1)), np.where(n == 1, np.argmax(moved, axis=1) + 1, np.where(n == 0, 0, -1))))
    return max(out, key=lambda t: t[0])


def moving_of(data: Measurements) -> tuple[float, np.ndarray]:
    """:func:`moving_joint` of the poses of ``data`` in the measurement order, a pose measured at several tool
    points (or again) once (:func:`casadical.data._poses.pose_index`); the joint each row's pose moves."""
    pose = pose_index(data.q, data.sessions)
    first = first_rows(pose)
    order = first[np.argsort(data.rows[first], kind="stable")]
    share, moving_ordered = moving_joint(data.q_deg[order])
    moving = np.empty(len(first), dtype=moving_ordered.dtype)
    moving[pose[order]] = moving_ordered
    return share, moving[pose]


def assess(cal: Measurements, kinematic: CalibrationResult, n_equations: int) -> Design:
    """How weak the design of ``cal`` is for the geometry (``kinematic``: its kinematic fit, on ``n_equations``
    measured coordinates)."""
    p = int(kinematic.parameters.free.sum())
    per = n_equations / max(p, 1)
    share, moving = moving_of(cal)
    poses = int(pose_index(cal.q, cal.sessions).max(initial=-1)) + 1
    unc = kinematic.uncertainty
    pairs = unc.strong_pairs(NEAR_ONE) if unc is not None else []
    reasons = []
    if per < WEAK_EQUATIONS:
        reasons.append(f"{poses} poses give {per:.1f} measured coordinates per free parameter of the kinematic "
                       f"model ({n_equations} for {p}; {WEAK_EQUATIONS:g} or more make a design that can tell them)")
    if share >= ONE_AT_A_TIME:
        reasons.append(f"{share:.0%} of the poses move one joint only (from a common pose or from the pose before)")
    if pairs:
        shown = ", ".join(f"{a}~{b} ({c:+.4f})" for a, b, c in pairs[:4])
        reasons.append(f"{len(pairs)} pair(s) of parameters correlated near 1 in the kinematic fit: {shown}"
                       + (" and more" if len(pairs) > 4 else ""))
    return Design(per, share, moving, pairs, reasons)


def priors(kinematic: CalibrationResult) -> dict[str, float]:
    """The precision of each geometric parameter's prior (at nominal, its scale the tolerance) in the units of a
    fold's normal equations: the noise variance of the fit (m^2) per scaled unit squared. The base pose has none."""
    sigma = kinematic.loss.sigma
    if not math.isfinite(sigma):
        sigma = kinematic.calibration.rms_mm / 1000 / math.sqrt(3)
    return {p.name: sigma ** 2 for p in kinematic.parameters
            if p.term == Geometric.name and p.group != "base" and not p.fixed}
