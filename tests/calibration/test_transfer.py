"""Taking a calibration further: only what the specification names is estimated again."""

import json
import math

import numpy as np
import pytest

from casadical import calibrate, load_calibration, load_robot
from casadical.cli import main
from casadical.data import Effects, simulate
from casadical.robot import robot_from_dict
from tests.helpers.arms import ARM7_DH


def _series(robot, truth, n, seed, base_xyz, base_rpy):
    """Another measurement series of the same robot: the tracker stands elsewhere."""
    from dataclasses import replace

    from casadical.kinematics import base_pose_matrix
    from casadical.model import pose_to_base0
    t2 = replace(truth, base0=pose_to_base0(base_pose_matrix(base_xyz, base_rpy)))
    data, _ = simulate(robot, n, truth=t2, seed=seed, floor_z=None)
    return data


@pytest.mark.parametrize("name,seed", [("ys100", 0), ("ys100", 1), ("seven", 2)])
def test_base_only_keeps_everything_else(name, seed):
    robot = load_robot("ys100") if name == "ys100" else robot_from_dict(ARM7_DH)
    eff = Effects(stiffness={2: 1.2e6, 3: 0.8e6}) if name == "ys100" else Effects(stiffness={2: 2e4, 4: 1e4})
    spec = "kinematic+compliance[2,3]" if name == "ys100" else "kinematic+compliance[2,4]"
    cal, truth = simulate(robot, 80, eff, seed=seed, floor_z=None)
    first = calibrate(robot, cal, spec, "lm", warn=False)
    other = _series(robot, truth, 60, seed + 10, (2.0, -1.0, 0.3), (0.01, 0.02, 1.2))
    few, rest = other.subset(np.arange(12)), other.subset(np.arange(12, 60))
    moved = calibrate(first, few, "base", "lm", warn=False)
    free = {p.name for p in moved.parameters if not p.fixed}
    assert free == {f"base_{k}" for k in ("x", "y", "z", "roll", "pitch", "yaw")}
    for p in moved.parameters:
        if p.group != "base":
            assert p.value == first.parameters[p.name].value, p.name
    # the calibrated model, moved to the new tracker set-up on 12 poses, predicts the rest as well
    # as it predicted its own validation poses
    val, _ = simulate(robot, 60, truth=truth, seed=seed + 20, floor_z=None)
    assert moved.stats(rest).mean_mm < 1.5 * first.stats(val).mean_mm + 0.01
    assert moved.model.spec == first.model.spec


def test_geometry_refit_keeps_compliance_and_adds_terms():
    robot = load_robot("ys100")
    cal, truth = simulate(robot, 80, Effects(stiffness={2: 1.2e6, 3: 0.8e6}), seed=4)
    first = calibrate(robot, cal, "kinematic+compliance[2,3]", "lm", warn=False)
    other = _series(robot, truth, 80, 14, (0.5, 0.2, 0.0), (0.0, 0.0, 0.4))
    refit = calibrate(first, other, "kinematic", "lm", warn=False)
    for j in (2, 3):
        p = refit.parameters[f"c{j}"]
        assert p.fixed and p.value == first.parameters[f"c{j}"].value
    assert not refit.parameters["a2"].fixed
    # a term the calibration lacks is added and estimated; the others are kept
    more = calibrate(first, other, "kinematic+encoder_scale[4]", "lm", warn=False)
    assert "escale4" in more.parameters and not more.parameters["escale4"].fixed
    assert more.parameters["c2"].fixed


def test_cli_transfer_and_rbf_compensator(tmp_path, capsys):
    robot = load_robot("ys100")
    # a smooth error no named term explains: a gear error of joint 2 with a slowly varying phase
    cal, truth = simulate(robot, 300, Effects(periodic=[(2, 2, math.radians(0.03), 0.3)]), seed=7)
    val, _ = simulate(robot, 150, truth=truth, seed=8)
    cal.write_csv(tmp_path / "cal.csv")
    val.write_csv(tmp_path / "val.csv")
    out = tmp_path / "rbf.json"
    assert main(["calibrate", "ys100", str(tmp_path / "cal.csv"), "--model", "kinematic+rbf_compensator",
                 "--out", str(out), "--solver", "lm"]) == 0
    doc = json.loads(out.read_text())
    assert doc["model"] == "kinematic+rbf_compensator" and doc["terms"]["rbf_compensator"]["network"]
    # the network's weights are not counted: no AIC or BIC (null, not a misleading number)
    assert doc["statistics"] is None and "AIC" not in capsys.readouterr().out
    with_rbf = load_calibration(out)
    plain = calibrate(robot, cal, "kinematic", "lm", warn=False)
    assert with_rbf.stats(val).mean_mm < 0.85 * plain.stats(val).mean_mm
    # taken to a new tracker set-up: the compensator (robot base frame) still holds
    other = _series(robot, truth, 40, 9, (1.0, 2.0, 0.0), (0.0, 0.0, 2.5))
    other.write_csv(tmp_path / "other.csv")
    assert main(["calibrate", str(out), str(tmp_path / "other.csv"), "--model", "base", "--solver", "lm",
                 "--out", str(tmp_path / "moved.json")]) == 0
    moved = load_calibration(tmp_path / "moved.json")
    assert moved.model.spec == "kinematic+rbf_compensator"
    assert moved.stats(other).mean_mm < 1.3 * with_rbf.stats(val).mean_mm


