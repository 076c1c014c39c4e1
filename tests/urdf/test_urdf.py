"""URDF in and out.

The reference forward kinematics is yourdfpy's own (``update_cfg`` / ``get_transform``), never
casadical's; the reference gravity torques are computed here from yourdfpy's link poses.
"""

import math
import warnings
from dataclasses import replace

import numpy as np
import pytest
import yourdfpy

from casadical import Model, calibrate, load_robot
from casadical.cli import main
from casadical.data import Effects, sample_poses, simulate
from casadical.errors import ModelError, RobotFileError
from casadical.robot import robot_from_dict
from casadical.stats import align
from casadical.urdf import PARALLEL_TOL_DEG, robot_from_urdf, robot_to_urdf
from tests.helpers.arms import ARM4_TRACK, ARM_COLUMN

TOL_M = 1e-9
SEEDS = [0, 1, 2]


def random_robot(seed: int, n: int, convention: str, beta: bool, gravity=(0.0, 0.0, -1.0)) -> dict:
    """A robot that is not built in: random link geometry; ``beta`` on one parallel pair or nowhere."""
    rng = np.random.default_rng(seed)
    joints = []
    for i in range(n):
        alpha = float(rng.choice([90.0, -90.0, rng.uniform(-150, 150)]))
        j = {"alpha_deg": alpha, "a_m": float(rng.uniform(-0.4, 0.6)), "d_m": float(rng.uniform(-0.3, 0.4)),
             "theta_deg": float(rng.uniform(-90, 90)), "min_deg": -170.0, "max_deg": 170.0,
             "mass_kg": float(rng.uniform(1, 40)), "com_m": rng.uniform(-0.3, 0.3, 3).tolist()}
        joints.append(j)
    k = int(rng.integers(1, n - 1))          # a parallel pair: alpha = 0 on link k
    joints[k]["alpha_deg"] = 0.0
    if beta:
        joints[k]["beta_deg"] = 0.0
    return {"name": f"random-{convention}-{n}", "convention": convention, "joint": joints,
            "base": {"xyz_m": rng.uniform(-1, 1, 3).tolist(), "rpy_deg": rng.uniform(-40, 40, 3).tolist()},
            "tool": {"a_m": 0.05, "b_m": -0.03, "d_m": 0.12}, "gravity": {"direction": list(gravity)}}


ROBOTS = {
    "ys100": lambda: load_robot("ys100"),
    "ur10": lambda: load_robot("ur10"),
    "mdh4-beta": lambda: robot_from_dict(random_robot(4, 4, "mdh", True)),
    "dh5": lambda: robot_from_dict(random_robot(5, 5, "dh", False)),
    "dh6-beta-wall": lambda: robot_from_dict(random_robot(6, 6, "dh", True, gravity=(1.0, 0.0, 0.0))),
    "mdh7": lambda: robot_from_dict(random_robot(7, 7, "mdh", False, gravity=(0.0, 0.0, 1.0))),
    "track (mdh, prismatic joint 1)": lambda: robot_from_dict(ARM4_TRACK),
    "column (dh, prismatic joint 2)": lambda: robot_from_dict(ARM_COLUMN),
}


def urdf_file(tmp_path, text: str, name: str = "robot.urdf") -> str:
    path = tmp_path / name
    path.write_text(text)
    return str(path)


def yourdfpy_fk(path: str, q: np.ndarray, tip: str, frame: str | None = None, names=None) -> np.ndarray:
    """Positions of ``tip`` in ``frame`` (default root) by yourdfpy, one row per configuration."""
    u = yourdfpy.URDF.load(path, load_meshes=False)
    out = []
    for row in q:
        u.update_cfg(dict(zip(names, row)) if names else row)
        out.append(u.get_transform(tip, frame)[:3, 3])
    return np.array(out)


def yourdfpy_torques(path: str, q: np.ndarray, names: list[str]) -> np.ndarray:
    """Gravity torques at the named joints: weights of every link below each joint, g = -9.81 z of the root."""
    u = yourdfpy.URDF.load(path, load_meshes=False)
    below = {}
    for name in names:
        links, stack = set(), [u.joint_map[name].child]
        while stack:
            link = stack.pop()
            links.add(link)
            stack += [j.child for j in u.robot.joints if j.parent == link]
        below[name] = links
    g = np.array([0.0, 0.0, -9.81])
    out = []
    for row in q:
        u.update_cfg(dict(zip(names, row)))
        tau = []
        for name in names:
            j = u.joint_map[name]
            T = u.get_transform(j.child)
            axis, origin = T[:3, :3] @ (j.axis / np.linalg.norm(j.axis)), T[:3, 3]
            moment = np.zeros(3)
            for link in below[name]:
                inertial = u.link_map[link].inertial
                if inertial is not None and inertial.mass:
                    com = (u.get_transform(link) @ inertial.origin)[:3, 3]
                    # a prismatic joint carries the weights' force along its axis, a revolute one their moment
                    moment += (inertial.mass * g if j.type == "prismatic"
                               else np.cross(com - origin, inertial.mass * g))
            tau.append(axis @ moment)
        out.append(tau)
    return np.array(out)


