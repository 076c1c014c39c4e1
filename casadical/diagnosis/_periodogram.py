"""Periodicity of the residuals in each joint angle.

The residual of each pose is projected on the direction the tool point moves
when joint j turns (the model's Jacobian column of ``theta<j>``), which
estimates joint j's angle error at that pose. A least-squares periodogram
over harmonics 1..H of that error against the joint reading finds periodic
transmission errors (gear errors of tens of cycles per turn included);
irregular sampling of the angles makes it free of the aliasing of an FFT.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass
class Periodogram:
    """Weighted least-squares periodogram of one joint's projected residual.

    Attributes
    ----------
    joint : int
    harmonics : ndarray of int
    power : ndarray
        Fraction of the projected residual's weighted sum of squares that
        ``a sin(h q) + b cos(h q)`` removes, per harmonic.
    amplitude : ndarray
        Fitted amplitude (rad) per harmonic.
    """

    joint: int
    harmonics: np.ndarray
    power: np.ndarray
    amplitude: np.ndarray


def joint_errors(residual: np.ndarray, direction: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Angle error estimate per pose and its weight, from residuals (N, 3) and d xyz / d theta_j (N, 3)."""
    w = np.einsum("ij,ij->i", direction, direction)
    s = np.einsum("ij,ij->i", residual, direction) / np.where(w > 0, w, np.inf)
    return s, w


def periodogram(q: np.ndarray, s: np.ndarray, w: np.ndarray, joint: int, max_harmonic: int) -> Periodogram:
    """Weighted periodogram of angle errors ``s`` against readings ``q`` (rad)."""
    hs = np.arange(1, max_harmonic + 1)
    sw = np.sqrt(w)
    y = s * sw
    # remove the weighted mean and linear trend (offset and scale are fitted by the model already)
    base = np.column_stack([sw, sw * q])
    y = y - base @ np.linalg.lstsq(base, y, rcond=None)[0]
    total = float(y @ y)
    power, amp = np.zeros(len(hs)), np.zeros(len(hs))
    if total <= 0:
        return Periodogram(joint, hs, power, amp)
    # every harmonic at once: [sin, cos, base] normal equations stacked, (H, 4, 4)
    S = sw * np.sin(np.outer(hs, q))                 # (H, N)
    C = sw * np.cos(np.outer(hs, q))
    cols = np.stack([S, C, np.broadcast_to(base[:, 0], S.shape), np.broadcast_to(base[:, 1], S.shape)], axis=1)
    G = np.einsum("hin,hjn->hij", cols, cols)
    b = np.einsum("hin,n->hi", cols, y)
    # least squares of every harmonic in one batch, with lstsq's cutoff (singular values below 4 eps of the largest)
    coef = np.einsum("hij,hj->hi", np.linalg.pinv(G, rcond=4 * np.finfo(float).eps), b)
    fit_sq = np.einsum("hi,hi->h", coef, b)          # |A c|^2 = c^T A^T y at the least-squares solution
    power[:] = fit_sq / total
    amp[:] = np.hypot(coef[:, 0], coef[:, 1])
    return Periodogram(joint, hs, power, amp)
