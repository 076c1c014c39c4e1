"""The GP compensator's answers at new poses, as :class:`ResidualGP` makes them (one kernel per component shared by
the mean and the variance, the last answers kept by the poses' bytes, the kernel computed in place), against the
textbook formulas computed here from scratch: the same numbers, in any order of asking."""

import numpy as np
import pytest
from scipy.linalg import cho_factor, cho_solve

from casadical.compensators import JITTER, ResidualGP

SEEDS = [0, 1, 2, 3]


def random_process(rng, n_train=40, n_joints=5, weights=True) -> ResidualGP:
    X = rng.uniform(-2, 2, (n_train, n_joints))
    Y = rng.normal(0, 1e-4, (n_train, 3))
    return ResidualGP(X, Y, rng.uniform(0.4, 3.0, (3, n_joints)), rng.uniform(0.5, 2.0, 3), rng.uniform(0.01, 0.3, 3),
                      Y.mean(axis=0), Y.std(axis=0), shrink=float(rng.choice([0.0, 0.5, 2.0])),
                      pose_weights=rng.uniform(0.2, 1.0, n_train) if weights else None)


def textbook(gp: ResidualGP, X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The posterior mean (m) and the predictive variance of the smooth part (standardised) of each component,
    from the kernel written out and a solve with the training kernel."""
    w = np.ones(len(gp.X)) if gp.pose_weights is None else gp.pose_weights
    Z = (gp.Y - gp.y_mean) / gp.y_std
    mean, var = np.empty((len(X), 3)), np.empty((len(X), 3))
    for a in range(3):
        def k(A, B):
            d = (A[:, None, :] - B[None, :, :]) / gp.length_scales[a]
            return gp.signal_var[a] * np.exp(-0.5 * np.sum(d ** 2, axis=2))
        L = cho_factor(k(gp.X, gp.X) + np.diag(gp.noise_var[a] / w + JITTER), lower=True)
        ks = k(X, gp.X)
        mean[:, a] = ks @ cho_solve(L, Z[:, a]) * gp.y_std[a] + gp.y_mean[a]
        var[:, a] = gp.signal_var[a] - np.einsum("ij,ji->i", ks, cho_solve(L, ks.T))
    return mean, var


@pytest.mark.parametrize("seed", SEEDS)
def test_the_kernel_is_the_squared_exponential(seed):
    rng = np.random.default_rng(seed)
    gp = random_process(rng)
    A, B = rng.uniform(-2, 2, (30, 5)), rng.uniform(-2, 2, (17, 5))
    for a in range(3):
        d = (A[:, None, :] - B[None, :, :]) / gp.length_scales[a]
        assert np.allclose(gp.kernel(A, B, a), gp.signal_var[a] * np.exp(-0.5 * np.sum(d ** 2, axis=2)),
                           rtol=1e-12, atol=0)
        assert np.allclose(np.diag(gp.kernel(A, A, a)), gp.signal_var[a], rtol=1e-12, atol=0)


@pytest.mark.parametrize("seed", SEEDS)
def test_every_answer_is_the_textbooks_in_any_order(seed):
    """Mean, std ratios (the largest and each component's), the predictive std with the correction applied and the
    weight: asked in a random order at a random sequence of pose sets, some asked again (the kept answers), more
    sets than are kept."""
    rng = np.random.default_rng(seed)
    gp = random_process(rng, weights=bool(seed % 2))
    sets = [rng.uniform(-2.5, 2.5, (int(rng.integers(1, 60)), 5)) for _ in range(6)]
    sets += [sets[0][::-1].copy(), rng.uniform(-2.5, 2.5, sets[0].shape)]     # the same shape: other answers
    expect = [textbook(gp, X) for X in sets]
    asks = ["predict", "ratio", "ratio_of", "std", "weight"]
    for _ in range(60):
        i, ask = int(rng.integers(len(sets))), asks[int(rng.integers(len(asks)))]
        X, (mean, var) = sets[i].copy(), expect[i]       # a copy: the answer is found by the poses, not the array
        ratios = np.sqrt(np.clip(var, 0, None) / gp.signal_var)
        if ask == "predict":
            assert np.allclose(gp.predict(X), mean, rtol=1e-9, atol=1e-15)
        elif ask == "ratio":
            assert np.allclose(gp.std_ratio(X), ratios.max(axis=1), rtol=1e-7, atol=1e-7)
        elif ask == "ratio_of":
            a = int(rng.integers(3))
            assert np.allclose(gp.std_ratio_of(X, a), ratios[:, a], rtol=1e-7, atol=1e-7)
        elif ask == "weight":
            r = ratios.max(axis=1)
            w = np.clip(1 - r ** 2, 0, 1) ** gp.shrink if gp.shrink > 0 else np.ones(len(r))
            assert np.allclose(gp.weight(X), np.where(r < gp.max_std_ratio, w, 0.0), rtol=1e-6, atol=1e-6)
        else:
            r = ratios.max(axis=1)
            w = np.where(r < gp.max_std_ratio, np.clip(1 - r ** 2, 0, 1) ** gp.shrink if gp.shrink > 0 else 1.0, 0.0)
            v = np.clip(var, 0, gp.signal_var)
            std = np.sqrt(v + (1 - w[:, None]) ** 2 * (gp.signal_var - v)) * gp.y_std
            assert np.allclose(gp.predictive_std(X), std, rtol=1e-6, atol=1e-6 * gp.y_std.max())


@pytest.mark.parametrize("seed", SEEDS)
def test_a_kept_answer_is_the_one_made_again(seed):
    """What a process answers from its kept answers is, to the bit, what a fresh copy of it computes."""
    rng = np.random.default_rng(seed)
    gp = random_process(rng)
    X = rng.uniform(-2, 2, (50, 5))
    first = (gp.std_ratio(X), gp.predict(X), gp.predictive_std(X), gp.std_ratio_of(X, 1))

    def fresh():
        return ResidualGP.from_dict(gp.to_dict())
    assert np.array_equal(first[0], fresh().std_ratio(X))
    assert np.array_equal(first[1], fresh().predict(X))
    assert np.array_equal(first[2], fresh().predictive_std(X))
    assert np.array_equal(first[3], fresh().std_ratio_of(X, 1))
