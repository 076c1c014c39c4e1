"""Every hidden effect on robots that are not built in, made by the independent truth, diagnosed with the full
search: the diagnosis names exactly the hidden causes (cause, joint, harmonic, scope), nothing else.

Robots (tests/helpers/hidden.py): 4 to 7 axes, MDH and DH, Hayati beta or none, a joint driven through a
parallelogram coupling. Effects: none, each cause alone, two sessions, several causes at once.
``pytest -m slow`` runs every robot, effect and seed (benchmarks/studies/study_hidden_effects.py prints the same
matrix); the default run takes one case per effect, on robots in turn. The cases in KNOWN are left out.
"""

import warnings

import pytest

from casadical.diagnosis import DiagnosisSettings, diagnose
from tests.helpers import hidden

#: cases of the matrix the diagnosis does not claim exactly today, kept out of the assertions: (robot, effect,
#: seed) -> what it names instead (benchmarks/studies/study_hidden_effects.py). None today: the last six (a drift on the
#: 7-axis arms, several causes on arm7, the bad shots on arm5-coupled) are tests/diagnosis/test_false_claims.py's
KNOWN: dict = {}

ALL = [(r, e, s) for r in hidden.ROBOTS for e in hidden.EFFECTS for s in (0, 1, 2)]
#: the default run: each effect once, the robots in turn, seeds in turn
FAST = [c for c in ((list(hidden.ROBOTS)[k % len(hidden.ROBOTS)], e, k % 3) for k, e in enumerate(hidden.EFFECTS))
        if c not in KNOWN]


def check(robot: str, effect: str, seed: int) -> None:
    c = hidden.case(robot, effect, seed)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        rob, cal, val, _ = hidden.make_data(c)
        report = diagnose(rob, cal, val, DiagnosisSettings(seed=seed, session_tools=c.sessions))
    hidden.assert_claims(report, c.expected, c.allowed)
    if effect == "torque backlash" or effect == "motion backlash":
        source = "torque" if effect == "torque backlash" else "motion"
        assert [f.candidate.source for f in report.findings if f.cause == "backlash"] == [source]
    if effect == "full pose":
        assert report.final.full_pose and report.final_orientation is not None
    if effect == "bad shots":       # set aside by the robust loss, and named by their file lines
        assert set(c.bad_lines) <= {d["line"] for d in report.final.downweighted}, (c.bad_lines,
                                                                                    report.final.downweighted)


@pytest.mark.parametrize("robot,effect,seed", FAST)
def test_hidden_effect(robot, effect, seed):
    check(robot, effect, seed)


@pytest.mark.slow
@pytest.mark.parametrize("robot,effect,seed", [c for c in ALL if c not in KNOWN and c not in FAST])
def test_hidden_effect_every_robot_and_seed(robot, effect, seed):
    check(robot, effect, seed)


def test_the_fast_set_covers_every_effect_and_robot():
    assert sorted({e for _, e, _ in FAST}) == sorted(hidden.EFFECTS)
    assert {r for r, _, _ in FAST} == set(hidden.ROBOTS)


def test_a_claim_is_exact_only_when_every_cause_joint_harmonic_and_scope_is():
    """The judge itself: a cause of the right kind on another joint, another harmonic, another scope, or one
    more cause is not exact (the per-type check it replaces passed compliance of joints 2 and 3 for joint 3);
    an ambiguity counts only where the test allows it and the report declares it."""
    from casadical.diagnosis import Candidate, Finding

    class Report:
        def __init__(self, *findings):
            self.findings = [Finding(Candidate("geometric"), 1.0, ""), *findings]

    def f(cause, joint=None, harmonic=None, session=None, ambiguous=(), in_model=True, source=None):
        return Finding(Candidate(cause, joint, harmonic, source=source, session=session), 0.1, "", in_model=in_model,
                       ambiguous_with=[{"cause": c, "joint": j, "harmonic": h} for c, j, h in ambiguous])
    c3 = ("joint_compliance", 3, None, "robot")
    assert hidden.judge(Report(f("joint_compliance", 3)), {c3}).exact
    assert not hidden.judge(Report(f("joint_compliance", 3), f("joint_compliance", 2)), {c3}).exact
    assert not hidden.judge(Report(f("joint_compliance", 2)), {c3}).exact
    assert hidden.judge(Report(f("joint_compliance", 3), f("unexplained", 2, in_model=False)), {c3}).exact
    g = ("joint_periodic", 2, 23, "robot")
    assert not hidden.judge(Report(f("joint_periodic", 2, 22)), {g}).exact
    assert not hidden.judge(Report(f("drift")), {("drift", None, None, "robot")}).exact   # a drift is the session's
    assert not hidden.judge(Report(f("joint_compliance", 3, session="B")), {c3}).exact
    assert not hidden.judge(Report(f("drift", session="A")), {("drift", None, None, "session B")}).exact
    assert hidden.judge(Report(f("drift", session="B")), {("drift", None, None, "session B")}).exact
    e = ("encoder_scale", 3, None, "robot")
    declared = Report(f("encoder_scale", 3, ambiguous=[("joint_compliance", 3, None)]))
    assert not hidden.judge(declared, {c3}).exact                        # not allowed by the test
    assert hidden.judge(declared, {c3}, {c3: {e}}).exact
    assert not hidden.judge(Report(f("encoder_scale", 3)), {c3}, {c3: {e}}).exact   # not declared
    m2 = ("backlash_motion", 2, None, "robot")       # a backlash by the load is not one by the last move
    assert hidden.judge(Report(f("backlash", 2, source="motion")), {m2}).exact
    assert not hidden.judge(Report(f("backlash", 2, source="torque")), {m2}).exact
