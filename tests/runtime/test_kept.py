"""runtime.kept: answers kept by the bytes of arrays."""

import copy
import pickle
import threading

import numpy as np

from casadical.runtime import Kept, array_key


def test_equal_arrays_share_a_key_and_different_ones_do_not():
    rng = np.random.default_rng(0)
    a = rng.normal(size=(50, 6))
    assert array_key(a) == array_key(a.copy()) == array_key(np.asfortranarray(a))
    assert array_key(a[:, :3]) == array_key(np.ascontiguousarray(a[:, :3]))
    b = a.copy()
    b[7, 2] = np.nextafter(b[7, 2], 1.0)
    assert array_key(b) != array_key(a)
    assert array_key(a.reshape(100, 3)) != array_key(a)          # the same bytes, another shape
    assert array_key(a, b) != array_key(a, a)


def test_the_oldest_answer_is_dropped_first_and_copies_keep_none():
    kept = Kept(3)
    for k in range(5):
        kept.put(k, str(k))
    assert len(kept) == 3 and kept.get(0) is None and kept.get(1) is None
    assert [kept.get(k) for k in (2, 3, 4)] == ["2", "3", "4"]
    for other in (copy.deepcopy(kept), pickle.loads(pickle.dumps(kept))):
        assert len(other) == 0 and other.size == 3
        other.put("x", 1)
        assert other.get("x") == 1 and kept.get("x") is None


def test_threads_put_and_get_without_losing_the_bound():
    kept = Kept(8)

    def work(t):
        for k in range(500):
            kept.put((t, k), k)
            kept.get((t, k - 1))

    threads = [threading.Thread(target=work, args=(t,)) for t in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert len(kept) == 8
