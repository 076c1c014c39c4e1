"""The independent truth (tests/truth) against the documented formulas, worked by hand at a few poses.

Nothing here uses casadical: the expected values are written out from the definitions of docs/formats.md
(link transforms, base pose, measurement CSV), docs/guide.md's term table and docs/diagnosis.md's sign
conventions. tests/model/test_truth_vs_package.py compares the truth with casadical's model.
"""

import csv
from math import cos, radians, sin

import numpy as np
import pytest

from tests.truth import Arm, Effects, Session, TrueRobot, four_bar, last_moves, measure, sample
from tests.truth import transforms as tf

G = 9.81
L1, L2, M1, M2, MP = 0.8, 0.6, 20.0, 10.0, 5.0

#: two links turning about parallel z axes, gravity along -y of the base frame: a planar arm in x-y
PLANAR = {
    "name": "planar", "convention": "dh",
    "joint": [{"alpha_deg": 0, "a_m": L1, "d_m": 0.0, "mass_kg": M1, "com_m": [-L1 / 2, 0, 0]},
              {"alpha_deg": 0, "a_m": L2, "d_m": 0.0, "mass_kg": M2, "com_m": [-L2 / 2, 0, 0]}],
    "payload": {"mass_kg": MP}, "gravity": {"direction": [0, -2, 0]},
}


def planar_point(q1, q2):
    return np.array([L1 * cos(q1) + L2 * cos(q1 + q2), L1 * sin(q1) + L2 * sin(q1 + q2), 0.0])


def planar_torques(q1, q2, payload=MP):
    """Torque of gravity (0, -m g, 0) about each z axis: the lever is the x distance, the torque -m g x."""
    c1, c12 = cos(q1), cos(q1 + q2)
    tau1 = -G * (M1 * L1 / 2 * c1 + M2 * (L1 * c1 + L2 / 2 * c12) + payload * (L1 * c1 + L2 * c12))
    tau2 = -G * (M2 * L2 / 2 * c12 + payload * L2 * c12)
    return np.array([tau1, tau2])


def nominal(doc, effects=None):
    return TrueRobot(Arm.from_dict(doc), effects=effects)


def point(robot, q, **kw):
    q = np.atleast_2d(q)
    return robot.tool_point(robot.state(q, **kw), kw.get("temperature"))


def test_planar_arm_and_its_torques():
    robot = nominal(PLANAR)
    q = np.radians([[30.0, 45.0], [-120.0, 80.0], [0.0, 0.0]])
    s = robot.state(q)
    for i, (q1, q2) in enumerate(q):
        assert np.allclose(robot.tool_point(s)[i], planar_point(q1, q2), atol=1e-15)
        assert np.allclose(s.torque[i], planar_torques(q1, q2), rtol=1e-12)
    # the payload of the row counts, not the file's
    s = robot.state(q, payload=[0.0, 50.0, 5.0])
    assert np.allclose(s.torque[1], planar_torques(*q[1], payload=50.0), rtol=1e-12)


def test_compliance_gives_way_with_the_torque_at_equilibrium():
    """Joint j turns by tau_j / k_j (and k3 tau^3 beyond), tau of the deflected arm: the hand iteration."""
    k, k3 = {1: 2e4, 2: 5e3}, {2: -2e-9}
    robot = nominal(PLANAR, Effects(stiffness=k, cubic=k3))
    q = np.radians([20.0, 30.0])
    a = q.copy()
    for _ in range(100):
        tau = planar_torques(*a)
        a = q + tau / [k[1], k[2]] + [0.0, k3[2] * tau[1] ** 3]
    assert np.allclose(point(robot, q), planar_point(*a), atol=1e-14)
    # gravity pulls the outstretched arm down: the point sinks, by 16 mm here
    assert 0.015 < planar_point(*q)[1] - point(robot, q)[0, 1] < 0.017


def test_gear_error_encoder_scale_and_backlash_by_hand():
    """A sin(h q + phi), s q, +b sign(tau), -b sign(last move) are added to the joint's angle."""
    A, h, phi, s, b = radians(0.02), 7, 0.4, 5e-4, radians(0.01)
    q = np.radians([[50.0, -20.0], [10.0, -20.0], [10.0, 60.0], [10.0, 60.0]])
    moves = np.array([[0, 0], [-1, 0], [-1, 1], [-1, 1]], float)   # joint 1 went down, then rests
    assert np.array_equal(last_moves(q), moves)
    for eff, extra in (
        (Effects(periodic=[(2, h, A, phi)]), lambda q1, q2, m: (0.0, A * sin(h * q2 + phi))),
        (Effects(encoder_scale={1: s}), lambda q1, q2, m: (s * q1, 0.0)),
        (Effects(backlash={2: b}), lambda q1, q2, m: (0.0, b * np.sign(planar_torques(q1, q2)[1]))),
        (Effects(backlash_motion={1: b, 2: b}), lambda q1, q2, m: (-b * m[0], -b * m[1])),
    ):
        got = point(nominal(PLANAR, eff), q)
        for i, (q1, q2) in enumerate(q):
            e1, e2 = extra(q1, q2, moves[i])
            assert np.allclose(got[i], planar_point(q1 + e1, q2 + e2), atol=1e-15), eff


