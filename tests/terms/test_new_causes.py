"""The two error terms outside the diagnosis catalogue, on data of the independent truth (tests/truth).

``joint_coupling[j:k]`` (joint j's drive off by ``c q_k``) and ``mount_compliance`` (the base tilts by ``C M``,
``M`` the weights' moment about the mount): the truth hides each effect on arms that are not built in (MDH
and DH), three seeds each; a calibration with the term finds the true value within a few standard errors
and reaches the noise on held-out poses, which the kinematic model alone does not; on data without the
effect the term's parameter breaks a rule of casadical.stats._physics (not significant, or at its bound): no cause.
"""

import math

import numpy as np
import pytest

from casadical import calibrate
from casadical.errors import ModelError
from casadical.model import Model, parse_spec
from casadical.robot import robot_from_dict
from casadical.stats import violations
from tests.helpers.arms import ARM4, ARM5
from tests.helpers.hidden import CATALOGUED, OUTSIDE, Case, case, make_data, noise_free
from tests.truth import Arm, Effects, TrueRobot, sample

ARMS = {"arm4": ARM4, "arm5": ARM5}       # MDH without beta, DH with beta on joint 3
#: joint j's error from joint k's reading: the last joint from the one before it (a wrist's coupling), and on
#: the five-axis arm joint 3 (a long lever) from joint 2
PAIRS = {"arm4": (4, 3), "arm5": (3, 2)}
#: the coupling: 1 mrad of joint j per rad of joint k
COUPLING = 1e-3
#: the mount tilts 0.3 mrad at the largest moment of the sampled poses (what the geometry cannot take up of it
#: is 0.08-0.1 mm)
TILT = 0.3e-3


def largest_moment(doc) -> float:
    t = TrueRobot(Arm.from_dict(doc))
    q = sample(t, 300, np.random.default_rng(0), floor_z=None)
    return float(np.linalg.norm(t.state(q).moment[:, :2], axis=1).max())


def fit(arm, seed, effects, spec):
    case = Case(arm, "new cause", seed, effects, set())
    robot, cal, val, true = make_data(case, n_cal=80, n_val=150)
    res = calibrate(robot, cal, spec, "lm", warn=False)
    exact = noise_free(case, true, val)
    model_error = 1e3 * np.linalg.norm(res.predict(val) - exact, axis=1).mean()     # mm
    return res, cal, val, model_error


@pytest.mark.parametrize("seed", [1, 2, 3])
@pytest.mark.parametrize("arm", ["arm4", "arm5"])
def test_joint_coupling_is_found_where_hidden_and_not_elsewhere(arm, seed):
    j, k = PAIRS[arm]
    spec, name = f"kinematic+joint_coupling[{j}:{k}]", f"cpl{j}_{k}"
    res, cal, val, model_error = fit(arm, seed, Effects(coupling={(j, k): COUPLING}), spec)
    p = res.parameters[name]
    assert abs(p.value - COUPLING) < 4 * p.std and p.std < 0.2 * COUPLING, (p.value, p.std)
    # the model's mean distance from the truth's noise-free points: what 80 poses with 0.02 mm of noise per axis
    # leave (8-14 um here); the kinematic model alone misses by 130-530 um
    assert model_error < 0.02, model_error
    assert res.stats(val).mean_mm < 0.045                 # held-out poses at the noise (0.032 mm mean)
    assert violations(res, cal, [name]) == []
    _, _, _, plain_error = fit(arm, seed, Effects(coupling={(j, k): COUPLING}), "kinematic")
    assert plain_error > 3 * model_error
    none, cal0, _, _ = fit(arm, seed, Effects(), spec)
    assert [v.rule for v in violations(none, cal0, [name])] == ["significance"]


