"""Never worse than a kinematic calibration of the same poses (issue 25 item 1), on arms that are not built in.

- A weak design (36 poses moving one joint at a time from a common pose, 24 to calibrate): the geometry step
  was rejected on folds that left out whole sweeps and on a BIC no design of 72 coordinates can pass, so the
  final model was the nominal one, twice as bad as a plain kinematic calibration. It must be no worse, and the
  report must say that the design is weak and why.
- A validation pose that no model of the robot predicts (the tracker bumped while measuring it): the final
  model's worst validation error rises over the kinematic model's; the validation poses never decide, so the
  model is the same with or without that pose, and the report must say the worst case rose, where, and why.
"""

import math

import numpy as np
import pytest

from casadical import calibrate
from casadical.data import Measurements
from casadical.diagnosis import DiagnosisSettings, diagnose
from casadical.robot import robot_from_dict
from tests.helpers.arms import ARM5, ARM6
from tests.truth import Arm, Effects, TrueRobot, measure, sample


def measured(tmp_path, name, robot, q, rng, **kw) -> Measurements:
    """Shots of the true robot at ``q``, written as a measurement file and read as a user's."""
    path = measure(robot, q, rng, **kw).write_csv(tmp_path / f"{name}.csv")
    return Measurements.read_csv(path, n_joints=robot.arm.n)

def one_joint_at_a_time(n_joints: int, width_deg: float, per_joint: int = 6) -> np.ndarray:
    """Poses that move one joint at a time from the zero pose, ``per_joint`` readings over +-``width_deg`` each."""
    rows = []
    for j in range(n_joints):
        for v in np.linspace(-width_deg, width_deg, per_joint):
            q = np.zeros(n_joints)
            q[j] = math.radians(v)
            rows.append(q)
    return np.array(rows)


@pytest.mark.parametrize("seed", [1, 5, 7])
def test_weak_design_is_never_worse_than_a_kinematic_calibration(tmp_path, seed):
    """36 poses, one joint at a time, 24 to calibrate (a compliance of joints 2 and 3 larger than the geometry's
    errors): the final model predicts the other 12 no worse than ``calibrate --model kinematic`` (mean; worst
    case within 5 % or said), and the report says the design is weak and why. In these seeds today's code
    (fe55b8a) rejects the geometry (folds that leave out whole sweeps; a BIC 72 coordinates cannot pass) and ends
    1.4-2x worse than the kinematic calibration: 0.53 against 0.37 mm, 0.57 against 0.30, 0.48 against 0.24."""
    robot = robot_from_dict(ARM6)
    rng = np.random.default_rng(seed)
    truth = TrueRobot.draw(Arm.from_dict(ARM6), Effects(stiffness={2: 3e4, 3: 6e4}), rng, length_sigma=0.3e-3,
                           angle_sigma=math.radians(0.03))
    data = measured(tmp_path, "poses", truth, one_joint_at_a_time(6, 90), rng, noise=100e-6)
    idx = rng.permutation(len(data))
    cal, val = data.subset(np.sort(idx[:24])), data.subset(np.sort(idx[24:]))
    rep = diagnose(robot, cal, val, DiagnosisSettings(seed=seed))
    kin = calibrate(robot, cal, "kinematic", "lm", warn=False).stats(val)
    assert rep.final_validation.mean_mm <= kin.mean_mm * 1.02, (rep.final_model, rep.final_validation.mean_mm,
                                                                 kin.mean_mm, rep.notes)
    assert (rep.final_validation.max_mm <= kin.max_mm * 1.05
            or any("worst validation error" in n for n in rep.notes)), (rep.final_validation.max_mm, kin.max_mm)
    weak = [n for n in rep.notes if n.startswith("the design of the calibration poses is weak")]
    assert weak and "move one joint only" in weak[0] and "per free parameter" in weak[0], rep.notes
    assert rep.final_model.startswith("kinematic")


