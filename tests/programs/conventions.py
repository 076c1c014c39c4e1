"""The controllers' orientation conventions, written for the tests alone (plain numpy, nothing of casadical):
URScript rotation vectors, KUKA A B C (``Rz(A) Ry(B) Rx(C)``, deg), ABB quaternions ``[w, x, y, z]``."""

from __future__ import annotations

import math

import numpy as np

from tests.truth import transforms as tf


def rotvec_to_matrix(rv) -> np.ndarray:
    return tf.rotation_vector_to_matrix(np.asarray(rv, float)[None])[0]


def matrix_to_quaternion(R) -> np.ndarray:
    """Shepperd's method: the largest of the four squares first; w >= 0."""
    R = np.asarray(R, float)
    tr = np.trace(R)
    squares = [1 + tr, 1 + 2 * R[0, 0] - tr, 1 + 2 * R[1, 1] - tr, 1 + 2 * R[2, 2] - tr]
    k = int(np.argmax(squares))
    s = math.sqrt(squares[k]) * 2
    if k == 0:
        q = [s / 4, (R[2, 1] - R[1, 2]) / s, (R[0, 2] - R[2, 0]) / s, (R[1, 0] - R[0, 1]) / s]
    elif k == 1:
        q = [(R[2, 1] - R[1, 2]) / s, s / 4, (R[0, 1] + R[1, 0]) / s, (R[0, 2] + R[2, 0]) / s]
    elif k == 2:
        q = [(R[0, 2] - R[2, 0]) / s, (R[0, 1] + R[1, 0]) / s, s / 4, (R[1, 2] + R[2, 1]) / s]
    else:
        q = [(R[1, 0] - R[0, 1]) / s, (R[0, 2] + R[2, 0]) / s, (R[1, 2] + R[2, 1]) / s, s / 4]
    q = np.array(q)
    return -q if q[0] < 0 else q


def quaternion_to_matrix(q) -> np.ndarray:
    w, x, y, z = np.asarray(q, float) / np.linalg.norm(q)
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


def matrix_to_rotvec(R) -> np.ndarray:
    w, x, y, z = matrix_to_quaternion(R)
    v = np.array([x, y, z])
    s = np.linalg.norm(v)
    return np.zeros(3) if s < 1e-15 else 2 * math.atan2(s, w) * v / s


def abc_to_matrix(a, b, c) -> np.ndarray:
    return tf.chain(tf.rot("z", math.radians(a)), tf.rot("y", math.radians(b)), tf.rot("x", math.radians(c)))[0, :3, :3]


def matrix_to_abc(R) -> np.ndarray:
    """A, B, C (deg) with R = Rz(A) Ry(B) Rx(C): R[2, 0] = -sin B, R[1, 0] / R[0, 0] = tan A, R[2, 1] / R[2, 2] =
    tan C."""
    b = math.asin(-np.clip(R[2, 0], -1, 1))
    a = math.atan2(R[1, 0], R[0, 0])
    c = math.atan2(R[2, 1], R[2, 2])
    return np.degrees([a, b, c])


def frame(xyz, R) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, xyz
    return T


def angle(A, B) -> float:
    """The angle (rad) between two rotations, exact near zero (from the quaternion, not the trace's arccos)."""
    return float(np.linalg.norm(matrix_to_rotvec(A.T @ B)))