@pytest.mark.parametrize("seed", [1, 2, 3])
@pytest.mark.parametrize("arm", ["arm4", "arm5"])
def test_mount_compliance_is_found_where_hidden_and_not_elsewhere(arm, seed):
    C = TILT / largest_moment(ARMS[arm])
    res, cal, val, model_error = fit(arm, seed, Effects(mount_compliance=C), "kinematic+mount_compliance")
    p = res.parameters["cmount"]
    assert abs(p.value - C) < 4 * p.std and p.std < 0.2 * C, (p.value / C, p.std / C)
    assert model_error < 0.02, model_error                # 8-14 um; the kinematic model alone 80-100 um
    assert res.stats(val).mean_mm < 0.045
    assert violations(res, cal, ["cmount"]) == []
    _, _, _, plain_error = fit(arm, seed, Effects(mount_compliance=C), "kinematic")
    assert plain_error > 3 * model_error
    none, cal0, _, _ = fit(arm, seed, Effects(), "kinematic+mount_compliance")
    assert {v.rule for v in violations(none, cal0, ["cmount"])} & {"significance", "bounds"}


def test_specifications_parameters_and_errors():
    robot = robot_from_dict(ARM5)
    m = Model(robot, "kinematic+joint_coupling[5:4,3:2]+mount_compliance[xy]", jit=False)
    assert m.spec == "kinematic+joint_coupling[3:2,5:4]+mount_compliance[xy]"
    P = m.parameters
    assert [P[n].unit for n in ("cpl3_2", "cpl5_4")] == ["rad/rad"] * 2
    assert (P["cpl5_4"].lower, P["cpl5_4"].upper, P["cpl5_4"].joint) == (-0.01, 0.01, 5)
    for n in ("cmount_x", "cmount_y"):
        assert P[n].unit == "rad/(N*m)" and P[n].lower == 0.0 and 0 < P[n].upper < 1e-4
    assert [p.name for p in Model(robot, "kinematic+mount_compliance", jit=False).parameters if
            p.term == "mount_compliance"] == ["cmount"]
    assert Model(robot, "kinematic+mount_compliance@B", jit=False).parameters["cmount@B"].lower == 0.0
    for bad, says in (("joint_coupling[5:5]", "encoder scale"), ("joint_coupling[5]", "joint:source"),
                      ("joint_coupling[5:9]", "source joints [9]"), ("mount_compliance[1z]", "[xy]"),
                      ("mount_compliance[height_m:3]", "degree")):
        with pytest.raises(ModelError, match=says.replace("[", r"\[").replace("]", r"\]")):
            Model(robot, f"kinematic+{bad}", jit=False)
    massless = {**ARM5, "payload": {}, "joint": [{k: v for k, v in r.items() if k not in ("mass_kg", "com_m")}
                                                 for r in ARM5["joint"]]}
    with pytest.raises(ModelError, match="no masses"):
        Model(robot_from_dict(massless), "kinematic+mount_compliance", jit=False)
    # both are the diagnosis catalogue's (tests/diagnosis/test_new_causes_named.py)
    from casadical.diagnosis import Candidate, compose_terms
    model = Model(robot, compose_terms([Candidate("joint_coupling", 5, source_joint=4), Candidate("mount_compliance"),
                                        Candidate("mount_compliance", session="B")]), jit=False)
    assert model.spec == "kinematic+joint_coupling[5:4]+mount_compliance+mount_compliance@B"
    assert [t.spec() for t in parse_spec("joint_coupling[6:5]+mount_compliance")] == ["joint_coupling[6:5]",
                                                                                      "mount_compliance"]


def test_a_calibration_file_keeps_them(tmp_path):
    from casadical import load_calibration
    C = TILT / largest_moment(ARM4)
    case = Case("arm4", "new cause", 4, Effects(mount_compliance=C, coupling={(4, 3): COUPLING}), set())
    robot, cal, val, _ = make_data(case, n_cal=80, n_val=40)
    res = calibrate(robot, cal, "kinematic+joint_coupling[4:3]+mount_compliance", "lm", warn=False)
    res.save(tmp_path / "cal.json")
    back = load_calibration(tmp_path / "cal.json")
    assert back.model.spec == res.model.spec
    assert np.abs(back.predict(val) - res.predict(val)).max() < 1e-12
    assert math.isclose(back.parameters["cmount"].value, res.parameters["cmount"].value)


