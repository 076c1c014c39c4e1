"""Closed-form rigid alignment of point sets (Kabsch / Umeyama without scale).

Starts the base pose: nominal predictions in the robot frame are aligned to
the measurements, so a tracker metres away at any rotation is no obstacle.
"""

from __future__ import annotations

import numpy as np

from ..errors import IdentifiabilityError


def align(source: np.ndarray, target: np.ndarray) -> np.ndarray:
    """Rigid transform ``T`` (4x4) minimising ``sum |R s_i + t - target_i|^2``.

    Raises
    ------
    IdentifiabilityError
        Fewer than 3 points, or points on a line (the rotation is undefined).
    """
    source, target = np.asarray(source, float), np.asarray(target, float)
    if len(source) < 3:
        raise IdentifiabilityError(f"the base pose needs at least 3 measured poses, got {len(source)}")
    cs, ct = source.mean(0), target.mean(0)
    S, Tt = source - cs, target - ct
    for pts, what in ((S, "the predicted tool points"), (Tt, "the measured tool points")):
        sv = np.linalg.svd(pts, compute_uv=False)
        if sv[1] < 1e-6 * max(sv[0], 1e-12):
            raise IdentifiabilityError(f"{what} lie on a line: the base pose cannot be found; "
                                       "measure poses spread over the workspace")
    U, _, Vt = np.linalg.svd(S.T @ Tt)
    d = np.sign(np.linalg.det(Vt.T @ U.T))
    R = Vt.T @ np.diag([1.0, 1.0, d]) @ U.T
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = ct - R @ cs
    return T
