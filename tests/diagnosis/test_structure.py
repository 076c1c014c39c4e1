"""Structure is not bad data; every cause for the robot and for each session; nothing skipped in silence.

Each case is hidden in data made by the independent truth (tests/truth) on robots that are not built in, with
several seeds: a gear error of one session only, a warm-up at the start of a session, a compliance the robot
file cannot model (no masses), a gear error a kinematic calibration does not model, bad shots.
"""

import json
import math
import warnings

import numpy as np
import pytest

from casadical import calibrate
from casadical.cli import main
from casadical.data import Measurements, combine
from casadical.diagnosis import DiagnosisSettings, diagnose
from casadical.errors import ParallelAxesWarning
from casadical.loading import load_robot
from casadical.robot import robot_from_dict
from casadical.stats import direction_test, order_test, session_test, set_aside_structure
from tests.helpers.arms import ARM3, ARM4, ARM4_BETA, ARM5, ARM7, ARM7_DH, to_toml
from tests.truth import Arm, Effects, Session, TrueRobot, measure, sample


def read(shots, path) -> Measurements:
    """The shots as a user's file: written, then read."""
    shots.write_csv(path)
    return Measurements.read_csv(path)


def named(report) -> set:
    """(cause, joint, harmonic, session, scope) of every cause in the final model."""
    return {(f.cause, f.candidate.joint, f.candidate.harmonic, f.candidate.session, f.scope)
            for f in report.findings if f.in_model and f.cause != "unexplained"}


def massless(arm: dict) -> dict:
    """The robot file without link masses and payload (what a user often has)."""
    out = {**arm, "joint": [{k: v for k, v in j.items() if k not in ("mass_kg", "com_m")} for j in arm["joint"]]}
    out.pop("payload", None)
    return out


# --- every cause for the robot and for each session ----------------------------------------------

def three_sessions(arm, seed, folder, n=80):
    """Three sessions of one robot (compliance of joints 2 and 3, a 17-cycle gear error of joint 2); session s2
    drifts, session s3 has a gear error of its own: 11 cycles per turn of joint 1 (a re-mounted joint-1 drive, or
    the tracker on its own stand: what one session alone carries)."""
    rng = np.random.default_rng(seed)
    arm_t = Arm.from_dict(arm)
    effects = Effects(stiffness={2: 4e5, 3: 2.5e5}, periodic=[(2, 17, math.radians(0.006), 0.3)])
    robot = TrueRobot.draw(arm_t, effects, rng)
    own = robot.with_effects(Effects(stiffness=effects.stiffness,
                                     periodic=effects.periodic + [(1, 11, math.radians(0.01), 0.7)]))
    sessions = [(robot, Session("s1")),
                (robot, Session("s2", (1.2, -0.8, 0.1), (0.01, -0.02, 2.2), drift=(1e-6, 0.0, -1e-6), t_ref=40.0)),
                (own, Session("s3", (-0.9, 1.1, 0.0), (0.0, 0.01, -1.4)))]
    out = {}
    for kind, m in (("cal", n), ("val", 120)):
        (folder / kind).mkdir()
        parts = []
        for truth, s in sessions:
            q = sample(truth, m, rng, floor_z=None)
            parts.append(read(measure(truth, q, rng, session=s, time_s=np.arange(m, dtype=float)),
                              folder / kind / f"{s.name}.csv"))
        out[kind] = combine(parts)
    return robot_from_dict(arm), out["cal"], out["val"]


