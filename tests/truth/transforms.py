"""Homogeneous transforms of batches of poses, in plain numpy (4x4 matrices, shape (N, 4, 4)).

Written for the truth alone: nothing here comes from casadical. Angles in
radians, lengths in metres. Every function takes scalars or arrays of N
values and returns (N, 4, 4) (N = 1 for scalars).
"""

from __future__ import annotations

import numpy as np


def _batch(x) -> np.ndarray:
    return np.atleast_1d(np.asarray(x, dtype=float))


def _n(*xs) -> int:
    return max(len(_batch(x)) for x in xs)


def eye(n: int) -> np.ndarray:
    return np.tile(np.eye(4), (n, 1, 1))


def rot(axis: str, angle) -> np.ndarray:
    """Rotation about the x, y or z axis by ``angle`` (right hand: a positive angle turns y to z, z to x, x to y)."""
    a = _batch(angle)
    c, s = np.cos(a), np.sin(a)
    T = eye(len(a))
    i, j = {"x": (1, 2), "y": (2, 0), "z": (0, 1)}[axis]
    T[:, i, i], T[:, i, j], T[:, j, i], T[:, j, j] = c, -s, s, c
    return T


def trans(x=0.0, y=0.0, z=0.0) -> np.ndarray:
    """Translation by (x, y, z)."""
    n = _n(x, y, z)
    T = eye(n)
    T[:, 0, 3], T[:, 1, 3], T[:, 2, 3] = (np.broadcast_to(_batch(v), (n,)) for v in (x, y, z))
    return T


def chain(*Ts: np.ndarray) -> np.ndarray:
    """The product T1 T2 ... (each (N, 4, 4) or (1, 4, 4), broadcast)."""
    out = Ts[0]
    for T in Ts[1:]:
        out = out @ T
    return out


def fixed_rpy(roll, pitch, yaw) -> np.ndarray:
    """Fixed-axis roll-pitch-yaw: first roll about x, then pitch about the fixed y, then yaw about the fixed z.

    As a product of matrices: Rz(yaw) Ry(pitch) Rx(roll).
    """
    return chain(rot("z", yaw), rot("y", pitch), rot("x", roll))


def pose(xyz, rpy) -> np.ndarray:
    """A frame placed at ``xyz`` and turned by fixed-axis ``rpy``: Trans(xyz) Rz Ry Rx."""
    return chain(trans(*xyz), fixed_rpy(*rpy))


def intrinsic_xyz(R: np.ndarray) -> np.ndarray:
    """Angles (rx, ry, rz), radians, with R = Rx(rx) Ry(ry) Rz(rz) (turn about x, then the new y, then the new z).

    From the product written out: R[0, 2] = sin ry, R[1, 2] = -sin rx cos ry, R[2, 2] = cos rx cos ry,
    R[0, 1] = -cos ry sin rz, R[0, 0] = cos ry cos rz. ``R``: (N, 3, 3) or (N, 4, 4).
    """
    R = np.asarray(R, dtype=float)
    ry = np.arctan2(R[:, 0, 2], np.hypot(R[:, 1, 2], R[:, 2, 2]))
    rx = np.arctan2(-R[:, 1, 2], R[:, 2, 2])
    rz = np.arctan2(-R[:, 0, 1], R[:, 0, 0])
    return np.column_stack([rx, ry, rz])


def rotation_vector_to_matrix(w: np.ndarray) -> np.ndarray:
    """Rodrigues: the rotation by |w| about w / |w|, (N, 3) -> (N, 3, 3)."""
    w = np.atleast_2d(np.asarray(w, dtype=float))
    angle = np.linalg.norm(w, axis=1)
    k = np.divide(w, angle[:, None], out=np.zeros_like(w), where=angle[:, None] > 0)
    K = np.zeros((len(w), 3, 3))
    K[:, 0, 1], K[:, 0, 2], K[:, 1, 2] = -k[:, 2], k[:, 1], -k[:, 0]
    K -= K.transpose(0, 2, 1)
    s, c = np.sin(angle)[:, None, None], np.cos(angle)[:, None, None]
    return np.eye(3) + s * K + (1 - c) * K @ K