@pytest.mark.parametrize("spec", ["base", "kinematic"])
def test_transfer_drops_what_belongs_to_the_session(tmp_path, capsys, spec):
    """A calibration with a drift taken to another series, whose times start anywhere: the drift is the
    first session's, so it is dropped and the output says so; the robot's values carry, and the error
    there is the robot's (not the drift run on the other file's clock)."""
    robot = robot_from_dict(ARM7_DH)
    eff = Effects(stiffness={2: 2e4}, drift=(2e-6, 0.0, -1e-6))
    cal, truth = simulate(robot, 120, eff, seed=3, floor_z=None)
    first = calibrate(robot, cal, "kinematic+compliance[2]+drift", "lm", warn=False)
    assert first.parameters["drift_x"].value == pytest.approx(2e-6, rel=0.1)
    other = _series(robot, truth, 80, 13, (1.0, -0.5, 0.2), (0.0, 0.01, 0.7))
    other.columns["time_s"] = other.columns["time_s"] + 5000.0     # another day's clock
    first.save(tmp_path / "cal.json")
    other.write_csv(tmp_path / "other.csv")
    capsys.readouterr()
    assert main(["calibrate", str(tmp_path / "cal.json"), str(tmp_path / "other.csv"), "--model", spec,
                 "--solver", "lm", "--out", str(tmp_path / "moved.json")]) == 0
    out = capsys.readouterr()
    assert "drift dropped" in out.out + out.err
    moved = load_calibration(tmp_path / "moved.json")
    assert "drift" not in moved.model.spec and not [p for p in moved.parameters if p.term == "drift"]
    assert moved.parameters["c2"].value == first.parameters["c2"].value
    # what is left is the drift of the other series itself (2.2 um/s over 80 s: ~0.1 mm), not 5000 s of it
    assert moved.calibration.mean_mm < 0.2


def test_diagnose_says_what_the_transfer_study_does(tmp_path, capsys):
    """Every finding taken to the other series gets a progress line (stderr); --quiet says nothing."""
    robot = load_robot("ys100")
    cal, truth = simulate(robot, 60, Effects(stiffness={2: 1.5e6}), seed=5)
    val, _ = simulate(robot, 60, truth=truth, seed=6)
    other = _series(robot, truth, 80, 7, (1.0, -0.5, 0.2), (0.0, 0.01, 0.8))
    for name, d in (("cal", cal), ("val", val), ("other", other)):
        d.write_csv(tmp_path / f"{name}.csv")
    args = ["diagnose", "ys100", str(tmp_path / "cal.csv"), "--validate", str(tmp_path / "val.csv"), "--transfer",
            str(tmp_path / "other.csv"), "--json", str(tmp_path / "r.json"), "--no-layer", "--force"]
    assert main(args) == 0
    err = capsys.readouterr().err
    doc = json.loads((tmp_path / "r.json").read_text())
    taken = [f for f in doc["findings"] if f.get("transfer")]
    assert taken and f"transfer: taking the final and the kinematic model to {tmp_path / 'other.csv'}" in err
    for k, f in enumerate(taken, 1):
        assert f"transfer: {k} of {len(taken)}, " in err
    assert main(args + ["--quiet"]) == 0
    assert capsys.readouterr().err == ""


def test_predict_warns_when_a_session_term_meets_another_file(tmp_path, capsys):
    """predict with a calibration holding a drift, on a file not named as of its session: a warning names the
    term and how to take the calibration there first."""
    robot = robot_from_dict(ARM7_DH)
    cal, truth = simulate(robot, 80, Effects(drift=(1e-6, 0.0, 0.0)), seed=5, floor_z=None)
    calibrate(robot, cal, "kinematic+drift", "lm", warn=False).save(tmp_path / "cal.json")
    other, _ = simulate(robot, 20, truth=truth, seed=6, floor_z=None)
    other.write_csv(tmp_path / "other.csv")
    capsys.readouterr()
    assert main(["predict", str(tmp_path / "cal.json"), str(tmp_path / "other.csv"), "--out",
                 str(tmp_path / "p.csv")]) == 0
    err = capsys.readouterr().err
    assert "holds drift, of the measurement session it was fitted on" in err and "--model base" in err
