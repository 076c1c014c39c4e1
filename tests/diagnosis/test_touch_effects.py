"""The hidden-effect matrix on touch data: a ball on the flange held in the two sockets of a block (50 mm
apart) at several placements of the block, made by the independent truth (tests/truth/touch.py: the readings
are what the encoders say when the true robot, with every drive effect, puts the ball in the socket). The
diagnosis must name exactly the hidden cause (cause, joint, harmonic), nothing else, judging on placements it
never fitted (their sockets fitted to their own rows).

Robots that are not built in: a 7-axis DH arm (beta on 4) and a 6-axis MDH arm (beta on 3), both with masses.
``pytest -m slow`` runs every robot, effect and seed; the default run each effect once, robots and seeds in turn
(benchmarks/studies/study_touch_effects.py prints the matrix).
"""

import warnings

import pytest

from casadical.diagnosis import DiagnosisSettings, diagnose
from tests.helpers import hidden

ROBOTS = ("arm7-dh", "arm6-mdh")
EFFECTS = ("none", "compliance", "gear error", "encoder scale")
ALL = [(r, e, s) for r in ROBOTS for e in EFFECTS for s in (0, 1, 2)]
FAST = [(ROBOTS[k % 2], e, k % 3) for k, e in enumerate(EFFECTS)]


def check(robot: str, effect: str, seed: int):
    c = hidden.case(robot, effect, seed)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        rob, cal, val, _ = hidden.make_touch_data(c)
        report = diagnose(rob, cal, val, DiagnosisSettings(seed=seed))
    hidden.assert_claims(report, c.expected, c.allowed)
    # judged as touches: the held-out placements' rows from their own sockets, the fixture's 50 mm kept
    v = report.final_validation
    assert set(v.touch) == {"consistency_mm", "distance_error_mm"}
    assert v.touch["consistency_mm"] < 0.06 and v.touch["distance_error_mm"] < 0.03, v.touch
    return report


@pytest.mark.parametrize("robot,effect,seed", FAST)
def test_touch_hidden_effect(robot, effect, seed):
    check(robot, effect, seed)


@pytest.mark.slow
@pytest.mark.parametrize("robot,effect,seed", [c for c in ALL if c not in FAST])
def test_touch_hidden_effect_every_robot_and_seed(robot, effect, seed):
    check(robot, effect, seed)
