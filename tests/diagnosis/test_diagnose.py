"""Diagnosis: a hidden effect must be named exactly (cause, joint, harmonic, scope); noise alone gives no finding.

The data are made by the independent truth (tests/truth, no casadical code) and read as a user's files;
tests/helpers/hidden.py judges the claims. Every effect on robots that are not built in:
tests/diagnosis/test_hidden_effects.py.
"""

import json
import math
import tempfile
from pathlib import Path

import numpy as np
import pytest

from casadical import load_robot
from casadical.cli import main
from casadical.data import Effects as SimEffects
from casadical.data import Measurements, simulate
from casadical.diagnosis import DiagnosisSettings, diagnose
from tests.helpers import hidden
from tests.helpers.arms import ARM3
from tests.truth import Effects, Session, measure, sample

SEEDS = [0, 1, 2]
YS100 = hidden.robot_doc("ys100")
R = "robot"


def data(effects, seed, doc=YS100, n_cal=80, n_val=200, floor_z=0.0, thermal=False, drift=(0.0, 0.0, 0.0)):
    """(case, robot, cal, val, true) of the truth hiding ``effects`` in ``doc``."""
    c = hidden.Case(doc["name"], "", seed, effects, set(), drift=drift, thermal=thermal)
    return (c, *hidden.make_data(c, n_cal, n_val, floor_z=floor_z, doc=doc))


def run(effects, seed, **kw):
    _, robot, cal, val, _ = data(effects, seed, **kw)
    return diagnose(robot, cal, val, DiagnosisSettings(seed=seed))


def causes(report):
    return [(f.candidate.cause, f.candidate.joint, f.candidate.harmonic) for f in report.findings]


def assert_named(report, expected, allowed=None):
    """Exactly the ``expected`` causes (cause, joint, harmonic, scope), each with its evidence and the gain of
    its step; the ambiguities ``allowed`` only where the report declares them."""
    hidden.assert_claims(report, expected, allowed)
    for f in report.findings:
        if f.in_model and f.cause not in ("geometric", "unexplained"):
            assert f.gain_mm > 0 and "F =" in f.evidence, (f.candidate, f.evidence)
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
    rep = run(Effects(stiffness={3: 1.2e6}), seed)
    assert_named(rep, {("joint_compliance", 3, None, R)})


@pytest.mark.parametrize("seed", SEEDS)
def test_periodic_gear_error(seed):
    rep = run(Effects(periodic=[(2, 23, math.radians(0.008), 1.0)]), seed)
    assert_named(rep, {("joint_periodic", 2, 23, R)})


@pytest.mark.parametrize("seed", SEEDS)
def test_encoder_scale(seed):
    rep = run(Effects(encoder_scale={4: 4e-4}), seed)
    assert_named(rep, {("encoder_scale", 4, None, R)})


@pytest.mark.parametrize("seed", SEEDS)
def test_backlash(seed):
    rep = run(Effects(backlash={2: math.radians(0.01)}), seed)
    assert_named(rep, {("backlash", 2, None, R)})
    assert rep.findings[-1].candidate.source == "torque"


@pytest.mark.parametrize("seed", SEEDS)
def test_thermal_expansion(seed):
    rep = run(Effects(thermal_alpha=15e-6, t_ref=25.0), seed, thermal=True)
    assert_named(rep, {("thermal_expansion", None, None, R)})


@pytest.mark.parametrize("seed", SEEDS)
def test_noise_only_gives_no_further_finding(seed):
    rep = run(Effects(), seed)
    assert causes(rep) == [("geometric", None, None)]
    assert rep.final_model == "kinematic"


PLANAR_ARM = {**ARM3, "payload": {"mass_kg": 20}}


@pytest.mark.parametrize("seed", SEEDS)
def test_other_robot_compliance(seed):
    rep = run(Effects(stiffness={2: 4e5}), seed, doc=PLANAR_ARM, n_cal=60, n_val=120, floor_z=None)
    assert_named(rep, {("joint_compliance", 2, None, R)})


