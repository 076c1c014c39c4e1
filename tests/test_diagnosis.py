"""Diagnosis: a hidden effect must be named with its joint; noise alone must give no finding."""

import json
import math

import pytest

from casadical import load_robot
from casadical.cli import main
from casadical.diagnosis import DiagnosisSettings, diagnose
from casadical.robot import robot_from_dict
from casadical.simulate import Effects, simulate

from arms import ARM3

SEEDS = [0, 1, 2]


def run(robot, effects, seed, n_cal=80, n_val=200, **kw):
    cal, truth = simulate(robot, n_cal, effects, seed=seed, **kw)
    val, _ = simulate(robot, n_val, truth=truth, seed=seed + 500, **kw)
    return diagnose(robot, cal, val, DiagnosisSettings(seed=seed))


def causes(report):
    return [(f.candidate.cause, f.candidate.joint, f.candidate.harmonic) for f in report.findings]


def assert_found(report, cause, joint=None, harmonic=None):
    named = causes(report)
    extra = [c for c in named if c[0] not in ("geometric", cause)]
    assert any(c[0] == cause and (joint is None or c[1] == joint) and (harmonic is None or c[2] == harmonic)
               for c in named), named
    assert not extra, f"spurious findings {extra} in {named}"
    f = next(f for f in report.findings if f.candidate.cause == cause)
    assert f.gain_mm > 0 and "F =" in f.evidence
    assert_gains_are_the_steps(report)


def assert_gains_are_the_steps(report):
    """A finding's validation gain is what its step did to the validation mean, full fit to full fit."""
    done = [s for s in report.steps if s.accepted]
    for before, step in zip(done, done[1:]):
        f = next((f for f in report.findings if f.candidate == step.candidate), None)
        if f is not None:   # (none when the final check dropped it)
            assert f.gain_mm == pytest.approx(before.validation.mean_mm - step.validation.mean_mm, abs=1e-12)


@pytest.mark.parametrize("seed", SEEDS)
def test_compliant_joint(seed):
    rep = run(load_robot("ys100"), Effects(stiffness={3: 1.2e6}), seed)
    assert_found(rep, "joint_compliance", 3)


@pytest.mark.parametrize("seed", SEEDS)
def test_periodic_gear_error(seed):
    rep = run(load_robot("ys100"), Effects(periodic=[(2, 23, math.radians(0.008), 1.0)]), seed)
    assert_found(rep, "joint_periodic", 2, 23)


@pytest.mark.parametrize("seed", SEEDS)
def test_encoder_scale(seed):
    rep = run(load_robot("ys100"), Effects(encoder_scale={4: 4e-4}), seed)
    assert_found(rep, "encoder_scale", 4)


@pytest.mark.parametrize("seed", SEEDS)
def test_backlash(seed):
    rep = run(load_robot("ys100"), Effects(backlash={2: math.radians(0.01)}), seed)
    assert_found(rep, "backlash", 2)
    assert rep.findings[-1].candidate.source == "torque"


@pytest.mark.parametrize("seed", SEEDS)
def test_thermal_expansion(seed):
    rep = run(load_robot("ys100"), Effects(thermal_alpha=15e-6, temperature=(15.0, 35.0)), seed)
    assert_found(rep, "thermal_expansion")


@pytest.mark.parametrize("seed", SEEDS)
def test_noise_only_gives_no_further_finding(seed):
    rep = run(load_robot("ys100"), Effects(), seed)
    assert causes(rep) == [("geometric", None, None)]
    assert rep.final_model == "kinematic"


PLANAR_ARM = {**ARM3, "payload": {"mass_kg": 20}}


@pytest.mark.parametrize("seed", SEEDS)
def test_other_robot_compliance(seed):
    robot = robot_from_dict(PLANAR_ARM)
    rep = run(robot, Effects(stiffness={2: 4e5}), seed, n_cal=60, n_val=120, floor_z=None)
    assert_found(rep, "joint_compliance", 2)


