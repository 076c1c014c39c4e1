"""Calibration from rows that say what the tool point touched (docs/formats.md section 11), on data of the
independent truth (tests/truth/touch.py): what touches cannot see is held and said, a fixture's known distance
identifies the scale of the lengths, rows of several kinds fit together, bad rows get one line."""

import dataclasses
import json
import warnings

import numpy as np
import pytest

from casadical import calibrate
from casadical.cli import main
from tests.helpers import hidden
from tests.helpers.arms import ARM4, to_toml
from tests.truth import Arm, Effects, Session, TrueRobot, measure, sample, touch


def _case(robot="arm7-dh", seed=0):
    return hidden.Case(robot, "none", seed, Effects(), set())


@pytest.mark.parametrize("seed", [0, 1])
def test_touches_alone_hold_and_say_the_base_pose_and_the_scale(seed):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        rob, cal, val, _ = hidden.make_touch_data(_case(seed=seed), fixture=False)
        res = calibrate(rob, cal, "kinematic", "lm")
    said = {u["what"]: u for u in res.unobservable}
    assert set(said) == {"the base pose", "the scale of every length"}
    base = set(said["the base pose"]["parameters"])
    assert {"base_x", "base_y", "base_z", "base_roll", "base_pitch", "base_yaw"} <= base
    for name in said["the base pose"]["parameters"] + said["the scale of every length"]["parameters"]:
        p = res.parameters[name]
        assert p.fixed and p.value == p.nominal, name
    assert res.frame == "base"
    doc = res.to_dict()
    assert doc["frame"] == "base" and doc["unobservable"] == res.unobservable
    # the held-out placements are consistent to about the contact noise (20 um per axis: 32 um on average)
    assert res.stats(val).touch["consistency_mm"] < 0.06


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_a_fixture_identifies_the_scale_the_free_sockets_cannot(seed):
    """Every length of the true robot 0.2 % longer than its nominal: with the fixture's 50 mm the calibration finds
    it (the longest length, held without a fixture, fitted to the truth); the free sockets' distance is then off
    by 0.1 mm, the fixture's fit keeps it."""
    c = _case("arm6-mdh", seed)
    rng = np.random.default_rng(100 + seed)
    drawn = TrueRobot.draw(Arm.from_dict(hidden.robot_doc(c.robot)), Effects(), rng)
    g = drawn.geometry
    true = TrueRobot(drawn.arm, dataclasses.replace(g, a=g.a * 1.002, d=g.d * 1.002, tool=g.tool * 1.002), Effects())
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        rob, cal, val, _ = hidden.make_touch_data(c, true=true)
        res = calibrate(rob, cal, "kinematic", "lm")
        free = calibrate(rob, cal.with_fixtures(()), "kinematic", "lm")
    assert not any(u["what"] == "the scale of every length" for u in res.unobservable)
    scale = next(u for u in free.unobservable if u["what"] == "the scale of every length")
    (name,) = scale["parameters"]
    p = res.parameters[name]
    assert not p.fixed
    assert abs(p.value - true_value(true, name)) < max(4 * p.std, 20e-6), (p.value, true_value(true, name), p.std)
    assert res.stats(val).touch["distance_error_mm"] < 0.02
    assert free.parameters[name].fixed


def true_value(true: TrueRobot, name: str) -> float:
    kind, j = name.rstrip("0123456789"), int(name[len(name.rstrip("0123456789")):])
    return float(getattr(true.geometry, kind)[j - 1])


def test_tracker_and_touch_rows_fit_together(tmp_path):
    """One session measured by a tracker, another only touching: one calibration, the base pose of the touching
    session alone unseen, the tracker's frame kept."""
    doc = hidden.robot_doc("arm7-dh")
    rng = np.random.default_rng(7)
    true = TrueRobot.draw(Arm.from_dict(doc), Effects(), rng)
    shots = measure(true, sample(true, 40, rng), rng, session=Session("T"))
    rows = touch.fixture_session(true, touch.two_sockets(), 20, rng, Session("S"), contact_noise=20e-6)
    a = shots.write_csv(tmp_path / "tracker.csv")
    b = rows.write_csv(tmp_path / "touch.csv")
    (tmp_path / "fx.toml").write_text(touch.fixture_toml([touch.two_sockets()]))
    (tmp_path / "robot.toml").write_text(to_toml(doc))
    code = main(["calibrate", str(tmp_path / "robot.toml"), str(a), str(b), "--model", "kinematic", "--fixture",
                 str(tmp_path / "fx.toml"), "--out", str(tmp_path / "cal.json"), "--quiet"])
    assert code == 0
    out = json.loads((tmp_path / "cal.json").read_text())
    assert "frame" not in out
    assert [u["what"] for u in out["unobservable"]] == ["the base pose of session touch"]
    assert out["calibration"]["consistency_mm"] < 0.06


BAD = [
    ("q1_deg,q2_deg,q3_deg,q4_deg,x_mm,y_mm,z_mm,point\n" + "0,10,20,30,1,2,3,s0\n" * 5, 2, "point",
     "measured positions too"),
    ("q1_deg,q2_deg,q3_deg,q4_deg,point\n" + "0,10,20,30,s0\n" * 3, 2, "point", "too few"),
    ("q1_deg,q2_deg,q3_deg,q4_deg,point,distance_mm\n" + "0,10,20,30,s0,100\n" * 4 + "0,10,20,30,,100\n", 6,
     "distance_mm", "without a point"),
    ("q1_deg,q2_deg,q3_deg,q4_deg,point,plane\n" + "0,10,20,30,s0,f\n" * 4, 2, "plane", "a point and a plane"),
]


@pytest.mark.parametrize("text,row,column,words", BAD)
def test_bad_touch_rows_get_one_line_naming_file_row_and_column(text, row, column, words, tmp_path, capsys):
    path = tmp_path / "bad.csv"
    path.write_text(text)
    out = tmp_path / "cal.json"
    code = main(["calibrate", _robot_file(tmp_path), str(path), "--model", "kinematic",
                 "--out", str(out)])
    err = capsys.readouterr().err.strip().splitlines()
    assert code != 0 and not out.exists()
    (line,) = [x for x in err if "error" in x]
    assert "bad.csv" in line and f"row {row}" in line and repr(column) in line and words in line, line


def _robot_file(tmp_path) -> str:
    p = tmp_path / "arm4.toml"
    p.write_text(to_toml(ARM4))
    return str(p)


def test_a_bad_fixture_file_gets_one_line(tmp_path, capsys):
    (tmp_path / "fx.toml").write_text('[[fixture]]\nname = "block"\n[fixture.points]\ns0 = [0, 0]\ns1 = [50, 0, 0]\n')
    path = tmp_path / "t.csv"
    path.write_text("q1_deg,q2_deg,q3_deg,q4_deg,point\n" + "".join(f"{k},10,20,30,s0\n" for k in range(8)))
    code = main(["calibrate", _robot_file(tmp_path), str(path), "--fixture", str(tmp_path / "fx.toml"),
                 "--out", str(tmp_path / "cal.json")])
    err = [x for x in capsys.readouterr().err.strip().splitlines() if "error" in x]
    assert code != 0 and len(err) == 1 and "fx.toml" in err[0] and "fixture[1].points.s0" in err[0], err
    assert not (tmp_path / "cal.json").exists()