def test_thermal_expansion_scales_lengths():
    """Every length times 1 + alpha (T - t_ref); per link: that row's lengths only."""
    q = np.radians([[30.0, 45.0]])
    doc = {**PLANAR, "tool": {"a_m": 0.1, "b_m": 0.0, "d_m": 0.0}}
    tool = lambda q1, q2, f: 0.1 * f * np.array([cos(q1 + q2), sin(q1 + q2), 0.0])   # noqa: E731
    r = nominal(doc, Effects(thermal_alpha=2e-5, t_ref=20.0))
    f = 1 + 2e-5 * 15.0
    expected = f * planar_point(*q[0]) + tool(*q[0], f)
    assert np.allclose(point(r, q, temperature=35.0), expected, atol=1e-15)
    r = nominal(doc, Effects(thermal_links={2: -3e-5}, t_ref=25.0))
    q1, q2 = q[0]
    f2 = 1 - 3e-5 * 10.0
    expected = np.array([L1 * cos(q1) + f2 * L2 * cos(q1 + q2), L1 * sin(q1) + f2 * L2 * sin(q1 + q2), 0.0])
    assert np.allclose(point(r, q, temperature=35.0), expected + tool(q1, q2, 1.0), atol=1e-15)


def test_mdh_and_dh_rows_with_hayati_beta():
    """mdh: Rx(alpha) Tx(a) Ry(beta) Ty(b) Rz(q + theta) Tz(d);
    dh: Rz(q + theta) Tz(d) Tx(a) Rx(alpha) Ry(beta) Ty(b)."""
    mdh = {"name": "m", "convention": "mdh", "tool": {"a_m": 0.2},
           "joint": [{"alpha_deg": 0, "a_m": 1.0, "beta_deg": 90.0, "d_m": 0.5}]}
    # Ry(90) turns z to x and x to -z: the axis now points along x, the tool's a along -z (q = 0) or y (q = 90)
    got = point(nominal(mdh), np.radians([[0.0], [90.0]]))
    assert np.allclose(got, [[1.5, 0.0, -0.2], [1.5, 0.2, 0.0]], atol=1e-15)
    mdh["joint"][0].update(b_m=0.1, theta_deg=90.0)
    got = point(nominal(mdh), np.radians([[0.0]]))
    assert np.allclose(got, [[1.5, 0.3, 0.0]], atol=1e-15)      # Ty(b) along y; theta like q
    dh = {"name": "d", "convention": "dh", "tool": {"d_m": 0.3},
          "joint": [{"alpha_deg": 90.0, "a_m": 1.0, "beta_deg": 90.0, "b_m": 0.1, "d_m": 0.5}]}
    # q = 90: Rz turns x to y; Tz(d) up, Tx(a) along y: (0, 1, 0.5). Rz(90) Rx(90) has the axes x' = (0, 1, 0),
    # y' = (0, 0, 1), z' = (1, 0, 0); Ry(90) keeps y' (Ty(b): +0.1 z) and turns z' to x' (the tool's d: +0.3 y)
    R = tf.chain(tf.rot("z", radians(90)), tf.rot("x", radians(90)), tf.rot("y", radians(90)))[0, :3, :3]
    assert np.allclose(R, [[0, 0, 1], [1, 0, 0], [0, 1, 0]] @ np.array([[0, 0, 1], [0, 1, 0], [-1, 0, 0]]))
    assert np.allclose(point(nominal(dh), np.radians([[90.0]])), [[0.0, 1.3, 0.6]], atol=1e-15)


