"""The GP compensator, the diagnosis's last step (issue 25 item 6, issue 26 item 3): the same hyperparameters
as scikit-learn's fit at a fraction of its cost, its support chosen on the folds, and at least as good as a
plain GP of the kinematic residual, on an arm that is not built in."""

import math

import numpy as np
import pytest

from casadical import calibrate
from casadical.compensators import FIT_ITERATIONS, LENGTH_BOUNDS, ResidualGP, log_likelihood, squared_differences
from casadical.data import Measurements
from casadical.diagnosis import SHRINKS, DiagnosisSettings, diagnose
from casadical.robot import robot_from_dict
from tests.helpers.arms import ARM7_DH
from tests.truth import Arm, Effects, TrueRobot, measure, sample


@pytest.mark.filterwarnings("ignore:The optimal value found")
def test_likelihood_and_fit_are_scikit_learns():
    """The log marginal likelihood and its gradient equal scikit-learn's (ConstantKernel * RBF + WhiteKernel,
    normalize_y, its alpha) at any hyperparameters; the fitted hyperparameters equal its regressor's."""
    from scipy.optimize import minimize
    from sklearn.gaussian_process import GaussianProcessRegressor
    from sklearn.gaussian_process.kernels import RBF, ConstantKernel, WhiteKernel

    rng = np.random.default_rng(3)
    X = rng.uniform(-2, 2, (120, 5))
    Y = np.column_stack([np.sin(X[:, 0] + X[:, 1]), np.cos(2 * X[:, 2]), X[:, 3] * X[:, 4]]) * 1e-4 \
        + rng.normal(0, 2e-5, (120, 3))
    kernel = ConstantKernel(1.0, (1e-4, 1e2)) * RBF(np.ones(5), LENGTH_BOUNDS) + WhiteKernel(0.5, (1e-4, 1.0))
    y = (Y[:, 0] - Y[:, 0].mean()) / Y[:, 0].std()
    ref = GaussianProcessRegressor(kernel, normalize_y=True, optimizer=None).fit(X, Y[:, 0])
    D = squared_differences(X)
    for _ in range(5):
        theta = np.log(np.r_[rng.uniform(0.1, 3), rng.uniform(0.2, 5, 5), rng.uniform(1e-3, 0.9)])
        a, ga = ref.log_marginal_likelihood(theta, eval_gradient=True)
        b, gb = log_likelihood(theta, D, y)
        assert b == pytest.approx(a, rel=1e-10)
        assert np.allclose(gb, ga, rtol=1e-7, atol=1e-9)

    def optimizer(obj, theta0, bounds):
        r = minimize(obj, theta0, method="L-BFGS-B", jac=True, bounds=bounds, options={"maxiter": FIT_ITERATIONS})
        return r.x, r.fun

    ours = ResidualGP.fit(X, Y)
    for a in range(3):
        k = GaussianProcessRegressor(kernel, normalize_y=True, optimizer=optimizer).fit(X, Y[:, a]).kernel_
        assert np.allclose(ours.length_scales[a], k.k1.k2.length_scale, rtol=1e-4)
        assert ours.signal_var[a] == pytest.approx(k.k1.k1.constant_value, rel=1e-4)
        assert ours.noise_var[a] == pytest.approx(k.k2.noise_level, rel=1e-4)


