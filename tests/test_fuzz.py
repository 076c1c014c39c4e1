"""Fuzzing the readers: random bytes and mutated valid files, only casadical errors may escape.

The measurement CSV reader (with the plausibility checks behind it), the
robot TOML loader and the calibration JSON loader get random bytes and valid
files with characters, cells, lines and keys deleted, duplicated or
altered, huge numbers, NaN, a byte-order mark, bytes that are not UTF-8.
Whatever they make of it, the only exceptions allowed out are
:class:`casadical.errors.CasadicalError` subclasses (one line on the
command line); a file that reads must give finite numbers. ``pytest -m slow``
runs many more examples.
"""

import json
import math
import warnings

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from casadical import calibrate, load_calibration, load_robot
from casadical.data import Effects, Measurements, check_poses, simulate
from casadical.errors import CasadicalError
from casadical.robot import BUILTIN_DIR, robot_from_dict
from tests.helpers.arms import ARMS, to_toml

#: the default run: the same examples every time (no flaky CI); -m slow draws new ones
FAST = settings(max_examples=100, deadline=2000, database=None, derandomize=True,
                suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])
SLOW = settings(FAST, max_examples=3000, derandomize=False)

#: what a mutation inserts: numbers at the edges, words that look like numbers, separators, bad bytes
TOKENS = ["nan", "NaN", "inf", "-inf", "1e999", "-1e308", "1e308", "9" * 40, "0", "-0", "1e-320", "", " ",
          ",", ";", '"', "\n", "\r\n", "=", "[", "]", "{", "}", "[[joint]]", "true", "q0_deg", "q01_deg",
          "q7_deg", "q99999999999_deg", "x_mm", "#", "\ufeff", "\x00", "\xe9", "1,5", "0x10", "1_000"]

_robot = robot_from_dict(ARMS["arm4"], "arm4")
_data, _ = simulate(_robot, 20, Effects(stiffness={2: 5e5}), seed=0, floor_z=None)
_rows = zip(*[c.tolist() for c in _data.columns.values()])
CSV = "\n".join([",".join(_data.columns)] + [",".join(repr(v) for v in r) for r in list(_rows)[:8]])
with warnings.catch_warnings():
    warnings.simplefilter("ignore")
    CAL = calibrate(_robot, _data, "kinematic+compliance[2]").to_dict()
CAL.pop("uncertainty", None)   # large and never read back: mutations belong where the loader looks
TOMLS = [to_toml(ARMS["arm5"]), (BUILTIN_DIR / "hh800.toml").read_text()]


@st.composite
def text_mutations(draw, text: str) -> bytes:
    """``text`` with a few characters or lines deleted, duplicated or replaced, as bytes (maybe not UTF-8)."""
    s = text
    for _ in range(draw(st.integers(1, 4))):
        i = draw(st.integers(0, len(s)))
        j = min(len(s), i + draw(st.integers(0, 12)))
        op = draw(st.sampled_from(["delete", "duplicate", "insert", "replace", "line"]))
        if op == "delete":
            s = s[:i] + s[j:]
        elif op == "duplicate":
            s = s[:j] + s[i:j] + s[j:]
        elif op == "insert":
            s = s[:i] + draw(st.sampled_from(TOKENS)) + s[i:]
        elif op == "replace":
            s = s[:i] + draw(st.sampled_from(TOKENS) | st.text(max_size=3)) + s[j:]
        else:
            lines = s.split("\n")
            k = draw(st.integers(0, len(lines) - 1))
            if draw(st.booleans()):
                lines.insert(draw(st.integers(0, len(lines))), lines[k])
            else:
                lines.pop(k)
            s = "\n".join(lines)
    data = s.encode("utf-8", "surrogatepass")
    if draw(st.booleans()):
        data = data.replace("\xe9".encode(), b"\xe9")   # latin-1, not UTF-8
    return (b"\xef\xbb\xbf" if draw(st.booleans()) else b"") + data


