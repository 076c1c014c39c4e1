"""The hypergeometric tail of the set-aside tests (casadical.stats._outliers.hypergeom_tail) is scipy.stats'
(``hypergeom.sf(k - 1, ...)``), which calibrate no longer imports (0.5-0.6 s of CPU whenever two poses are set
aside)."""

import numpy as np
import pytest
from scipy import stats

from casadical.stats import hypergeom_tail


@pytest.mark.parametrize("seed", range(5))
def test_the_tail_is_scipys(seed):
    rng = np.random.default_rng(seed)
    for _ in range(40):
        total = int(rng.integers(2, 200_000 if seed == 4 else 2_000))
        drawn = int(rng.integers(1, total + 1))
        n_in = rng.integers(0, total + 1, size=6)
        k = rng.integers(-1, drawn + 2, size=6)
        ours = hypergeom_tail(k, total, n_in, drawn)
        theirs = stats.hypergeom.sf(k - 1, total, n_in, drawn)
        assert np.allclose(ours, theirs, rtol=1e-7, atol=1e-300), (total, drawn, n_in, k, ours, theirs)


def test_far_tails_keep_their_size():
    """29 of 29 set-aside poses in one session of 60 among 120: p ~ 1e-10, not rounded to 0."""
    assert hypergeom_tail(29, 120, 60, 29)[()] == pytest.approx(stats.hypergeom.sf(28, 120, 60, 29), rel=1e-9)
    assert 0 < hypergeom_tail(29, 120, 60, 29)[()] < 1e-8