def test_base_pose_is_fixed_axis_rpy():
    """Trans(xyz) Rz(yaw) Ry(pitch) Rx(roll): roll 90 turns y to z, then yaw 90 turns x to y."""
    doc = {"name": "one", "convention": "dh", "joint": [{"alpha_deg": 0, "a_m": 0.0, "d_m": 0.0}],
           "tool": {"a_m": 1.0, "b_m": 2.0, "d_m": 3.0}}
    robot = nominal(doc)
    q = np.zeros((1, 1))
    pure = measure(robot, q, session=Session(base_rpy=(radians(90), 0.0, 0.0)), noise=0.0)
    assert np.allclose(pure.xyz, [[1.0, -3.0, 2.0]], atol=1e-15)     # (x, y, z) -> (x, -z, y)
    both = measure(robot, q, session=Session(base_xyz=(10, 20, 30), base_rpy=(radians(90), 0.0, radians(90))),
                   noise=0.0)
    assert np.allclose(both.xyz, [[10 + 3.0, 20 + 1.0, 30 + 2.0]], atol=1e-14)   # then (x, y, z) -> (-y, x, z)
    pitch = measure(robot, q, session=Session(base_rpy=(0.0, radians(90), 0.0)), noise=0.0)
    assert np.allclose(pitch.xyz, [[3.0, 2.0, -1.0]], atol=1e-15)    # z -> x, x -> -z


def test_orientation_is_intrinsic_xyz_tracker_to_probe(tmp_path):
    """The probe's frame in the measurement frame, written as R = Rx(rx) Ry(ry) Rz(rz)."""
    robot = nominal(PLANAR)
    q = np.radians([[30.0, 45.0]])
    shots = measure(robot, q, noise=0.0, orientation_noise=0.0)
    assert np.allclose(shots.R[0], tf.rot("z", radians(75.0))[0, :3, :3], atol=1e-15)
    head, rows = shots.header_and_rows()
    ang = dict(zip(head, map(float, rows[0])))
    assert (ang["rx_deg"], ang["ry_deg"]) == pytest.approx((0.0, 0.0), abs=1e-12)
    assert ang["rz_deg"] == pytest.approx(75.0, abs=1e-12)
    # a mounting of the probe and a base rotation: R = R_base R_flange R_mount, and its angles rebuild it
    ses = Session(base_rpy=(0.3, -0.2, 1.1), mount_rpy=(0.1, 0.5, -2.0))
    shots = measure(robot, q, session=ses, noise=0.0, orientation_noise=0.0)
    R = (tf.fixed_rpy(0.3, -0.2, 1.1) @ tf.rot("z", radians(75.0)) @ tf.fixed_rpy(0.1, 0.5, -2.0))[0, :3, :3]
    assert np.allclose(shots.R[0], R, atol=1e-15)
    rx, ry, rz = tf.intrinsic_xyz(shots.R)[0]
    assert np.allclose(tf.chain(tf.rot("x", rx), tf.rot("y", ry), tf.rot("z", rz))[0, :3, :3], R, atol=1e-15)
    from scipy.spatial.transform import Rotation  # an independent library's reading of "intrinsic XYZ"
    assert np.allclose(Rotation.from_matrix(R).as_euler("XYZ"), [rx, ry, rz], atol=1e-12)


def test_sessions_drift_noise_bad_shots_and_the_csv(tmp_path):
    """Drift v (t - t_ref) moves the measured point; the probe's shift is in the flange frame; the CSV has
    the contract's columns and units."""
    robot = nominal(PLANAR)
    q = np.radians([[30.0, 45.0], [40.0, 45.0], [50.0, 45.0]])
    t = np.array([0.0, 10.0, 20.0])
    ses = Session("B", tool_shift=(0.01, 0.0, 0.002), drift=(1e-6, 0.0, -2e-6), t_ref=10.0)
    shots = measure(robot, q, session=ses, noise=0.0, time_s=t, temperature_c=[20, 21, 22], payload_kg=5.0)
    for i, (q1, q2) in enumerate(q):
        flange_x = np.array([cos(q1 + q2), sin(q1 + q2), 0.0])
        expected = planar_point(q1, q2) + 0.01 * flange_x + [0, 0, 0.002] + (t[i] - 10.0) * np.array([1e-6, 0, -2e-6])
        assert np.allclose(shots.xyz[i], expected, atol=1e-15)
    other = measure(robot, q, session=Session("A"), noise=0.0, time_s=t, temperature_c=20.0, payload_kg=5.0)
    path = (other + shots).write_csv(tmp_path / "two.csv")
    rows = list(csv.DictReader(open(path)))
    assert list(rows[0]) == ["q1_deg", "q2_deg", "x_mm", "y_mm", "z_mm", "payload_kg", "temperature_c", "time_s",
                             "session"]
    assert [r["session"] for r in rows] == ["A"] * 3 + ["B"] * 3
    assert float(rows[4]["q1_deg"]) == pytest.approx(40.0, abs=1e-12)
    assert float(rows[4]["x_mm"]) == pytest.approx(shots.xyz[1, 0] * 1000, rel=1e-15)
    # noise: Gaussian per axis; bad shots: that many rows off by the gross error
    rng = np.random.default_rng(3)
    qq = sample(robot, 4000, rng, floor_z=None)
    clean = measure(robot, qq, rng, noise=0.0)
    noisy = measure(robot, qq, np.random.default_rng(4), noise=20e-6, bad=5, bad_mm=8.0)
    err = np.linalg.norm(noisy.xyz - clean.xyz, axis=1)
    assert np.sort(np.flatnonzero(err > 1e-3)).tolist() == noisy.bad.tolist() and len(noisy.bad) == 5
    assert np.std(np.delete(noisy.xyz - clean.xyz, noisy.bad, axis=0)) == pytest.approx(20e-6, rel=0.03)
    assert np.allclose(err[noisy.bad], 8e-3, atol=2e-4)