def test_each_session_its_own_mount(tmp_path):
    """Two sessions on mounts of different compliance (a column of another height): a term per session finds
    each, the robot's geometry shared."""
    from casadical.data import Measurements
    from tests.helpers.hidden import session_of
    from tests.truth import measure

    C = TILT / largest_moment(ARM4)
    rng = np.random.default_rng(7)
    true = TrueRobot.draw(Arm.from_dict(ARM4), Effects(mount_compliance=C), rng)
    case = Case("arm4", "mounts", 7, true.effects, set(), sessions=True)
    files = []
    for name, n in (("cal", 100), ("val", 100)):
        shots = None
        for s, c in (("A", C), ("B", 3 * C)):
            ses = session_of(case, s)
            ses.mount_compliance = c
            more = measure(true, sample(true, n, rng), rng, session=ses)
            shots = more if shots is None else shots + more
        files.append(Measurements.read_csv(shots.write_csv(tmp_path / f"{name}.csv"), n_joints=4,
                                           require_positions=True))
    cal, val = files
    robot = robot_from_dict(ARM4)
    res = calibrate(robot, cal, "kinematic+mount_compliance@A+mount_compliance@B", "lm", warn=False,
                    session_tools=True)                # the probe was re-mounted for B (hidden.session_of)
    for name, c in (("cmount@A", C), ("cmount@B", 3 * C)):
        p = res.parameters[name]
        assert abs(p.value - c) < 4 * p.std and p.std < 0.1 * C, (name, p.value / c, p.std / c)
    assert res.stats(val).mean_mm < 0.045
    one = calibrate(robot, cal, "kinematic+mount_compliance", "lm", warn=False, session_tools=True)
    assert one.stats(val).mean_mm > 3 * res.stats(val).mean_mm       # one mount for both cannot be either


def test_a_calibration_taken_further_joins_the_couplings():
    from casadical.calibration import merge_terms

    out, named = merge_terms(parse_spec("kinematic+joint_coupling[4:3]"), parse_spec("joint_coupling[3:2]"))
    assert [t.spec() for t in out][1:] == ["joint_coupling[3:2,4:3]"] and named == {"joint_coupling"}


def test_a_mount_at_its_bound_says_what_that_means():
    from casadical.parameters import Parameter
    from casadical.stats import inside_bounds

    p = {"cmount": Parameter("cmount", 0.0, "rad/(N*m)", 1e-8, "mount_compliance", lower=0.0, upper=1e-5,
                             value=-1e-9),
         "cpl5_4": Parameter("cpl5_4", 0.0, "rad/rad", 1e-4, "joint_coupling", 5, lower=-0.01, upper=0.01,
                             value=0.01)}
    text = [v.text for v in inside_bounds(p, ["cmount", "cpl5_4"])]
    assert "away from its weights" in text[0] and "coupling ratio" in text[1]


@pytest.mark.parametrize("effect", OUTSIDE)
@pytest.mark.parametrize("arm", ["arm4", "arm5"])
def test_effects_outside_the_catalogue_leave_what_the_geometry_cannot_take(arm, effect):
    """The hidden-effect cases outside the catalogue (tests/helpers/hidden.py OUTSIDE; the joint coupling and the
    mount compliance are the catalogue's now) are big enough to be found: a kinematic calibration misses the truth
    by more than twice what a complete model does (10-14 um)."""
    c = case(arm, effect, 0)
    if effect in CATALOGUED:        # the diagnosis screens these now: it must name them
        assert c.expected and c.unexplained is None
    else:
        assert c.expected == set() and c.unexplained is not None
    robot, cal, val, true = make_data(c, n_cal=80, n_val=150)
    res = calibrate(robot, cal, "kinematic", "lm", warn=False)
    miss = 1e3 * np.linalg.norm(res.predict(val) - noise_free(c, true, val), axis=1).mean()
    assert miss > 0.03, miss
