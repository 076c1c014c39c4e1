"""Forward kinematics, Jacobian, gravity torques and the HH800 loop against independent computations."""

import math
from dataclasses import replace

import numpy as np
import pytest

from casadical import Model, load_robot
from casadical.robot import robot_from_dict

RNG = np.random.default_rng(12345)


def planar(convention, masses=(0.0, 0.0), coms=([0, 0, 0], [0, 0, 0]), payload=0.0, gravity=(0, 0, -1)):
    L1, L2 = 0.7, 0.45
    if convention == "mdh":  # link i frame after Rx Tx Rz Tz: lengths sit in the next row / tool
        joints = [dict(alpha_deg=0, a_m=0, d_m=0), dict(alpha_deg=0, a_m=L1, d_m=0)]
        tool = dict(a_m=L2, b_m=0, d_m=0)
    else:
        joints = [dict(alpha_deg=0, a_m=L1, d_m=0), dict(alpha_deg=0, a_m=L2, d_m=0)]
        tool = dict(a_m=0, b_m=0, d_m=0)
    for j, m, c in zip(joints, masses, coms):
        j.update(mass_kg=m, com_m=list(c), min_deg=-180, max_deg=180)
    return robot_from_dict(dict(name="planar", convention=convention, joint=joints, tool=tool,
                                payload=dict(mass_kg=payload), gravity=dict(direction=list(gravity)))), L1, L2


@pytest.mark.parametrize("convention", ["mdh", "dh"])
def test_planar_closed_form(convention):
    robot, L1, L2 = planar(convention)
    q = RNG.uniform(-math.pi, math.pi, (50, 2))
    xyz = Model(robot, "nominal").predict(q)
    x = L1 * np.cos(q[:, 0]) + L2 * np.cos(q.sum(1))
    y = L1 * np.sin(q[:, 0]) + L2 * np.sin(q.sum(1))
    np.testing.assert_allclose(xyz, np.column_stack([x, y, 0 * x]), atol=1e-12)


def _rx(a):
    c, s = math.cos(a), math.sin(a)
    return np.array([[1, 0, 0, 0], [0, c, -s, 0], [0, s, c, 0], [0, 0, 0, 1.0]])


def _ry(a):
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, 0, s, 0], [0, 1, 0, 0], [-s, 0, c, 0], [0, 0, 0, 1.0]])


def _rz(a):
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, -s, 0, 0], [s, c, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1.0]])


def _t(x=0, y=0, z=0):
    T = np.eye(4)
    T[:3, 3] = [x, y, z]
    return T


def explicit_fk(robot, q):
    """The definition of docs/formats.md section 1, written out with 4x4 matrices."""
    x, y, z = robot.base_xyz
    r, p, w = robot.base_rpy
    T = _t(x, y, z) @ _rz(w) @ _ry(p) @ _rx(r)
    for qi, j in zip(q, robot.joints):
        th = qi + j.theta
        beta, b = j.beta or 0.0, j.b or 0.0
        if robot.convention == "mdh":
            T = T @ _rx(j.alpha) @ _t(j.a) @ _ry(beta) @ _t(0, b) @ _rz(th) @ _t(0, 0, j.d)
        else:
            T = T @ _rz(th) @ _t(0, 0, j.d) @ _t(j.a) @ _rx(j.alpha) @ _ry(beta) @ _t(0, b)
    return (T @ _t(*robot.tool))[:3, 3]


@pytest.mark.parametrize("name", ["ys100", "ur10"])
def test_explicit_matrix_product(name):
    robot = load_robot(name)
    # perturb everything, including beta/b, theta offsets and the base pose
    rng = np.random.default_rng(7)
    joints = [replace(j, alpha=j.alpha + rng.normal(0, 0.01), a=j.a + rng.normal(0, 0.01),
                      theta=j.theta + rng.normal(0, 0.02), d=j.d + rng.normal(0, 0.01),
                      beta=None if j.beta is None else rng.normal(0, 0.01),
                      b=None if j.b is None else rng.normal(0, 0.01)) for j in robot.joints]
    robot = replace(robot, joints=joints, base_xyz=np.array([1.5, -2.0, 0.3]),
                    base_rpy=np.array([0.3, -0.4, 2.5]), tool=np.array([0.05, -0.02, 0.12]))
    q = rng.uniform(-3, 3, (20, robot.n))
    got = Model(robot, "nominal").predict(q)
    want = np.array([explicit_fk(robot, qi) for qi in q])
    np.testing.assert_allclose(got, want, atol=1e-12)