@pytest.mark.parametrize("seed", SEEDS)
@pytest.mark.parametrize("gear", [(2, 9), (3, 7)])
def test_closed_chain_heavy_arm_compliance_and_gear_error(seed, gear):
    """HH800 (four-bar, 2 t links): a compliance on joint 2 and a gear error, and nothing else named.

    Two things used to add a cause: the fit stopped short of the truth until a fitted compliance could free the
    tilt of joint 1 against gravity (a spurious first harmonic of joint 1 took up the rest), and a compliance of
    joint 3, accepted (physical causes first) while the joint-3 gear error was not yet in the model, stayed after
    it was found (the final check drops it)."""
    j, h = gear
    rep = run(load_robot("hh800"), Effects(stiffness={2: 2e6}, periodic=[(j, h, math.radians(0.01), 0.4)]), seed,
              n_cal=150, n_val=300)
    truth = [("geometric", None, None), ("joint_compliance", 2, None), ("joint_periodic", j, h)]
    assert sorted(causes(rep), key=str) == sorted(truth, key=str), causes(rep)
    assert_gains_are_the_steps(rep)


def test_cli_json_contract_and_html(tmp_path):
    robot = load_robot("ys100")
    cal, truth = simulate(robot, 60, Effects(stiffness={2: 1.5e6}), seed=9)
    val, _ = simulate(robot, 80, truth=truth, seed=10)
    cal.write_csv(tmp_path / "cal.csv")
    val.write_csv(tmp_path / "val.csv")
    args = ["diagnose", "ys100", str(tmp_path / "cal.csv"), "--validate", str(tmp_path / "val.csv"),
            "--json", str(tmp_path / "r.json"), "--html", str(tmp_path / "r.html"), "--quiet"]
    assert main(args) == 0
    doc = json.loads((tmp_path / "r.json").read_text())
    assert doc["steps"][0]["model"] == "nominal" and doc["steps"][1]["model"] == "kinematic"
    assert {"mean_mm", "max_mm", "rms_mm"} <= set(doc["steps"][0]["validation"])
    f = [f for f in doc["findings"] if f["cause"] == "joint_compliance"][0]
    assert f["joint"] == 2 and f["gain_mm"] > 0 and f["evidence"]
    assert {"model", "validation"} <= set(doc["final"])
    page = (tmp_path / "r.html").read_text()
    assert page.startswith("<!DOCTYPE html>") and page.count("<svg") >= 3
    assert main(args) == 2  # refuses to overwrite the reports


@pytest.mark.parametrize("seed", SEEDS)
def test_drift_of_the_measurement_frame(seed):
    # 0.6 um per second along x and z, one pose a second: 48 um over the 80 calibration rows
    rep = run(load_robot("ys100"), Effects(drift=(0.6e-6, 0.0, -0.6e-6)), seed)
    assert_found(rep, "drift")


def without_time(data):
    from casadical.data import Measurements
    return Measurements({k: v for k, v in data.columns.items() if k != "time_s"}, data.path)


