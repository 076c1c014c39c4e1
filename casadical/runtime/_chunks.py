"""Work in chunks of poses: the model's Jacobian of every pose of a large set is never held at once."""

from __future__ import annotations

#: poses per chunk when linearising (Jacobian block of 3 x chunk x P doubles)
CHUNK = 4096


def pose_chunks(N: int):
    """Slices of at most ``CHUNK`` poses covering ``N``."""
    for a in range(0, N, CHUNK):
        yield slice(a, min(a + CHUNK, N))
