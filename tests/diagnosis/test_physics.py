"""A named cause must be physics: inside its bounds, told apart from the geometry, significant, and
meaningful over the data (casadical.stats._physics, its use by the diagnosis)."""

import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from casadical import calibrate, load_robot
from casadical.data import Effects, Measurements, simulate
from casadical.diagnosis import DiagnosisSettings, diagnose
from casadical.robot import robot_from_dict
from casadical.stats import term_causes, value_violations, violations
from tests.helpers.arms import ARM3, ARM4

SEEDS = [0, 1, 2]
UR10_B = Path(__file__).resolve().parents[2] / "problems" / "datasets" / "ur10-ipa" / "series_b.csv"


def narrow(arm: dict, joint: int, lo: float, hi: float):
    """``arm`` with joint ``joint`` confined to [lo, hi] deg."""
    r = robot_from_dict(arm)
    joints = list(r.joints)
    joints[joint - 1] = replace(joints[joint - 1], min=math.radians(lo), max=math.radians(hi))
    return replace(r, joints=joints)


def run(robot, effects, seed, n_cal=80, n_val=200):
    cal, truth = simulate(robot, n_cal, effects, seed=seed, floor_z=None)
    val, _ = simulate(robot, n_val, truth=truth, seed=seed + 500, floor_z=None)
    return diagnose(robot, cal, val, DiagnosisSettings(seed=seed)), cal


def named(report):
    return [f.candidate for f in report.findings if f.in_model and f.cause not in ("geometric", "unexplained")]


@pytest.mark.parametrize("seed", SEEDS)
def test_motion_backlash_trails_its_motor(seed):
    """Play taken up by the direction of motion (the output trails its motor) is found with a positive half
    play, on an arm that is not built in."""
    robot = robot_from_dict(ARM4)
    rep, _ = run(robot, Effects(backlash_motion={3: math.radians(0.01)}), seed)
    found = named(rep)
    assert [(c.cause, c.joint, c.source) for c in found] == [("backlash", 3, "motion")], found
    f = next(f for f in rep.findings if f.candidate in found)
    assert f.parameters["backlash_m3"]["value"] == pytest.approx(0.01, rel=0.1)


@pytest.mark.parametrize("seed", SEEDS)
def test_a_lead_is_not_backlash(seed):
    """A joint whose output *leads* its motor by the direction of the last move has the structure of motion
    backlash with a negative half play: never named backlash; reported as structure of that joint."""
    robot = robot_from_dict(ARM4)
    rep, _ = run(robot, Effects(backlash_motion={3: -math.radians(0.01)}), seed)
    assert not [c for c in named(rep) if c.cause == "backlash"], named(rep)
    kept = [f for f in rep.findings if f.cause == "unexplained" and f.candidate.joint == 3]
    assert kept and "lead" in kept[0].where


@pytest.mark.parametrize("seed", SEEDS)
def test_backlash_whose_sign_never_changes_is_a_joint_offset(seed):
    """Joint 2 of the three-axis DH arm confined to -10..50 deg: its gravity torque never changes sign, so
    a hidden 'backlash' of it is a constant offset of the joint. The diagnosis does not name it (the
    geometry's theta2 takes it), and a calibration that asks for it says so."""
    robot = narrow(ARM3, 2, -10, 50)
    rep, cal = run(robot, Effects(backlash={2: math.radians(0.02)}), seed)
    assert not [c for c in named(rep) if c.cause == "backlash"], named(rep)
    res = calibrate(robot, cal, "kinematic+backlash[2]", "lm", warn=False)
    broken = violations(res, cal, ["backlash2"])
    assert broken and any("constant offset" in v.text for v in broken), broken


def test_value_rules_flag_bounds_and_a_spring_that_turns_back():
    """The rules on values alone: a negative compliance or half play is outside its bounds; a progressive
    spring whose deflection falls with load inside the data's torque range is not a stiffness; one that
    stiffens but keeps rising passes."""
    robot = robot_from_dict(ARM4)
    data, _ = simulate(robot, 60, Effects(stiffness={2: 2e5}), seed=0, floor_z=None)
    res = calibrate(robot, data, "kinematic+compliance[2]+nonlinear_stiffness[2]+backlash_motion[3]", "lm",
                    warn=False)
    tau = res.model.torques(data.q, res.parameters.values, res.model.covariates(data))
    top = float(np.max(np.abs(tau[:, 1])))
    P = res.parameters.copy()
    P["c2"].value = 5e-6
    for cubic, turns in ((-5e-6 / (3 * (0.8 * top) ** 2), True), (-5e-6 / (3 * (1.2 * top) ** 2), False)):
        P["cubic2"].value = cubic
        out = value_violations(P, ["c2", "cubic2"], tau, data.moves)
        assert any(v.rule == "physics" and "turns back" in v.text for v in out) == turns, out
    P["c2"].value, P["backlash_m3"].value = -1e-7, -1e-5
    out = value_violations(P, ["c2", "backlash_m3"], tau, data.moves)
    assert {v.parameters[0] for v in out if v.rule == "bounds"} == {"c2", "backlash_m3"}
    assert any("lead its motor" in v.text for v in out)


def test_compliance_without_an_effect_is_not_significant():
    """A compliance fitted where there is none (LM, unbounded) is flagged: below its bound or not
    significant; the compliance that is there passes every rule."""
    robot = robot_from_dict(ARM4)
    data, _ = simulate(robot, 80, Effects(stiffness={2: 2e5}), seed=1, floor_z=None)
    res = calibrate(robot, data, "kinematic+compliance[2,3]", "lm", warn=False)
    assert violations(res, data, ["c2"]) == []
    assert {v.rule for v in violations(res, data, ["c3"])} & {"bounds", "significance"}
    assert {c.label for c in term_causes(res)} == {"joint compliance of joint 2", "joint compliance of joint 3"}


def test_real_ur10_findings_are_physics():
    """The README job (series B, 300 calibration poses): every cause the diagnosis names passes every rule
    in the final model, and the final model does no worse than the kinematic one on its folds."""
    data = Measurements.read_csv(UR10_B, n_joints=6, require_positions=True)
    idx = np.sort(np.random.default_rng(0).permutation(len(data))[:300])
    cal, val = data.subset(idx), data.subset(np.setdiff1d(np.arange(len(data)), idx))
    rep = diagnose(load_robot("ur10"), cal, val, DiagnosisSettings(blackbox=False))
    final = rep.final
    for f in rep.findings:
        if f.in_model and f.cause not in ("geometric", "unexplained"):
            assert violations(final, cal, f.candidate.parameter_names()) == [], f.label()
    assert not [f for f in rep.findings if f.cause == "drift"]     # series B has no times
    assert rep.final_validation.mean_mm < rep.kinematic_validation.mean_mm
