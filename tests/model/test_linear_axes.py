"""Linear (prismatic) axes: casadical's chain and gravity loads against the independent truth (tests/truth), on a
four-axis arm on a track (MDH, joint 1) and an arm on a lifting column (DH, joint 2)."""

import math
import warnings

import numpy as np
import pytest

from casadical.errors import ModelError
from casadical.model.kinematics import base_pose_matrix
from casadical.model.symbolic import Model, pose_to_base0
from casadical.robot import robot_from_dict
from tests.helpers.arms import ARM4_TRACK, ARM_COLUMN
from tests.truth import Arm, Effects, Session, TrueRobot, measure, sample

LINEAR = {"track (MDH, joint 1)": ARM4_TRACK, "column (DH, joint 2)": ARM_COLUMN}


def robot(doc):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return robot_from_dict(doc)


def geometry_values(model: Model, true: TrueRobot) -> np.ndarray:
    P, g = model.parameters, true.geometry
    v = P.nominal.copy()
    for i in range(true.arm.n):
        for k in ("alpha", "a", "beta", "b", "d", "theta"):
            if f"{k}{i + 1}" in P:
                v[P.index(f"{k}{i + 1}")] = getattr(g, k)[i]
    for k, x in zip("xyz", g.tool):
        v[P.index(f"tool_{k}")] = x
    return v


@pytest.mark.parametrize("arm", sorted(LINEAR))
def test_chain_with_a_linear_axis_is_the_truths(arm):
    """The reading of a prismatic joint slides its link along z (added to d), theta a constant: casadical's
    point is the truth's at drawn geometry errors, over the axis' whole travel; reading it as a revolute
    joint misses by metres."""
    doc = LINEAR[arm]
    rng = np.random.default_rng(3)
    true = TrueRobot.draw(Arm.from_dict(doc), Effects(), rng)
    q = sample(true, 40, rng)
    session = Session(base_xyz=(1.5, -0.5, 0.3), base_rpy=(0.1, -0.2, 0.7))
    shots = measure(true, q, rng, session=session, noise=0.0)
    model = Model(robot(doc), "kinematic")
    b0 = pose_to_base0(base_pose_matrix(session.base_xyz, session.base_rpy))
    v = geometry_values(model, true)
    xyz = model.predict(q, v, model.default_covariates(len(q)), b0)
    assert np.abs(xyz - shots.xyz).max() < 1e-12
    revolute = dict(doc, joint=[{k: v for k, v in j.items() if k not in ("type", "min_mm", "max_mm")}
                                for j in doc["joint"]])
    other = Model(robot(revolute), "kinematic")
    wrong = other.predict(q, v, other.default_covariates(len(q)), b0)
    assert np.abs(wrong - shots.xyz).max() > 0.1


@pytest.mark.parametrize("arm", sorted(LINEAR))
def test_gravity_load_of_a_linear_axis_is_the_force_along_it(arm):
    doc = LINEAR[arm]
    rng = np.random.default_rng(4)
    true = TrueRobot(Arm.from_dict(doc))
    q = sample(true, 20, rng)
    model = Model(robot(doc), "kinematic")
    payload = np.full(len(q), doc["payload"]["mass_kg"])
    tau = model.torques(q, cov=payload[:, None])
    np.testing.assert_allclose(tau, true.state(q, payload).torque, atol=1e-9)


def test_joint_errors_of_a_revolute_joint_refused_on_a_linear_axis():
    r = robot(ARM4_TRACK)
    m = Model(r, "kinematic+joint_compliance+encoder_scale")
    assert m.term("joint_compliance").joints == [2, 3, 4, 5]       # by default the revolute joints only
    for spec in ("joint_compliance[1]", "joint_periodic[1:2]", "encoder_scale[1,2]", "backlash[1]",
                 "joint_coupling[2:1]"):
        with pytest.raises(ModelError, match=r"joint 1 of .* is prismatic \(a linear axis\)") as e:
            Model(r, "kinematic+" + spec)
        assert "\n" not in str(e.value)
    assert math.isfinite(float(m.predict(np.zeros((1, 5)))[0, 0]))
