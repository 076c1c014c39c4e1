"""What differs between sessions (issue 49), hidden by the independent truth on arms that are not built in and
diagnosed with the full search: an arm on a lifting column at four heights (the mount's give growing with the
session column ``height_m``, beside joint 2's compliance) names the mount compliance and its law and joint 2's
compliance, the robot's, nothing else (no joint property of one session); an arm on a floor that tilts from pose
to pose, read by a tilt sensor, names nothing and locates the structure on the sensor's two columns, never on a
column that follows nothing.

The default run takes each case once; ``pytest -m slow`` runs every arm and seed
(benchmarks/studies/study_session_effects.py prints the same matrix with the per-session kinematic baseline).
"""

import warnings

import numpy as np
import pytest

from casadical import calibrate
from casadical.calibration import TOLERANCE_DEG, check_gravity
from casadical.diagnosis import DiagnosisSettings, diagnose
from casadical.errors import GravityWarning
from casadical.robot import robot_from_dict
from tests.helpers import hidden

ALL = [(r, e, s) for e in hidden.SESSION_EFFECTS for r in hidden.SESSION_ROBOTS for s in (0, 1, 2)]
FAST = [("arm6", "column", 0), ("arm7", "floor", 1)]


def check(robot: str, effect: str, seed: int) -> None:
    c = hidden.session_case(robot, effect, seed)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        rob, cal, val, _ = hidden.make_data(c, n_cal=60, n_val=60)
        report = diagnose(rob, cal, val, DiagnosisSettings(seed=seed))
    hidden.assert_claims(report, c.expected, c.allowed)
    screened = [f.to_dict() for f in report.findings if f.structure]
    located = {(d.get("joint"), d["covariate"], d["effect"]) for d in screened}
    assert set(c.located) <= located, located
    assert not any(d["covariate"] == "acc_spare_x" for d in screened), screened
    for f in report.findings:       # a joint's own parameter is the robot's
        assert not (f.in_model and f.candidate.session is not None and f.candidate.kind.session_part is None), f
    if effect == "floor":
        words = [f.where for f in report.findings if f.structure]
        assert any("base tilts with tilt_x_rad" in w for w in words), words


@pytest.mark.parametrize("robot,effect,seed", FAST)
def test_what_differs_between_sessions(robot, effect, seed):
    check(robot, effect, seed)


@pytest.mark.slow
@pytest.mark.parametrize("robot,effect,seed", [c for c in ALL if c not in FAST])
def test_what_differs_between_sessions_every_arm_and_seed(robot, effect, seed):
    check(robot, effect, seed)


def test_the_fast_set_covers_every_effect():
    assert {e for _, e, _ in FAST} == set(hidden.SESSION_EFFECTS)


def _turned(doc: dict, direction) -> dict:
    return {**doc, "gravity": {"direction": list(direction)}}


def test_a_robot_file_whose_gravity_is_not_the_levelled_instruments_down_is_a_warning():
    """The column case's arm stands upright (gravity down its base's z, the tracker levelled): described with its
    gravity along its base's x (another mounting), the fitted base poses of its four sessions put the instrument's
    down 90 deg from it, along the base's -z: a warning naming that direction; the right file gets none, nor does
    one whose sessions are not said to be levelled and cannot tell (one session)."""
    c = hidden.session_case("arm6", "column", 1)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        right, cal, _, _ = hidden.make_data(c, n_cal=40, n_val=5)
    doc = hidden.robot_doc("arm6")
    wrong = robot_from_dict(_turned(doc, (1.0, 0.0, 0.0)))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        good = calibrate(right, cal, "kinematic", "lm", warn=False)
        bad = calibrate(wrong, cal, "kinematic", "lm", warn=False)
    ok = check_gravity(good)
    assert ok is not None and ok.levelled == "inferred" and not ok.warns and ok.off_deg < 1.0, ok
    off = check_gravity(bad)
    assert off.warns and abs(off.off_deg - 90.0) < 2.0 and off.off_deg > TOLERANCE_DEG
    assert np.allclose(off.down, [0.0, 0.0, -1.0], atol=0.02), off.down
    assert "direction = [0, 0, -1]" in off.text(), off.text()
    assert check_gravity(bad, levelled=False) is None
    one = cal.subset(cal.sessions == cal.session_names[0])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        single = calibrate(wrong, one, "kinematic", "lm", warn=False)
    assert check_gravity(single) is None                 # one session: nothing says the instrument is levelled
    assert check_gravity(single, levelled=True).warns    # unless the user does
    with pytest.warns(GravityWarning, match="give \\[gravity\\] direction"):
        from casadical.calibration import warn_gravity
        warn_gravity(single, levelled=True)


def test_the_screen_tilts_the_base_about_the_axes_across_gravity():
    """The structure screen's base tilt and moment are about the two axes across the robot file's gravity: the
    base's x and y where gravity is along its z (as before), two horizontal axes for an arm on a wall (gravity along
    its base's x), never about gravity's own line (the moment of vertical weights has no part along it)."""
    from casadical.diagnosis import across_gravity

    doc = hidden.robot_doc("arm6")
    assert np.array_equal(across_gravity(robot_from_dict(doc)), np.eye(3)[:2])
    for g in ((1.0, 0.0, 0.0), (0.0, 0.0, 1.0), (0.3, -0.2, -0.9)):
        axes = across_gravity(robot_from_dict(_turned(doc, g)))
        assert np.allclose(axes @ axes.T, np.eye(2)) and np.allclose(axes @ np.asarray(g), 0.0), (g, axes)