def test_jacobian_matches_finite_differences():
    robot = load_robot("ys100")
    model = Model(robot, "kinematic+compliance+periodic[2:3]+encoder_scale[3]+thermal")
    rng = np.random.default_rng(3)
    q = rng.uniform(-1.5, 1.5, (6, robot.n))
    p0 = model.parameters.values + model.parameters.scales * rng.normal(0, 1, len(model.parameters))
    cov = model.default_covariates(6)
    cov[:, model.covariate_names.index("temperature_c")] = rng.uniform(15, 30, 6)
    _, J = model.predict_jacobian(q, p0, cov)
    h = model.parameters.scales * 0.05  # big enough to stay clear of round-off
    for k in range(len(p0)):
        dp = np.zeros_like(p0)
        dp[k] = h[k]
        fd = (model.predict(q, p0 + dp, cov) - model.predict(q, p0 - dp, cov)) / (2 * h[k])
        np.testing.assert_allclose(J[:, :, k], fd, atol=1e-6 * max(1.0, np.abs(fd).max()),
                                   err_msg=model.parameters.names[k])


@pytest.mark.parametrize("name", ["ys100", "hh800", "arm4", "arm5", "arm7"])
def test_angle_jacobian_is_the_derivative_of_a_joint_angle_error(name):
    """predict_angle_jacobian: the column of a periodic error is the angle derivative times sin/cos, on MDH and
    DH arms with and without beta, 4 to 7 joints, and the HH800's four-bar (where theta's column differs)."""
    from tests.helpers.arms import ARMS

    robot = load_robot(name) if name in ("ys100", "hh800") else robot_from_dict(ARMS[name])
    harm = [(j, 2 + j) for j in range(1, robot.n + 1)]
    spec = "kinematic+compliance+encoder_scale+periodic[" + ",".join(f"{j}:{h}" for j, h in harm) + "]"
    model = Model(robot, spec, jit=False)
    rng = np.random.default_rng(7)
    q = rng.uniform(-1.2, 1.2, (9, robot.n))
    p0 = model.parameters.values + model.parameters.scales * rng.normal(0, 1, len(model.parameters))
    xyz, J, JA = model.predict_angle_jacobian(q, p0)
    np.testing.assert_allclose(xyz, model.predict(q, p0), atol=1e-14)
    np.testing.assert_allclose(J, model.predict_jacobian(q, p0)[1], atol=1e-14)
    for j, h in harm:
        for kind, f in (("s", np.sin), ("c", np.cos)):
            col = J[:, :, model.parameters.index(f"gear{j}_{kind}{h}")]
            np.testing.assert_allclose(JA[:, :, j - 1] * f(h * q[:, j - 1])[:, None], col,
                                       atol=1e-12 * max(1.0, np.abs(col).max()), err_msg=f"{name} joint {j}")


def test_gravity_torques_hand_computed():
    m1, m2, mp, r1, r2 = 12.0, 7.0, 3.0, 0.3, 0.2
    # gravity along -y of the base frame: the joint axes (z) are horizontal
    robot, L1, L2 = planar("dh", masses=(m1, m2), coms=([r1 - 0.7, 0, 0], [r2 - 0.45, 0, 0]),
                           payload=mp, gravity=(0, -1, 0))
    q = RNG.uniform(-math.pi, math.pi, (30, 2))
    tau = Model(robot, "nominal").torques(q)
    g = 9.81
    c1, c12 = np.cos(q[:, 0]), np.cos(q.sum(1))
    tau1 = -g * (m1 * r1 * c1 + m2 * (L1 * c1 + r2 * c12) + mp * (L1 * c1 + L2 * c12))
    tau2 = -g * (m2 * r2 * c12 + mp * L2 * c12)
    np.testing.assert_allclose(tau, np.column_stack([tau1, tau2]), atol=1e-9)


