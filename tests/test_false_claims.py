"""The diagnosis's misses and false claims on the independent truth's data (tests/truth), each with the step of
the search that lost the cause or named a false one.

- A drift of the measurement frame (48 um over 80 s) on the 7-axis arms: the warm-ups' ten time constants
  filled the round's fits (a warm-up scores above the drift it must be told from), so the drift was never
  fitted; fitted, it was then undone by the never-worse judge for a worst held-out error that rose 4 um inside
  the noise (0.0700 -> 0.0744 mm at sigma 0.019 mm). d0b139e names nothing (validation 0.072 mm; the true
  model 0.040).
- Several causes at once on the 7-axis arm (seed 0): a compliance of joint 2 and a backlash of joint 2 by the last
  move. Where the last move follows the joint's reading (random poses in row order) the load's sign stands for
  both: a backlash by the load was accepted (held-out random 0.111 -> 0.092 mm against the compliance's 0.095),
  and then neither the compliance (p = 0.58) nor the motion's backlash (one backlash a joint) could come in.
  d0b139e named a false torque backlash and missed the other two (validation 0.087 mm; the true model 0.035).
"""

import warnings

import pytest

import hidden
from casadical.diagnosis import DiagnosisSettings, diagnose
from casadical.diagnosis.never_worse import Held


def diagnosed(robot: str, effect: str, seed: int):
    c = hidden.case(robot, effect, seed)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        rob, cal, val, _ = hidden.make_data(c)
        return c, diagnose(rob, cal, val, DiagnosisSettings(seed=seed, session_tools=c.sessions))


@pytest.mark.parametrize("robot,seed", [("arm7", 1), ("arm7-dh", 1), ("arm7", 2)])
def test_a_drift_is_fitted_beside_the_warmups_it_must_be_told_from(robot, seed):
    c, rep = diagnosed(robot, "drift", seed)
    hidden.assert_claims(rep, c.expected, c.allowed)
    assert not any(n.startswith("never worse than a kinematic calibration") for n in rep.notes), rep.notes


def test_a_worst_held_out_error_counts_beyond_the_noise_band_only():
    ref = Held({"random": 0.035}, {"random": 0.070})
    assert Held({"random": 0.033}, {"random": 0.0744}).worse_than(ref, band=0.097) == []    # a draw of the noise
    assert Held({"random": 0.033}, {"random": 0.0744}).worse_than(ref) != []                # no band: the 5 % rule
    assert Held({"random": 0.033}, {"random": 0.120}).worse_than(ref, band=0.097) != []     # beyond it: a worst case
    assert Held({"random": 0.036}, {"random": 0.070}).worse_than(ref, band=0.097) != []     # a mean never has a band


@pytest.mark.parametrize("robot,seed", [("arm7", 0), ("arm7", 1), ("arm7-dh", 0)])
def test_a_backlash_by_the_load_does_not_stand_for_a_compliance_and_a_backlash_by_the_motion(robot, seed):
    c, rep = diagnosed(robot, "several", seed)
    hidden.assert_claims(rep, c.expected, c.allowed)
    assert [f.candidate.source for f in rep.findings if f.cause == "backlash" and f.in_model] == ["motion"]
