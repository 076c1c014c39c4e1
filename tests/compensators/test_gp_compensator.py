"""The GP compensator (one per session): a Gaussian process of the residual that knows where it holds
(casadical.calibration._per_session)."""

import json
import math

import numpy as np
import pytest

from casadical import calibrate, load_calibration
from casadical.cli import main
from casadical.compensators import ResidualGP
from casadical.data import Effects, another_session, simulate
from casadical.diagnosis import DiagnosisSettings, diagnose
from casadical.robot import robot_from_dict
from tests.helpers.arms import ARM5, ARM7_DH, to_toml

SEEDS = [0, 1, 2]


def smooth_error(q: np.ndarray) -> np.ndarray:
    """A smooth error of the tool point no catalogued cause makes (m): 0.1 mm, a function of joints 1-3."""
    return 1e-4 * np.column_stack([np.sin(2 * q[:, 0] + q[:, 1]), np.cos(q[:, 1] - q[:, 2]), np.sin(q[:, 2] * 1.5)])


def with_structure(robot, n, truth, seed):
    """Poses of ``truth`` with the smooth error added to their measured points (in the robot base frame)."""
    data, _ = simulate(robot, n, truth=truth, seed=seed, floor_z=None)
    R = truth.base0[:9].reshape(3, 3)
    return data.with_positions(data.xyz + smooth_error(data.q) @ R.T, prefix_existing="true_")


def test_the_process_is_scikit_learns():
    """The numbers held (and evaluated without scikit-learn, numerically and in CasADi) are scikit-learn's own
    Gaussian process: mean and predictive std at new poses; the file form reads back to the same process."""
    import casadi as ca
    from sklearn.gaussian_process import GaussianProcessRegressor
    from sklearn.gaussian_process.kernels import RBF, ConstantKernel, WhiteKernel

    rng = np.random.default_rng(0)
    X = rng.uniform(-2, 2, (60, 4))
    Y = (np.column_stack([np.sin(X[:, 0]), np.cos(X[:, 1] * X[:, 2]), X[:, 3] ** 2]) * 1e-4
         + rng.normal(0, 1e-6, (60, 3)))
    gp = ResidualGP.fit(X, Y)
    Xt = rng.uniform(-2, 2, (25, 4))
    for a in range(3):
        k = (ConstantKernel(gp.signal_var[a], "fixed") * RBF(gp.length_scales[a], "fixed")
             + WhiteKernel(gp.noise_var[a], "fixed"))
        sk = GaussianProcessRegressor(k, normalize_y=True, optimizer=None).fit(X, Y[:, a])
        mean, std = sk.predict(Xt, return_std=True)
        assert np.allclose(gp.predict(Xt)[:, a], mean, rtol=1e-8, atol=1e-14)
        # scikit-learn's std includes the white noise; the compensator's ratio is of the smooth part
        ratio = np.sqrt(np.clip(std ** 2 / gp.y_std[a] ** 2 - gp.noise_var[a], 0, None) / gp.signal_var[a])
        assert np.all(gp.std_ratio(Xt) >= ratio - 1e-6)
    x = ca.SX.sym("x", 4)
    f = ca.Function("f", [x], [gp.casadi(x)])
    assert np.allclose(np.array(f.map(len(Xt))(Xt.T)).T, gp.predict(Xt), rtol=1e-10, atol=1e-16)
    again = ResidualGP.from_dict(json.loads(json.dumps(gp.to_dict())))
    assert np.array_equal(again.predict(Xt), gp.predict(Xt))
    # it knows near its poses, not far from them
    assert gp.knows(X).mean() > 0.9 and not gp.knows(X + 50.0).any()


@pytest.mark.parametrize("seed", SEEDS)
def test_the_gp_compensator_takes_what_no_cause_names(seed):
    """A hidden compliance and a smooth error in no catalogue: the compliance is named, the rest is taken by
    the GP compensator (an unexplained finding of the session, in the final model), which lowers the
    held-out error of that session; a calibration taken to another session drops it (and says so)."""
    robot = robot_from_dict(ARM7_DH)
    _, truth = simulate(robot, 10, Effects(stiffness={2: 2e4}), seed=seed, floor_z=None)
    cal, val = with_structure(robot, 150, truth, seed + 1), with_structure(robot, 200, truth, seed + 2)
    rep = diagnose(robot, cal, val, DiagnosisSettings(seed=seed))
    named = [(f.cause, f.candidate.joint) for f in rep.findings if f.in_model and f.cause != "geometric"]
    assert ("joint_compliance", 2) in named and ("unexplained", None) in named, named
    compensator = next(f for f in rep.findings if f.in_model and f.cause == "unexplained")
    assert compensator.scope == "session" and "gp_compensator" in rep.final_model
    kept = [s for s in rep.steps if s.accepted]
    assert kept[-1].validation.mean_mm < 0.8 * kept[-2].validation.mean_mm
    other = another_session(truth, (0.8, 0.4, 0.0), (0.0, 0.0, 1.0))
    there, _ = simulate(robot, 40, truth=other, seed=seed + 3, floor_z=None)
    moved = calibrate(rep.final, there, "base", "lm", warn=False)
    assert "gp_compensator" not in moved.model.spec and any("gp_compensator dropped" in n for n in moved.notes)