@pytest.mark.parametrize("seed", [0, 1])
def test_gp_compensator_at_least_as_good_as_a_plain_gp(tmp_path, seed):
    """A seven-axis arm with a compliance, a gear error and a smooth error no named cause explains (a coupling
    of joints 2 and 4, 0.3 mm): the final model, with the GP compensator, predicts the other poses at least as well as a
    kinematic calibration plus a plain Gaussian process of its residual, and its worst error is no higher
    (5 %); the strength of its shrinkage is one of those tried, chosen on the folds."""
    robot = robot_from_dict(ARM7_DH)
    rng = np.random.default_rng(seed)
    truth = TrueRobot.draw(Arm.from_dict(ARM7_DH), Effects(stiffness={2: 4e4},
                                                           periodic=[(1, 9, math.radians(0.015), 0.3)]), rng)

    def shots(name, n):
        s = measure(truth, sample(truth, n, rng), rng, noise=30e-6)
        q = s.q
        s.xyz = s.xyz + 0.3e-3 * np.column_stack([np.sin(q[:, 1] + 2 * q[:, 3]), np.cos(q[:, 1] - q[:, 3]),
                                                  np.sin(2 * q[:, 1])])
        return Measurements.read_csv(s.write_csv(tmp_path / f"{name}.csv"), n_joints=7)

    cal, val = shots("cal", 200), shots("val", 200)
    rep = diagnose(robot, cal, val, DiagnosisSettings(seed=seed))
    kin = calibrate(robot, cal, "kinematic", "lm", warn=False)
    R = kin.base_matrix()[:3, :3]
    gp = ResidualGP.fit(cal.q, kin.residuals(cal) @ R, seed=seed)
    plain = np.linalg.norm(kin.predict(val) + gp.predict(val.q) @ R.T - val.xyz, axis=1) * 1000
    compensator = next(f for f in rep.findings if f.cause == "unexplained" and f.in_model)
    assert compensator.holds_up["shrink"] in SHRINKS
    assert rep.final_validation.mean_mm <= plain.mean(), (rep.final_model, rep.final_validation.mean_mm, plain.mean())
    assert rep.final_validation.max_mm <= 1.05 * plain.max(), (rep.final_validation.max_mm, plain.max())


def test_paired_gain_is_scipys_wilcoxon():
    """The GP compensator's test of its gain: scipy's one-sided Wilcoxon signed-rank test, with zeros and ties, computed
    without importing scipy.stats for large samples."""
    from scipy import stats

    from casadical.diagnosis import paired_gain

    rng = np.random.default_rng(0)
    for n in (20, 51, 120, 300):
        for shift in (0.0, 0.05, 0.2):
            before = rng.gamma(2.0, 1.0, n)
            after = before - rng.normal(shift, 0.3, n)
            after[: n // 5] = before[: n // 5]                    # poses where the compensator adds nothing
            before[-10:], after[-10:] = np.round(before[-10:], 1), np.round(after[-10:], 1)    # ties
            expected = stats.wilcoxon(before - after, alternative="greater").pvalue
            assert paired_gain(before, after) == pytest.approx(expected, rel=1e-9, abs=1e-300)


@pytest.mark.parametrize("seed", [1, 2])
def test_a_rejected_gp_compensator_says_why_without_contradicting_itself(seed):
    """A 5-axis arm whose axis tilts (an effect no catalogue cause has), 36 calibration poses as in the ABB IRB 120
    tracker set of issue 47: the GP compensator is rejected, and its reason never reads as no change where it says
    a change ('0.0516 -> 0.0516 mm') nor as a significant p-value where it says not significant ('p = 0.0021'):
    each before -> after differs as written or says by how much, and each p-value comes with the level it is not
    below."""
    import re

    from tests.helpers import hidden

    c = hidden.case("arm5", "axis tilt", seed)
    robot, cal, val = hidden.make_data(c, n_cal=36, n_val=100)[:3]
    report = diagnose(robot, cal, val, DiagnosisSettings(seed=seed))
    step = report.steps[-1]
    assert step.model.endswith("+gp_compensator") and not step.accepted
    reason = step.reason
    pairs = re.findall(r"(\d+\.\d+) -> (\d+\.\d+) mm( \((\S+) mm (lower|higher)\))?", reason)
    assert pairs, reason
    for before, after, said, change, _ in pairs:
        assert before != after or (said and float(change) > 0), reason
    for p, level in re.findall(r"p = (\S+), not below the level (\S+) of its tests", reason):
        assert float(p) >= float(level), reason
    assert len(re.findall(r"p = ", reason)) == len(re.findall(r"not below the level", reason)), reason
