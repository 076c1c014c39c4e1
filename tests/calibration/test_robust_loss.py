"""Robust estimation: a bad tracker shot is set aside and named, not fitted."""

import json

import numpy as np
import pytest

from casadical import calibrate, load_robot
from casadical.cli import main
from casadical.data import Effects, simulate
from casadical.problem import RobustLoss
from casadical.robot import robot_from_dict
from tests.helpers.arms import ARM4_BETA


def _spoil(data, rows, rng, size_mm=20.0):
    """Add gross errors (a tracker shot ``size_mm`` off in a random direction) to some rows."""
    bad = data.subset(np.arange(len(data)))
    for r in rows:
        v = rng.normal(size=3)
        for c, dv in zip(("x_mm", "y_mm", "z_mm"), size_mm * v / np.linalg.norm(v)):
            bad.columns[c] = bad.columns[c].copy()
            bad.columns[c][r] += dv
    return bad


@pytest.mark.parametrize("robot_name,n_bad,seed", [("ys100", 1, 0), ("ys100", 3, 1), ("ys100", 3, 2),
                                                   ("four", 1, 3), ("four", 3, 4)])
@pytest.mark.parametrize("solver", ["lm", "ipopt"])
def test_gross_outliers_are_set_aside(robot_name, n_bad, seed, solver):
    robot = load_robot("ys100") if robot_name == "ys100" else robot_from_dict(ARM4_BETA)
    spec = "kinematic+compliance" if robot_name == "ys100" else "kinematic"
    eff = Effects(stiffness={2: 1.5e6, 3: 1.2e6}) if robot_name == "ys100" else Effects()
    cal, truth = simulate(robot, 90, eff, seed=seed, floor_z=None)
    val, _ = simulate(robot, 200, truth=truth, seed=seed + 100, floor_z=None)
    rng = np.random.default_rng(seed)
    rows = sorted(rng.choice(len(cal), n_bad, replace=False))
    bad = _spoil(cal, rows, rng)
    clean = calibrate(robot, cal, spec, solver, warn=False).stats(val).mean_mm
    robust = calibrate(robot, bad, spec, solver, warn=False)
    plain = calibrate(robot, bad, spec, solver, warn=False, robust="none").stats(val).mean_mm
    assert robust.stats(val).mean_mm < 1.2 * clean, (robust.stats(val).mean_mm, clean, plain)
    assert plain > 3 * clean                      # the outliers do matter without the robust loss
    named = sorted(d["line"] for d in robust.downweighted)
    assert named == [int(bad.lines[r]) for r in rows]
    assert all(d["residual_mm"] > 10 for d in robust.downweighted)


def test_clean_data_lose_nothing():
    """With Gaussian noise only, the robust loss sets nothing aside and the fit equals least squares."""
    robot = load_robot("ys100")
    for seed in range(3):
        cal, truth = simulate(robot, 80, Effects(), seed=seed)
        val, _ = simulate(robot, 200, truth=truth, seed=seed + 100)
        r = calibrate(robot, cal, "kinematic", "lm", warn=False)
        p = calibrate(robot, cal, "kinematic", "lm", warn=False, robust="none")
        assert r.downweighted == []
        assert abs(r.stats(val).mean_mm / p.stats(val).mean_mm - 1) < 0.03
        # the noise scale is the simulated one (20 um per axis)
        assert 0.014 < r.loss.sigma * 1000 < 0.026


def test_loss_is_least_squares_near_zero_and_linear_far_out():
    loss = RobustLoss("huber", c=3.0, sigma=1e-3)
    u = np.array([1e-6, 1.0])  # m
    rho = loss.rho(u ** 2)
    assert abs(rho[0] / (0.5 * u[0] ** 2) - 1) < 1e-6
    assert abs(rho[1] / (3e-3 * u[1]) - 1) < 0.01          # c sigma |r|
    assert RobustLoss("none").weight(np.array([1.0]))[0] == 1.0


def test_cli_reports_set_aside_lines(tmp_path, capsys):
    robot = load_robot("ys100")
    cal, _ = simulate(robot, 80, Effects(), seed=5)
    bad = _spoil(cal, [10], np.random.default_rng(5))
    bad.write_csv(tmp_path / "cal.csv")
    out = tmp_path / "cal.json"
    assert main(["calibrate", "ys100", str(tmp_path / "cal.csv"), "--model", "kinematic", "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "1 pose(s) down-weighted" in text and "12" in text      # file line of data row 10
    doc = json.loads(out.read_text())
    assert [d["line"] for d in doc["robust"]["downweighted"]] == [12]
    assert main(["calibrate", "ys100", str(tmp_path / "cal.csv"), "--model", "kinematic", "--out",
                 str(tmp_path / "plain.json"), "--robust", "none"]) == 0
    assert json.loads((tmp_path / "plain.json").read_text())["robust"]["downweighted"] == []