@pytest.mark.parametrize("seed", SEEDS)
@pytest.mark.parametrize("gear", [(2, 9), (3, 7)])
def test_closed_chain_heavy_arm_compliance_and_gear_error(seed, gear):
    """HH800 (four-bar, 2 t links): a compliance of drive 2 (the TLBO paper's k2, a 0.6 mrad sag) and a gear
    error, and nothing else named; the first-order compliance is enough (no note).

    Two things used to add a cause: the fit stopped short of the truth until a fitted compliance could free the
    tilt of joint 1 against gravity (a spurious first harmonic of joint 1 took up the rest), and a compliance of
    joint 3, accepted (physical causes first) while the joint-3 gear error was not yet in the model, stayed after
    it was found (the final check drops it)."""
    j, h = gear
    rep = run(Effects(stiffness={2: 6.159e7}, periodic=[(j, h, math.radians(0.01), 0.4)]), seed,
              doc=hidden.robot_doc("hh800"), n_cal=150, n_val=300)
    assert_named(rep, {("joint_compliance", 2, None, R), ("joint_periodic", j, h, R)})
    assert not [n for n in rep.notes if "undeflected arm" in n]


def test_a_soft_heavy_arm_is_said_to_sag_beyond_the_first_order():
    """The same HH800 made 30 times softer (k2 = 2e6) sags 18 mrad: the model's torques, those of the
    undeflected arm, leave 0.37 mm there (the truth's equilibrium), and the report says so. (It names
    further causes of joint 2 for it today: docs/diagnosis.md, known limits.)"""
    rep = run(Effects(stiffness={2: 2e6}, periodic=[(3, 7, math.radians(0.01), 0.4)]), 1,
              doc=hidden.robot_doc("hh800"), n_cal=150, n_val=300)
    note = [n for n in rep.notes if "undeflected arm" in n]
    assert note and "joint 2 sags up to" in note[0], rep.notes
    sag, leaves = (float(note[0].split(x)[1].split()[0]) for x in ("sags up to ", "leaves up to "))
    assert 15 < sag < 22 and 0.25 < leaves < 0.5, note


def test_cli_json_contract_and_html(tmp_path):
    robot = load_robot("ys100")
    cal, truth = simulate(robot, 60, SimEffects(stiffness={2: 1.5e6}), seed=9)
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
    rep = run(Effects(), seed, drift=(0.6e-6, 0.0, -0.6e-6))
    assert_named(rep, {("drift", None, None, "session")})


def without_time(data):
    return Measurements({k: v for k, v in data.columns.items() if k != "time_s"}, data.path)


@pytest.mark.parametrize("seed", SEEDS)
def test_drift_needs_times(seed, tmp_path, capsys):
    """The same drift in files without time_s: the row numbers are never taken for times, so no drift is
    fitted or named; declaring the rows' spacing (--row-spacing-s) finds it again. A model with a drift
    asked of such a file is one line naming the column."""
    _, robot, cal, val, _ = data(Effects(), seed, drift=(0.6e-6, 0.0, -0.6e-6))
    cal, val = without_time(cal), without_time(val)
    rep = diagnose(robot, cal, val, DiagnosisSettings(seed=seed))
    assert "drift" not in [c[0] for c in causes(rep)]
    paths = {}
    for name, d in (("cal", cal), ("val", val)):
        paths[name] = str(tmp_path / f"{name}.csv")
        d.write_csv(paths[name])
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
    """Encoder scale over a small joint range looks like a first harmonic: the report names one, declares the
    other, and says what measurement tells them apart."""
    narrow = {**YS100, "joint": [dict(j) for j in YS100["joint"]]}
    narrow["joint"][1].update(min_deg=40.0, max_deg=80.0)
    rep = run(Effects(encoder_scale={2: 6e-4}), 1, doc=narrow)
    scale, first = ("encoder_scale", 2, None, R), ("joint_periodic", 2, 1, R)
    assert_named(rep, {scale}, allowed={scale: {first}})
    f = [f for f in rep.findings if f.candidate.cause in ("encoder_scale", "joint_periodic")]
    others = {(a["cause"], a.get("joint")) for a in f[0].ambiguous_with}
    assert ("joint_periodic", 2) in others or ("encoder_scale", 2) in others, f[0].ambiguous_with
    assert all(a["tell_apart"] for a in f[0].ambiguous_with)