@pytest.mark.parametrize("seed", SEEDS)
def test_drift_needs_times(seed, tmp_path, capsys):
    """The same drift in files without time_s: the row numbers are never taken for times, so no drift is
    fitted or named; declaring the rows' spacing (--row-spacing-s) finds it again. A model with a drift
    asked of such a file is one line naming the column."""
    robot = load_robot("ys100")
    cal, truth = simulate(robot, 80, Effects(drift=(0.6e-6, 0.0, -0.6e-6)), seed=seed)
    val, _ = simulate(robot, 200, truth=truth, seed=seed + 500)
    cal, val = without_time(cal), without_time(val)
    rep = diagnose(robot, cal, val, DiagnosisSettings(seed=seed))
    assert "drift" not in [c[0] for c in causes(rep)]
    paths = {}
    for name, data in (("cal", cal), ("val", val)):
        paths[name] = str(tmp_path / f"{name}.csv")
        data.write_csv(paths[name])
    out = str(tmp_path / "d.json")
    assert main(["diagnose", "ys100", paths["cal"], "--validate", paths["val"], "--json", out, "-q",
                 "--row-spacing-s", "1", "--seed", str(seed)]) == 0
    assert "drift" in [f["cause"] for f in json.loads(open(out).read())["findings"]]
    capsys.readouterr()
    assert main(["calibrate", "ys100", paths["cal"], "--model", "kinematic+drift", "--out",
                 str(tmp_path / "c.json")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "cal.csv, row 1, column 'time_s'" in err and "--row-spacing-s" in err


def test_ambiguous_causes_are_reported():
    """Encoder scale over a small joint range looks like a first harmonic: both are named."""
    robot = load_robot("ys100")
    from dataclasses import replace
    joints = list(robot.joints)
    joints[1] = replace(joints[1], min=math.radians(40), max=math.radians(80))
    narrow = replace(robot, joints=joints)
    rep = run(narrow, Effects(encoder_scale={2: 6e-4}), 1)
    f = [f for f in rep.findings if f.candidate.cause in ("encoder_scale", "joint_periodic")]
    assert f and f[0].candidate.joint == 2
    others = {(a["cause"], a.get("joint")) for a in f[0].ambiguous_with}
    assert ("joint_periodic", 2) in others or ("encoder_scale", 2) in others, f[0].ambiguous_with
    assert all(a["tell_apart"] for a in f[0].ambiguous_with)


def _noise_floor(truth, val):
    """Validation mean error of the true model itself: the best any model can do on these poses."""
    import numpy as np
    return float(np.mean(np.linalg.norm(truth.predict(val) - val.xyz, axis=1)) * 1000)


@pytest.mark.parametrize("seed", SEEDS)
def test_progressive_stiffness_is_compliance_not_backlash(seed):
    """A joint that stiffens with load: compliance (and its cubic term), never backlash or a gear error."""
    # the cubic term takes back 30 % of the linear deflection at the largest torque (~6000 N m)
    rep = run(load_robot("ys100"), Effects(stiffness={2: 1.5e6}, cubic={2: -5e-15}), seed)
    named = causes(rep)
    assert ("joint_compliance", 2, None) in named or ("nonlinear_stiffness", 2, None) in named, named
    assert not [c for c in named if c[0] not in ("geometric", "joint_compliance", "nonlinear_stiffness")], named
    assert rep.final_validation.mean_mm < 0.04      # noise 0.02 mm per axis: the spring is modelled


@pytest.mark.parametrize("seed", SEEDS)
def test_thermal_expansion_of_two_links(seed):
    """Two links growing with temperature (one coefficient each): the final model reaches the noise floor."""
    robot = load_robot("ys100")
    eff = Effects(thermal_links={2: 25e-6, 3: -15e-6}, temperature=(15.0, 35.0))
    cal, truth = simulate(robot, 80, eff, seed=seed)
    val, _ = simulate(robot, 200, truth=truth, seed=seed + 500)
    rep = diagnose(robot, cal, val, DiagnosisSettings(seed=seed))
    assert any(c[0] == "thermal_expansion" for c in causes(rep)), causes(rep)
    assert rep.final_validation.mean_mm <= 1.3 * _noise_floor(truth, val), (rep.final_model,
                                                                             rep.final_validation.mean_mm)


@pytest.mark.parametrize("seed", SEEDS)
def test_structure_no_cause_explains_is_unexplained(seed):
    """An angle error of joint 2 that grows with the square of its reading is in no catalogue: it is reported
    as unexplained structure on joint 2 and kept out of the model, and never named an encoder scale error
    (the trend it looks like over part of the range). Known limit (docs/diagnosis.md): physical terms of
    the same joints (compliance) absorb part of it, and in one seed of three a harmonic of the rest passes."""
    robot = load_robot("ys100")
    cal, truth = simulate(robot, 120, Effects(), seed=seed)
    val, _ = simulate(robot, 200, truth=truth, seed=seed + 500)

    def bend(d):
        # first-order effect of the angle error e(q2) = k (q2 - 0.6)^2 on the tool point
        _, J = truth.model.predict_jacobian(d.q, truth.values, truth.model.covariates(d), truth.base0)
        e = 1e-4 * (d.q[:, 1] - 0.6) ** 2
        xyz = d.xyz + J[:, :, truth.model.parameters.index("theta2")] * e[:, None]
        return d.with_positions(xyz)
    rep = diagnose(robot, bend(cal), bend(val), DiagnosisSettings(seed=seed))
    named = causes(rep)
    assert ("encoder_scale", 2, None) not in named, named
    f = [f for f in rep.findings if f.cause == "unexplained" and f.candidate.joint == 2]
    assert f and not f[0].in_model and f[0].potential_gain_mm > 0 and "joint 2" in f[0].where
    assert "unexplained" not in rep.final_model and "rbf" not in rep.final_model


def test_transfer_to_another_series():
    """A compliant joint found on one series holds on another (tracker elsewhere): the finding transfers
    and the diagnosed model beats the kinematic one there, both ways of travelling."""
    from dataclasses import replace as dreplace

    from casadical.kinematics import base_pose_matrix
    from casadical.model import pose_to_base0
    robot = load_robot("ys100")
    cal, truth = simulate(robot, 80, Effects(stiffness={3: 1.2e6}), seed=4)
    val, _ = simulate(robot, 100, truth=truth, seed=5)
    moved = dreplace(truth, base0=pose_to_base0(base_pose_matrix((1.5, -0.5, 0.2), (0.0, 0.01, 0.8))))
    other, _ = simulate(robot, 200, truth=moved, seed=6)
    rep = diagnose(robot, cal, val, DiagnosisSettings(seed=4), other=other)
    f = next(f for f in rep.findings if f.cause == "joint_compliance")
    assert f.transfer["verdict"] == "transfers", f.transfer
    t = rep.transfer
    assert t["final"]["base_mm"] < 0.5 * t["kinematic"]["base_mm"]
    assert t["final"]["refit_mm"] < 0.5 * t["kinematic"]["refit_mm"]
    doc = rep.to_dict()
    assert doc["transfer"]["n_base"] == 30 and "verdict" in next(
        x for x in doc["findings"] if x["cause"] == "joint_compliance")["transfer"]


def test_periodogram_is_each_harmonics_least_squares():
    """The batched periodogram is the least-squares fit of each harmonic (with the mean and trend) on its
    own: to 1e-9 on a joint's full range, and as the per-harmonic solve of the same normal equations (the
    loop it replaced, same cutoff), to what their conditioning allows, where a harmonic is all but
    degenerate with the trend (a short range)."""
    import numpy as np

    from casadical.diagnosis.periodogram import periodogram

    rng = np.random.default_rng(4)
    for span in (2.5, 0.05):
        q = rng.uniform(-span / 2, span / 2, 120)
        s = 1e-4 * np.sin(7 * q + 0.3) + rng.normal(0, 2e-5, len(q))
        w = rng.uniform(0.5, 2.0, len(q))
        pg = periodogram(q, s, w, 3, 12)
        sw = np.sqrt(w)
        base = np.column_stack([sw, sw * q])
        y = s * sw - base @ np.linalg.lstsq(base, s * sw, rcond=None)[0]
        for h, power, amp in zip(pg.harmonics, pg.power, pg.amplitude):
            A = np.column_stack([sw * np.sin(h * q), sw * np.cos(h * q), base])
            G = A.T @ A
            c = np.linalg.lstsq(G, A.T @ y, rcond=None)[0]               # the loop it replaced
            tol = 1e-9 + np.linalg.cond(G) * np.finfo(float).eps        # what the conditioning allows
            assert power == pytest.approx(c @ (A.T @ y) / (y @ y), rel=tol)
            assert amp == pytest.approx(np.hypot(c[0], c[1]), rel=tol)
            if span > 1:                                                  # well conditioned: least squares itself
                c = np.linalg.lstsq(A, y, rcond=None)[0]
                assert power == pytest.approx(np.sum((A @ c) ** 2) / (y @ y), rel=1e-9)
        if span > 1:
            assert pg.harmonics[np.argmax(pg.power)] == 7