def test_coupled_joint_errors_travel_through_the_coupling():
    """theta_2 = q_2 - q_1 + offset (a parallelogram-like coupling): the second link keeps its absolute
    direction q_2 + offset, whatever joint 1's drive does; drive 1 carries tau_1 - tau_2 (virtual work)."""
    doc = {**PLANAR, "joint": [PLANAR["joint"][0], {**PLANAR["joint"][1], "coupling": [-1.0, 1.0],
                                                      "coupling_offset_deg": 10.0}]}
    q = np.radians([[30.0, 70.0]])
    q1, q2 = q[0]
    c2 = q2 - q1 + radians(10.0)
    assert np.allclose(point(nominal(doc), q), planar_point(q1, c2), atol=1e-15)
    # an encoder scale error of joint 1 turns link 1 only: link 2's absolute direction is q2 + 10 deg
    s = 1e-3
    got = point(nominal(doc, Effects(encoder_scale={1: s})), q)[0]
    a1 = (1 + s) * q1
    assert np.allclose(got, planar_point(a1, q2 + radians(10.0) - a1), atol=1e-15)
    tau = planar_torques(q1, c2)
    st = nominal(doc).state(q)
    assert np.allclose(st.drive_torque[0], [tau[0] - tau[1], tau[1]], rtol=1e-12)


def test_four_bar():
    """A parallelogram's rocker is parallel to its crank; any four-bar's coupler keeps its length."""
    rng = np.random.default_rng(0)
    link, crank = rng.uniform(-1, 1, 50), rng.uniform(0.6, 2.5, 50)
    assert np.allclose(four_bar(link, link + crank, 1.6, 0.8, 1.6, 0.8), link + crank - 2 * np.pi *
                       np.round((link + crank) / (2 * np.pi)), atol=1e-12)
    psi = four_bar(link, link + crank, 1.6, 0.8, 1.62, 0.79)
    C = 0.8 * np.column_stack([np.cos(link + crank), np.sin(link + crank)])
    R = 1.6 * np.column_stack([np.cos(link), np.sin(link)]) + 0.79 * np.column_stack([np.cos(psi), np.sin(psi)])
    assert np.allclose(np.linalg.norm(R - C, axis=1), 1.62, atol=1e-12)


def test_reads_the_toml_text_as_the_dict(tmp_path):
    from tests.helpers.arms import ARM7, to_toml
    a, b = Arm.from_dict(ARM7), Arm.from_toml(to_toml(ARM7))
    rng = np.random.default_rng(1)
    q = sample(TrueRobot(a), 20, rng)
    assert np.array_equal(point(TrueRobot(a), q), point(TrueRobot(b), q))
    assert a.links[3].beta == 0.0 and a.links[2].beta is None and a.convention == "mdh"


# --- effects outside the catalogue: joint coupling, another joint's reading, axis tilt, mount compliance, the
# instrument's own errors -------------------------------------------------------------------------------------

def _arm7_poses(n=12, seed=5):
    from tests.helpers.arms import ARM7
    rng = np.random.default_rng(seed)
    robot = TrueRobot.draw(Arm.from_dict(ARM7), Effects(stiffness={2: 3e5}), rng)
    return robot, sample(robot, n, rng)


def test_new_effects_at_zero_change_nothing():
    robot, q = _arm7_poses()
    zero = Effects(stiffness={2: 3e5}, coupling={(6, 5): 0.0}, cross_error={(3, 2): lambda x: 0.0 * x},
                   axis_tilt={4: (0.0, 0.0)}, mount_compliance=0.0)
    for mount in (0.0, (0.0, 0.0)):
        zero.mount_compliance = mount
        a, b = robot.state(q), robot.with_effects(zero).state(q)
        assert np.array_equal(robot.tool_point(a), robot.tool_point(b))
        assert np.array_equal(a.flange, b.flange) and b.tilt is None
    ses = Session(angle_error=(0.0, 0.3), distance_scale=0.0, base_xyz=(2.0, 1.0, 0.0))
    assert np.array_equal(measure(robot, q, session=ses, noise=0.0).xyz,
                          measure(robot, q, session=Session(base_xyz=(2.0, 1.0, 0.0)), noise=0.0).xyz)


