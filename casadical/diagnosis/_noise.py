"""The instrument's noise floor, and what the final model leaves in its units.

Where the user states the instrument's noise (``diagnose --noise-mm SIGMA``, per axis, 1 sigma) or the data
hold repeated poses (readings equal to :data:`REPEAT_DEG`, rounded, in one session: the scatter of their
measured points is the instrument's and the robot's repeatability, nothing a model can take), the report says
what the final model leaves on the validation poses in units of that noise, and when it is well above it
(:data:`WELL_ABOVE`): structure no term of the model holds.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..data import Measurements
from ..terms._tool_points import tool_column

#: readings equal to this (deg; mm for a linear axis), rounded, are one pose measured again
REPEAT_DEG = 1e-3
#: a leftover above this many times the noise is well above it
WELL_ABOVE = 1.5


@dataclass
class NoiseFloor:
    """The noise per axis (mm), where it comes from, and the final model's leftover in its units."""

    sigma_mm: float
    source: str                 # "stated" or "repeated poses"
    n_repeats: int              # poses measured again (repeated poses: the degrees of freedom)
    leftover_mm: float          # the final model's validation rms per axis
    ratio: float

    def text(self) -> str:
        where = ("stated with --noise-mm" if self.source == "stated" else
                 f"from {self.n_repeats} repeated measurements of the same poses")
        text = (f"the final model leaves {self.leftover_mm:.4f} mm per axis (rms) on the validation poses: "
                f"{self.ratio:.1f} times the noise floor ({self.sigma_mm:.4f} mm per axis, {where})")
        if self.ratio > WELL_ABOVE:
            text += "; well above it: what remains is structure no term of the model holds, not noise"
        return text

    def to_dict(self) -> dict:
        return {"sigma_mm": self.sigma_mm, "source": self.source, "repeats": self.n_repeats,
                "leftover_mm": self.leftover_mm, "ratio": self.ratio}


def repeated_sigma(data: Measurements) -> tuple[float, int] | None:
    """The noise per axis (m) from poses measured again (readings equal to :data:`REPEAT_DEG` in one session):
    the pooled scatter of their points about each group's mean, and its degrees of freedom; None without any."""
    # degrees (as read: millimetres on a linear axis)
    key = np.round((data.q_deg if any(data.prismatic) else np.degrees(data.q)) / REPEAT_DEG).astype(np.int64)
    if data.sessions is not None:
        key = np.column_stack([np.unique(data.sessions, return_inverse=True)[1], key])
    # a pose measured at several tool points (a tool column) is not a pose measured again
    key = np.column_stack([np.unique(tool_column(data), return_inverse=True)[1].ravel(), key])
    _, group, count = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    group = group.ravel()
    again = count[group] > 1
    if data.touches:        # rows that touch measure no point: the measured rows alone
        again &= ~data.touching
        count = np.bincount(group[again], minlength=len(count))
        again &= count[group] > 1
    if not again.any():
        return None
    xyz, g = data.xyz[again], group[again]
    means = np.zeros((group.max() + 1, 3))
    np.add.at(means, g, xyz)
    means /= count[:, None]
    dof = int(np.sum(count[count > 1] - 1))
    ss = float(np.sum((xyz - means[g]) ** 2))
    return math.sqrt(ss / (3 * dof)), dof


def noise_floor(cal: Measurements, stated_mm: float | None, val_rms_mm: float) -> NoiseFloor | None:
    """The noise floor as stated, else from repeated calibration poses; None when neither is known."""
    if stated_mm is not None:
        sigma, source, n = stated_mm, "stated", 0
    else:
        rep = repeated_sigma(cal)
        if rep is None or rep[0] <= 0:
            return None
        sigma, source, n = rep[0] * 1000, "repeated poses", rep[1]
    leftover = val_rms_mm / math.sqrt(3)
    return NoiseFloor(sigma, source, n, leftover, leftover / sigma)
