"""Robot TOML loading: built-ins, every kind of bad field, encodings and huge numbers."""

import copy
import math

import numpy as np
import pytest

from casadical import load_robot
from casadical.errors import RobotFileError
from casadical.robot import robot_from_dict
from tests.helpers.arms import ARMS, to_toml
from tests.helpers.cli import cli, one_error

GOOD = """
name = "two"
convention = "dh"
[[joint]]
alpha_deg = 90
a_m = 0.1
d_m = 0.2
[[joint]]
alpha_deg = 0
a_m = 0.5
d_m = 0
mass_kg = 3.0
com_m = [0.1, 0, 0]
[tool]
d_m = 0.1
"""


@pytest.mark.parametrize("name,n", [("ys100", 6), ("hh800", 6), ("ur10", 6), ("YS100", 6)])
def test_builtins_load(name, n):
    r = load_robot(name)
    assert r.n == n and r.payload_mass >= 0


def test_good_file_and_units(write):
    r = load_robot(write("r.toml", GOOD))
    assert r.convention == "dh" and r.n == 2
    assert r.joints[0].alpha == pytest.approx(math.pi / 2)
    assert r.joints[0].min == pytest.approx(-math.pi)   # default limits
    assert r.joints[0].beta is None and r.loop is None


@pytest.mark.parametrize("edit,where,what", [
    (lambda s: s.replace("a_m = 0.1", "a_m = \"0.1\""), "joint[1].a_m", "must be a number"),
    (lambda s: s.replace("a_m = 0.1\n", ""), "joint[1].a_m", "missing required key"),
    (lambda s: s.replace("alpha_deg = 90", "alpha_deg = 90\nalfa_deg = 3"), "joint[1].alfa_deg", "unknown key"),
    (lambda s: s.replace("mass_kg = 3.0", "mass_kg = -3.0"), "joint[2].mass_kg", "negative"),
    (lambda s: s.replace("com_m = [0.1, 0, 0]", "com_m = [0.1, 0]"), "joint[2].com_m", "list of 3"),
    (lambda s: s.replace('convention = "dh"', 'convention = "DHX"'), "convention", "mdh"),
    (lambda s: s.replace('name = "two"\n', ""), "name", "missing required key"),
    (lambda s: s + "\n[payload]\nmass = 3\n", "payload.mass", "unknown key"),
    (lambda s: s + "\n[gravity]\ndirection = [0, 0, 0]\n", "gravity.direction", "zero"),
    (lambda s: s + "\n[loop]\njoint = 9\ncrank_m = 1\ncoupler_m = 1\nrocker_m = 1\n", "loop.joint", "joint number"),
    (lambda s: s.replace("d_m = 0.2", "d_m = 0.2\nmin_deg = 10\nmax_deg = -10"), "joint[1].min_deg", "below"),
])
def test_bad_fields_name_file_table_key(write, edit, where, what):
    path = write("bad.toml", edit(GOOD))
    with pytest.raises(RobotFileError) as e:
        load_robot(path)
    msg = str(e.value)
    assert path in msg and repr(where) in msg and what in msg
    assert "\n" not in msg


def test_unknown_robot_and_bad_toml(write):
    with pytest.raises(RobotFileError, match="built-in"):
        load_robot("ys1000")
    with pytest.raises(RobotFileError, match="not valid TOML"):
        load_robot(write("x.toml", "name = \n"))


# --- robot TOML -----------------------------------------------------------------------------------


def test_robot_toml_encodings(tmp_path, capsys):
    text = to_toml(ARMS["arm4"])
    (tmp_path / "bom.toml").write_bytes(b"\xef\xbb\xbf" + text.encode())
    assert load_robot(tmp_path / "bom.toml").n == 4
    (tmp_path / "latin.toml").write_bytes(text.replace("palletiser", "palletis\u00e9r").encode("latin-1"))
    with pytest.raises(RobotFileError, match="not UTF-8"):
        load_robot(tmp_path / "latin.toml")
    code, _, err = cli(capsys, "inspect", tmp_path / "latin.toml", "--poses", "5")
    assert code == 2
    one_error(err, "latin.toml", "not UTF-8", "0xe9")


