"""What a calibration saw, and whether new poses lie outside it.

A calibrated model is trustworthy where it was fitted. :class:`Coverage`
keeps the joint ranges of the calibration poses and a sample of the poses
themselves; :meth:`Coverage.outside` names the poses of another data set
that lie beyond those ranges or far from every calibration pose, so that
``predict`` and ``compensate`` can say when they extrapolate.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np

from ..errors import ExtrapolationWarning, listing
from ..runtime._kept import Kept, array_key

#: calibration poses kept for the distance check (a subsample of larger sets)
MAX_SAMPLE = 2000


@dataclass
class Coverage:
    """Joint ranges and poses of a calibration's data (degrees).

    Attributes
    ----------
    q_min_deg, q_max_deg : ndarray, shape (n,)
        Range of each joint reading in the calibration poses.
    poses_deg : ndarray, shape (k, n)
        The calibration poses (a subsample of at most ``MAX_SAMPLE``).
    spacing_deg : float
        Median distance (joint space, degrees) from a calibration pose to
        its nearest neighbour: the density of the calibration poses.
    """

    q_min_deg: np.ndarray
    q_max_deg: np.ndarray
    poses_deg: np.ndarray
    spacing_deg: float
    #: each joint's unit in the messages (``deg``; ``mm`` for a linear axis, whose readings the fields hold in mm
    #: whatever their ``_deg``); None: every joint ``deg``. Not in the file: its robot says it.
    units: tuple[str, ...] | None = None

    def unit(self, j: int) -> str:
        """Joint ``j``'s unit (0-based)."""
        return "deg" if self.units is None else self.units[j]

    @classmethod
    def of(cls, q_deg: np.ndarray, seed: int = 0, units=None) -> "Coverage":
        q = np.atleast_2d(np.asarray(q_deg, float))
        sample = q if len(q) <= MAX_SAMPLE else q[np.random.default_rng(seed).choice(len(q), MAX_SAMPLE,
                                                                                     replace=False)]
        return cls(q.min(axis=0), q.max(axis=0), sample, _spacing(sample), None if units is None else tuple(units))

    def to_dict(self) -> dict:
        return {"q_min_deg": self.q_min_deg.tolist(), "q_max_deg": self.q_max_deg.tolist(),
                "spacing_deg": self.spacing_deg, "poses_deg": np.round(self.poses_deg, 6).tolist()}

    @classmethod
    def from_dict(cls, d: dict, units=None) -> "Coverage":
        poses = np.asarray(d["poses_deg"], float)
        lo, hi = np.asarray(d["q_min_deg"], float), np.asarray(d["q_max_deg"], float)
        if poses.ndim != 2 or poses.shape[1] != len(lo) or len(hi) != len(lo) or not (
                np.isfinite(poses).all() and np.isfinite(lo).all() and np.isfinite(hi).all()):
            raise ValueError("coverage: inconsistent or non-finite joint ranges and poses")
        return cls(lo, hi, poses, float(d["spacing_deg"]),
                   None if units is None or len(units) != len(lo) else tuple(units))

    def outside(self, q_deg: np.ndarray, far_factor: float = 4.0) -> tuple[np.ndarray, np.ndarray]:
        """Which poses extrapolate.

        Returns
        -------
        beyond : ndarray of bool, shape (N, n)
            Joint readings outside the calibration's range of that joint.
        far : ndarray of bool, shape (N,)
            Poses farther from every calibration pose than ``far_factor``
            times the calibration poses' own spacing (and 10 degrees).
        """
        q = np.atleast_2d(np.asarray(q_deg, float))
        tol = 1e-6
        beyond = (q < self.q_min_deg - tol) | (q > self.q_max_deg + tol)
        far = (_nearest(q, self.poses_deg) > self.far_limit_deg(far_factor) if len(self.poses_deg)
               else np.zeros(len(q), bool))
        return beyond, far

    def far_limit_deg(self, far_factor: float = 4.0) -> float:
        """Distance in joint space (deg) beyond which a pose is far from every calibration pose."""
        return max(far_factor * self.spacing_deg, 10.0)

    def warn(self, q_deg: np.ndarray, lines: np.ndarray, file: str) -> None:
        """Issue :meth:`describe`'s lines as :class:`ExtrapolationWarning`."""
        for text in self.describe(q_deg, lines, file):
            warnings.warn(text, ExtrapolationWarning, stacklevel=3)

    def describe(self, q_deg: np.ndarray, lines: np.ndarray, file: str) -> list[str]:
        """Warnings (one line each) for poses that extrapolate; empty if none does."""
        beyond, far = self.outside(q_deg)
        out = []
        if beyond.any():
            rows = np.flatnonzero(beyond.any(axis=1))
            joints = sorted({int(j) + 1 for j in np.flatnonzero(beyond.any(axis=0))})
            out.append(f"{file}: {len(rows)} pose(s) (rows {listing(lines[rows].tolist())}) have joint readings "
                       "outside "
                       f"the ranges the calibration saw (joints {', '.join(map(str, joints))}: "
                       + "; ".join(f"q{j} {self.q_min_deg[j - 1]:.1f}..{self.q_max_deg[j - 1]:.1f} {self.unit(j - 1)}"
                                   for j in joints)
                       + "): the model extrapolates there")
        only_far = far & ~beyond.any(axis=1)
        if only_far.any():
            rows = np.flatnonzero(only_far)
            out.append(f"{file}: {len(rows)} pose(s) (rows {listing(lines[rows].tolist())}) lie far from every "
                       f"calibration pose (more than {self.far_limit_deg():.0f} deg away in joint space"
                       + (", a linear axis' mm counted as deg" if "mm" in (self.units or ()) else "") + "): "
                       "the model interpolates over a gap there")
        return out


#: the last few spacings, by the sample's bytes: every fit of a diagnosis is of the same calibration poses (the
#: 2,000-pose job: 13 fits, 35 ms each)
_SPACINGS = Kept(4)


def _spacing(sample: np.ndarray) -> float:
    """Median distance from a pose of ``sample`` to its nearest other pose (0 for one pose)."""
    if len(sample) <= 1:
        return 0.0
    key = array_key(sample)
    got = _SPACINGS.get(key)
    if got is None:
        got = float(np.median(_nearest(sample, sample, exclude_self=True)))
        _SPACINGS.put(key, got)
    return got


def _nearest(a: np.ndarray, b: np.ndarray, exclude_self: bool = False, block: int = 2048) -> np.ndarray:
    """Distance from each row of ``a`` to its nearest row of ``b`` (chunked)."""
    out = np.empty(len(a))
    b2 = np.sum(b * b, axis=1)
    for s in range(0, len(a), block):
        x = a[s:s + block]
        d2 = np.sum(x * x, axis=1)[:, None] + b2[None, :] - 2 * x @ b.T
        if exclude_self:
            d2[np.arange(len(x)), np.arange(s, s + len(x))] = np.inf
        out[s:s + block] = np.sqrt(np.maximum(d2.min(axis=1), 0.0))
    return out
