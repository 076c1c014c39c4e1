"""Poses of the robot: rows of one session with the same joint readings are one pose.

A tool of several points (reflector nests, balls; the ``tool`` column of docs/formats.md) is measured at each
point in turn while the robot stands still: one pose, several rows with the same readings. So is a pose measured
again. What is true of one of them (the robot's error there) is true of all: a fold that holds out one of them
while fitting the others is not held out (:mod:`casadical.diagnosis._validation` leaves a pose out whole), and a
design is judged by its poses, not its rows (:mod:`casadical.diagnosis._design`).

"The same readings" are the same numbers: every joint's reading equal, in one session (rows of two sessions are
two poses: each session has its own base pose).
"""

from __future__ import annotations

import numpy as np


def pose_index(q: np.ndarray, sessions: np.ndarray | None = None) -> np.ndarray:
    """Each row's pose (0, 1, ... in the order of their first rows): rows with equal readings ``q`` (N, n) in one
    session (``sessions``: each row's name, or None for one session) share one."""
    q = np.ascontiguousarray(np.asarray(q, float))
    if not len(q):
        return np.zeros(0, int)
    key = q + 0.0           # -0.0 and 0.0 are one reading
    if sessions is not None:
        key = np.column_stack([np.unique(np.asarray(sessions), return_inverse=True)[1].ravel(), key])
    _, first, inverse = np.unique(key, axis=0, return_index=True, return_inverse=True)
    inverse = inverse.ravel()
    order = np.argsort(first, kind="stable")        # number the poses by their first rows
    rank = np.empty_like(order)
    rank[order] = np.arange(len(order))
    return rank[inverse]


def first_rows(pose: np.ndarray) -> np.ndarray:
    """The first row of each pose of :func:`pose_index`, in pose order."""
    _, first = np.unique(pose, return_index=True)
    return first