@pytest.mark.parametrize("key,value,match", [
    ("a_m", "1e400", "must be finite"),
    ("a_m", "99999999999999999999999999999", "metres"),
    ("a_m", "1e300", "metres"),
    ("mass_kg", "1e308", "kg"),
    ("max_deg", "1e10", "degrees"),
    ("max_deg", "9" * 400, "must be finite"),
])
def test_robot_toml_huge_numbers(tmp_path, key, value, match):
    lines = to_toml(ARMS["arm4"]).splitlines()
    start = [i for i, line in enumerate(lines) if line == "[[joint]]"][2]       # joint 3
    k = next(i for i in range(start, len(lines)) if lines[i].startswith(key + " ="))
    lines[k] = f"{key} = {value}"
    (tmp_path / "r.toml").write_text("\n".join(lines))
    with pytest.raises(RobotFileError, match=match) as e:
        load_robot(tmp_path / "r.toml")
    assert e.value.column == f"joint[3].{key}"


@pytest.mark.parametrize("direction", [[0, 0, -1e308], [1e308, 1e308, 0], [0, 0, -1e-320]])
def test_gravity_of_any_finite_size(direction):
    doc = copy.deepcopy(ARMS["arm5"])
    doc["gravity"] = {"direction": direction}
    g = robot_from_dict(doc).gravity
    d = np.array(direction, dtype=float) / np.max(np.abs(direction))
    np.testing.assert_allclose(g, 9.81 * d / np.linalg.norm(d))


TRACK = """
name = "on a track"
[[joint]]
type = "prismatic"
alpha_deg = -90
a_m = 0.0
d_m = 0.3
theta_deg = 90
min_mm = 0
max_mm = 4000
mass_kg = 80
[[joint]]
alpha_deg = 90
a_m = 0.1
d_m = 0.4
coupling = [0, 1]
[tool]
d_m = 0.1
"""


def test_prismatic_joint_units_and_round_trip(write):
    from casadical.robot import robot_to_dict

    r = load_robot(write("t.toml", TRACK))
    assert r.prismatic == (True, False) and r.units == ["mm", "deg"]
    assert r.q_columns == ["q1_mm", "q2_deg"]
    assert r.joints[0].min == 0.0 and r.joints[0].max == pytest.approx(4.0)     # metres
    assert r.joints[0].theta == pytest.approx(math.pi / 2)
    np.testing.assert_allclose(r.file_limits[0], [0.0, 4000.0])
    np.testing.assert_allclose(r.from_file_units([[1500.0, 90.0]]), [[1.5, math.pi / 2]])
    back = robot_from_dict(robot_to_dict(r))
    assert back.prismatic == r.prismatic and back.joints[0].max == pytest.approx(4.0)


@pytest.mark.parametrize("edit,where,what", [
    (lambda s: s.replace("min_mm = 0", "min_deg = 0"), "joint[1].min_deg", "millimetres"),
    (lambda s: s.replace("min_mm = 0\n", ""), "joint[1].min_mm", "missing required key"),
    (lambda s: s.replace("max_mm = 4000", "max_mm = -1"), "joint[1].min_mm", "below"),
    (lambda s: s.replace("d_m = 0.4", "d_m = 0.4\nmin_mm = 0"), "joint[2].min_mm", "degrees"),
    (lambda s: s.replace('type = "prismatic"', 'type = "linear"'), "joint[1].type", "prismatic"),
    (lambda s: s.replace("coupling = [0, 1]", "coupling = [1, 1]"), "joint[2].coupling", "revolute readings only"),
    (lambda s: s.replace("mass_kg = 80", "mass_kg = 80\ncoupling = [1, 0]"), "joint[1].coupling", "coupled"),
    (lambda s: s.replace("max_mm = 4000", "max_mm = 4e7"), "joint[1].max_mm", "millimetres"),
])
def test_bad_prismatic_fields_one_line(write, edit, where, what):
    path = write("bad.toml", edit(TRACK))
    with pytest.raises(RobotFileError) as e:
        load_robot(path)
    msg = str(e.value)
    assert path in msg and repr(where) in msg and what in msg and "\n" not in msg
