"""plan-poses REPORT.json: the poses that answer a diagnosis' open questions (issue 27).

The Ds-optimal augmentation is checked against brute force and cvxpy; the
loop on simulated arms that are not built in: the first poses cannot tell
the cause, the planned poses "measured" with the simulator let the
diagnosis name it, M random candidates of the same pool do not.
"""

import itertools
import json

import numpy as np
import pytest

from casadical.cli import main
from casadical.planning import Criterion, criterion_value, ds_design, relax_ds_cvxpy
from tests.helpers.planning_loop import JOINT_SCOPE, SCENARIOS, diagnose, loop, setup


@pytest.mark.parametrize("interest", [[4], [4, 5], list(range(6))])
def test_ds_augmentation_is_certified_and_finds_the_best_set(interest):
    """On a pool small enough to enumerate: the exact best augmentation is found, no set beats the bound,
    and the first-order relaxation agrees with cvxpy's conic program."""
    rng = np.random.default_rng(0)
    A = rng.normal(size=(14, 3, 6))
    A[:, :, 4] *= 0.1                       # a weakly seen parameter
    B0 = rng.normal(size=(5, 6))
    B0[:, 4:] *= 0.01                       # the measured poses barely see the last two
    crit = Criterion(A, B0.T @ B0 + 0.01 * np.eye(6), interest)
    for m in (1, 2, 3):
        best = max(criterion_value([crit], S) for S in itertools.combinations(range(14), m))
        d = ds_design([crit], m)
        assert d.value == pytest.approx(best, abs=1e-9)
        assert best <= d.upper_bound + 1e-9 and d.efficiency <= 1
        c = relax_ds_cvxpy(crit, m)
        assert c.value == pytest.approx(d.relaxation.value, abs=1e-3)
        assert best <= c.upper_bound + 1e-7


def test_two_questions_are_planned_together_and_certified():
    rng = np.random.default_rng(1)
    A = rng.normal(size=(12, 3, 6))
    M0 = np.eye(6) * 0.05
    crits = [Criterion(A, M0, [4]), Criterion(A[:, :, :5], M0[:5, :5], [0, 1])]
    for m in (2, 3):
        best = max(criterion_value(crits, S) for S in itertools.combinations(range(12), m))
        d = ds_design(crits, m)
        assert best <= d.upper_bound + 1e-9
        assert d.value >= best - 1e-6 or d.efficiency > 0.9


def _quiet(capsys):
    capsys.readouterr()


def test_planned_poses_resolve_a_narrow_range_random_ones_do_not(tmp_path, capsys):
    """A scale error of joint 2 measured over 40 deg: the diagnosis cannot tell it from a first harmonic.
    15 of 500 candidates reach beyond the region: the plan takes them, and the diagnosis of the measured and
    planned poses names the scale error alone; 10 random candidates leave the ambiguity (5-axis DH arm)."""
    out = loop(SCENARIOS["narrow range"], 0, tmp_path)
    assert not out["first"]
    assert out["far_picked"] >= 5 and out["far_random"] <= 1
    assert out["planned"], out["planned_findings"]
    assert not out["random"], out["random_findings"]
    q = out["plan"]["questions"][0]
    assert q["kind"] == "ambiguous" and q["planned"]["power"] > 0.9 > q["random"]["power"]
    assert out["plan"]["criterion"]["ds_efficiency"] > 0.95


@pytest.mark.parametrize("name", list(JOINT_SCOPE))
def test_a_joints_property_is_the_robots_whatever_a_sessions_poses(tmp_path, name):
    """Two sessions of a 5-axis DH arm, session B holding joint 1 within 6 deg, where a scale is a turn of B's base.
    An encoder scale error of joint 1 (200 ppm), the robot's or session A's alone (its drive re-mastered), is named
    the robot's from the first poses, with no question of its scope: a joint's own parameter is the robot's (issue
    49), and B's poses cannot say it lacks it (before, the report asked "the robot's or session A's own?" and
    plan-poses planned B's poses to tell)."""
    env = setup(JOINT_SCOPE[name], 0, tmp_path)
    p = env["paths"]
    first = diagnose(p["robot"], p["cal"], p["val"], str(tmp_path / "first.json"))
    named = [f for f in first["findings"] if f["in_model"] and f["cause"] not in ("geometric", "unexplained")]
    assert [(f["cause"], f.get("joint"), f.get("session")) for f in named] == [("encoder_scale", 1, None)], named
    assert not [a for a in named[0].get("ambiguous_with", []) if a.get("session")], named[0]


