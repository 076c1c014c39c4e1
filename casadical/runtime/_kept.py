"""A few answers kept by the bytes of the arrays they were computed from.

A diagnosis asks the same question of the same poses many times (every fit of it evaluates its model at the
calibration poses at every iteration; every model's gate asks the GP compensator at the validation poses). The
answers are kept by a digest of those arrays' bytes, not by their identity: a subset or a copy of the same poses is
the same question. :class:`Kept` keeps the last few, the oldest dropped first, and is safe across threads (studies
fit in threads). Used for the GP compensator's posterior at new poses, the superset's periodic factors and the
calibration poses' spacing.
"""

from __future__ import annotations

import hashlib
import threading
from collections import OrderedDict

import numpy as np


def array_key(*arrays: np.ndarray) -> tuple:
    """Each array's shape and a 16-byte digest of its bytes (C order): a key two equal arrays share."""
    return tuple((a.shape, hashlib.blake2b(np.ascontiguousarray(a).tobytes(), digest_size=16).digest())
                 for a in arrays)


class Kept:
    """The last ``size`` answers, by key; the oldest is dropped first. Read the answers, never write to them."""

    def __init__(self, size: int):
        self.size = size
        self._answers: OrderedDict = OrderedDict()
        self._lock = threading.Lock()

    def __getstate__(self) -> dict:      # a copy or a pickle (studies send results to processes) keeps none
        return {"size": self.size}

    def __setstate__(self, state: dict) -> None:
        self.__init__(state["size"])

    def __len__(self) -> int:
        return len(self._answers)

    def get(self, key):
        """The answer kept under ``key``, or None."""
        with self._lock:
            return self._answers.get(key)

    def put(self, key, answer) -> None:
        with self._lock:
            self._answers[key] = answer
            while len(self._answers) > self.size:
                self._answers.popitem(last=False)