# --- export: the URDF of a calibration has the calibration's forward kinematics ----------------


@pytest.mark.parametrize("seed", SEEDS[:2])
@pytest.mark.parametrize("robot_name", list(ROBOTS))
def test_exported_calibration_has_its_forward_kinematics(tmp_path, robot_name, seed):
    robot = ROBOTS[robot_name]()
    effects = Effects(length_sigma=1e-3, angle_sigma=math.radians(0.2), base_xyz=(1.5, -2.0, 0.3),
                      base_rpy=(0.1, -0.2, 2.0))
    data, truth = simulate(robot, 40, effects, seed=seed, floor_z=None)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        cal = calibrate(robot, data, "kinematic")
    path = urdf_file(tmp_path, robot_to_urdf(cal))
    val, _ = simulate(robot, 15, truth=truth, seed=seed + 100, floor_z=None)
    ref = yourdfpy_fk(path, val.q, "tool_point", "measurement_frame")
    assert np.abs(ref - cal.predict(val)).max() < TOL_M
    # the links are the calibrated ones: in the robot's own base frame the nominal URDF is elsewhere
    nominal = urdf_file(tmp_path, robot_to_urdf(robot), "nominal.urdf")
    shift = yourdfpy_fk(path, val.q, "tool_point", "base_link") - yourdfpy_fk(nominal, val.q, "tool_point", "base_link")
    assert np.abs(shift).max() > 1e-4


def test_mimic_coupling_is_exported(tmp_path):
    doc = random_robot(3, 5, "mdh", True)
    doc["joint"][4]["coupling"] = [0, 0, -0.5, 0, 0]
    doc["joint"][4]["coupling_offset_deg"] = 12.0
    robot = robot_from_dict(doc)
    path = urdf_file(tmp_path, robot_to_urdf(robot))
    q = sample_poses(robot, 12, np.random.default_rng(0), floor_z=None)
    names = [f"joint_{i}" for i in range(1, 5)]      # joint_5 follows joint_3: not actuated
    ref = yourdfpy_fk(path, q[:, :4], "tool_point", "measurement_frame", names)
    assert np.abs(ref - Model(robot, "nominal").predict(q)).max() < TOL_M
    back = robot_from_urdf(path)
    assert back.joints[4].coupling.tolist() == [0, 0, -0.5, 0, 0]
    assert back.joints[4].coupling_offset == pytest.approx(math.radians(12.0), abs=1e-15)


@pytest.mark.parametrize("robot_name,what", [("hh800", "loop"), ("hh800-coupling", "coupling of joint 3")])
def test_what_urdf_cannot_carry_is_refused(robot_name, what):
    robot = load_robot("hh800")
    if robot_name == "hh800-coupling":
        robot = replace(robot, loop=None)
    with pytest.raises(ModelError, match=what):
        robot_to_urdf(robot)


# --- import: a URDF read back has the same forward kinematics and gravity torques ----------------