def test_joint_coupling_and_another_joints_reading_by_hand():
    """e_j += c q_k and e_j += f(q_k): joint j's angle moves by them, signs as written (c > 0 turns joint j
    forward when q_k > 0)."""
    c, f = 2e-3, (lambda x: 1e-3 * x ** 2)
    q = np.radians([[50.0, -20.0], [-30.0, 70.0]])
    got = point(nominal(PLANAR, Effects(coupling={(2, 1): c})), q)
    got2 = point(nominal(PLANAR, Effects(cross_error={(1, 2): f})), q)
    for i, (q1, q2) in enumerate(q):
        assert np.allclose(got[i], planar_point(q1, q2 + c * q1), atol=1e-15)
        assert np.allclose(got2[i], planar_point(q1 + f(q2), q2), atol=1e-15)
    # a 3-D arm: the same as the nominal arm at readings with joint 6 moved by c q5 (exact: no couplings there)
    robot, q = _arm7_poses()
    moved = q.copy()
    moved[:, 5] += c * q[:, 4]
    coupled = robot.with_effects(Effects(stiffness={2: 3e5}, coupling={(6, 5): c}))
    assert np.allclose(point(coupled, q), point(robot, moved), atol=1e-14)


def test_axis_tilt_tips_the_link_about_its_x_axis():
    """The link after joint 2 turns by Rx(w), w = a sin q2 + b cos q2: a tool 0.1 m along its z axis swings
    to -0.1 sin w along the link's y; points on the link's x axis stay."""
    doc = {**PLANAR, "tool": {"d_m": 0.1}}
    a, b = 2e-3, -1e-3
    q = np.radians([[30.0, 45.0], [-60.0, 120.0]])
    got = point(nominal(doc, Effects(axis_tilt={2: (a, b)})), q)
    for i, (q1, q2) in enumerate(q):
        w = a * sin(q2) + b * cos(q2)
        y_link = np.array([-sin(q1 + q2), cos(q1 + q2), 0.0])
        expected = planar_point(q1, q2) + 0.1 * np.array([0, 0, cos(w)]) - 0.1 * sin(w) * y_link
        assert np.allclose(got[i], expected, atol=1e-15)
    assert np.allclose(point(nominal(PLANAR, Effects(axis_tilt={2: (a, b)})), q), point(nominal(PLANAR), q),
                       atol=1e-15)


def test_mount_compliance_tilts_the_base_towards_the_weights():
    """theta = C M, M = sum c x (m g) about the base frame's origin; the rotation by theta about the origin."""
    # planar arm, gravity along -y: M is along z and equals joint 1's torque (its axis is the base's z): the
    # whole arm turns about joint 1 by C tau1
    C = 2e-6
    q = np.radians([[20.0, 30.0], [150.0, -40.0]])
    got = point(nominal(PLANAR, Effects(mount_compliance=C)), q)
    for i, (q1, q2) in enumerate(q):
        assert np.allclose(got[i], planar_point(q1 + C * planar_torques(q1, q2)[0], q2), atol=1e-15)
    assert (got[:, 1] < point(nominal(PLANAR), q)[:, 1]).all()        # both sink (the weights pull them down)
    # one link along x, gravity -z, 10 kg at its middle and 5 kg of payload at its end (1 m): at q = 0 the
    # moment is (0, 9.81 (10 * 0.5 + 5 * 1), 0) and Ry(C M_y) turns the end down; at q = 90 deg it is about -x
    doc = {"name": "one", "convention": "dh", "payload": {"mass_kg": 5.0},
           "joint": [{"alpha_deg": 0, "a_m": 1.0, "d_m": 0.0, "mass_kg": 10.0, "com_m": [-0.5, 0, 0]}]}
    M = G * (10 * 0.5 + 5 * 1.0)
    for mount, (cx, cy) in ((C, (C, C)), ((1e-6, 3e-6), (1e-6, 3e-6))):
        r = nominal(doc, Effects(mount_compliance=mount))
        s = r.state(np.radians([[0.0], [90.0]]))
        assert np.allclose(s.moment, [[0, M, 0], [-M, 0, 0]], atol=1e-12)
        assert np.allclose(r.tool_point(s), [[cos(cy * M), 0, -sin(cy * M)], [0, cos(cx * M), -sin(cx * M)]],
                           atol=1e-15)
        # the flange's orientation turns with it: Ry(C M) at q = 0
        assert np.allclose(s.flange[0, :3, :3], tf.rot("y", cy * M)[0, :3, :3], atol=1e-15)
    # a session's own mount; the measured orientation turns too
    r = nominal(doc, Effects(mount_compliance=C))
    q0 = np.zeros((1, 1))
    own = measure(r, q0, session=Session(mount_compliance=3 * C), noise=0.0, orientation_noise=0.0)
    assert np.allclose(own.xyz, [[cos(3 * C * M), 0, -sin(3 * C * M)]], atol=1e-15)
    assert np.allclose(own.R[0], tf.rot("y", 3 * C * M)[0, :3, :3], atol=1e-15)
    # a 3-D arm, first order: the point moves by theta x p, theta from the weights summed here
    robot, q = _arm7_poses()
    base = robot.state(q)
    C = 1e-6
    tilted = robot.with_effects(Effects(stiffness={2: 3e5}, mount_compliance=C)).state(q)
    arm = robot.arm
    M = sum(np.cross(base.links[:, i, :3, :3] @ arm.links[i].com + base.links[:, i, :3, 3], arm.links[i].mass *
                     arm.gravity) for i in range(arm.n))
    p = robot.tool_point(base)
    M = M + np.cross(base.flange[:, :3, :3] @ arm.payload_com + p, arm.payload * arm.gravity)
    move = robot.tool_point(tilted) - p
    assert np.abs(move).max() > 2e-5
    assert np.allclose(move, np.cross(C * M, p), atol=1e-8)      # second order: |theta|^2 |p| < 3e-9 m