@pytest.mark.parametrize("seed", SEEDS)
def test_no_gp_compensator_on_noise(seed):
    """Geometry and noise only: nothing for the GP compensator to learn, and it is not kept."""
    robot = robot_from_dict(ARM5)
    cal, truth = simulate(robot, 120, Effects(), seed=seed, floor_z=None)
    val, _ = simulate(robot, 150, truth=truth, seed=seed + 500, floor_z=None)
    rep = diagnose(robot, cal, val, DiagnosisSettings(seed=seed))
    assert "gp_compensator" not in rep.final_model
    step = rep.steps[-1]
    assert step.model.endswith("+gp_compensator") and not step.accepted and step.reason


def test_predict_says_where_the_compensator_applies(tmp_path, capsys):
    """calibrate --model kinematic+gp_compensator: the JSON holds the process, predict applies it at the poses
    where it knows and says at how many; poses far from the calibration's (another joint range) fall back to
    the physical model."""
    robot = robot_from_dict(ARM7_DH)
    _, truth = simulate(robot, 10, Effects(), seed=4, floor_z=None)
    cal = with_structure(robot, 150, truth, 5)
    val = with_structure(robot, 100, truth, 6)
    arm = tmp_path / "arm.toml"
    arm.write_text(to_toml(ARM7_DH))
    cal.write_csv(tmp_path / "cal.csv")
    val.write_csv(tmp_path / "val.csv")
    out = tmp_path / "cal.json"
    assert main(["calibrate", str(arm), str(tmp_path / "cal.csv"), "--model", "kinematic+gp_compensator",
                 "--solver", "lm", "--out", str(out)]) == 0
    res = load_calibration(out)
    plain = calibrate(robot, cal, "kinematic", "lm", warn=False)
    assert res.stats(val).mean_mm < 0.6 * plain.stats(val).mean_mm
    capsys.readouterr()
    assert main(["predict", str(out), str(tmp_path / "val.csv"), "--out", str(tmp_path / "p.csv")]) == 0
    text = capsys.readouterr().out
    assert "GP compensator" in text and "of 100 poses" in text
    far = val.subset(np.arange(20))
    for j in (1, 2, 3):             # joints 1-3 turned 200 deg: poses the process never saw
        far.columns[f"q{j}_deg"] = far.columns[f"q{j}_deg"] + 200.0
    known = res.model.term("gp_compensator").gp.knows(far.q)
    assert not known.all()
    gp_off = res.model.covariates(far)[:, res.model.covariate_names.index("gp_gate")]
    assert np.array_equal(gp_off.astype(bool), known)
    assert math.isfinite(res.stats(far).mean_mm)


def test_a_transfer_keeps_the_compensator_only_when_asked(tmp_path):
    robot = robot_from_dict(ARM7_DH)
    _, truth = simulate(robot, 10, Effects(), seed=8, floor_z=None)
    cal = with_structure(robot, 120, truth, 9)
    res = calibrate(robot, cal, "kinematic+gp_compensator", "lm", warn=False)
    few = with_structure(robot, 30, truth, 10)
    assert "gp_compensator" not in calibrate(res, few, "base", "lm", warn=False).model.spec
    kept = calibrate(res, few, "base", "lm", warn=False, keep_compensator=True)
    assert "gp_compensator" in kept.model.spec
    assert np.array_equal(kept.model.term("gp_compensator").gp.Y, res.model.term("gp_compensator").gp.Y)