@pytest.mark.parametrize("robot_name", list(ROBOTS))
def test_nominal_robot_round_trip(tmp_path, robot_name):
    robot = ROBOTS[robot_name]()
    path = urdf_file(tmp_path, robot_to_urdf(robot))
    back = robot_from_urdf(path)
    names = [f"joint_{i}" for i in range(1, robot.n + 1)]
    q = sample_poses(robot, 20, np.random.default_rng(1), floor_z=None)
    # tool point: casadical (original, measurement frame; read back, root frame) against yourdfpy
    assert np.abs(yourdfpy_fk(path, q, "tool_point", "measurement_frame") - Model(robot, "nominal").predict(q)
                  ).max() < TOL_M
    assert np.abs(yourdfpy_fk(path, q, "tool_point") - Model(back, "nominal").predict(q)).max() < TOL_M
    # gravity torques: original, read back and yourdfpy's link poses agree
    tau = Model(robot, "nominal").torques(q, cov=np.zeros((len(q), 1)))
    scale = np.abs(tau).max()
    assert np.abs(Model(back, "nominal").torques(q) - tau).max() < 1e-9 * scale
    assert np.abs(yourdfpy_torques(path, q, names) - tau).max() < 1e-9 * scale
    assert back.convention == "mdh" and back.n == robot.n
    assert [j.mass for j in back.joints] == pytest.approx([j.mass for j in robot.joints], rel=1e-12)
    np.testing.assert_allclose(np.degrees(back.limits), np.degrees(robot.limits), atol=1e-9)
    assert back.prismatic == robot.prismatic         # a linear axis is read back as one
    # beta exactly where consecutive axes are (nearly) parallel; no link longer than the robot's reach
    frames = yourdfpy.URDF.load(path, load_meshes=False)
    axes = [np.array([0.0, 0.0, 1.0])] + [frames.get_transform(f"link_{i}", "world")[:3, 2]
                                          for i in range(1, robot.n + 1)]
    for i, j in enumerate(back.joints, start=1):
        parallel = abs(axes[i - 1] @ axes[i]) >= math.cos(math.radians(PARALLEL_TOL_DEG))
        assert (j.beta is not None) == parallel, (i, j)
    reach = sum(abs(j.a) + abs(j.d) for j in robot.joints) + np.abs(robot.tool).sum() + np.abs(robot.base_xyz).sum()
    assert max(max(abs(j.a), abs(j.d)) for j in back.joints) <= reach


def test_calibrated_urdf_reads_back_with_beta(tmp_path):
    """A calibration tilts parallel axes slightly: read back, they stay Hayati links, not a far common normal."""
    robot = load_robot("ur10")
    data, truth = simulate(robot, 40, Effects(angle_sigma=math.radians(0.3)), seed=4, floor_z=None)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        cal = calibrate(robot, data, "kinematic")
    path = urdf_file(tmp_path, robot_to_urdf(cal))
    back = robot_from_urdf(path)
    assert [j.beta is not None for j in back.joints] == [True, False, True, True, False, False]
    assert max(max(abs(j.a), abs(j.d)) for j in back.joints) < 1.0
    q = sample_poses(robot, 15, np.random.default_rng(2), floor_z=None)
    assert np.abs(yourdfpy_fk(path, q, "tool_point") - Model(back, "nominal").predict(q)).max() < TOL_M


