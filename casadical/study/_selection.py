"""The calibration poses a plan selects in one repetition of a study."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass
class Selection:
    """Calibration poses of one plan: rows of its pool, the design criterion and the time."""

    indices: np.ndarray
    o1: float = float("nan")
    log_det: float = float("nan")
    time_s: float = 0.0
