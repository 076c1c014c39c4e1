"""The stand-in check's F-tests (``stand_ins._Questions.beside``) make each least-squares fit once and ask it again;
what they answer is the test computed from scratch (``lstsq``'s residual, ``matrix_rank``'s rank), in any order of
asking, with column blocks collinear with the rest and with fresh arrays of the same shape asked in turn."""

import numpy as np
import pytest

from casadical.diagnosis import nested_test, weighted
from casadical.diagnosis._stand_ins import _Questions

SEEDS = [0, 1, 2, 3]


def from_scratch(ask: _Questions, more, extra):
    base = ask.rest if more is None else np.concatenate([ask.rest, more], axis=2)
    A0 = weighted(base, ask.sw)
    A1 = np.hstack([A0, weighted(extra, ask.sw)])
    r0 = ask.rw - A0 @ np.linalg.lstsq(A0, ask.rw, rcond=None)[0]
    r1 = ask.rw - A1 @ np.linalg.lstsq(A1, ask.rw, rcond=None)[0]
    k = np.linalg.matrix_rank(A1) - np.linalg.matrix_rank(A0)
    noise = None if ask.share is None else float((r1 ** 2) @ ask.share)
    return nested_test(float(r0 @ r0), A0.shape[1], float(r1 @ r1), A0.shape[1] + max(k, 1), len(ask.rw), noise)


@pytest.mark.parametrize("seed", SEEDS)
def test_the_tests_are_those_computed_from_scratch(seed):
    rng = np.random.default_rng(seed)
    n = 150
    rest = rng.normal(size=(n, 3, 6))
    sw = np.repeat(np.sqrt(rng.uniform(0.1, 1.0, n)), 3)
    share = np.minimum(1.0, rng.uniform(0.2, 3.0, 3 * n)) if seed % 2 else None
    mine = rng.normal(size=(n, 3, 2))
    collinear = np.concatenate([rest[:, :, :2] @ rng.normal(size=(2, 3)), rng.normal(size=(n, 3, 1))], axis=2)
    rw = (rest @ rng.normal(size=6) + mine @ rng.normal(size=2)).ravel() * sw + rng.normal(0, 0.1, 3 * n)
    ask = _Questions(rw, sw, rest, mine, -3.0, share)
    blocks = [mine, collinear, rng.normal(size=(n, 3, 4)), rng.normal(size=(n, 3, 4))]
    for _ in range(40):
        more = None if rng.random() < 0.3 else blocks[int(rng.integers(len(blocks)))]
        extra = blocks[int(rng.integers(len(blocks)))]
        if rng.random() < 0.3:        # a fresh block, dropped after the question (its id free again)
            extra = rng.normal(size=(n, 3, 4))
        got, want = ask.beside(more, extra), from_scratch(ask, more, extra)
        assert got.dof == want.dof
        assert np.isclose(got.f, want.f, rtol=1e-8, atol=1e-9)        # (a block beside itself: f 0 or 1e-13)
        assert np.isclose(got.log10_p, want.log10_p, rtol=1e-8, atol=1e-6)
        assert np.isclose(got.delta_bic, want.delta_bic, rtol=1e-8, atol=1e-8)
