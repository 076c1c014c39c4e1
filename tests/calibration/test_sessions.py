"""Sessions: several measurement sessions of one robot, each with its own base pose (and tool), the robot's
parameters shared; the diagnosis tells the robot's causes from a session's."""

import json
import warnings

import numpy as np
import pytest

from casadical import calibrate
from casadical.cli import main
from casadical.data import Effects, another_session, combine, simulate
from casadical.diagnosis import DiagnosisSettings, diagnose
from casadical.robot import robot_from_dict
from tests.helpers.arms import ARM5, ARM7_DH, to_toml

SEEDS = [0, 1, 2]
ARMS = {"seven-axis DH": (ARM7_DH, 2e4), "five-axis DH": (ARM5, 6e4)}


def two_sessions(arm, stiffness, seed, n_cal=80, n_val=150, drift=(1.0e-6, 0.0, -1.0e-6)):
    """Session A, and session B of the same robot: the tracker elsewhere, the probe re-mounted 3-4 mm off,
    and a drift of its own (one pose a second). The joint 2 compliance is the robot's."""
    robot = robot_from_dict(arm)
    a, truth = simulate(robot, n_cal, Effects(stiffness={2: stiffness}), seed=seed, floor_z=None)
    va, _ = simulate(robot, n_val, truth=truth, seed=seed + 100, floor_z=None)
    tb = another_session(truth, (1.2, -0.8, 0.1), (0.01, -0.02, 2.2), tool_shift=(0.003, -0.002, 0.004),
                         drift=drift, t_ref=40.0)
    b, _ = simulate(robot, n_cal, truth=tb, seed=seed + 1, floor_z=None)
    vb, _ = simulate(robot, n_val, truth=tb, seed=seed + 101, floor_z=None)
    for d in (a, va) if any(drift) else ():    # every session has times, or none
        d.columns["time_s"] = np.arange(len(d), dtype=float)
    for d, name in ((a, "A.csv"), (va, "A.csv"), (b, "B.csv"), (vb, "B.csv")):
        d.path = name
    return robot, combine([a, b]), combine([va, vb]), truth


def session_files(arm, cal, folder):
    """The arm's robot TOML and one CSV per session of ``cal`` (A.csv, B.csv, no session column)."""
    robot_file = folder / "arm.toml"
    robot_file.write_text(to_toml(arm))
    paths = []
    for s in ("A", "B"):
        part = cal.subset(cal.sessions == s)
        part.sessions = None
        paths.append(str(folder / f"{s}.csv"))
        part.write_csv(paths[-1])
    return robot_file, paths


@pytest.mark.parametrize("seed", SEEDS)
@pytest.mark.parametrize("arm", sorted(ARMS))
def test_robot_causes_and_session_causes(arm, seed):
    """The shared compliance is named a cause of the robot, session B's drift a property of session B; each
    session has its own base pose and (asked) tool, and nothing else is named."""
    robot, cal, val, truth = two_sessions(*ARMS[arm], seed)
    rep = diagnose(robot, cal, val, DiagnosisSettings(seed=seed, session_tools=True))
    named = {(f.candidate.cause, f.candidate.joint, f.candidate.session, f.scope) for f in rep.findings
             if f.cause != "unexplained"}
    assert named == {("geometric", None, None, "robot"), ("joint_compliance", 2, None, "robot"),
                     ("drift", None, "B", "session")}, named
    final = rep.final
    assert final.sessions == ["A", "B"]
    c2 = final.parameters["c2"]
    assert abs(c2.value - truth.value("c2")) < 4 * c2.std
    doc = rep.to_dict()
    scopes = {f["cause"]: f.get("scope") for f in doc["findings"]}
    assert scopes["drift"] == "session" and scopes["joint_compliance"] == "robot"
    # each session's validation error is reported
    assert set(doc["final"]["sessions"]) == {"A", "B"}


