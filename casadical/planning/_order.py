"""The order a measurement run visits its poses: short joint moves, no needless wrist turns.

A joint move (PTP) takes as long as its slowest joint: the distance between two poses is the largest change of
any joint (degrees; a millimetre of a linear axis weighs as a degree). The path starts at the pose nearest the
middle of the poses, goes to the nearest pose not yet visited, and is then shortened by 2-opt (reversing a stretch
of the path, the first or any other, wherever that shortens it) until no reversal does.
"""

from __future__ import annotations

import numpy as np


def distances(q: np.ndarray) -> np.ndarray:
    """(M, M): the largest joint change between each pair of poses (``q`` in degrees, or mm)."""
    return np.abs(q[:, None, :] - q[None, :, :]).max(axis=2)


def measurement_order(q: np.ndarray, max_rounds: int = 50) -> np.ndarray:
    """A short open path through the poses ``q`` ((M, n), degrees; mm of a linear axis): their indices in visiting
    order (nearest neighbour, then 2-opt)."""
    q = np.asarray(q, float)
    M = len(q)
    if M <= 2:
        return np.arange(M)
    D = distances(q)
    start = int(np.argmin(np.abs(q - np.median(q, axis=0)).max(axis=1)))
    path = [start]
    left = np.ones(M, bool)
    left[start] = False
    while left.any():
        d = np.where(left, D[path[-1]], np.inf)
        k = int(np.argmin(d))
        path.append(k)
        left[k] = False
    path = np.array(path)
    for _ in range(max_rounds):
        better = False
        # reversing a first stretch path[0..j] swaps the edge (path[j], path[j+1]) for (path[0], path[j+1])
        gain = D[path[:-1], path[1:]] - D[path[0], path[1:]]
        j = int(np.argmax(gain))
        if gain[j] > 1e-9:
            path[:j + 1] = path[:j + 1][::-1]
            better = True
        for i in range(1, M - 1):
            a, b = path[i - 1], path[i]
            # reversing path[i..j] swaps edges (a, b), (c, e) for (a, c), (b, e); the last stretch has no e
            c = path[i + 1:]
            e = np.append(path[i + 2:], -1)
            gain = D[a, b] + np.where(e >= 0, D[c, np.maximum(e, 0)], 0.0) - D[a, c] \
                - np.where(e >= 0, D[b, np.maximum(e, 0)], 0.0)
            k = int(np.argmax(gain))
            if gain[k] > 1e-9:
                j = i + 1 + k
                path[i:j + 1] = path[i:j + 1][::-1]
                better = True
        if not better:
            break
    return path


def path_length(q: np.ndarray, order: np.ndarray) -> float:
    """The sum of the largest joint changes along ``order``."""
    q = np.asarray(q, float)[order]
    return float(np.abs(np.diff(q, axis=0)).max(axis=1).sum()) if len(q) > 1 else 0.0
