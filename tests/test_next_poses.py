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
from casadical.planning.augment import Criterion, criterion_value, ds_design, relax_ds_cvxpy

from planning_loop import SCENARIOS, loop, setup


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


@pytest.mark.slow
@pytest.mark.parametrize("name", ["narrow range", "harmonic band"])
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
    assert main(["diagnose", p["robot"], p["cal"], "--validate", p["val"], "--json", rep, "--no-blackbox", "-q"]) == 0
    doc = json.loads(open(rep).read())
    assert doc["inputs"]["data"] == ["cal.csv"] and doc["final"]["sigma_mm"] > 0
    out = str(tmp_path / "n.csv")
    _quiet(capsys)
    cases = [
        (["--question", "3"], "--question 3: the report has 1 open question"),
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
    """The questions of a real report (ambiguous scale error / first harmonic), with one named parameter marked
    not significant: three questions, each planned alone with --question, each planned set lowering the
    standard errors it asks about below the measured poses' and below the random sets' median."""
    env = setup(SCENARIOS["narrow range"], 0, tmp_path)
    p = env["paths"]
    rep = tmp_path / "rep.json"
    assert main(["diagnose", p["robot"], p["cal"], "--validate", p["val"], "--json", str(rep), "--no-blackbox",
                 "-q"]) == 0
    doc = json.loads(rep.read_text())
    for e in doc["final"]["parameters"]:
        if e["name"] == "escale2":
            e["significant"] = False
    rep.write_text(json.dumps(doc))
    from casadical.planning.questions import open_questions

    qs = open_questions(doc, {"escale2": 6e-4})
    assert [q.kind for q in qs] == ["ambiguous", "not significant"], [q.text for q in qs]
    assert qs[1].interest == ["escale2"]
    for n in (1, 2):
        plan = tmp_path / f"plan{n}.json"
        assert main(["plan-poses", str(rep), p["cand"], "-m", "6", "--out", str(tmp_path / f"n{n}.csv"),
                     "--question", str(n), "--json", str(plan), "-q"]) == 0
        q = json.loads(plan.read_text())["questions"][0]
        for name in q["parameters"]:     # null: the poses do not determine it
            planned = q["planned"]["std"][name]
            assert planned is not None
            assert q["random"]["std"][name] is None or planned < q["random"]["std"][name]
            assert q["before"]["std"][name] is None or planned < q["before"]["std"][name]