@pytest.mark.parametrize("seed", SEEDS)
def test_progressive_stiffness_is_compliance_not_backlash(seed):
    """A joint that stiffens with load: its compliance and its cubic term, never backlash or a gear error."""
    # the cubic term takes back 30 % of the linear deflection at the largest torque (~6000 N m)
    rep = run(Effects(stiffness={2: 1.5e6}, cubic={2: -5e-15}), seed)
    assert_named(rep, {("joint_compliance", 2, None, R), ("nonlinear_stiffness", 2, None, R)})
    assert rep.final_validation.mean_mm < 0.04      # noise 0.02 mm per axis: the spring is modelled


@pytest.mark.parametrize("seed", SEEDS)
def test_thermal_expansion_of_two_links(seed):
    """Two links growing with temperature (one coefficient each): both named, and the final model reaches the
    noise floor (the truth's own error)."""
    c, robot, cal, val, true = data(Effects(thermal_links={2: 25e-6, 3: -15e-6}, t_ref=25.0), seed, thermal=True)
    rep = diagnose(robot, cal, val, DiagnosisSettings(seed=seed))
    assert_named(rep, {("thermal_expansion", 2, None, R), ("thermal_expansion", 3, None, R)})
    floor = np.mean(np.linalg.norm(hidden.noise_free(c, true, val) - val.xyz, axis=1)) * 1000
    assert rep.final_validation.mean_mm <= 1.3 * floor, (rep.final_model, rep.final_validation.mean_mm)


@pytest.mark.parametrize("seed", SEEDS)
def test_structure_no_cause_explains_is_unexplained(seed):
    """An angle error of joint 2 that grows with the square of its reading is in no catalogue: it is reported
    as unexplained structure on joint 2 and kept out of the model, located by the structure screen (joint 2's
    angle against its own reading), and no catalogue cause is named for it: the compliance of joint 2 and the
    harmonics of joint 3 that took part of it (in every seed before the stand-in check) are dropped as stand-ins,
    with a note each."""
    rep = run(Effects(reading_error={2: lambda q: 1e-4 * (q - 0.6) ** 2}), seed, n_cal=120)
    assert not hidden.named(rep), causes(rep)
    f = [f for f in rep.findings if f.cause == "unexplained" and f.candidate.joint == 2]
    assert f and not f[0].in_model and f[0].potential_gain_mm > 0 and "joint 2" in f[0].where
    assert [(f.candidate.joint, f.structure["covariate"], f.structure["effect"]) for f in rep.findings
            if f.structure][:1] == [(2, "q2", "angle")]
    assert [n for n in rep.notes if "closest catalogue approximation" in n]
    assert "unexplained" not in rep.final_model and "rbf" not in rep.final_model


def test_transfer_to_another_series():
    """A compliant joint found on one series holds on another (tracker elsewhere): the finding transfers
    and the diagnosed model beats the kinematic one there, both ways of travelling."""
    c, robot, cal, val, true = data(Effects(stiffness={3: 1.2e6}), 4, n_val=100)
    rng = np.random.default_rng(6)
    elsewhere = Session("A", base_xyz=(1.5, -0.5, 0.2), base_rpy=(0.0, 0.01, 0.8))
    with tempfile.TemporaryDirectory() as tmp:
        path = measure(true, sample(true, 200, rng), rng, session=elsewhere).write_csv(Path(tmp) / "other.csv")
        other = Measurements.read_csv(path, n_joints=6, require_positions=True)
    rep = diagnose(robot, cal, val, DiagnosisSettings(seed=4), other=other)
    assert_named(rep, {("joint_compliance", 3, None, R)})
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

    from casadical.diagnosis import periodogram

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