@st.composite
def csv_cell_mutations(draw) -> bytes:
    """The measurement file with cells (header included) replaced, deleted or duplicated."""
    rows = [r.split(",") for r in CSV.split("\n")]
    for _ in range(draw(st.integers(1, 4))):
        r = draw(st.integers(0, len(rows) - 1))
        c = draw(st.integers(0, len(rows[r]) - 1))
        op = draw(st.sampled_from(["set", "delete", "duplicate", "row"]))
        if op == "set":
            rows[r][c] = draw(st.sampled_from(TOKENS) | st.floats().map(repr) | st.integers().map(str))
        elif op == "delete":
            del rows[r][c]
        elif op == "duplicate":
            rows[r].insert(c, rows[r][c])
        else:
            rows.insert(draw(st.integers(1, len(rows))), list(rows[r]))
    return "\n".join(",".join(r) for r in rows).encode("utf-8", "surrogatepass")


JSON_VALUES = st.recursive(
    st.none() | st.booleans() | st.integers(min_value=-(10 ** 400), max_value=10 ** 400) | st.floats()
    | st.text(max_size=8) | st.sampled_from(["kinematic", "kinematic+compliance[9]", "joint", "nominal"]),
    lambda inner: st.lists(inner, max_size=4) | st.dictionaries(st.text(max_size=6), inner, max_size=4),
    max_leaves=8)


@st.composite
def json_mutations(draw) -> bytes:
    """The calibration JSON with keys deleted or values replaced anywhere in its tree."""
    doc = json.loads(json.dumps(CAL))
    for _ in range(draw(st.integers(1, 3))):
        node, key = None, None
        cur = doc
        while isinstance(cur, (dict, list)) and cur and (node is None or draw(st.integers(0, 2))):
            keys = list(cur) if isinstance(cur, dict) else list(range(len(cur)))
            node, key = cur, draw(st.sampled_from(keys))
            cur = cur[key]
        if node is None:
            continue
        if isinstance(node, dict) and draw(st.booleans()):
            del node[key]
        else:
            node[key] = draw(JSON_VALUES)
    return json.dumps(doc, allow_nan=True).encode()


def _only_casadical_errors(call):
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UserWarning)
            return call()
    except CasadicalError as e:
        assert str(e) and "\n" not in str(e).strip(), repr(e)
        return None


def _read_csv(tmp_path, content: bytes):
    path = tmp_path / "fuzz.csv"
    path.write_bytes(content)

    def read():
        data = Measurements.read_csv(path, n_joints=4)
        assert np.isfinite(data.q_deg).all()
        check_poses(data, _robot)
        if data.has_positions:
            assert np.isfinite(data.xyz).all()
        return data
    _only_casadical_errors(read)


def _load_robot(tmp_path, content: bytes):
    path = tmp_path / "fuzz.toml"
    path.write_bytes(content)
    robot = _only_casadical_errors(lambda: load_robot(path))
    if robot is not None:
        assert np.isfinite(robot.limits).all() and np.isfinite(robot.gravity).all()
        assert math.isclose(float(np.linalg.norm(robot.gravity)), 9.81)


def _load_calibration(tmp_path, content: bytes):
    path = tmp_path / "fuzz.json"
    path.write_bytes(content)
    cal = _only_casadical_errors(lambda: load_calibration(path))
    if cal is not None:
        assert np.isfinite(cal.predict(_data)).all()


@FAST
@given(content=st.binary(max_size=600) | text_mutations(CSV) | csv_cell_mutations())
def test_fuzz_measurement_csv(tmp_path, content):
    _read_csv(tmp_path, content)


@FAST
@given(content=st.binary(max_size=600) | st.sampled_from(TOMLS).flatmap(text_mutations))
def test_fuzz_robot_toml(tmp_path, content):
    _load_robot(tmp_path, content)


@FAST
@given(content=st.binary(max_size=600) | text_mutations(json.dumps(CAL)) | json_mutations())
def test_fuzz_calibration_json(tmp_path, content):
    _load_calibration(tmp_path, content)


@pytest.mark.slow
@SLOW
@given(content=st.binary(max_size=2000) | text_mutations(CSV) | csv_cell_mutations())
def test_fuzz_measurement_csv_long(tmp_path, content):
    _read_csv(tmp_path, content)


@pytest.mark.slow
@SLOW
@given(content=st.binary(max_size=2000) | st.sampled_from(TOMLS).flatmap(text_mutations))
def test_fuzz_robot_toml_long(tmp_path, content):
    _load_robot(tmp_path, content)


@pytest.mark.slow
@SLOW
@given(content=st.binary(max_size=2000) | text_mutations(json.dumps(CAL)) | json_mutations())
def test_fuzz_calibration_json_long(tmp_path, content):
    _load_calibration(tmp_path, content)