def test_strong_design_is_not_called_weak(tmp_path):
    """Random poses, many per parameter: no weak-design note, the folds as before (no prior)."""
    robot = robot_from_dict(ARM5)
    rng = np.random.default_rng(4)
    truth = TrueRobot.draw(Arm.from_dict(ARM5), Effects(), rng)
    cal = measured(tmp_path, "cal", truth, sample(truth, 80, rng), rng)
    val = measured(tmp_path, "val", truth, sample(truth, 60, rng), rng)
    rep = diagnose(robot, cal, val, DiagnosisSettings(seed=4, blackbox=False))
    assert not any("is weak" in n for n in rep.notes), rep.notes
    assert rep.final_model == "kinematic"


@pytest.mark.parametrize("seed", [0, 1])
def test_a_worst_case_that_rises_is_said_and_never_decides(tmp_path, seed):
    """A validation pose measured with the tracker bumped (a 10 mm displacement, along the kinematic model's own
    error there): the final model, better everywhere else, misses it by more than the kinematic model does. The
    report says so, names the pose, and says no model of the robot predicts it; and the same diagnosis without
    that pose gives the same final model (the validation poses judge, never decide). Today's code says nothing."""
    robot = robot_from_dict(ARM5)
    rng = np.random.default_rng(seed)
    truth = TrueRobot.draw(Arm.from_dict(ARM5), Effects(stiffness={2: 1.5e5},
                                                         periodic=[(1, 11, math.radians(0.02), 0.4)]), rng)
    cal = measured(tmp_path, "cal", truth, sample(truth, 120, rng), rng, noise=30e-6)
    val = measured(tmp_path, "val", truth, sample(truth, 80, rng), rng, noise=30e-6)
    kin = calibrate(robot, cal, "kinematic", "lm", warn=False)
    r = kin.predict(val) - val.xyz                          # the kinematic model's error at each validation pose
    i = int(np.argmax(np.linalg.norm(r, axis=1)))
    xyz = val.xyz.copy()
    xyz[i] += 10e-3 * r[i] / np.linalg.norm(r[i])
    bumped = val.with_positions(xyz)
    rep = diagnose(robot, cal, bumped, DiagnosisSettings(seed=seed))
    e_kin = np.linalg.norm(kin.predict(bumped) - bumped.xyz, axis=1) * 1000
    assert rep.final_validation.max_mm > 1.05 * e_kin.max()          # the case: it rose
    said = [n for n in rep.notes if "worst validation error" in n]
    assert said, rep.notes
    assert f":{bumped.line(i)}" in said[0] and "likely bad measurements" in said[0], said[0]
    clean = diagnose(robot, cal, val.subset(np.setdiff1d(np.arange(len(val)), [i])), DiagnosisSettings(seed=seed))
    assert clean.final_model == rep.final_model
    assert np.allclose(clean.final.parameters.values, rep.final.parameters.values)


def test_a_worst_fold_error_that_rises_is_worse_unless_the_mean_drops_as_much():
    """The fold judge: a mean above the kinematic model's is worse; a worst error more than 5 % above it is worse,
    unless the same kind's mean drops by more than 5 % (a trade the report states: two sessions, one holding
    joint 1 within 6 deg, made its encoder scale look worse on the other session's fold while the validation mean
    fell from 0.136 to 0.032 mm; tests/planning/test_next_poses.py's robot-or-session loop runs that case)."""
    from casadical.diagnosis import Held

    kin = Held({"random": 0.10, "session": 0.12}, {"random": 0.40, "session": 0.46})
    assert Held({"random": 0.09, "session": 0.10}, {"random": 0.40, "session": 0.49}).worse_than(kin) == []
    assert Held({"random": 0.09, "session": 0.10}, {"random": 0.40, "session": 0.49}).traded(kin) == ["session"]
    assert Held({"random": 0.09, "session": 0.118}, {"random": 0.40, "session": 0.49}).worse_than(kin) == [
        "worst session 0.4600 -> 0.4900 mm"]
    assert Held({"random": 0.11, "session": 0.10}, {"random": 0.40, "session": 0.46}).worse_than(kin) == [
        "mean random 0.1000 -> 0.1100 mm"]