def test_bearing_compliance_tips_a_joints_axis_towards_the_weights_it_carries():
    """Joint 2's axis (vertical, the arm in a level plane, gravity -z) tips about its origin by (cx M_x, cy M_y, 0)
    in its own frame, M the moment of link 2 and the payload about it, at the tipped arm's centres: a fixed point
    written out here."""
    L1, L2, m2, mp = 0.8, 0.6, 10.0, 5.0
    doc = {"name": "level", "convention": "dh", "payload": {"mass_kg": mp},
           "joint": [{"alpha_deg": 0, "a_m": L1, "d_m": 0.0, "mass_kg": 20.0, "com_m": [-L1 / 2, 0, 0]},
                     {"alpha_deg": 0, "a_m": L2, "d_m": 0.0, "mass_kg": m2, "com_m": [-L2 / 2, 0, 0]}]}
    cx, cy = 2e-4, 1e-4
    r = nominal(doc, Effects(bearing_compliance={2: (cx, cy)}))
    # q2 = 0: link 2 along joint 2's frame x; tipped by t about y: r = L (cos t, 0, -sin t), M_y = g L cos t (...)
    t = 0.0
    for _ in range(100):
        t = cy * G * L2 * (m2 / 2 + mp) * cos(t)
    s = r.state(np.zeros((1, 2)))
    assert s.bearing[0, 1] == pytest.approx([0.0, t, 0.0], abs=1e-15)
    assert np.allclose(r.tool_point(s), [[L1 + L2 * cos(t), 0.0, -L2 * sin(t)]], atol=1e-14)
    # q2 = 90 deg: link 2 along the frame's y; M_x < 0 turns it down about x
    u = 0.0
    for _ in range(100):
        u = -cx * G * L2 * (m2 / 2 + mp) * cos(u)
    s = r.state(np.radians([[0.0, 90.0]]))
    assert s.bearing[0, 1] == pytest.approx([u, 0.0, 0.0], abs=1e-15)
    assert np.allclose(r.tool_point(s), [[L1, L2 * cos(u), L2 * sin(u)]], atol=1e-14)
    # joint 1 carries no weight across its axis then? it does (the whole arm), but it has no bearing compliance
    assert not s.bearing[0, 0].any()
    # a 3-D arm: a compliance of zero changes nothing; one tips everything after the joint, first order
    robot, q = _arm7_poses()
    plain = robot.with_effects(Effects())
    zero = robot.with_effects(Effects(bearing_compliance={3: (0.0, 0.0)}))
    assert np.array_equal(zero.tool_point(zero.state(q)), plain.tool_point(plain.state(q)))
    tipped = robot.with_effects(Effects(bearing_compliance={3: (1e-6, 2e-6)}))
    st, s0 = tipped.state(q), plain.state(q)
    w = np.einsum("nij,nj->ni", s0.axis_frames[:, 2], st.bearing[:, 2])    # the tilt in the base frame
    p0 = plain.tool_point(s0)
    move = tipped.tool_point(st) - p0
    arm = p0 - s0.origins[:, 2]
    second_order = np.linalg.norm(w, axis=1).max() ** 2 * np.linalg.norm(arm, axis=1).max()     # |w|^2 |r|
    assert np.abs(move).max() > 1e3 * second_order
    assert np.allclose(move, np.cross(w, arm), atol=second_order)


