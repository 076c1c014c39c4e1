"""A small calibration problem keeps the model's Jacobian at the last parameter values (CalibrationProblem.
model_jacobian): the robust loss's re-weighting, the precision and the separation check linearise again where
the solver stopped. The same numbers, one model evaluation, nothing a caller can change by accident."""

import math

import numpy as np
import pytest

from casadical import load_robot
from casadical.data import Effects, simulate
from casadical.model import Model
from casadical.problem import MEMO_NUMBERS, CalibrationProblem, RobustLoss


def problem(full_pose: bool, n: int = 120, seed: int = 0):
    robot = load_robot("ys100")
    data, _ = simulate(robot, n, Effects(), seed=seed)
    model = Model(robot, "kinematic+compliance" + ("+tool_orientation" if full_pose else ""))
    rng = np.random.default_rng(seed)
    rot = np.array([np.linalg.qr(rng.normal(size=(3, 3)))[0] for _ in range(n)]) if full_pose else None
    return CalibrationProblem(model, model.parameters.copy(), data.q, data.xyz, model.covariates(data),
                              model.base0_nominal(), RobustLoss(), rot)


class Counting:
    """The problem's real model, counting its Jacobian evaluations (every call is passed on)."""

    def __init__(self, prob):
        self.calls = 0
        for name in ("predict_jacobian", "pose_jacobian"):
            real = getattr(prob.model, name)

            def counted(*a, _real=real, **k):
                self.calls += 1
                return _real(*a, **k)
            setattr(prob.model, name, counted)


@pytest.mark.parametrize("full_pose", [False, True])
def test_a_second_linearisation_at_the_same_values_evaluates_nothing(full_pose):
    prob = problem(full_pose)
    fresh = problem(full_pose)
    count = Counting(prob)
    x = 0.3 * np.random.default_rng(1).normal(size=len(prob.free))
    values = prob.values_from_x(x)
    first = prob.linearize(values)
    assert count.calls == 1
    prob.loss = fresh.loss = RobustLoss("huber", sigma=2e-4, sigma_rot=1e-4 if full_pose else math.nan)   # re-weighted
    again = prob.linearize(values.copy())
    assert count.calls == 1                                   # the same values: the model's Jacobian kept
    ref = fresh.linearize(values)                             # a problem that never saw them: the same bits
    for a, b in ((again.A, ref.A), (again.g, ref.g), (again.r, ref.r), (again.weights, ref.weights)):
        assert np.array_equal(a, b)
    assert not np.array_equal(first.A, again.A)               # the loss did change the normal equations
    values[prob.free[0]] += 1e-9
    prob.linearize(values)
    assert count.calls == 2                                   # other values: evaluated anew


def test_what_it_keeps_is_read_only():
    prob = problem(True)
    values = prob.params.values.copy()
    out = prob.model_jacobian(values, slice(0, prob.n_poses))
    with pytest.raises(ValueError):
        out[1][0, 0, 0] = 1.0


def test_a_large_problem_keeps_nothing():
    prob = problem(True, n=MEMO_NUMBERS // (6 * len(Model(load_robot("ys100"), "kinematic+compliance+tool_orientation")
                                                   .parameters)) + 1)
    count = Counting(prob)
    values = prob.params.values.copy()
    prob.linearize(values)
    prob.linearize(values)
    assert count.calls >= 2 and prob._memo is None
