"""Predict and compensate say when they extrapolate beyond what the calibration saw."""

import math
import re
from dataclasses import replace

import numpy as np
import pytest

from casadical import calibrate, load_robot
from casadical.cli import main
from casadical.data import Effects, simulate
from casadical.stats import Coverage


def _narrow(robot, j, lo, hi):
    joints = list(robot.joints)
    joints[j - 1] = replace(joints[j - 1], min=math.radians(lo), max=math.radians(hi))
    return replace(robot, joints=joints)


def test_predict_warns_outside_the_joint_ranges(tmp_path, capsys):
    robot = load_robot("ys100")
    cal, truth = simulate(_narrow(robot, 1, -40, 40), 60, Effects(), seed=3)
    inside = cal.subset(np.arange(10))
    outside, _ = simulate(_narrow(robot, 1, 60, 120), 5, truth=truth, seed=5)
    cal.write_csv(tmp_path / "cal.csv")
    inside.write_csv(tmp_path / "in.csv")
    outside.write_csv(tmp_path / "out.csv")
    assert main(["calibrate", "ys100", str(tmp_path / "cal.csv"), "--model", "kinematic", "--solver", "lm",
                 "--out", str(tmp_path / "cal.json")]) == 0
    capsys.readouterr()
    assert main(["predict", str(tmp_path / "cal.json"), str(tmp_path / "in.csv"),
                 "--out", str(tmp_path / "p1.csv")]) == 0
    assert "outside the ranges" not in capsys.readouterr().err
    assert main(["predict", str(tmp_path / "cal.json"), str(tmp_path / "out.csv"), "--out", str(tmp_path / "p2.csv"),
                 "--allow-mismatch"]) == 0
    err = capsys.readouterr().err
    assert "5 pose(s) (rows 2, 3, 4, 5, 6) have joint readings outside the ranges" in err and "joints 1" in err


def test_far_from_every_calibration_pose():
    rng = np.random.default_rng(0)
    q = rng.normal(0, 2, size=(300, 6))
    q[:, 2] = rng.uniform(-90, 90, 300)
    q[:, 2] = np.where(q[:, 2] > 0, q[:, 2] + 30, q[:, 2] - 30)     # a hole in joint 3: -30..30 never seen
    cov = Coverage.of(q)
    probe = np.zeros((2, 6))
    probe[1, :] = q[0]
    beyond, far = cov.outside(probe)
    assert not beyond.any()
    assert far[0] and not far[1]


def test_coverage_travels_with_the_calibration(tmp_path):
    robot = load_robot("ys100")
    cal, _ = simulate(robot, 40, Effects(), seed=1)
    res = calibrate(robot, cal, "kinematic", "lm", warn=False)
    res.save(tmp_path / "c.json")
    from casadical import load_calibration
    back = load_calibration(tmp_path / "c.json")
    assert np.allclose(back.coverage.q_min_deg, cal.q_deg.min(axis=0))
    assert np.allclose(back.coverage.poses_deg, cal.q_deg, atol=1e-6)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_the_spacing_is_the_median_nearest_neighbour_whenever_asked(seed):
    """The spacing (kept by the poses' bytes: a diagnosis' fits are of the same poses) is the median distance to
    the nearest other pose, computed here pose by pose, for every set asked, again and in turn (more sets than
    are kept, some of the same shape)."""
    rng = np.random.default_rng(seed)
    sets = [rng.uniform(-180, 180, (int(rng.integers(2, 80)), 6)) for _ in range(6)]
    sets.append(rng.uniform(-180, 180, sets[0].shape))
    for _ in range(25):
        q = sets[int(rng.integers(len(sets)))]
        d = np.sqrt(((q[:, None, :] - q[None, :, :]) ** 2).sum(axis=2)) + np.diag(np.full(len(q), np.inf))
        assert math.isclose(Coverage.of(q.copy()).spacing_deg, float(np.median(d.min(axis=1))), rel_tol=1e-9)


@pytest.mark.parametrize("units", [None, ("mm", "deg", "deg", "deg", "deg", "deg")], ids=["revolute", "track"])
def test_far_poses_are_said_with_the_distance_and_its_unit(units):
    """The distance a far pose lies from every calibration pose comes with its unit (issue 47: "more than 61 in
    joint space: deg"); with a linear axis, how its millimetres count."""
    rng = np.random.default_rng(1)
    q = rng.normal(0, 2, size=(300, 6))
    q[:, 2] = rng.uniform(-90, 90, 300)
    q[:, 2] = np.where(q[:, 2] > 0, q[:, 2] + 30, q[:, 2] - 30)     # joint 3 never between -30 and 30
    cov = Coverage.of(q, units=units)
    text, = cov.describe(np.zeros((1, 6)), np.array([2]), "p.csv")
    limit = cov.far_limit_deg()
    assert text.startswith("p.csv: 1 pose(s) (rows 2) lie far from every calibration pose (more than "
                           f"{limit:.0f} deg away in joint space"), text
    assert ("a linear axis' mm counted as deg" in text) == (units is not None), text


def test_a_file_row_is_a_row_in_every_message(tmp_path, capsys):
    """One word for a pose's place in its file, the one errors use ("row", the header row 1): the calibration's
    poses set aside, predict's warnings of poses outside what it saw, and an error (issue 47: "rows" and
    "lines" for the same thing)."""
    robot = load_robot("ys100")
    cal, truth = simulate(_narrow(robot, 1, -40, 40), 60, Effects(), seed=3)
    cal.columns["x_mm"][[4, 9]] += 3.0                           # two bad shots: rows 6 and 11 of the file
    outside, _ = simulate(_narrow(robot, 1, 60, 120), 3, truth=truth, seed=5)
    cal.write_csv(tmp_path / "cal.csv")
    outside.write_csv(tmp_path / "out.csv")
    (tmp_path / "bad.csv").write_text((tmp_path / "out.csv").read_text().replace("\n", "\n1,", 3)[:-1])
    said = []
    assert main(["calibrate", "ys100", str(tmp_path / "cal.csv"), "--model", "kinematic", "--solver", "lm",
                 "--out", str(tmp_path / "cal.json")]) == 0
    said.append(capsys.readouterr())
    assert main(["predict", str(tmp_path / "cal.json"), str(tmp_path / "out.csv"), "--out", str(tmp_path / "p.csv"),
                 "--allow-mismatch"]) == 0
    said.append(capsys.readouterr())
    assert main(["predict", str(tmp_path / "cal.json"), str(tmp_path / "bad.csv"), "--out",
                 str(tmp_path / "p2.csv")]) == 2
    said.append(capsys.readouterr())
    text = "\n".join(s.out + s.err for s in said)
    assert "(rows 11, 6)" in text and "(rows 2, 3, 4)" in text and "bad.csv, row 2" in text, text
    assert not re.search(r"\blines? \d", text), text