def test_one_base_pose_per_session_is_what_lets_them_be_fitted_together():
    """Two sessions with the tracker 1.5 m and 126 deg apart calibrate together to their own errors' size;
    the sessions' base poses are recovered; a file of the same robot with one base pose could not."""
    robot, cal, val, truth = two_sessions(ARM7_DH, 2e4, 5, drift=(0.0, 0.0, 0.0))
    both = calibrate(robot, cal, "kinematic+compliance[2]", "lm", warn=False, session_tools=True)
    assert both.sessions == ["A", "B"] and both.calibration.mean_mm < 0.05
    assert set(both.by_session) == {"A", "B"}
    xyz, rpy = both.base_pose("B")
    assert np.allclose(xyz, (1.2, -0.8, 0.1), atol=2e-3) and np.allclose(rpy, (0.01, -0.02, 2.2), atol=2e-3)
    assert both.stats(val).mean_mm < 0.05
    # without its own tool, session B's re-mounted probe shows
    shared_tool = calibrate(robot, cal, "kinematic+compliance[2]", "lm", warn=False)
    assert shared_tool.by_session["B"].mean_mm > 1.0


def test_combine_keeps_order_and_names_the_sessions():
    robot, cal, _, _ = two_sessions(ARM7_DH, 2e4, 0, n_cal=20, n_val=20)
    assert cal.session_names == ["A", "B"] and list(cal.sessions[:20]) == ["A"] * 20
    assert np.all(np.diff(cal.rows) > 0)          # measurement order kept, and numbered on
    a = cal.subset(np.arange(20))
    b = cal.subset(np.arange(20, 40))
    b.columns.pop("time_s")
    with pytest.warns(Warning, match="time_s: not in every file"):
        both = combine([a, b], names=["day1", "day2"])
    assert both.session_names == ["A", "B"]       # their own session names win
    a.sessions = b.sessions = None
    a.path, b.path = "runs/one.csv", "other/one.csv"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        assert combine([a, b]).session_names == ["one", "one-2"]