@pytest.mark.parametrize("arm, seed", [(ARM4_BETA, 0), (ARM5, 1), (ARM7_DH, 2)], ids=["arm4", "arm5", "arm7dh"])
def test_structure_of_one_session_is_named_with_its_session(arm, seed, tmp_path):
    """Session s3's own gear error of joint 1 is what differs between the sessions showing on joint 1 (a joint's
    own parameter is the robot's, issue 49): an ``unexplained`` finding of joint 1 naming session s3 and the
    harmonic, kept out of the model; the robot's causes and session s2's drift are named with their scope, nothing
    else (before issue 49 it was named a gear error "of session s3")."""
    robot, cal, val = three_sessions(arm, seed, tmp_path)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ParallelAxesWarning)
        rep = diagnose(robot, cal, val, DiagnosisSettings(seed=seed))
    assert named(rep) == {("geometric", None, None, None, "robot"),
                          ("joint_compliance", 2, None, None, "robot"), ("joint_compliance", 3, None, None, "robot"),
                          ("joint_periodic", 2, 17, None, "robot"), ("drift", None, None, "s2", "session")}, \
        rep.final_model
    f = next(f for f in rep.findings if f.cause == "unexplained" and f.candidate.session == "s3")
    d = f.to_dict()
    assert d["session"] == "s3" and d["scope"] == "session" and d["joint"] == 1 and not f.in_model
    assert 11 in [s.get("harmonic") for s in f.holds_up["structures"]], f.holds_up
    assert "session s3 only" in f.where and "the mount" in f.evidence, (f.where, f.evidence)


# --- structure is not bad data ----------------------------------------------------------------------

def warm_up(arm, seed, folder, times=True, n=250):
    """One session in time order, a pose every 10 s; the first poses stand off (0.25, -0.15, 0.2) mm, dying away
    with a 70 s time constant (a robot warming up: written here, apart from the package's term); calibration and
    validation poses interleaved."""
    rng = np.random.default_rng(seed)
    robot = TrueRobot.draw(Arm.from_dict(arm), Effects(stiffness={2: 6e4}), rng)
    q = sample(robot, n, rng, floor_z=None)
    t = np.arange(n) * 10.0
    shots = measure(robot, q, rng, time_s=t)
    shots.xyz += np.outer(np.exp(-t / 70.0), [0.25e-3, -0.15e-3, 0.2e-3])
    if not times:
        shots.columns.pop("time_s")
    data = read(shots, folder / "series.csv")
    cal = np.sort(np.random.default_rng(seed + 7).permutation(n)[:150])
    return robot_from_dict(arm), data.subset(cal), data.subset(np.setdiff1d(np.arange(n), cal))


@pytest.mark.parametrize("arm, seed", [(ARM4_BETA, 0), (ARM7, 1), (ARM7_DH, 2)], ids=["arm4", "arm7", "arm7dh"])
def test_a_warm_up_is_named_where_the_times_are_known(arm, seed, tmp_path):
    """With times the warm-up is named, of the session, and nothing else (today: its first 5-9 poses were
    called bad measurements)."""
    robot, cal, val = warm_up(arm, seed, tmp_path)
    rep = diagnose(robot, cal, val, DiagnosisSettings(seed=seed))
    assert {(c, j) for c, j, *_ in named(rep)} == {("geometric", None), ("joint_compliance", 2), ("warmup", None)}, \
        rep.final_model
    f = next(f for f in rep.findings if f.cause == "warmup")
    assert f.scope == "session" and 20 < f.candidate.time_constant < 250
    assert "warmup[" in rep.final_model
    assert not rep.set_aside or not rep.set_aside["structured"], rep.set_aside


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_without_times_the_warm_up_is_structure_at_the_start(seed, tmp_path):
    """Without times the first poses are set aside: reported as structure at the start of the measurement
    order, and what would let a warm-up be tried (time_s, --row-spacing-s), never as bad measurements."""
    robot, cal, val = warm_up(ARM4_BETA, seed, tmp_path, times=False)
    rep = diagnose(robot, cal, val, DiagnosisSettings(seed=seed))
    assert rep.set_aside["structured"], rep.notes
    kinds = {s["kind"] for s in rep.set_aside["structure"]}
    assert "order" in kinds, rep.set_aside
    note = next(n for n in rep.notes if n.startswith("the robust loss set aside"))
    assert "the start" in note and "--row-spacing-s" in note and "likely bad" not in note, note
    assert any("warmup" in n["cause"] and "--row-spacing-s" in n["allow"] for n in rep.to_dict()["not_tried"])


