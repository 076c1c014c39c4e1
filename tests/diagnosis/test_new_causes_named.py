"""The catalogue's joint coupling and mount compliance, hidden by the independent truth (tests/truth) on arms that
are not built in: the diagnosis names exactly the hidden cause, nothing else.

- a joint coupling: the last joint's angle error 2 mrad per rad of the joint before it (a wrist's gearing); the
  claim is ``joint_coupling`` of joint n from joint n-1's reading (the source joint is part of the claim);
- a mount compliance: the base tilting 0.3 mrad at the largest moment of the weights.

The default run takes each cause on one arm, three seeds; ``pytest -m slow`` every arm of
tests/helpers/hidden.py's open-world set (arm4, arm5, arm7-dh).
"""

import json
import warnings

import pytest

from casadical.diagnosis import Candidate, DiagnosisSettings, diagnose
from tests.helpers import hidden

ROBOTS = ("arm4", "arm5", "arm7-dh")
SEEDS = (0, 1, 2)
FAST = [("arm5", "joint coupling"), ("arm4", "mount compliance")]
ALL = [(r, e) for e in hidden.CATALOGUED for r in ROBOTS if (r, e) not in FAST]


def run(c: hidden.Case, seed: int):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        rob, cal, val, _ = hidden.make_data(c)
        return diagnose(rob, cal, val, DiagnosisSettings(seed=seed, session_tools=c.sessions))


def check(robot: str, effect: str) -> None:
    for seed in SEEDS:
        c = hidden.case(robot, effect, seed)
        report = run(c, seed)
        hidden.assert_claims(report, c.expected)
        f = next(f for f in report.findings if f.in_model and f.cause in ("joint_coupling", "mount_compliance"))
        d = json.loads(json.dumps(f.to_dict()))
        if effect == "joint coupling":
            (n, k), = c.effects.coupling
            assert (d["cause"], d["joint"], d["source_joint"]) == ("joint_coupling", n, k), d
            assert f"mrad per rad of joint {k}" in f.evidence
        else:
            assert d["cause"] == "mount_compliance" and "joint" not in d and "source_joint" not in d, d
            assert "the base tilts" in f.evidence
        # the structure screen finds nothing left where the cause is named
        assert not [g for g in report.findings if g.structure], (robot, effect, seed)


@pytest.mark.parametrize("robot,effect", FAST)
def test_a_new_cause_is_named_exactly(robot, effect):
    check(robot, effect)


@pytest.mark.slow
@pytest.mark.parametrize("robot,effect", ALL)
def test_a_new_cause_is_named_exactly_on_every_arm(robot, effect):
    check(robot, effect)


def test_the_source_joint_is_part_of_the_claim():
    """A coupling from another joint than the truth's is a false claim and a miss, not a match."""
    from casadical.diagnosis import Finding

    class Report:
        def __init__(self, *findings):
            self.findings = [Finding(Candidate("geometric"), 1.0, ""), *findings]

    right = hidden.coupling_claim(5, 4)
    assert hidden.judge(Report(Finding(Candidate("joint_coupling", 5, source_joint=4), 0.1, "")), {right}).exact
    wrong = hidden.judge(Report(Finding(Candidate("joint_coupling", 5, source_joint=3), 0.1, "")), {right})
    assert not wrong.exact and wrong.missing == {right}


def test_the_catalogue_offers_them_where_the_data_can_test_them():
    """A coupling for every pair of joints that move, the source before the joint (the robot's only), a mount
    compliance (and each session's) where the robot has masses and the moment changes; without masses (or, for a
    coupling, on poses that move one joint at a time) said in not_tried."""
    import numpy as np

    from casadical import calibrate
    from casadical.data import sample_poses, simulate
    from casadical.diagnosis import Catalogue, DiagnosisSettings, not_tried
    from casadical.robot import robot_from_dict
    from tests.helpers.arms import ARM5

    def offered(doc, still=None, one_at_a_time=False):
        robot = robot_from_dict(doc)
        q = sample_poses(robot, 60, np.random.default_rng(0), floor_z=None)
        if still is not None:
            q[:, still - 1] = 0.3
        if one_at_a_time:       # each pose moves one joint from the first
            q = np.repeat(q[:1], 60, axis=0)
            for i in range(1, 60):
                q[i, i % robot.n] += 0.02 * i
        cal, _ = simulate(robot, q, seed=0)
        res = calibrate(robot, cal, "kinematic", "lm", warn=False)
        cat = Catalogue(robot, cal, DiagnosisSettings())
        torques = np.ones((len(cal), robot.n))
        cands = cat.candidates(res, [], set(), set(), lambda: torques)
        return cands, not_tried(robot, cal, torques, DiagnosisSettings())

    cands, _ = offered(ARM5)
    pairs = {(c.joint, c.source_joint) for c in cands if c.cause == "joint_coupling"}
    assert pairs == {(j, k) for j in range(1, 6) for k in range(1, j)}      # the source before the joint
    assert [c for c in cands if c.cause == "mount_compliance"] == [Candidate("mount_compliance")]
    assert Candidate("joint_coupling", 5, source_joint=4).to_dict() == {"cause": "joint_coupling", "joint": 5,
                                                                         "source_joint": 4}
    cands, _ = offered(ARM5, still=2)
    assert all(2 not in (c.joint, c.source_joint) for c in cands if c.cause == "joint_coupling")
    cands, why = offered(ARM5, one_at_a_time=True)       # a coupling would show at one configuration only
    assert not [c for c in cands if c.cause == "joint_coupling"]
    assert any(n.cause == "joint_coupling" and "one joint at a time" in n.why for n in why)
    massless = {**ARM5, "payload": {}, "joint": [{k: v for k, v in r.items() if k not in ("mass_kg", "com_m")}
                                                 for r in ARM5["joint"]]}
    cands, why = offered(massless)
    assert not [c for c in cands if c.cause == "mount_compliance"]
    assert any(n.cause == "mount_compliance" and "masses" in n.why for n in why)


def test_plan_poses_asks_their_questions():
    """A named coupling ambiguous with an encoder scale, and a mount compliance not significant: plan-poses's
    questions carry the coupling's source joint and the mount's parameter."""
    from casadical.planning import open_questions

    doc = {"findings": [
        {"cause": "joint_coupling", "joint": 5, "source_joint": 4, "in_model": True,
         "ambiguous_with": [{"cause": "encoder_scale", "joint": 5}]},
        {"cause": "mount_compliance", "in_model": True}],
        "final": {"parameters": [{"name": "cpl5_4", "value": 2e-3, "significant": True, "t": 40.0},
                                 {"name": "cmount", "value": 1e-8, "significant": False, "t": 1.2}]}}
    qs = open_questions(doc, {"cpl5_4": 2e-3, "cmount": 1e-8})
    amb = next(q for q in qs if q.kind == "ambiguous")
    assert "coupling j5<-j4" in amb.text and amb.interest[0] == "cpl5_4" and "escale5" in amb.interest
    weak = next(q for q in qs if q.kind == "not significant")
    assert "cmount" in weak.text