def test_payload_column_changes_torque():
    robot = load_robot("ys100")
    model = Model(robot, "kinematic+compliance")
    q = np.radians([[0, 60, 10, 0, 30, 0]])
    cov0 = np.array([[0.0]])
    cov1 = np.array([[robot.payload_mass]])
    assert abs(model.torques(q, cov=cov1)[0, 1]) > abs(model.torques(q, cov=cov0)[0, 1]) + 100


def test_compliance_deflects_along_torque():
    robot = load_robot("ys100")
    model = Model(robot, "kinematic+compliance[2]")
    q = np.radians([[0, 45, 20, 0, 30, 0]])
    p = model.parameters.values
    p[model.parameters.index("c2")] = 1e-6
    dq = model.joint_offsets(q, p)
    tau = model.torques(q, p)
    np.testing.assert_allclose(dq[0, 1], 1e-6 * tau[0, 1])
    assert np.count_nonzero(dq) == 1


def test_hh800_loop_reduces_to_linear_coupling():
    robot = load_robot("hh800")
    linear = replace(robot, loop=None)
    from casadical.data import sample_poses
    q = sample_poses(robot, 40, np.random.default_rng(5), floor_z=None)
    np.testing.assert_allclose(Model(robot, "nominal").predict(q), Model(linear, "nominal").predict(q),
                               atol=1e-12)


def test_hh800_loop_closes_with_other_lengths():
    import casadi as ca

    from casadical.kinematics import fourbar_rocker_angle
    rng = np.random.default_rng(9)
    for _ in range(20):
        lam, phi = rng.uniform(0.5, 2.5), 0.0
        phi = lam + rng.uniform(0.6, 2.5)  # keep away from the dead points
        g, c, k, r = 1.6, 0.8 + rng.normal(0, 0.01), 1.6 + rng.normal(0, 0.01), 0.8 + rng.normal(0, 0.01)
        psi = float(ca.evalf(fourbar_rocker_angle(lam, phi, g, c, k, r)))
        S = c * np.array([math.cos(phi), math.sin(phi)])
        R = g * np.array([math.cos(lam), math.sin(lam)]) + r * np.array([math.cos(psi), math.sin(psi)])
        assert abs(np.linalg.norm(R - S) - k) < 1e-12
        assert abs(psi - phi) < 0.1  # the parallelogram branch, not the crossed one
    # and the lengths do move the tool
    robot = load_robot("hh800")
    model = Model(robot, "kinematic")
    # (at q3 - q2 = 90 deg the crank is square to the link and the first-order effect vanishes)
    q = np.radians([[0, 80, 140, 0, 0, 0]])
    _, J = model.predict_jacobian(q)
    assert np.linalg.norm(J[0, :, model.parameters.index("loop_rocker")]) > 0.1


def test_model_rejects_bad_inputs():
    from casadical.errors import ModelError
    model = Model(load_robot("ys100"), "kinematic")
    with pytest.raises(ModelError, match="6 joint values"):
        model.predict(np.zeros((3, 5)))
    with pytest.raises(ModelError, match="unknown model item"):
        Model(load_robot("ys100"), "kinematic+stiffnesss")
    with pytest.raises(ModelError, match="do not exist"):
        Model(load_robot("ys100"), "kinematic+compliance[7]")


def test_jit_falls_back_without_compiler(tmp_path):
    """No C compiler: same numbers from CasADi's VM, one warning, no files in the working folder."""
    import subprocess
    import sys
    code = ("import numpy as np, warnings\n"
            "from casadical import Model, load_robot\n"
            "q = np.linspace(-1, 1, 12).reshape(2, 6)\n"
            "ref = Model(load_robot('ys100'), 'kinematic', jit=False).predict(q)\n"
            "with warnings.catch_warnings(record=True) as w:\n"
            "    warnings.simplefilter('always')\n"
            "    got = Model(load_robot('ys100'), 'kinematic', jit=True).predict(q)\n"
            "assert np.allclose(got, ref, atol=1e-14)\n"
            "assert any('JIT compilation failed' in str(x.message) for x in w)\n")
    env = {"PATH": str(tmp_path), "HOME": str(tmp_path)}
    r = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, env=env, capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    assert list(tmp_path.iterdir()) == []
