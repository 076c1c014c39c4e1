"""Linear (prismatic) axes: casadical's chain and gravity loads against the independent truth (tests/truth), on a
four-axis arm on a track (MDH, joint 1) and an arm on a lifting column (DH, joint 2)."""

import math
import warnings

import numpy as np
import pytest

from casadical.errors import ModelError
from casadical.kinematics import base_pose_matrix
from casadical.model import Model, pose_to_base0
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
    assert m.term("encoder_scale").joints == [1, 2, 3, 4, 5]       # a linear axis' scale (per metre) too
    for spec in ("joint_compliance[1]", "nonlinear_stiffness[1]", "joint_coupling[2:1]", "joint_coupling[1:2]"):
        with pytest.raises(ModelError, match=r"joint 1 of .* is prismatic \(a linear axis\)") as e:
            Model(r, "kinematic+" + spec)
        assert "\n" not in str(e.value)
    for spec in ("straightness[2]", "carriage_angle[3:roll]"):     # a linear axis' own errors on a revolute joint
        with pytest.raises(ModelError, match=r"joint [23] of .* is revolute") as e:
            Model(r, "kinematic+" + spec)
        assert "\n" not in str(e.value)
    with pytest.raises(ModelError, match="direction 'z'"):
        Model(r, "kinematic+straightness[1:z]")
    assert math.isfinite(float(m.predict(np.zeros((1, 5)))[0, 0]))


def bow(arm: Arm, j: int, c1: float, c2: float, c3: float):
    """A smooth function of linear axis ``j``'s position (m): c1 u + c2 (3u^2 - 1)/2 + c3 (5u^3 - 3u)/2, u the
    position scaled by the axis' limits to [-1, 1] (written here, not taken from casadical)."""
    lo, hi = arm.limits[j - 1]

    def f(p):
        u = 2 * (np.asarray(p) - lo) / (hi - lo) - 1
        return c1 * u + c2 * (3 * u ** 2 - 1) / 2 + c3 * (5 * u ** 3 - 3 * u) / 2
    return f


def axis_effects(arm: Arm, j: int) -> tuple[Effects, str, dict]:
    """Every error of linear axis ``j`` at once: the truth's effects, casadical's terms and their values."""
    eff = Effects(encoder_scale={j: 2e-4}, periodic=[(j, 5, 0.05e-3, 0.7)], backlash_motion={j: 0.04e-3},
                  straightness={(j, "x"): bow(arm, j, 0.0, 0.1e-3, -0.05e-3), (j, "y"): bow(arm, j, 0.0, -0.08e-3,
                                                                                             0.06e-3)},
                  carriage_angle={(j, "roll"): bow(arm, j, 0.1e-3, 0.05e-3, 0.0),
                                  (j, "pitch"): bow(arm, j, -0.08e-3, 0.1e-3, 0.0),
                                  (j, "yaw"): bow(arm, j, 0.06e-3, -0.07e-3, 0.0)})
    spec = f"encoder_scale[{j}]+joint_periodic[{j}:5]+backlash_motion[{j}]+straightness[{j}]+carriage_angle[{j}]"
    values = {f"escale{j}": 2e-4, f"gear{j}_s5": 0.05e-3 * math.cos(0.7), f"gear{j}_c5": 0.05e-3 * math.sin(0.7),
              f"backlash_m{j}": 0.04e-3, f"straight{j}x_p2": 0.1e-3, f"straight{j}x_p3": -0.05e-3,
              f"straight{j}y_p2": -0.08e-3, f"straight{j}y_p3": 0.06e-3, f"roll{j}_p1": 0.1e-3, f"roll{j}_p2": 0.05e-3,
              f"pitch{j}_p1": -0.08e-3, f"pitch{j}_p2": 0.1e-3, f"yaw{j}_p1": 0.06e-3, f"yaw{j}_p2": -0.07e-3}
    return eff, spec, values


@pytest.mark.parametrize("arm", sorted(LINEAR))
def test_a_linear_axis_errors_are_the_truths(arm):
    """Scale (per metre), a periodic error (cycles per metre), play by the motion, straightness across the axis
    and the carriage's roll, pitch and yaw (ISO 230-1): casadical's point is the truth's within 2e-3 of the
    effect (second-order differences: the truth's carriage errors follow its true position, the reading plus
    the scale and pitch errors, casadical's the reading; the small rotations in another order), the superset's
    too; the terms turned the other way miss by more than the effect."""
    doc = LINEAR[arm]
    j = next(i for i, row in enumerate(doc["joint"], start=1) if row.get("type") == "prismatic")
    rng = np.random.default_rng(5)
    a = Arm.from_dict(doc)
    eff, spec, vals = axis_effects(a, j)
    true = TrueRobot.draw(a, eff, rng)
    q = sample(true, 60, rng)
    session = Session(base_xyz=(1.5, -0.5, 0.3), base_rpy=(0.1, -0.2, 0.7))
    shots = measure(true, q, rng, session=session, noise=0.0)
    rigid = measure(true.with_effects(Effects()), q, rng, session=session, noise=0.0)
    size = np.linalg.norm(shots.xyz - rigid.xyz, axis=1).max()
    assert size > 0.2e-3, size
    b0 = pose_to_base0(base_pose_matrix(session.base_xyz, session.base_rpy))
    moves = np.vstack([np.zeros(a.n), np.sign(np.diff(q, axis=0))])
    for jit in (False, True):
        model = Model(robot(doc), "kinematic+" + spec, jit=jit)
        assert (model._mapping is not None) == jit      # the superset holds every error of a linear axis
        v = geometry_values(model, true)
        for name, x in vals.items():
            v[model.parameters.index(name)] = x
        cov = model.default_covariates(len(q))
        cov[:, model.covariate_names.index(f"move{j}")] = moves[:, j - 1]
        xyz = model.predict(q, v, cov, b0)
        assert np.abs(xyz - shots.xyz).max() < 2e-3 * size
        own = [i for i, p in enumerate(model.parameters) if p.term != "geometric"]
        mirrored = v.copy()
        mirrored[own] = -v[own]
        assert np.linalg.norm(model.predict(q, mirrored, cov, b0) - shots.xyz, axis=1).max() > size


def test_a_columns_give_under_the_arms_moment_has_the_extension_as_lever():
    """The column's compliance under the arm's moment is ``mount_compliance``: the base tilts about its origin,
    so the same arm pose moves the point the more the column is extended (its lever: the column's height), as in
    the truth, whose tilted arm is the package's to rounding at both ends of the column."""
    doc = ARM_COLUMN
    a = Arm.from_dict(doc)
    q = np.array([[0.3, 0.05, 0.4, -0.6], [0.3, 1.15, 0.4, -0.6]])     # the column low, then high
    C = 2e-7
    model = Model(robot(doc), "kinematic+mount_compliance")
    v = model.parameters.nominal.copy()
    v[model.parameters.index("cmount")] = C
    cov = model.default_covariates(len(q))
    moved = np.linalg.norm(model.predict(q, v, cov) - model.predict(q, None, cov), axis=1)
    assert moved[1] > 1.3 * moved[0] > 0, moved        # the same moment, a longer lever (1.1 m higher)
    true = TrueRobot(a, effects=Effects(mount_compliance=C))
    rigid = TrueRobot(a)
    truth = np.linalg.norm(true.tool_point(true.state(q)) - rigid.tool_point(rigid.state(q)), axis=1)
    np.testing.assert_allclose(moved, truth, rtol=2e-3)