UR10_ROS = """<?xml version="1.0"?>
<!-- UR10 in the style of the classic ROS description: axes along y, rotated joint origins,
     fixed joints, two leaves (ee_link, tool0) on the last link and inertials -->
<robot name="ur10_ros_style">
  <link name="world"/>
  <joint name="world_joint" type="fixed">
    <parent link="world"/><child link="base_link"/><origin xyz="0 0 0" rpy="0 0 0"/>
  </joint>
  <link name="base_link">
    <inertial><mass value="4.0"/><origin xyz="0 0 0"/><inertia ixx="0.006" iyy="0.006" izz="0.006"/></inertial>
  </link>
  <joint name="shoulder_pan_joint" type="revolute">
    <parent link="base_link"/><child link="shoulder_link"/>
    <origin xyz="0 0 0.1273" rpy="0 0 0"/><axis xyz="0 0 1"/>
    <limit lower="-6.2832" upper="6.2832" effort="330" velocity="2.16"/>
  </joint>
  <link name="shoulder_link">
    <inertial><mass value="7.778"/><origin xyz="0 0 0"/><inertia ixx="0.03" iyy="0.03" izz="0.02"/></inertial>
  </link>
  <joint name="shoulder_lift_joint" type="revolute">
    <parent link="shoulder_link"/><child link="upper_arm_link"/>
    <origin xyz="0 0.220941 0" rpy="0 1.570796326794897 0"/><axis xyz="0 1 0"/>
    <limit lower="-6.2832" upper="6.2832" effort="330" velocity="2.16"/>
  </joint>
  <link name="upper_arm_link">
    <inertial><mass value="12.93"/><origin xyz="0 0 0.306" rpy="0.3 0 0"/><inertia ixx="0.4" iyy="0.4" izz="0.03"/></inertial>
  </link>
  <joint name="elbow_motor_joint" type="fixed">
    <parent link="upper_arm_link"/><child link="elbow_motor"/><origin xyz="0.02 -0.1 0.6" rpy="0.2 0.1 0"/>
  </joint>
  <link name="elbow_motor">
    <inertial><mass value="2.5"/><origin xyz="0 0.01 0.03"/><inertia ixx="0.01" iyy="0.01" izz="0.01"/></inertial>
  </link>
  <joint name="elbow_joint" type="revolute">
    <parent link="upper_arm_link"/><child link="forearm_link"/>
    <origin xyz="0 -0.1719 0.612" rpy="0 0 0"/><axis xyz="0 1 0"/>
    <limit lower="-3.1416" upper="3.1416" effort="150" velocity="3.15"/>
  </joint>
  <link name="forearm_link">
    <inertial><mass value="3.87"/><origin xyz="0 0 0.28615"/><inertia ixx="0.1" iyy="0.1" izz="0.01"/></inertial>
  </link>
  <joint name="wrist_1_joint" type="revolute">
    <parent link="forearm_link"/><child link="wrist_1_link"/>
    <origin xyz="0 0 0.5723" rpy="0 1.570796326794897 0"/><axis xyz="0 1 0"/>
    <limit lower="-6.2832" upper="6.2832" effort="54" velocity="3.2"/>
  </joint>
  <link name="wrist_1_link">
    <inertial><mass value="1.96"/><origin xyz="0 0.01 0"/><inertia ixx="0.005" iyy="0.005" izz="0.004"/></inertial>
  </link>
  <joint name="wrist_2_joint" type="revolute">
    <parent link="wrist_1_link"/><child link="wrist_2_link"/>
    <origin xyz="0 0.1149 0" rpy="0 0 0"/><axis xyz="0 0 1"/>
    <limit lower="-6.2832" upper="6.2832" effort="54" velocity="3.2"/>
  </joint>
  <link name="wrist_2_link">
    <inertial><mass value="1.96"/><origin xyz="0 0 0.01"/><inertia ixx="0.005" iyy="0.005" izz="0.004"/></inertial>
  </link>
  <joint name="wrist_3_joint" type="continuous">
    <parent link="wrist_2_link"/><child link="wrist_3_link"/>
    <origin xyz="0 0 0.1157" rpy="0 0 0"/><axis xyz="0 1 0"/>
  </joint>
  <link name="wrist_3_link">
    <inertial><mass value="0.202"/><origin xyz="0 0.07 0"/><inertia ixx="0.0005" iyy="0.0005" izz="0.0005"/></inertial>
  </link>
  <joint name="ee_fixed_joint" type="fixed">
    <parent link="wrist_3_link"/><child link="ee_link"/><origin xyz="0 0.0922 0" rpy="0 0 1.570796326794897"/>
  </joint>
  <link name="ee_link"/>
  <joint name="tool0_joint" type="fixed">
    <parent link="wrist_3_link"/><child link="tool0"/><origin xyz="0 0.0922 0" rpy="-1.570796326794897 0 0"/>
  </joint>
  <link name="tool0">
    <inertial><mass value="0.8"/><origin xyz="0.01 0 0.05"/><inertia ixx="0.001" iyy="0.001" izz="0.001"/></inertial>
  </link>
</robot>
"""
UR10_JOINTS = ["shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint", "wrist_1_joint", "wrist_2_joint",
               "wrist_3_joint"]


def test_hand_written_urdf(tmp_path):
    path = urdf_file(tmp_path, UR10_ROS)
    with pytest.raises(RobotFileError, match="branches: leaves ee_link, tool0"):
        robot_from_urdf(path)
    robot = robot_from_urdf(path, tip="tool0", tool=(0.01, -0.02, 0.093))
    q = np.random.default_rng(3).uniform(-3, 3, (25, 6))
    # tool point: yourdfpy's tool0 frame plus the offset
    u = yourdfpy.URDF.load(path, load_meshes=False)
    ref = []
    for row in q:
        u.update_cfg(dict(zip(UR10_JOINTS, row)))
        ref.append((u.get_transform("tool0") @ [0.01, -0.02, 0.093, 1.0])[:3])
    model = Model(robot, "nominal")
    assert np.abs(np.array(ref) - model.predict(q)).max() < TOL_M
    # gravity torques from the inertials (elbow_motor is merged into link 2, tool0 into link 6)
    tau = yourdfpy_torques(path, q, UR10_JOINTS)
    assert np.abs(model.torques(q) - tau).max() < 1e-9 * np.abs(tau).max()
    assert [round(j.mass, 9) for j in robot.joints] == [7.778, 12.93 + 2.5, 3.87, 1.96, 1.96, 0.202 + 0.8]
    np.testing.assert_allclose(np.degrees(robot.limits[5]), [-180, 180])        # continuous
    np.testing.assert_allclose(robot.limits[0], [-6.2832, 6.2832])


