"""Bearing compliance (a joint's axis tilting under the moment of the weights it carries across its axis), hidden
by the independent truth (tests/truth) on arms that are not built in: the diagnosis names exactly it, on its joint,
and nothing else; where the truth hides none, it is never named.

The tilt is 0.3 mrad at the largest moment across the joint's axis over the poses, about its x, on joint 3 of a
7-axis DH arm and of a 7-axis MDH arm and on joint 5 of the DH arm, three seeds each. About its y the axis is joint
2's (joint 4's), and that joint's compliance takes the tilt to first order: the diagnosis names the compliance and
says why the bearing's y is not tried.
"""

import json
import warnings

import numpy as np
import pytest

from casadical.diagnosis import DiagnosisSettings, diagnose
from casadical.diagnosis import _words as words
from casadical.terms import bearing_moments
from tests.helpers import hidden
from tests.truth import Arm, Effects, TrueRobot, sample

SEEDS = (0, 1, 2)
CASES = [("arm7-dh", 3), ("arm7", 3), ("arm7-dh", 5)]


def case(robot: str, joint: int, seed: int, share=(1.0, 0.0)) -> hidden.Case:
    arm = Arm.from_dict(hidden.robot_doc(robot))
    t = TrueRobot(arm)
    s = t.state(sample(t, 300, np.random.default_rng(0), floor_z=None))
    local = np.einsum("nki,nk->ni", s.axis_frames[:, joint - 1],
                      _moment(t, s, joint))            # the moment across the axis, in its own frame
    C = 0.3e-3 / float(np.linalg.norm(local[:, :2], axis=1).max())
    return hidden.Case(robot, "bearing compliance", seed,
                       Effects(bearing_compliance={joint: (share[0] * C, share[1] * C)}),
                       {("bearing_compliance", joint, None, "robot")})


def _moment(t: TrueRobot, s, joint: int) -> np.ndarray:
    """The moment of links joint..n and the payload about joint's origin, base frame (written from the truth's
    frames, not casadical's)."""
    arm = t.arm
    out = np.zeros((len(s.links), 3))
    for i in range(joint - 1, arm.n):
        c = s.links[:, i, :3, :3] @ arm.links[i].com + s.links[:, i, :3, 3]
        out += np.cross(c - s.origins[:, joint - 1], arm.links[i].mass * arm.gravity)
    c = s.flange[:, :3, :3] @ arm.payload_com + t.tool_point(s)
    return out + np.cross(c - s.origins[:, joint - 1], arm.payload * arm.gravity)


def run(c: hidden.Case):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        rob, cal, val, true = hidden.make_data(c)
        return diagnose(rob, cal, val, DiagnosisSettings(seed=c.seed)), rob, cal


@pytest.mark.parametrize("robot,joint", CASES, ids=[f"{r}-j{j}" for r, j in CASES])
def test_a_bearing_compliance_is_named_exactly(robot, joint):
    for seed in SEEDS:
        c = case(robot, joint, seed)
        report, rob, cal = run(c)
        hidden.assert_claims(report, c.expected)
        f = next(f for f in report.findings if f.in_model and f.candidate.kind.name == "bearing_compliance")
        d = json.loads(json.dumps(f.to_dict()))
        assert (d["cause"], d["joint"]) == ("bearing_compliance", joint), d
        assert "the axis tilts" in f.evidence and f"joint {joint}'s bearing" in words.where(f)
        assert f.candidate.direction in ("x", "y")
        # the size it names: each compliance the poses identify within three standard errors of the truth's
        named = [k for k in "xy" if f"cbear{joint}_{k}" in report.final.parameters]
        assert named
        for k in named:
            p, true = report.final.parameters[f"cbear{joint}_{k}"], c.effects.bearing_compliance[joint]["xy".index(k)]
            assert abs(p.value - true) < 3 * p.std, (seed, k, p.value, p.std, true)
        assert not [g for g in report.findings if g.structure], (robot, seed)    # nothing left to locate


def test_the_moment_across_the_axis_is_the_truths():
    """casadical's moment across a joint's axis (nominal geometry) is the independent truth's, in the axis frame:
    its z the torque the drive carries."""
    for robot, joint in CASES:
        arm = Arm.from_dict(hidden.robot_doc(robot))
        t = TrueRobot(arm)
        q = sample(t, 20, np.random.default_rng(1), floor_z=None)
        s = t.state(q)
        want = np.einsum("nki,nk->ni", s.axis_frames[:, joint - 1], _moment(t, s, joint))
        from casadical.robot import robot_from_dict
        got = bearing_moments(robot_from_dict(hidden.robot_doc(robot)), q, None, joint)
        assert np.allclose(got, want, rtol=1e-9, atol=1e-9)
        assert np.allclose(got[:, 2], s.torque[:, joint - 1], rtol=1e-9, atol=1e-9)


def test_a_tilt_about_an_earlier_joints_axis_is_that_joints_compliance():
    """Joint 3's bearing tilting about its y (joint 2's axis): joint 2's compliance is named, and the report says
    that the bearing's y was not tried because that compliance takes it."""
    c = case("arm7-dh", 3, 0, share=(0.0, 1.0))
    report, _, _ = run(c)
    hidden.assert_claims(report, {("joint_compliance", 2, None, "robot")})
    said = [n for n in report.not_tried if n["cause"] == "bearing_compliance" and 3 in n.get("joints", [])]
    assert said and "joint 2 for 3" in said[0]["why"] and "about its y" in said[0]["why"], report.not_tried


def test_never_named_where_the_truth_has_none():
    """A joint's compliance beside which a bearing could stand: the compliance is named, no bearing."""
    for seed in SEEDS:
        c = hidden.case("arm7-dh", "compliance", seed)
        report, _, _ = run(c)
        hidden.assert_claims(report, c.expected)