def test_instrument_angle_and_distance_errors():
    """The tracker turns a point about its vertical axis by A sin(az + phi) and reads (1 + s) times its
    distance: a point at azimuth az moves A sin(az + phi) r_xy across, s r along."""
    robot = nominal(PLANAR)
    q = np.radians([[30.0, 45.0], [100.0, -30.0], [-40.0, 10.0]])
    where = Session(base_xyz=(2.0, -1.0, 0.5))
    clean = measure(robot, q, session=where, noise=0.0).xyz
    A, phi, s = 1e-4, 0.7, 2e-5
    turned = measure(robot, q, session=Session(base_xyz=(2.0, -1.0, 0.5), angle_error=(A, phi)), noise=0.0).xyz
    scaled = measure(robot, q, session=Session(base_xyz=(2.0, -1.0, 0.5), distance_scale=s), noise=0.0).xyz
    for i, (x, y, z) in enumerate(clean):
        w = A * np.sin(np.arctan2(y, x) + phi)
        assert np.allclose(turned[i], [x * cos(w) - y * sin(w), x * sin(w) + y * cos(w), z], atol=1e-15)
        assert np.allclose(turned[i] - clean[i], w * np.array([-y, x, 0.0]), atol=1e-8)   # first order (w^2 r)
        assert np.allclose(scaled[i], (1 + s) * clean[i], atol=1e-15)


# --- a session's covariates, a mount compliance that follows one, a tilting floor and its sensor ---------------

def test_a_session_column_and_a_mount_compliance_growing_with_it(tmp_path):
    """A session's ``columns`` are written as constant columns; the mount's compliance is C0 + c h in a session
    of height h (``Effects.mount_law``): on the planar arm (gravity -y, joint 1's axis the base's z) the whole arm
    turns about joint 1 by (C0 + c h) tau1, as the hand calculation of the mount test above."""
    C0, c = 1e-6, 2e-6
    q = np.radians([[20.0, 30.0], [150.0, -40.0], [-70.0, 100.0]])
    robot = nominal(PLANAR, Effects(mount_compliance=C0, mount_law={"height_m": c}))
    low, high = Session("low", columns={"height_m": 1.5}), Session("high", columns={"height_m": 3.25})
    shots = measure(robot, q, session=low, noise=0.0) + measure(robot, q, session=high, noise=0.0)
    for i, (q1, q2) in enumerate(np.vstack([q, q])):
        h = 1.5 if i < 3 else 3.25
        assert np.allclose(shots.xyz[i], planar_point(q1 + (C0 + c * h) * planar_torques(q1, q2)[0], q2), atol=1e-15)
    rows = list(csv.DictReader(open(shots.write_csv(tmp_path / "two.csv"))))
    assert list(rows[0]) == ["q1_deg", "q2_deg", "x_mm", "y_mm", "z_mm", "height_m", "session"]
    assert [float(r["height_m"]) for r in rows] == [1.5] * 3 + [3.25] * 3
    # the law adds to a session's own mount too; a session without the law's column is an error
    own = measure(robot, q, session=Session(mount_compliance=4e-6, columns={"height_m": 2.0}), noise=0.0)
    q1, q2 = q[0]
    assert np.allclose(own.xyz[0], planar_point(q1 + (4e-6 + c * 2.0) * planar_torques(q1, q2)[0], q2), atol=1e-15)
    with pytest.raises(ValueError, match="height_m"):
        measure(robot, q, session=Session("bare"), noise=0.0)
    # a law may be any function of the column: a telescoping column's give grows faster than its length
    cubic = nominal(PLANAR, Effects(mount_law={"height_m": lambda h: 1e-7 * h ** 3}))
    got = measure(cubic, q, session=high, noise=0.0).xyz[0]
    assert np.allclose(got, planar_point(q1 + 1e-7 * 3.25 ** 3 * planar_torques(q1, q2)[0], q2), atol=1e-15)
    # a column without a law changes no point
    plain = nominal(PLANAR, Effects(mount_compliance=C0))
    assert np.array_equal(measure(plain, q, session=low, noise=0.0).xyz,
                          measure(plain, q, session=Session("low"), noise=0.0).xyz)