def test_hand_written_ur10_is_the_manufacturers_dh_table(tmp_path):
    """Independent of yourdfpy: the ROS-style UR10 equals ur10.toml's DH table up to one rigid transform."""
    robot = robot_from_urdf(urdf_file(tmp_path, UR10_ROS), tip="tool0")
    dh = replace(load_robot("ur10"), tool=np.zeros(3))
    q = np.random.default_rng(5).uniform(-3, 3, (40, 6))
    a, b = Model(robot, "nominal").predict(q), Model(dh, "nominal").predict(q)
    T = align(a, b)
    assert np.abs(a @ T[:3, :3].T + T[:3, 3] - b).max() < TOL_M


MIMIC = """<robot name="gripper-arm">
  <link name="root"/>
  <link name="l1"><inertial><origin xyz="0.1 0 0.2"/><mass value="5"/></inertial></link>
  <link name="l2"><inertial><origin xyz="0.3 0.05 0" rpy="0 0.4 0"/><mass value="3"/></inertial></link>
  <link name="l3"><inertial><origin xyz="0 0.2 0"/><mass value="2"/></inertial></link>
  <link name="l4"><inertial><origin xyz="0 0 0.1"/><mass value="1"/></inertial></link>
  <link name="tip"/>
  <joint name="j1" type="revolute"><parent link="root"/><child link="l1"/>
    <origin xyz="0.1 0.2 0.3" rpy="0.1 0.2 0.3"/><axis xyz="0 0 1"/><limit lower="-3" upper="3" effort="1" velocity="1"/></joint>
  <joint name="j2" type="revolute"><parent link="l1"/><child link="l2"/>
    <origin xyz="0.05 0 0.4" rpy="1.2 0 0.5"/><axis xyz="1 1 0"/><limit lower="-2" upper="2" effort="1" velocity="1"/></joint>
  <joint name="j3" type="revolute"><parent link="l2"/><child link="l3"/>
    <origin xyz="0.6 0 0" rpy="0 0 0.02"/><axis xyz="1 1 0.01"/><limit lower="-2" upper="2" effort="1" velocity="1"/></joint>
  <joint name="j4" type="revolute"><parent link="l3"/><child link="l4"/>
    <origin xyz="0 0.5 0" rpy="0.3 -0.6 0"/><axis xyz="0 -1 0"/><limit lower="-2" upper="2" effort="1" velocity="1"/>
    <mimic joint="j2" multiplier="-0.5" offset="0.2"/></joint>
  <joint name="flange" type="fixed"><parent link="l4"/><child link="tip"/><origin xyz="0.1 0.1 0.2" rpy="0 1 0"/></joint>
</robot>
"""


def test_mimic_joint_becomes_a_coupling(tmp_path):
    path = urdf_file(tmp_path, MIMIC)
    robot = robot_from_urdf(path)
    assert robot.n == 4 and robot.joints[3].coupling.tolist() == [0, -0.5, 0, 0]
    assert robot.joints[2].beta is not None     # axes of j2 and j3 are 0.4 deg apart: Hayati
    q = np.random.default_rng(6).uniform(-1.5, 1.5, (20, 4))   # q4 is not read: the coupling drives joint 4
    ref = yourdfpy_fk(path, q[:, :3], "tip", names=["j1", "j2", "j3"])
    model = Model(robot, "nominal")
    assert np.abs(ref - model.predict(q)).max() < TOL_M
    # reference torques with the mimic joint at the angle it follows; the drives carry them by virtual work:
    # j2's drive turns j4 too (by -0.5 of its angle), so it carries tau2 - 0.5 tau4, and j4's reading drives nothing
    full = np.column_stack([q[:, :3], -0.5 * q[:, 1] + 0.2])
    tau_ref = yourdfpy_torques(path, full, ["j1", "j2", "j3", "j4"])
    drives = tau_ref @ np.array([[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, -0.5, 0, 0]], float)
    assert np.abs(drives[:, 3]).max() == 0 and np.abs(tau_ref[:, 3]).max() > 0.5
    assert np.abs(model.torques(q) - drives).max() < 1e-9 * np.abs(tau_ref).max()


CALIBRATED = {
    # the URDF carries no payload: the data give it per row
    "ys100": lambda: load_robot("ys100"),
    # with the tool point on the flange axis the nominal is degenerate (theta6 has no effect) and the
    # DH and MDH models prune different parameters there; off the axis both are complete
    "ur10-tool-off-axis": lambda: replace(load_robot("ur10"), tool=np.array([0.05, -0.03, 0.093])),
    "mdh4-beta": ROBOTS["mdh4-beta"],
}