def test_planned_poses_tell_compliance_from_encoder_scale(tmp_path, capsys):
    """Compliance of joint 2 of the 5-axis arm measured with joints 3 and 4 held: joint 2's torque follows its
    reading, and the report cannot tell the compliance from a function of the reading (an encoder scale, a first
    harmonic). The planned poses move joints 3 and 4 (the torque changes at the same q2): the diagnosis then names
    the compliance alone; 10 random candidates leave the ambiguity."""
    out = loop(SCENARIOS["compliance or scale"], 1, tmp_path)
    assert not out["first"], out["first_findings"]
    kinds = {(q["kind"], q["text"].split(" (")[0]) for q in out["plan"]["questions"]}
    assert ("ambiguous", "compliance j2 or encoder scale j2?") in kinds, kinds
    assert out["far_picked"] >= 5 and out["far_random"] <= 1
    assert out["planned"], out["planned_findings"]
    assert not out["random"], out["random_findings"]
    for q in out["plan"]["questions"]:
        assert q["planned"]["power"] > 0.9 and q["random"]["power"] < 0.1 and q["before"]["power"] < 0.01


@pytest.mark.slow
@pytest.mark.parametrize("name", list(SCENARIOS))
def test_planned_poses_resolve_what_random_ones_do_not_in_most_seeds(tmp_path, name):
    """Three seeds: the planned poses resolve what M random candidates do not in at least 2 of 3."""
    wins = 0
    for seed in range(3):
        folder = tmp_path / str(seed)
        folder.mkdir()
        out = loop(SCENARIOS[name], seed, folder)
        wins += out["planned"] and not out["random"]
    assert wins >= 2


def test_report_mode_errors(tmp_path, capsys):
    env = setup(SCENARIOS["narrow range"], 0, tmp_path)
    p = env["paths"]
    rep = str(tmp_path / "rep.json")
    assert main(["diagnose", p["robot"], *p["cal"], "--validate", *p["val"], "--json", rep, "--no-blackbox",
                 "-q"]) == 0
    doc = json.loads(open(rep).read())
    assert doc["inputs"]["data"] == ["cal.csv"] and doc["final"]["sigma_mm"] > 0
    out = str(tmp_path / "n.csv")
    _quiet(capsys)
    # the narrow range's scale error of joint 2: ambiguous with joint 2's first harmonic and with a coupling of
    # joint 3 from joint 2's reading
    cases = [
        (["--question", "3"], "--question 3: the report has 2 open questions"),
        (["--method", "ga"], "--method and --model are for plan-poses ROBOT"),
        (["--measured", str(tmp_path / "nope.csv")], "nope.csv"),
    ]
    for extra, words in cases:
        assert main(["plan-poses", rep, p["cand"], "-m", "5", "--out", out, *extra]) == 2
        err = capsys.readouterr().err.strip()
        assert len(err.splitlines()) == 1 and words in err, err
    # a report whose data moved: one line naming where it looked, and the fix
    (tmp_path / "cal.csv").rename(tmp_path / "moved.csv")
    assert main(["plan-poses", rep, p["cand"], "-m", "5", "--out", out]) == 2
    err = capsys.readouterr().err
    assert "--measured" in err and len(err.strip().splitlines()) == 1
    assert main(["plan-poses", rep, p["cand"], "-m", "5", "--out", out, "--measured",
                 str(tmp_path / "moved.csv"), "-q"]) == 0
    # the robot's form of the command refuses the report's options
    assert main(["plan-poses", p["robot"], p["cand"], "-m", "40", "--out", str(tmp_path / "r.csv"), "--question",
                 "1"]) == 2
    # an older report (no robot description): one line saying to run diagnose again
    del doc["robot_description"]
    old = tmp_path / "old.json"
    old.write_text(json.dumps(doc))
    capsys.readouterr()
    assert main(["plan-poses", str(old), p["cand"], "-m", "5", "--out", str(tmp_path / "o.csv")]) == 2
    assert "run diagnose again" in capsys.readouterr().err


