"""The fixture rows' unknown (the fixture's pose): its fit, where it puts each row's point, and the basis the
Jacobian is projected away from, checked against what they must be, not against the code's own numbers."""

import numpy as np
import pytest

from casadical.rows import FIXTURE_POINTS, Fixture, Group


def _rotation(v: np.ndarray) -> np.ndarray:
    """Rodrigues: the rotation by |v| about v."""
    a = np.linalg.norm(v)
    K = np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]]) / (a or 1.0)
    return np.eye(3) + np.sin(a) * K + (1 - np.cos(a)) * K @ K


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_fixture_pose_is_the_least_squares_placement(seed):
    """Three sockets of an L-shaped block touched by a noisy tool point (rows of the sockets interleaved): the
    fitted pose puts each socket at its rows' mean to the noise, no small move of the pose lowers the sum of
    squares, and the basis is the residual's derivative with respect to that move."""
    rng = np.random.default_rng(seed)
    fixture = Fixture("block", {"a": np.zeros(3), "b": np.array([0.05, 0.0, 0.0]), "c": np.array([0.0, 0.03, 0.0])})
    R, t = _rotation(rng.normal(size=3)), rng.normal(size=3) * 0.3
    names = rng.choice(["a", "b", "c"], size=40)
    names[:3] = ["a", "b", "c"]
    P = np.array([R @ fixture.points[p] + t for p in names]) + rng.normal(scale=1e-4, size=(40, 3))
    group = Group(FIXTURE_POINTS, np.arange(40), name="block", fixture=fixture, point_names=names.astype(object))
    fitted = FIXTURE_POINTS.fit(P, group)
    r = FIXTURE_POINTS.residual(P, fitted, group)
    placed = P - r
    for p in "abc":     # every row of a socket at one place, that socket's place under the true pose to the noise
        assert np.ptp(placed[names == p], axis=0).max() < 1e-12
        assert np.linalg.norm(placed[names == p][0] - (R @ fixture.points[p] + t)) < 1e-4
    B = FIXTURE_POINTS.basis(P, fitted, group)
    assert abs(B.T @ r.ravel()).max() < 1e-12                # the least-squares optimum: no descent along a move

    def moved(e):       # the residual when the pose moves by e = (translation, small rotation about the origin)
        Rf, tf = fitted
        Q = _rotation(e[3:])
        return (P - np.array([Q @ (Rf @ fixture.points[p] + tf) + e[:3] for p in names])).ravel()

    h = 1e-7
    numeric = np.column_stack([(moved(h * e) - moved(-h * e)) / (2 * h) for e in np.eye(6)])
    assert abs(numeric - B).max() < 1e-6