def one_joint_at_a_time(arm, seed, folder):
    """36 poses, each joint swept alone from the middle of the ranges; the arm has a compliant joint 2; 24 poses
    calibrate, 12 validate."""
    rng = np.random.default_rng(seed)
    robot = TrueRobot.draw(Arm.from_dict(arm), Effects(stiffness={2: 6e4}), rng)
    lim = robot.arm.limits
    home = lim.mean(axis=1)
    q = []
    for j in range(robot.arm.n):
        for v in np.linspace(lim[j, 0] + 0.1, lim[j, 1] - 0.1, 36 // robot.arm.n):
            q.append(home.copy())
            q[-1][j] = v
    data = read(measure(robot, np.array(q), rng), folder / "sweeps.csv")
    cal = np.sort(rng.permutation(len(q))[:2 * len(q) // 3])
    return data.subset(cal), data.subset(np.setdiff1d(np.arange(len(q)), cal))


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_a_compliance_the_robot_file_cannot_model_is_structure(seed, tmp_path):
    """A robot file without masses: the poses a compliant joint 2 bends most are set aside; their errors are
    angle errors of joint 2 (or of a joint parallel to it), reported as structure with what would let a
    compliance be tried (the masses), not as bad measurements."""
    cal, val = one_joint_at_a_time(ARM5, seed, tmp_path)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ParallelAxesWarning)
        robot = robot_from_dict(massless(ARM5))
    rep = diagnose(robot, cal, val, DiagnosisSettings(seed=seed))
    doc = rep.to_dict()
    assert any("joint_compliance" in n["cause"] and "mass_kg" in n["allow"] for n in doc["not_tried"])
    assert rep.set_aside.get("structured"), rep.notes
    assert {s.get("joint") for s in rep.set_aside["structure"]} & {2, 3}, rep.set_aside
    note = next(n for n in rep.notes if n.startswith("the robust loss set aside"))
    assert "not bad measurements" in note and "mass_kg" in note, note
    # a cause named on joint 2 may be its compliance, which could not be tried: declared ambiguous with it
    for f in rep.findings:
        if f.in_model and f.candidate.joint == 2 and f.cause in ("encoder_scale", "joint_periodic", "backlash"):
            assert any(a["cause"] == "joint_compliance" and a["joint"] == 2 and "mass_kg" in a["tell_apart"]
                       for a in f.ambiguous_with), f.ambiguous_with


@pytest.mark.parametrize("arm, seed", [(ARM4_BETA, 0), (ARM3, 1), (ARM3, 3)], ids=["arm4-0", "arm3-1", "arm3-3"])
def test_a_gear_error_a_kinematic_calibration_leaves_is_structure(arm, seed, tmp_path):
    """calibrate --model kinematic of an arm with no bad measurement but a gear error of joint 1: the poses it
    sets aside are the gear's (their errors along joint 1's motion): structure, not bad measurements."""
    rng = np.random.default_rng(seed)
    robot = TrueRobot.draw(Arm.from_dict(arm), Effects(periodic=[(1, 11, math.radians(0.012), 0.4)]), rng)
    data = read(measure(robot, sample(robot, 60, rng, floor_z=None), rng), tmp_path / "cal.csv")
    res = calibrate(robot_from_dict(arm), data, "kinematic", "lm", warn=False)
    assert len(res.downweighted) >= 3
    note = next(n for n in res.notes if n.startswith("the robust loss set aside"))
    assert "not bad measurements" in note and "joint 1" in note and "likely bad" not in note, note


@pytest.mark.parametrize("arm, seed", [(ARM4_BETA, 0), (ARM7, 1), (ARM7_DH, 2)], ids=["arm4", "arm7", "arm7dh"])
def test_real_bad_shots_are_still_bad_measurements(arm, seed, tmp_path):
    """A gear error of joint 1 and four bad shots (1-2 mm in random directions): calibrate --model kinematic
    tells the gear's poses (structure) from the bad shots; the diagnosis names the gear error, and what its
    final fit sets aside is exactly the bad shots, called bad measurements."""
    rng = np.random.default_rng(seed)
    robot = TrueRobot.draw(Arm.from_dict(arm), Effects(periodic=[(1, 11, math.radians(0.012), 0.4)]), rng)
    shots = measure(robot, sample(robot, 120, rng, floor_z=None), rng, bad=4, bad_mm=1.5)
    data = read(shots, tmp_path / "series.csv")
    cal_idx = np.setdiff1d(np.arange(80), [])
    cal, val = data.subset(cal_idx), data.subset(np.arange(80, 120))
    bad = {int(cal.lines[i]) for i in shots.bad if i < 80}
    rep = diagnose(robot_from_dict(arm), cal, val, DiagnosisSettings(seed=seed))
    assert ("joint_periodic", 1, 11, None, None) in named(rep), rep.final_model
    assert {d["line"] for d in rep.final.downweighted} == bad
    assert not rep.set_aside["structured"] and set(map(int, rep.set_aside["bad_measurements"])) == bad
    note = next(n for n in rep.notes if n.startswith("the robust loss set aside"))
    assert "likely bad measurements" in note and "structure" not in note.split(":", 1)[1].split("(")[0], note
    # a kinematic calibration of the same poses: the bad shots are named bad, the rest (the gear's) structure
    res = calibrate(robot_from_dict(arm), cal, "kinematic", "lm", warn=False)
    note = next(n for n in res.notes if n.startswith("the robust loss set aside"))
    shared = note.split("; the other", 1)
    if "not bad measurements" in note:
        assert len(shared) == 2 and all(str(b) in shared[1] for b in bad), note


# --- the tests themselves ----------------------------------------------------------------------------

def test_the_structure_tests_keep_their_level_on_bad_shots_alone():
    """Set-aside poses drawn at random, their errors in random directions (what bad measurements are): the
    family-wise level of 0.001 holds over 300 draws (no structure found), while the same draws concentrated in
    one session, at the start, or along one joint's motion are found."""
    rng = np.random.default_rng(0)
    N = 120
    q = rng.uniform(-2, 2, (N, 4))
    sessions = np.array(["A"] * 40 + ["B"] * 40 + ["C"] * 40, dtype=object)
    data = Measurements.from_arrays(q, np.zeros((N, 3)))
    data.sessions = sessions
    directions = rng.normal(size=(N, 3, 4))
    found = 0
    for _ in range(300):
        idx = np.sort(rng.choice(N, 5, replace=False))
        r = rng.normal(size=(N, 3))
        found += set_aside_structure(data, idx, r, directions, torques=None).structured
    assert found == 0
    idx = np.arange(80, 92)                 # session C
    assert session_test(sessions, idx).p_value < 1e-4
    assert min(t.p_value for t in order_test(data, np.arange(0, 6))) < 1e-4
    r = directions[:, :, 2] * rng.normal(size=(N, 1))        # along joint 3's motion
    t = direction_test(r, directions[:, :, 2], np.arange(10, 16), 3)
    assert t.p_value < 1e-6 and len(t.poses) == 6


# --- nothing skipped in silence -----------------------------------------------------------------------

def test_every_kind_not_tried_says_why_and_what_would_allow_it(tmp_path, capsys):
    """A robot file without masses, poses without times or temperatures, few poses: the terminal summary, the
    JSON and the HTML say that compliance, drift and warm-up, thermal expansion and the high harmonics were not
    tried, why, and what would allow each."""
    cal, val = one_joint_at_a_time(ARM7, 0, tmp_path)
    (tmp_path / "arm.toml").write_text(to_toml(massless(ARM7)))
    cal.write_csv(tmp_path / "cal.csv")
    val.write_csv(tmp_path / "val.csv")
    rc = main(["diagnose", str(tmp_path / "arm.toml"), str(tmp_path / "cal.csv"), "--validate",
               str(tmp_path / "val.csv"), "--json", str(tmp_path / "r.json"), "--html", str(tmp_path / "r.html")])
    assert rc == 0
    out = capsys.readouterr().out
    doc = json.loads((tmp_path / "r.json").read_text())
    html = (tmp_path / "r.html").read_text()
    expect = {"joint_compliance": "mass_kg", "drift": "--row-spacing-s", "thermal_expansion": "temperature_c",
              "joint_periodic (high harmonics)": "poses"}
    for cause, allow in expect.items():
        item = next(n for n in doc["not_tried"] if cause in n["cause"])
        assert allow in item["allow"] and item["why"]
        assert allow in out and allow in html
    assert "not tried on these data" in out and 'id="not-tried"' in html


def test_parallel_axes_without_beta_warn_naming_the_link(tmp_path):
    """DH: axes i and i+1 are parallel when link i's alpha is 0 (its beta is link i's); MDH: axes i-1 and i when
    link i's alpha is 0. A robot file without beta there warns when it is read, naming the file and the link; with
    it, or where no consecutive axes are parallel, it does not. The built-in robots do not warn; of
    tests/helpers/arms.py, ARM4 (MDH, no beta) and
    ARM5 (DH, beta on link 3 but not on link 2) do."""
    def warned(doc):
        path = tmp_path / "arm.toml"
        path.write_text(to_toml(doc))
        with warnings.catch_warnings(record=True) as w:
            warnings.simplefilter("always")
            load_robot(path)
        return [str(x.message) for x in w if issubclass(x.category, ParallelAxesWarning)]

    arm4 = warned(ARM4)
    assert len(arm4) == 2 and "joint[3]" in arm4[0] and "joints 2 and 3" in arm4[0] and "joint[4]" in arm4[1]
    arm5 = warned(ARM5)
    assert len(arm5) == 1 and "joint[2]" in arm5[0] and "joints 2 and 3" in arm5[0] and "beta_deg" in arm5[0]
    for doc in (ARM3, ARM4_BETA, ARM7, ARM7_DH):
        assert warned(doc) == [], doc["name"]
    fixed = {**ARM5, "joint": [dict(j, beta_deg=0.0) if k == 1 else j for k, j in enumerate(ARM5["joint"])]}
    assert warned(fixed) == []
    for name in ("ys100", "hh800", "ur10"):
        with warnings.catch_warnings():
            warnings.simplefilter("error", ParallelAxesWarning)
            load_robot(name)
    # a robot given as a dict, or held by a calibration file, was checked when its file was read: no warning
    with warnings.catch_warnings():
        warnings.simplefilter("error", ParallelAxesWarning)
        robot_from_dict(ARM4)


# --- a progressive spring is named only where the poses tell it from the joint's harmonics ---------------------

@pytest.mark.parametrize("seed", [0, 1, 2, 3])
def test_a_progressive_spring_is_not_named_where_a_harmonic_of_the_joint_fits_as_well(seed):
    """40 poses of a 4-axis arm with a linear compliance of joint 2 and a 2-cycle gear error of the same joint: no
    progressive spring is named (today: seed 3 named one, its cubic absorbing the gear error); where its cubic is
    significant the report says these poses cannot tell it from the harmonic, as the joint's structure."""
    rng = np.random.default_rng(seed)
    robot = TrueRobot.draw(Arm.from_dict(ARM4_BETA), Effects(stiffness={2: 3e5},
                                                            periodic=[(2, 2, math.radians(0.01), 0.5)]), rng)
    shots = measure(robot, sample(robot, 90, rng, floor_z=None), rng)
    data = Measurements.from_arrays(shots.q, shots.xyz)
    rep = diagnose(robot_from_dict(ARM4_BETA), data.subset(np.arange(40)), data.subset(np.arange(40, 90)),
                   DiagnosisSettings(seed=seed))
    assert not [c for c in named(rep) if c[0] == "nonlinear_stiffness"], rep.final_model
    assert ("joint_compliance", 2, None, None, None) in named(rep)
    told = [s for s in rep.steps if s.candidate is not None and s.candidate.cause == "nonlinear_stiffness"]
    for s in told:
        assert s.accepted is False and "cannot tell a progressive spring" in s.reason, s.reason


def test_the_closed_chain_protocol_names_no_cause_the_truth_lacks(tmp_path):
    """The TLBO paper's protocol (HH800, 745 kg payload, 40 calibration poses; problems/protocols/tlbo-hh800.toml),
    simulated and diagnosed by the command line: every cause named is one the truth has (compliance of joints 2-5,
    gear errors of joints 2 and 3), no progressive stiffness (before: k2 7.87e7 against a true 6.16e7 with a cubic
    term absorbing the difference). The GP compensator is no cause: where it is kept here (issue 38: its shrunk
    correction lowers the folds' mean 0.0656 -> 0.0581 mm and the validation mean 0.0951 -> 0.0894 mm) it takes
    the true gear errors this seed's 40 poses do not name."""
    assert main(["simulate", "tlbo-hh800", "--out-dir", str(tmp_path)]) == 0
    assert main(["diagnose", "hh800", str(tmp_path / "calibration.csv"), "--validate",
                 str(tmp_path / "validation.csv"), "--json", str(tmp_path / "r.json")]) == 0
    doc = json.loads((tmp_path / "r.json").read_text())
    truth = {("geometric", None, None)} | {("joint_compliance", j, None) for j in (2, 3, 4, 5)} | \
        {("joint_periodic", 2, 2), ("joint_periodic", 3, 1)}
    found = {(f["cause"], f.get("joint"), f.get("harmonic")) for f in doc["findings"] if f["in_model"]
             and not (f["cause"] == "unexplained" and "shrink" in f.get("holds_up", {}))}
    assert found <= truth, found - truth


@pytest.mark.parametrize("arm, seed", [(ARM4_BETA, 0), (ARM7_DH, 1), (ARM7, 2)], ids=["arm4", "arm7dh", "arm7"])
def test_a_sessions_own_encoder_scale_is_structure_of_that_session(arm, seed, tmp_path):
    """Session A's drive 2 reads 500 ppm off (session B's does not): a joint's encoder scale is the robot's (issue
    49), so it is structure of session A on joint 2, an ``unexplained`` finding naming the session and its trend
    (about 500 ppm), kept out of the model; no cause but the geometry is named."""
    rng = np.random.default_rng(seed)
    robot = TrueRobot.draw(Arm.from_dict(arm), Effects(), rng)
    own = robot.with_effects(Effects(encoder_scale={2: 5e-4}))
    parts = {"cal": [], "val": []}
    for kind, n in (("cal", 80), ("val", 120)):
        (tmp_path / kind).mkdir()
        for truth, s in ((own, Session("A")), (robot, Session("B", (1.1, 0.4, -0.2), (0.0, 0.02, 1.9)))):
            parts[kind].append(read(measure(truth, sample(truth, n, rng, floor_z=None), rng, session=s),
                                    tmp_path / kind / f"{s.name}.csv"))
    rep = diagnose(robot_from_dict(arm), combine(parts["cal"]), combine(parts["val"]), DiagnosisSettings(seed=seed))
    assert named(rep) == {("geometric", None, None, None, "robot")}, rep.final_model
    f = next(f for f in rep.findings if f.cause == "unexplained" and f.candidate.session == "A"
             and f.candidate.joint == 2 and "structures" in f.holds_up)
    assert not f.in_model and "session A only" in f.where, f.where
    ppm = [s["trend_ppm"] for s in f.holds_up["structures"] if "trend_ppm" in s]
    assert ppm and abs(ppm[0] - 500) < 100, f.holds_up