def test_every_kind_of_question_is_read_and_planned(tmp_path, capsys):
    """The questions of a real report (ambiguous scale error / first harmonic, and scale error / a coupling of
    joint 3 from joint 2's reading), with one named parameter marked not significant: three questions, each
    planned alone with --question, each planned set lowering the standard errors it asks about below the
    measured poses' and below the random sets' median."""
    env = setup(SCENARIOS["narrow range"], 0, tmp_path)
    p = env["paths"]
    rep = tmp_path / "rep.json"
    assert main(["diagnose", p["robot"], *p["cal"], "--validate", *p["val"], "--json", str(rep), "--no-blackbox",
                 "-q"]) == 0
    doc = json.loads(rep.read_text())
    for e in doc["final"]["parameters"]:
        if e["name"] == "escale2":
            e["significant"] = False
    rep.write_text(json.dumps(doc))
    from casadical.planning import open_questions

    qs = open_questions(doc, {"escale2": 6e-4})
    assert [q.kind for q in qs] == ["ambiguous", "ambiguous", "not significant"], [q.text for q in qs]
    assert "coupling j3<-j2" in qs[1].text and "cpl3_2" in qs[1].interest
    assert qs[2].interest == ["escale2"]
    for n in (1, 2, 3):
        plan = tmp_path / f"plan{n}.json"
        assert main(["plan-poses", str(rep), p["cand"], "-m", "6", "--out", str(tmp_path / f"n{n}.csv"),
                     "--question", str(n), "--json", str(plan), "-q"]) == 0
        q = json.loads(plan.read_text())["questions"][0]
        for name in q["parameters"]:     # null: the poses do not determine it
            planned = q["planned"]["std"][name]
            assert planned is not None
            assert q["random"]["std"][name] is None or planned < q["random"]["std"][name]
            assert q["before"]["std"][name] is None or planned < q["before"]["std"][name]


def test_session_options_and_a_sessions_own_structure(tmp_path, capsys):
    """--session: one line of error where it cannot hold; a structure the report could not name in one session
    (an unexplained harmonic of session A, written into a real report of two sessions) asks which harmonic and
    whether it is the robot's, and the poses planned in session B answer the scope question better than random
    ones."""
    env = setup(JOINT_SCOPE["robot or session"], 0, tmp_path)
    p = env["paths"]
    rep = tmp_path / "rep.json"
    assert main(["diagnose", p["robot"], *p["cal"], "--validate", *p["val"], "--json", str(rep), "--no-blackbox",
                 "-q"]) == 0
    out = str(tmp_path / "n.csv")
    capsys.readouterr()
    with_column = tmp_path / "cand_s.csv"
    lines = open(p["cand"]).read().splitlines()
    with_column.write_text("\n".join([lines[0] + ",session"] + [r + ",B" for r in lines[1:3]] + [lines[3] + ",C"]
                                     + [r + ",B" for r in lines[4:]]) + "\n")
    cases = [
        ([p["cand"], "--session", "C"], "--session C: none of the measured sessions (A, B)"),
        ([str(with_column), "--session", "B"], "the candidates name their sessions"),
        ([str(with_column)], "session 'C' is none of the measured sessions"),
    ]
    for args, words in cases:
        assert main(["plan-poses", str(rep), *args, "-m", "5", "--out", out]) == 2
        err = capsys.readouterr().err.strip()
        assert len(err.splitlines()) == 1 and words in err, err
    assert "row 4" in err                      # the file line of the first candidate of an unknown session
    assert main(["plan-poses", p["robot"], p["cand"], "-m", "40", "--out", out, "--session", "B"]) == 2
    assert "--session is for plan-poses REPORT.json" in capsys.readouterr().err
    # an unexplained harmonic of session A only
    doc = json.loads(rep.read_text())
    cand = {"cause": "joint_periodic", "joint": 3, "harmonic": 7, "session": "A"}
    doc["findings"].append({"cause": "unexplained", "joint": 3, "in_model": False, "holds_up": {"structures": [
        {"candidate": cand, "band": [7, 8], "values": {"gear3_s7@A": 2e-5, "gear3_c7@A": -1e-5}}]}})
    rep.write_text(json.dumps(doc))
    from casadical.planning import open_questions

    qs = open_questions(doc, {})
    texts = [(q.kind, q.text.split(" (finding")[0]) for q in qs]
    assert ("unexplained", "joint 3 in session A: which harmonic, 7..8?") in texts, texts
    assert ("scope", "periodic j3 h7 seen in session A: session A's own or the robot's?") in texts, texts
    n = 1 + [k for k, _ in texts].index("scope", 1)
    scope = qs[n - 1]
    assert scope.interest == ["gear3_s7@A", "gear3_c7@A", "gear3_s7", "gear3_c7"]
    assert scope.tested == {"gear3_s7": 2e-5, "gear3_c7": -1e-5}
    plan = tmp_path / "plan.json"
    assert main(["plan-poses", str(rep), p["cand"], "-m", "8", "--out", out, "--session", "B", "--question", str(n),
                 "--json", str(plan), "-q"]) == 0
    q = json.loads(plan.read_text())["questions"][0]
    for name in ("gear3_s7", "gear3_c7"):
        assert q["planned"]["std"][name] < q["random"]["std"][name] < q["before"]["std"][name]
