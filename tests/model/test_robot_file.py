"""Robot TOML loading: built-ins and every kind of bad field."""

import math

import pytest

from casadical import load_robot
from casadical.errors import RobotFileError

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