def test_the_correction_shrinks_with_what_it_knows():
    """With a shrinkage strength p the correction is the posterior mean times (1 - r^2)^p, r its std over its
    prior's: nearly whole near the poses it learnt from, nothing far from them; what it leaves has the variance
    v + (1 - w)^2 (s^2 - v) (its predictive std where all applies, its prior's where none); the file keeps p."""
    rng = np.random.default_rng(1)
    X = rng.uniform(-2, 2, (80, 4))
    Y = np.column_stack([np.sin(X[:, 0]), np.cos(X[:, 1]), X[:, 2] * X[:, 3]]) * 1e-4 + rng.normal(0, 2e-6, (80, 3))
    gp = ResidualGP.fit(X, Y)
    gp.max_std_ratio, gp.shrink = 1.0, 2.0
    r = gp.std_ratio(X)
    assert np.allclose(gp.weight(X), (1 - r ** 2) ** 2)
    assert np.median(gp.weight(X)) > 0.9 and np.all(gp.weight(X + 50.0) == 0)
    mid = X + rng.normal(0, 0.8, X.shape)
    w = gp.weight(mid)
    assert np.all(np.diff(gp.weight(X[:1] + np.linspace(0, 6, 30)[:, None])) <= 1e-12)   # shrinks going away
    std = gp.predictive_std(mid)
    for a in range(3):
        v = (gp.std_ratio_of(mid, a) ** 2) * gp.signal_var[a]
        assert np.allclose(std[:, a], np.sqrt(v + (1 - w) ** 2 * (gp.signal_var[a] - v)) * gp.y_std[a])
    assert np.allclose(gp.predictive_std(X + 50.0), np.sqrt(gp.signal_var) * gp.y_std)
    again = ResidualGP.from_dict(json.loads(json.dumps(gp.to_dict())))
    assert again.shrink == 2.0 and np.array_equal(again.weight(mid), w)
    old = gp.to_dict()
    del old["shrink"]                    # a file of an earlier version: the on/off support
    assert set(np.unique(ResidualGP.from_dict(old).weight(mid))) <= {0.0, 1.0}


def test_the_worst_case_judge_compares_like_with_like():
    """The GP compensator's worst held-out error leaves out the poses both models miss by more than the noise:
    a rise there does not veto a real gain; a rise elsewhere does."""
    from casadical.calibration import GPCompensatorFolds
    from casadical.diagnosis import judge

    rng = np.random.default_rng(0)
    n = 200
    Y = rng.normal(0, 1e-4, (n, 3))
    Y[0] = [3e-3, 0, 0]                              # a pose both models miss by far
    pred = 0.6 * Y                                   # a real gain at every pose
    pred[0] = [-0.5e-3, 0, 0]                        # ... and a worse miss of the far pose
    ratio = np.full(n, 0.1)
    folds = GPCompensatorFolds(np.linalg.norm(Y, axis=1), {"random": [(np.arange(n), Y, pred, ratio)]},
                               {"random": 1})
    assert judge(folds, 1.0, 0.05)[0]                # judged on every pose: the worst case vetoes
    assert not judge(folds, 1.0, 0.05, band=1.0)[0]  # the far pose left out: the gain stands
    pred[5] = Y[5] + [1.5e-3, 0, 0]                  # a rise at a pose within the noise: it vetoes
    reasons = judge(folds, 1.0, 0.05, band=1.0)[0]
    assert reasons and "worst" in reasons[0]


@pytest.mark.parametrize("seed", SEEDS)
def test_a_student_t_likelihood_is_not_pulled_by_the_poses_it_misses(seed):
    """A smooth residual and a few poses missed by far (a bad shot in every axis, 10-30x the noise): with the
    Student-t likelihood those poses get small weights, the others about 1, and the correction at new poses stays
    near the smooth residual where the Gaussian's is pulled; the file keeps the weights."""
    rng = np.random.default_rng(seed)
    X = rng.uniform(-2, 2, (200, 5))

    def smooth(X):
        return np.column_stack([np.sin(X[:, 0] + X[:, 1]), np.cos(X[:, 1] * X[:, 2]), X[:, 3] * X[:, 4] / 4]) * 1e-4

    Y = smooth(X) + rng.normal(0, 1e-5, (200, 3))
    bad = rng.choice(200, 5, replace=False)
    Y[bad] += rng.choice([-1, 1], (5, 3)) * rng.uniform(1e-4, 3e-4, (5, 3))
    Xt = rng.uniform(-2, 2, (300, 5))
    gaussian = ResidualGP.fit(X, Y, seed=seed)
    err = {nu: np.linalg.norm(ResidualGP.fit(X, Y, seed=seed, robust_nu=nu).predict(Xt) - smooth(Xt), axis=1).mean()
           for nu in (None, 4.0)}
    t = ResidualGP.fit(X, Y, seed=seed, robust_nu=4.0)
    # started from the Gaussian fit already made (the GP compensator fits both): the same to the bit
    warm = ResidualGP.fit(X, Y, seed=seed, robust_nu=4.0, gaussian=gaussian)
    for a in ("length_scales", "signal_var", "noise_var", "pose_weights"):
        assert np.array_equal(getattr(warm, a), getattr(t, a)), a
    good = np.setdiff1d(np.arange(200), bad)
    assert t.pose_weights[bad].max() < 0.2 and np.median(t.pose_weights[good]) > 0.7, t.pose_weights[bad]
    assert err[4.0] < 0.8 * err[None], err
    again = ResidualGP.from_dict(json.loads(json.dumps(t.to_dict())))
    assert np.array_equal(again.pose_weights, t.pose_weights)
    assert np.allclose(again.predict(Xt), t.predict(Xt), rtol=1e-10, atol=1e-16)
    assert np.allclose(t.refit(good).pose_weights, t.pose_weights[good])