def test_cli_several_files_are_sessions(tmp_path, capsys):
    """calibrate ROBOT A.csv B.csv --session-tool: one robot, a base pose and a tool per session, in the JSON
    and the summary; predict takes a file of either session (its session column), and an unknown session is
    one line naming file, row and column."""
    robot, cal, val, _ = two_sessions(ARM7_DH, 2e4, 3, drift=(0.0, 0.0, 0.0))
    arm, paths = session_files(ARM7_DH, cal, tmp_path)
    out = tmp_path / "cal.json"
    assert main(["calibrate", str(arm), *paths, "--model", "kinematic+compliance[2]", "--solver", "lm",
                 "--session-tool", "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "session A:" in text and "session B (its own tool):" in text
    doc = json.loads(out.read_text())
    assert [s["name"] for s in doc["sessions"]] == ["A", "B"] and doc["sessions"][1]["own_tool"]
    assert doc["model"] == "kinematic+sessions+joint_compliance[2]"
    vb = val.subset(val.sessions == "B")
    vb.columns["session"] = np.array(["B"] * len(vb), dtype=object)
    vb.write_csv(tmp_path / "vb.csv")
    assert main(["predict", str(out), str(tmp_path / "vb.csv"), "--out", str(tmp_path / "p.csv")]) == 0
    assert "mean 0.0" in capsys.readouterr().out
    vb.columns["session"] = np.array(["C"] * len(vb), dtype=object)
    vb.write_csv(tmp_path / "vc.csv")
    assert main(["predict", str(out), str(tmp_path / "vc.csv"), "--out", str(tmp_path / "p2.csv")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "vc.csv, row 2, column 'session'" in err and "'C'" in err



def test_the_base_reference_is_shown_wherever_the_base_parameters_are(tmp_path, capsys):
    """base_x .. base_yaw deviate from a reference pose (base0, one per session): the summary, the HTML parameter
    section and the exported table say which, and the base pose it gives."""
    import math

    from casadical.apply import parameter_table
    from casadical.html import calibration_html

    robot, cal, _, _ = two_sessions(ARM7_DH, 2e4, 3, drift=(0.0, 0.0, 0.0))
    res = calibrate(robot, cal, "kinematic+compliance[2]", "lm", warn=False)
    text = res.summary()
    html = calibration_html(res, cal)
    table = parameter_table(res).to_csv().splitlines()[0]
    for s in ("A", "B"):
        (rx, rr), (bx, br) = res.base_reference(s), res.base_pose(s)
        ref = "xyz [" + ", ".join(f"{v * 1000:.3f}" for v in rx) + "] mm, rpy [" + ", ".join(
            f"{math.degrees(v):.4f}" for v in rr) + "] deg"
        pose = "xyz [" + ", ".join(f"{v * 1000:.3f}" for v in bx) + "] mm, rpy [" + ", ".join(
            f"{math.degrees(v):.4f}" for v in br) + "] deg"
        at = "" if s == "A" else "@B"
        line = next(x for x in text.splitlines() if x.startswith(f"base in the measurement frame of session {s}:"))
        assert pose in line
        nxt = text.splitlines()[text.splitlines().index(line) + 1]
        assert ref in nxt and f"base_x{at} .. base_yaw{at}" in nxt
        assert ref in table and (s == "A" or pose in table)
        assert f"<code>base_x{at}</code> .. <code>base_yaw{at}</code> deviate from" in html
        assert ref.replace("[", "").replace("] mm, rpy", " mm, roll, pitch, yaw").replace("] deg", " deg") in html
    # the references differ: the second session's is not base0
    assert not np.allclose(res.base_reference("A")[0], res.base_reference("B")[0])
    # one session: base0
    one = calibrate(robot, cal.subset(cal.sessions == "A"), "kinematic", "lm", warn=False)
    assert "  = reference pose base0 xyz [" in one.summary()
    assert "the calibration's reference pose base0 (xyz [" in parameter_table(one).to_markdown()


def test_a_left_out_session_keeps_the_robot_and_fits_its_own_base():
    """The session fold of the linearised cross-validation: the robot's parameters come from the other
    sessions, the left-out session's own (its base pose) from its own poses, exactly as two least-squares
    fits in turn give them."""
    from casadical.diagnosis import linear_cv, session_scheme

    rng = np.random.default_rng(0)
    n = 40
    sessions = np.array(["A"] * n + ["B"] * n, dtype=object)
    J = np.zeros((2 * n, 3, 4))
    J[:, :, :2] = rng.normal(size=(2 * n, 3, 2))              # two robot parameters
    J[:n, :, 2] = rng.normal(size=(n, 3))                     # session A's own
    J[n:, :, 3] = rng.normal(size=(n, 3))                     # session B's own
    r = rng.normal(size=(2 * n, 3))
    cv = linear_cv(J, r, np.ones(2 * n), [session_scheme(sessions)])
    for own, F, T in ((2, np.arange(n), np.arange(n, 2 * n)), (3, np.arange(n, 2 * n), np.arange(n))):
        other = [0, 1, 5 - own]                               # robot + the training session's own
        d = np.zeros(4)
        d[other] = np.linalg.lstsq(J[T][:, :, other].reshape(-1, 3), -r[T].reshape(-1), rcond=None)[0]
        rest = r[F] + J[F] @ d
        d[own] = np.linalg.lstsq(J[F][:, :, own].reshape(-1, 1), -rest.reshape(-1), rcond=None)[0][0]
        assert np.allclose(cv.errors["session"][F], np.linalg.norm(r[F] + J[F] @ d, axis=1), atol=1e-9)


def test_terms_of_one_session_in_a_calibration():
    """calibrate with terms of one session (a periodic error and a drift of B): each is fitted at B's poses
    only, the notes name them by their own parameters, and the JSON reads back to the same predictions."""
    import tempfile

    from casadical import load_calibration
    from casadical.stats import term_causes

    robot, cal, val, _ = two_sessions(ARM7_DH, 2e4, 0)
    res = calibrate(robot, cal, "kinematic+compliance[2]+joint_periodic[2:3]@B+drift@B", "lm", warn=False,
                    session_tools=True)
    labels = [c.label for c in term_causes(res)]
    assert "periodic error of joint 2, harmonic 3 in session B" in labels and "drift in session B" in labels
    assert res.parameters["drift_x@B"].value == pytest.approx(1e-6, rel=0.2)
    with tempfile.TemporaryDirectory() as d:
        res.save(f"{d}/c.json")
        again = load_calibration(f"{d}/c.json")
    assert np.abs(again.predict(val) - res.predict(val)).max() < 1e-12


def test_the_urdf_of_sessions_is_in_the_first_sessions_frame(tmp_path, capsys):
    """A calibration of two sessions exported: measurement_frame is session A's tracker frame (yourdfpy's forward
    kinematics is the calibration's prediction of A's poses), and the file says so."""
    import yourdfpy

    robot, cal, val, _ = two_sessions(ARM5, 6e4, 4, drift=(0.0, 0.0, 0.0))
    res = calibrate(robot, cal, "kinematic", "lm", warn=False)
    res.save(tmp_path / "c.json")
    assert main(["export", str(tmp_path / "c.json"), "--urdf", str(tmp_path / "c.urdf")]) == 0
    capsys.readouterr()
    text = (tmp_path / "c.urdf").read_text()
    assert "'measurement_frame' is the measurement frame of session A, the calibration's first of A, B" in text
    u = yourdfpy.URDF.load(str(tmp_path / "c.urdf"), load_meshes=False)
    va = val.subset(val.sessions == "A")
    xyz = []
    for q in va.q:
        u.update_cfg(q)
        xyz.append(u.get_transform("tool_point", "measurement_frame")[:3, 3])
    assert np.abs(np.array(xyz) - res.predict(va)).max() < 1e-9
    vb = val.subset(val.sessions == "B")
    xyz_b = []
    for q in vb.q:
        u.update_cfg(q)
        xyz_b.append(u.get_transform("tool_point", "measurement_frame")[:3, 3])
    # near what was measured in A's frame (the kinematic model leaves the compliance: mm), a metre off B's
    assert np.linalg.norm(np.array(xyz) - va.xyz, axis=1).mean() < 0.01
    assert np.linalg.norm(np.array(xyz_b) - vb.xyz, axis=1).mean() > 0.5


def test_poses_without_a_session_column_are_said_to_be_in_the_first_sessions_frame(tmp_path, capsys):
    """predict and compensate with a calibration of sessions A and B, on a file with no session column: a warning
    before the work says its rows are taken in A's frame and how to choose B's; B's poses so read then miss by
    the distance between the trackers (the mismatch error), and with their session column they are predicted."""
    robot, cal, val, _ = two_sessions(ARM5, 6e4, 5, drift=(0.0, 0.0, 0.0))
    arm, paths = session_files(ARM5, cal, tmp_path)
    assert main(["calibrate", str(arm), *paths, "--model", "kinematic", "--solver", "lm",
                 "--out", str(tmp_path / "c.json")]) == 0
    vb = val.subset(val.sessions == "B")
    vb.sessions = None
    vb.write_csv(tmp_path / "vb.csv")
    capsys.readouterr()
    assert main(["predict", str(tmp_path / "c.json"), str(tmp_path / "vb.csv"), "--out", str(tmp_path / "p.csv")]) == 2
    err = capsys.readouterr().err
    assert ("vb.csv: has no 'session' column; " in err and "holds the sessions A, B, so its rows are taken in the "
            "measurement frame of the first, A; add a 'session' column" in err and "mean error of" in err)
    assert main(["compensate", str(tmp_path / "c.json"), str(tmp_path / "vb.csv"), "--out", str(tmp_path / "j.csv"),
                 "--position-only"]) == 2
    assert "frame of the first, A" in capsys.readouterr().err
    vb.columns["session"] = np.array(["B"] * len(vb), dtype=object)
    vb.write_csv(tmp_path / "vb2.csv")
    assert main(["predict", str(tmp_path / "c.json"), str(tmp_path / "vb2.csv"), "--out", str(tmp_path / "p.csv")]) == 0
    assert "'session' column" not in capsys.readouterr().err
    # calibrate --validate with the sessions' data: the same word before the fit
    assert main(["calibrate", str(arm), *paths, "--model", "kinematic", "--solver", "lm", "--validate",
                 str(tmp_path / "vb.csv"), "--out", str(tmp_path / "c2.json")]) == 2
    assert "the calibration holds the sessions A, B, so its rows are taken in" in capsys.readouterr().err


def test_validation_files_out_of_order_are_an_error():
    """With two sessions, validation poses labelled with the other session (--validate files out of order) would
    be judged in the other tracker's frame, metres off: one error naming the session, before the rounds; the
    override goes on with a warning."""
    from casadical.errors import DataFileError

    robot, cal, val, _ = two_sessions(ARM5, 6e4, 6, drift=(0.0, 0.0, 0.0))
    swapped = val.subset(np.arange(len(val)))
    swapped.sessions = np.where(val.sessions == "A", "B", "A").astype(object)
    settings = DiagnosisSettings(max_rounds=1, blackbox=False)
    with pytest.raises(DataFileError, match=r"validation poses of session [AB] are missed by \d+ mm on average.*in the "
                                            r"order of the DATA files.*--allow-mismatch"):
        diagnose(robot, cal, swapped, settings)
    with pytest.warns(Warning, match="allowed by --allow-mismatch"):
        rep = diagnose(robot, cal, swapped, settings, allow_mismatch=True)
    assert rep.steps[0].validation.mean_mm > 500
    assert diagnose(robot, cal, val, settings).steps[0].validation.mean_mm < 50        # in order: no complaint