@pytest.mark.parametrize("seed", SEEDS[:2])
@pytest.mark.parametrize("robot_name", list(CALIBRATED))
def test_calibration_with_the_urdf_robot_equals_the_toml_robot(tmp_path, robot_name, seed):
    """Same data, same model spec: the same calibrated predictions and stiffness.

    The YS100 read back has the TOML's own structure (MDH, beta on links 1 and 3) and agrees to
    rounding; the others differ in which parameters calibrate() fixes as redundant at nominal (a
    first-order test), which leaves differences of second order: measured up to 0.5 um, 1/40 of the
    simulated noise.
    """
    robot = CALIBRATED[robot_name]()
    back = robot_from_urdf(urdf_file(tmp_path, robot_to_urdf(robot)))
    effects = Effects(stiffness={2: 8e5}, base_xyz=(0.4, 2.0, -0.5), base_rpy=(0.0, 0.1, -1.0))
    payload = np.random.default_rng(seed).choice([0.0, 110.0], 50)
    data, truth = simulate(robot, 50, effects, seed=seed, floor_z=None, payload_kg=payload)
    val, _ = simulate(robot, 30, truth=truth, seed=seed + 50, floor_z=None, payload_kg=50.0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        a = calibrate(robot, data, "kinematic+compliance[2]")
        b = calibrate(back, data, "kinematic+compliance[2]")
    assert np.abs(a.predict(val) - b.predict(val)).max() < 1e-6
    assert abs(a.calibration.rms_mm - b.calibration.rms_mm) < 1e-4
    c_a, c_b = a.parameters["c2"], b.parameters["c2"]
    assert abs(c_a.value - c_b.value) < 0.05 * c_a.std
    assert abs(1 / c_a.value - 8e5) < 4 * c_a.std / c_a.value ** 2      # and the stiffness is found


# --- bad URDFs: one line naming the file, the line and the element --------------------------------

LINK = '<link name="{}"/>'
REV = ('<joint name="{n}" type="revolute"><parent link="{p}"/><child link="{c}"/>'
       '<origin xyz="0 0 0.3" rpy="0 0 0"/><axis xyz="0 0 1"/><limit lower="-1" upper="1" effort="1" velocity="1"/></joint>')


def arm(*extra: str, joints: str | None = None) -> str:
    body = "".join(LINK.format(x) for x in ("a", "b", "c"))
    body += joints if joints is not None else REV.format(n="j1", p="a", c="b") + REV.format(n="j2", p="b", c="c")
    return '<?xml version="1.0"?>\n<robot name="bad">\n' + body + "\n" + "\n".join(extra) + "\n</robot>\n"


BAD = {
    "not-xml": ("<robot name='x'><link name='a'></robot>", "not valid XML"),
    "not-urdf": ("<?xml version='1.0'?><sdf version='1.6'/>", "<sdf>, a URDF's is <robot>"),
    "no-revolute": (arm(joints='<joint name="f" type="fixed"><parent link="a"/><child link="b"/></joint>'
                             '<joint name="g" type="fixed"><parent link="b"/><child link="c"/></joint>'),
                    "no revolute or continuous joint"),
    "two-parents": (arm(REV.format(n="j3", p="a", c="c")), "joint 'j3': link 'c' is already the child"),
    "cycle": (arm(joints=REV.format(n="j1", p="a", c="b") + REV.format(n="j2", p="b", c="c")
                  + REV.format(n="j3", p="c", c="a")), "closed loop"),
    "prismatic": (arm(joints=REV.format(n="j1", p="a", c="b")
                       + REV.format(n="slide", p="b", c="c").replace("revolute", "prismatic")
                       .replace('lower="-1" upper="1" ', "")),
                  "joint 'slide': a prismatic joint needs <limit lower=... upper=...> (metres)"),
    "prismatic-mimic": (arm(joints=REV.format(n="j1", p="a", c="b").replace("revolute", "prismatic")
                             + REV.format(n="j2", p="b", c="c").replace("</joint>", '<mimic joint="j1"/></joint>')),
                        "joint 'j2': <mimic> couples 'j1', a prismatic joint"),
    "planar": (arm(joints=REV.format(n="j1", p="a", c="b")
                    + REV.format(n="flat", p="b", c="c").replace("revolute", "planar")),
               "joint 'flat': is planar"),
    "zero-axis": (arm(joints=REV.format(n="j1", p="a", c="b")
                       + REV.format(n="j2", p="b", c="c").replace('axis xyz="0 0 1"', 'axis xyz="0 0 0"')),
                  "joint 'j2': <axis> has zero length"),
    "nan-origin": (arm(joints=REV.format(n="j1", p="a", c="b").replace('xyz="0 0 0.3"', 'xyz="0 nan 0.3"')
                        + REV.format(n="j2", p="b", c="c")), "joint 'j1': <origin> has a non-finite number"),
    "inf-mass": (arm().replace('<link name="b"/>', '<link name="b"><inertial><mass value="inf"/></inertial></link>'),
                 "link 'b': <inertial> mass must be a finite number"),
    "negative-mass": (arm().replace('<link name="b"/>', '<link name="b"><inertial><mass value="-2"/></inertial></link>'),
                      "link 'b': <inertial> mass must be a finite number >= 0"),
    "not-a-number": (arm(joints=REV.format(n="j1", p="a", c="b").replace('rpy="0 0 0"', 'rpy="0 zero 0"')
                          + REV.format(n="j2", p="b", c="c")), "<joint name='j1'>: cannot read it"),
    "no-parent": (arm(joints=REV.format(n="j1", p="a", c="b")
                       + REV.format(n="j2", p="b", c="c").replace('<parent link="b"/>', "")),
                  "<joint name='j2'>: missing a required element"),
    "unknown-link": (arm(joints=REV.format(n="j1", p="a", c="b") + REV.format(n="j2", p="b", c="zz")),
                     "joint 'j2': its child link 'zz' is not defined"),
    "no-limit": (arm(joints=REV.format(n="j1", p="a", c="b")
                      + REV.format(n="j2", p="b", c="c").replace('lower="-1" upper="1" ', "")),
                 "joint 'j2': a revolute joint needs <limit"),
    "limits-reversed": (arm(joints=REV.format(n="j1", p="a", c="b")
                             + REV.format(n="j2", p="b", c="c").replace('lower="-1" upper="1"', 'lower="1" upper="-1"')),
                        "joint 'j2': lower limit 1.0 must be below upper limit -1.0"),
    "branching": (arm(LINK.format("d"), REV.format(n="j3", p="b", c="d")), "the chain branches: leaves c, d"),
    "mimic-off-chain": (arm(LINK.format("d"), '<joint name="f" type="fixed"><parent link="b"/><child link="d"/></joint>',
                            joints=REV.format(n="j1", p="a", c="b")
                            + REV.format(n="j2", p="b", c="c").replace("</joint>", '<mimic joint="f"/></joint>')),
                        "joint 'j2': <mimic> follows 'f', which is not a revolute joint of the chain"),
}


@pytest.mark.parametrize("case", list(BAD))
def test_bad_urdf_is_one_clear_line(tmp_path, case):
    text, expected = BAD[case]
    path = urdf_file(tmp_path, text, f"{case}.urdf")
    with pytest.raises(RobotFileError) as e:
        load_robot(path)
    message = str(e.value)
    assert expected in message and message.startswith(path) and "\n" not in message


def test_bad_urdf_row_and_tip(tmp_path):
    path = urdf_file(tmp_path, BAD["zero-axis"][0])
    with pytest.raises(RobotFileError, match=r"row 3"):      # the line of <joint name="j2">
        load_robot(path)
    good = urdf_file(tmp_path, arm(), "good.urdf")
    with pytest.raises(RobotFileError, match="no link named 'nosuch' .the tip link.; links: a, b, c"):
        robot_from_urdf(good, tip="nosuch")
    with pytest.raises(RobotFileError, match="link 'a' is not below link 'b'"):
        robot_from_urdf(good, base="b", tip="a")


def test_cli_bad_urdf_exits_2_with_one_line(tmp_path, capsys):
    import subprocess
    import sys
    path = urdf_file(tmp_path, BAD["prismatic"][0], "arm.urdf")
    r = subprocess.run([sys.executable, "-m", "casadical", "inspect", path], capture_output=True, text=True)
    assert r.returncode == 2 and "Traceback" not in r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and path in lines[0] and "'slide'" in lines[0]
    assert main(["inspect", urdf_file(tmp_path, BAD["not-xml"][0], "x.urdf")]) == 2
    assert len(capsys.readouterr().err.strip().splitlines()) == 1
    assert main(["inspect", urdf_file(tmp_path, arm(), "ok.urdf"), "--model", "kinematic", "--poses", "30"]) == 0


def test_cli_chooses_the_chain_of_a_urdf(tmp_path, capsys):
    """--urdf-tip/--urdf-tool pick the chain and the measured point; yourdfpy is the reference."""
    path = urdf_file(tmp_path, UR10_ROS)
    q = np.random.default_rng(5).uniform(-1.5, 1.5, (12, 6))
    poses = tmp_path / "poses.csv"
    poses.write_text("q1_deg,q2_deg,q3_deg,q4_deg,q5_deg,q6_deg\n"
                     + "".join(",".join(f"{v:.12f}" for v in np.degrees(row)) + "\n" for row in q))
    out = tmp_path / "xyz.csv"
    # the default chain branches: one line that names the leaves
    assert main(["predict", path, str(poses), "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "branches: leaves ee_link, tool0" in err[0]
    assert main(["predict", path, str(poses), "--out", str(out), "--urdf-tip", "tool0",
                 "--urdf-tool", "0.01,-0.02,0.093"]) == 0
    got = np.loadtxt(out, delimiter=",", skiprows=1)[:, -3:] / 1000
    u = yourdfpy.URDF.load(path, load_meshes=False)
    ref = []
    for row in np.radians(np.loadtxt(poses, delimiter=",", skiprows=1)):
        u.update_cfg(dict(zip(UR10_JOINTS, row)))
        ref.append((u.get_transform("tool0") @ [0.01, -0.02, 0.093, 1.0])[:3])
    assert np.abs(got - np.array(ref)).max() < 1e-6          # the CSV carries micrometres
    # the other tip, from another base link: a different chain, not the same numbers
    out2 = tmp_path / "xyz2.csv"
    assert main(["predict", path, str(poses), "--out", str(out2), "--urdf-tip", "ee_link",
                 "--urdf-base", "base_link"]) == 0
    assert np.abs(np.loadtxt(out2, delimiter=",", skiprows=1)[:, -3:] / 1000 - np.array(ref)).max() > 1e-3


@pytest.mark.parametrize("argv, expected", [
    (["inspect", "ur10", "--urdf-tip", "tool0"], "not one (give a .urdf file"),
    (["inspect", "{urdf}", "--urdf-tip", "nosuch"], "no link named 'nosuch'"),
    (["inspect", "{urdf}", "--urdf-tip", "tool0", "--urdf-tool", "0.1,0.2"], "three numbers"),
    (["inspect", "{urdf}", "--urdf-tip", "tool0", "--urdf-tool", "0.1,x,0"], "not a number"),
])
def test_cli_urdf_chain_errors_are_one_line(tmp_path, capsys, argv, expected):
    path = urdf_file(tmp_path, UR10_ROS)
    assert main([a.format(urdf=path) for a in argv]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert expected in err[-1] and "Traceback" not in "\n".join(err)


def test_cli_urdf_chain_options_refused_with_a_calibration(tmp_path, capsys):
    robot = load_robot("ur10")
    data, _ = simulate(robot, 40, Effects(), seed=3)
    csv = tmp_path / "poses.csv"
    data.write_csv(csv)
    cal = tmp_path / "cal.json"
    calibrate(robot, data, "kinematic", "lm", warn=False).save(cal)
    for argv in (["predict", str(cal), str(csv), "--out", str(tmp_path / "p.csv"), "--urdf-tip", "tool0"],
                 ["calibrate", str(cal), str(csv), "--model", "base", "--out", str(tmp_path / "c.json"),
                  "--urdf-base", "world", "--urdf-tool", "0,0,0.1"],
                 ["export", str(cal), "--table", str(tmp_path / "t.csv"), "--urdf-tip", "tool0"]):
        capsys.readouterr()
        assert main(argv) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and str(cal) in err[0] and "a calibration JSON already holds its robot" in err[0]
        assert not any(p.exists() for p in (tmp_path / "p.csv", tmp_path / "c.json", tmp_path / "t.csv"))


def test_every_command_that_reads_a_robot_takes_the_chain_options(capsys):
    """A command whose ROBOT (or MODEL, or CAL.json) may be a robot file takes --urdf-base/-tip/-tool; others not."""
    from casadical.cli import build_parser

    ap = build_parser()
    sub = next(a for a in ap._actions if a.dest == "command")
    chain = {"--urdf-base", "--urdf-tip", "--urdf-tool"}
    robots = set()
    for name, p in sub.choices.items():
        takes_robot = any("robot" in (a.help or "").lower() and "protocol" not in (a.help or "").lower()
                          for a in p._actions if not a.option_strings)
        options = {o for a in p._actions for o in a.option_strings}
        assert (chain <= options) == takes_robot, name
        assert not (chain & options) or chain <= options, name
        robots |= {name} if takes_robot else set()
    assert robots == {"inspect", "predict", "calibrate", "diagnose", "plan-poses", "candidates", "compare", "export",
                      "iso9283"}
    # a command that reads a calibration only: the options are unknown there (one line)
    assert main(["compensate", "cal.json", "targets.csv", "--out", "j.csv", "--urdf-tip", "tool0"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "unrecognized arguments: --urdf-tip tool0" in err[0]
