"""The errors of a linear axis (ISO 230-1), hidden by the independent truth on arms on a track and on a lifting
column (MDH and DH), diagnosed with the full search: each is named where it is (cause, axis, and a straightness'
direction or a carriage's angle), and nothing else, no arm cause for it and no other error of the axis.

Effects (tests/helpers/hidden.py :func:`~tests.helpers.hidden.linear_case`): the axis' scale per metre, a periodic
error per metre (a screw's or a rack's pitch), play by the direction of motion, straightness across the axis in
x and y, the carriage's roll, pitch and yaw, the mount's give under the arm's moment, a straightness, the scale
and an arm joint's compliance at once, and a straightness that is only a slope (the geometry's: nothing named).
The default run takes one case per effect, the robots and seeds in turn; ``pytest -m slow`` runs every robot,
effect and seed (benchmarks/studies/study_linear_axes.py prints the same matrix).
"""

import math
import warnings

import numpy as np
import pytest

from casadical.diagnosis import DiagnosisSettings, describe_pair, diagnose, not_tried
from tests.helpers import hidden
from tests.truth import Arm, Effects

ALL = [(r, e, s) for r in hidden.LINEAR_ROBOTS for e in hidden.LINEAR_EFFECTS for s in (0, 1, 2)]
#: the default run: each effect once, the robots in turn, seeds in turn
FAST = [(list(hidden.LINEAR_ROBOTS)[k % len(hidden.LINEAR_ROBOTS)], e, k % 3)
        for k, e in enumerate(hidden.LINEAR_EFFECTS)]


def diagnosed(c: hidden.Case):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        rob, cal, val, _ = hidden.make_data(c)
        return rob, cal, diagnose(rob, cal, val, DiagnosisSettings(seed=c.seed))


def check(robot: str, effect: str, seed: int) -> None:
    c = hidden.linear_case(robot, effect, seed)
    rob, _, report = diagnosed(c)
    hidden.assert_claims(report, c.expected, c.allowed)
    axis = hidden.linear_axis(Arm.from_dict(hidden.robot_doc(robot)))
    for f in report.findings:       # an error of the axis in its units: mm, mm per m, mrad; never arcsec
        if f.in_model and f.candidate.joint == axis:
            assert "arcsec" not in f.evidence and " rad" not in f.evidence, f.evidence
            assert "mm" in f.evidence or "mrad" in f.evidence, f.evidence


@pytest.mark.parametrize("robot,effect,seed", FAST)
def test_linear_axis_effect(robot, effect, seed):
    check(robot, effect, seed)


@pytest.mark.slow
@pytest.mark.parametrize("robot,effect,seed", [c for c in ALL if c not in FAST])
def test_linear_axis_effect_every_robot_and_seed(robot, effect, seed):
    check(robot, effect, seed)


def test_the_fast_set_covers_every_effect_and_robot():
    assert sorted({e for _, e, _ in FAST}) == sorted(hidden.LINEAR_EFFECTS)
    assert {r for r, _, _ in FAST} == set(hidden.LINEAR_ROBOTS)
    assert {s for _, _, s in FAST} == {0, 1, 2}


def test_a_claim_names_the_direction_and_the_angle():
    """The judge: a straightness in the other direction, or another angle of the carriage, is not exact."""
    from casadical.diagnosis import Candidate, Finding

    class Report:
        def __init__(self, *cands):
            self.findings = [Finding(c, 0.1, "") for c in cands]
    sx = ("straightness x", 1, None, "robot")
    assert hidden.judge(Report(Candidate("straightness", 1, direction="x")), {sx}).exact
    assert not hidden.judge(Report(Candidate("straightness", 1, direction="y")), {sx}).exact
    assert not hidden.judge(Report(Candidate("straightness", 2, direction="x")), {sx}).exact
    pitch = ("carriage_angle pitch", 2, None, "robot")
    assert hidden.judge(Report(Candidate("carriage_angle", 2, angle="pitch")), {pitch}).exact
    assert not hidden.judge(Report(Candidate("carriage_angle", 2, angle="yaw")), {pitch}).exact
    assert Candidate("straightness", 1, direction="x").to_dict() == {"cause": "straightness", "joint": 1,
                                                                     "direction": "x"}
    assert Candidate("carriage_angle", 2, angle="roll").to_dict() == {"cause": "carriage_angle", "joint": 2,
                                                                      "angle": "roll"}