def test_a_tilting_floor_turns_the_base_and_its_sensor_reads_it():
    """Each pose the base turns about its x and y axes by (t_x, t_y), uniform within +-floor_tilt; the measured
    point is B R(t) p and the orientation B R(t) R_flange (R(t) by scipy's rotation vector, an independent
    reading); the columns tilt_x_rad, tilt_y_rad hold t plus the sensor's noise; an unrelated column follows
    nothing and changes no shot."""
    from scipy.spatial.transform import Rotation
    doc = {"name": "one", "convention": "dh", "tool": {"d_m": 0.2},
           "joint": [{"alpha_deg": 90, "a_m": 1.0, "d_m": 0.3, "mass_kg": 10.0, "com_m": [-0.5, 0, 0]}]}
    robot = nominal(doc)
    rng = np.random.default_rng(7)
    q = rng.uniform(-np.pi, np.pi, (4000, 1))
    T = 2e-3
    ses = Session(base_xyz=(2.0, -1.0, 0.5), base_rpy=(0.1, -0.2, 0.7), floor_tilt=T)
    shots = measure(robot, q, np.random.default_rng(3), session=ses, noise=0.0, orientation_noise=0.0)
    t = np.column_stack([shots.columns["tilt_x_rad"], shots.columns["tilt_y_rad"]])
    assert np.abs(t).max() <= T and np.abs(t).min(axis=0).max() < 0.01 * T and (np.abs(t).max(axis=0) > 0.99 * T).all()
    flat = measure(robot, q, session=Session(base_xyz=(2.0, -1.0, 0.5)), noise=0.0, orientation_noise=0.0)
    R_t = Rotation.from_rotvec(np.column_stack([t, np.zeros(len(t))])).as_matrix()
    B = tf.fixed_rpy(0.1, -0.2, 0.7)[0, :3, :3]
    p = flat.xyz - [2.0, -1.0, 0.5]                                   # the untilted arm's point, base frame
    assert np.allclose(shots.xyz, np.einsum("ij,njk,nk->ni", B, R_t, p) + [2.0, -1.0, 0.5], atol=1e-14)
    assert np.allclose(shots.R, np.einsum("ij,njk,nkl->nil", B, R_t, flat.R), atol=1e-14)
    # by hand at one pose: q = 0 puts the tool at (1, -0.2, 0.3) (Rx(90) turns the tool's z to -y); the floor's
    # tilt t moves it by t x p to first order (a tilt about y turns x down)
    one = Session(floor_tilt=T)
    s = measure(robot, np.zeros((1, 1)), np.random.default_rng(11), session=one, noise=0.0)
    tx, ty = s.columns["tilt_x_rad"][0], s.columns["tilt_y_rad"][0]
    p0 = np.array([1.0, -0.2, 0.3])
    assert np.allclose(s.xyz[0], p0 + np.cross([tx, ty, 0.0], p0), atol=T ** 2)
    assert s.xyz[0, 2] - 0.3 == pytest.approx(-ty - 0.2 * tx, abs=T ** 2)
    # the sensor's noise: the same draws otherwise (same shots), its columns off by N(0, sigma)
    noisy = measure(robot, q, np.random.default_rng(3), session=Session(base_xyz=(2.0, -1.0, 0.5),
                    base_rpy=(0.1, -0.2, 0.7), floor_tilt=T, tilt_noise=1e-4), noise=0.0, orientation_noise=0.0)
    assert np.array_equal(noisy.xyz, shots.xyz)
    err = np.column_stack([noisy.columns["tilt_x_rad"], noisy.columns["tilt_y_rad"]]) - t
    assert np.std(err) == pytest.approx(1e-4, rel=0.05) and abs(np.mean(err)) < 1e-5
    # an unrelated column: drawn last (the shots are those without it), in the tilt's range, following nothing
    decoy = measure(robot, q, np.random.default_rng(3), session=Session(base_xyz=(2.0, -1.0, 0.5),
                    base_rpy=(0.1, -0.2, 0.7), floor_tilt=T, unrelated="acc_spare_x"), noise=0.0,
                    orientation_noise=0.0)
    assert np.array_equal(decoy.xyz, shots.xyz)
    x = decoy.columns["acc_spare_x"]
    assert np.abs(x).max() <= T and np.ptp(x) > 1.9 * T
    assert max(abs(np.corrcoef(x, t[:, k])[0, 1]) for k in range(2)) < 0.1
    head, _ = decoy.header_and_rows()
    assert head[1:] == ["x_mm", "y_mm", "z_mm", "tilt_x_rad", "tilt_y_rad", "acc_spare_x", "rx_deg", "ry_deg",
                        "rz_deg"]