def test_a_position_error_outside_the_catalogue_is_located_along_the_axis_in_mm():
    """An error of the track's position that bows over its travel (quadratic in the position: no catalogue cause;
    the scale takes its slope) is named as nothing and located: axis 1's position error along it, varying with
    its own position, its flexible term an offset in metres (a cause of one's own: docs/guide.md)."""
    arm = Arm.from_dict(hidden.robot_doc("track"))
    c = hidden.Case("track", "position bow", 0, Effects(reading_error={1: hidden.smooth(arm, 1, bow=0.1e-3)}), set())
    _, _, report = diagnosed(c)
    hidden.assert_claims(report, set())
    found = [f for f in report.findings if f.cause == "unexplained" and f.structure]
    assert [(f.candidate.joint, f.structure["covariate"], f.structure["effect"]) for f in found][:1] == [
        (1, "q1", "position")]
    assert "axis 1's position error (along it, mm)" in found[0].where
    term = found[0].structure["term"]
    assert term["joint"] == 1 and "offset" in term and "angle" not in term
    assert {p["unit"] for p in term["parameters"].values()} == {"m"}
    # a revolute joint's words are unchanged
    assert describe_pair("q2", "angle", 2) == "joint 2's angle error varies with its own reading (not as any " \
                                              "catalogue cause of that joint)"


def test_what_the_catalogue_cannot_try_on_a_linear_axis():
    """The axis' own errors are tried; a revolute joint's (compliance, coupling) are said not to be; a periodic
    error is screened from two cycles over the travel the data cover (one cycle over a 1 m column is a bow)."""
    from casadical.diagnosis import DiagnosisSettings as S
    c = hidden.linear_case("column", "none", 0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        rob, cal, _, _ = hidden.make_data(c)
    items = {(n.cause, tuple(n.joints)): n for n in not_tried(rob, cal, np.ones((len(cal), rob.n)), S())}
    revolute = [cause.split(", ") for cause, joints in items if joints == (2,) and "joint_compliance" in cause]
    assert len(revolute) == 1 and {"joint_compliance", "nonlinear_stiffness", "joint_coupling",
                                   "bearing_compliance"} == set(revolute[0])
    assert not any("encoder_scale" in cause or "straightness" in cause for cause, _ in items)
    low = items[("joint_periodic (low harmonics of a linear axis)", (2,))]
    travel = float(np.ptp(cal.q[:, 1]))
    assert f"below {math.ceil(2 / travel)} cycles per metre" in low.why


def test_every_error_of_a_column_at_once_in_words_json_and_html():
    """The column's scale, pitch error, straightness and carriage pitch beside an arm joint's compliance, 300
    poses: each named where it is, in mm, mm per m and mrad; the JSON carries a straightness' direction and a
    carriage's angle; the HTML report (figures of the axis against its position, the periodic halves in mm) is
    made (it failed on the halves of a periodic error in mm)."""
    from casadical.html import diagnosis_html

    arm = Arm.from_dict(hidden.robot_doc("column"))
    c = hidden.linear_case("column", "axis and arm", 0)
    c.effects.periodic = [(2, 4, 0.05e-3, 0.7)]
    c.effects.carriage_angle = {(2, "pitch"): hidden.smooth(arm, 2, slope=0.1e-3, bow=0.08e-3)}
    expected = c.expected | {("joint_periodic", 2, 4, "robot"), ("carriage_angle pitch", 2, None, "robot")}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        rob, cal, val, _ = hidden.make_data(c, n_cal=300)
        report = diagnose(rob, cal, val, DiagnosisSettings(seed=0))
    hidden.assert_claims(report, expected)
    words = report.text()
    assert "mm per m" in words and "cycles/m" in words and "mrad over the travel" in words
    found = [f.candidate.to_dict() for f in report.findings]
    assert {"cause": "straightness", "joint": 2, "direction": "y"} in found
    assert {"cause": "carriage_angle", "joint": 2, "angle": "pitch"} in found
    page = diagnosis_html(report, poses=cal)
    assert "axis 2 position (mm)" in page and "cycles per metre" in page
