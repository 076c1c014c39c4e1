"""Every command on robots with a linear axis: a four-axis arm on a 4 m track (MDH, joint 1 prismatic) and an
arm on a lifting column (DH, joint 2 prismatic), measured by the independent truth (tests/truth) with hidden
geometric errors, the track's own among them (its zero, d1, and its direction, alpha1 and theta1); the readings
of the linear axis in a ``qK_mm`` column."""

import json
import math
import warnings
from pathlib import Path

import numpy as np
import pytest

from casadical.data import Measurements
from casadical.loading import load_robot
from casadical.robot import PROBLEMS
from tests.helpers.arms import ARM4_TRACK, ARM_COLUMN, to_toml
from tests.helpers.cli import cli, one_error
from tests.truth import Arm, Effects, Session, TrueRobot, measure, sample

ARMS = {"track": (ARM4_TRACK, 1), "column": (ARM_COLUMN, 2)}


def ok(capsys, *args):
    code, out, err = cli(capsys, *args)
    assert code == 0, (args, err)
    return out


@pytest.fixture(scope="module", params=sorted(ARMS))
def arm(request, tmp_path_factory):
    """The robot file, 100 truth poses (calibration) and 60 more (validation), and the truth."""
    name = request.param
    doc, axis = ARMS[name]
    d = tmp_path_factory.mktemp(name)
    (d / "robot.toml").write_text(to_toml(doc))
    rng = np.random.default_rng(11)
    true = TrueRobot.draw(Arm.from_dict(doc), Effects(), rng)
    g = true.geometry            # the linear axis' own errors: its zero 3 mm off, its direction 1 mrad off
    g.d[axis - 1] += 3e-3
    g.alpha[axis - 1] += 1e-3
    g.theta[axis - 1] += 1e-3
    session = Session(base_xyz=(1.5, -0.5, 0.3), base_rpy=(0.0, 0.0, 0.6))
    measure(true, sample(true, 100, rng), rng, session=session, noise=20e-6).write_csv(d / "cal.csv")
    measure(true, sample(true, 60, rng), rng, session=session, noise=20e-6).write_csv(d / "val.csv")
    return name, axis, d


def test_split_inspect_and_the_column(arm, capsys):
    name, axis, d = arm
    header = (d / "cal.csv").read_text().splitlines()[0].split(",")
    assert f"q{axis}_mm" in header and f"q{axis}_deg" not in header
    ok(capsys, "split", d / "cal.csv", "-n", "70", "--out-cal", d / "a.csv", "--out-val", d / "b.csv")
    robot = load_robot(d / "robot.toml")
    a = Measurements.read_csv(d / "a.csv", robot=robot)
    assert len(a) == 70 and a.prismatic[axis - 1] and a.q[:, axis - 1].max() < 4.0     # metres
    out = ok(capsys, "inspect", d / "robot.toml", "--poses", "60", "--json")
    doc = json.loads(out)
    assert doc["n_joints"] == robot.n and doc["identifiability"]["rank"] > 6


def test_calibrate_recovers_the_axis_and_predicts(arm, capsys):
    name, axis, d = arm
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        ok(capsys, "calibrate", d / "robot.toml", d / "cal.csv", "--model", "kinematic", "--out", d / "cal.json")
        out = ok(capsys, "predict", d / "cal.json", d / "val.csv", "--out", d / "pred.csv")
        mean = float(out.split("mean ")[1].split()[0])
        assert mean < 0.06, out            # noise 0.02 mm per axis: the track's zero and direction are found
        out = ok(capsys, "predict", d / "robot.toml", d / "val.csv", "--out", d / "nominal.csv")
    pred = Measurements.read_csv(d / "pred.csv")
    assert f"q{axis}_mm" in pred.columns and np.isfinite(pred.xyz).all()


def test_diagnose_runs_and_names_nothing_on_the_axis(arm, capsys):
    name, axis, d = arm
    ok(capsys, "diagnose", d / "robot.toml", d / "cal.csv", "--validate", d / "val.csv", "--json", d / "report.json",
       "--max-harmonic", "4", "--max-rounds", "2", "--no-blackbox", "--quiet", "--out", d / "final.json")
    doc = json.loads((d / "report.json").read_text())
    assert doc["final"]["validation"]["mean_mm"] < 0.06, doc["final"]
    assert not [f for f in doc["findings"] if f.get("joint") == axis], doc["findings"]
    ok(capsys, "predict", d / "final.json", d / "val.csv", "--out", d / "pred2.csv")


def test_compensate_moves_the_linear_axis_too(arm, capsys):
    name, axis, d = arm
    val = Measurements.read_csv(d / "val.csv")
    targets = Measurements({c: val.columns[c] for c in val.q_columns + ["x_mm", "y_mm", "z_mm"]})
    rng = np.random.default_rng(2)
    targets.columns["x_mm"] = targets.columns["x_mm"] + rng.normal(0, 0.5, len(targets))
    targets.write_csv(d / "targets.csv")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        ok(capsys, "compensate", d / "cal.json", d / "targets.csv", "--out", d / "joints.csv", "--position-only")
    out = Measurements.read_csv(d / "joints.csv")
    assert f"q{axis}_mm" in out.columns and f"dq{axis}_mm" in out.columns and f"programmed_q{axis}_mm" in out.columns
    assert np.abs(out.columns[f"dq{axis}_mm"]).max() > 1e-3       # the axis moved (mm)
    # every row on its target but those near a singular configuration (a stretched arm), damped where the joints
    # would move more than 2 deg (a linear axis 2 mm) per mm of correction: a millimetre weighs as a degree
    residual = out.columns["residual_mm"]
    assert np.mean(residual < 1e-6) > 0.9 and residual.max() < 0.1, residual


def test_candidates_plan_poses(arm, capsys):
    name, axis, d = arm
    robot = load_robot(d / "robot.toml")
    ok(capsys, "candidates", d / "robot.toml", "-n", "150", "--floor-z", "none", "--out", d / "cand.csv")
    cand = Measurements.read_csv(d / "cand.csv", robot=robot)
    lim = robot.file_limits
    assert len(cand) == 150 and np.all((cand.q_deg >= lim[:, 0]) & (cand.q_deg <= lim[:, 1]))
    assert cand.q_deg[:, axis - 1].max() > 100.0        # millimetres
    ok(capsys, "plan-poses", d / "robot.toml", d / "cand.csv", "-m", "20", "--model", "kinematic",
       "--out", d / "sel.csv", "--json", d / "plan.json")
    sel = Measurements.read_csv(d / "sel.csv", robot=robot)
    assert len(sel) == 20
    # the design uses the axis' travel: its selected positions spread to the ends, wider than the candidates'
    assert np.std(sel.q_deg[:, axis - 1]) > 1.2 * np.std(cand.q_deg[:, axis - 1])


def test_bad_readings_are_one_line(arm, capsys):
    name, axis, d = arm
    text = (d / "val.csv").read_text()
    (d / "deg.csv").write_text(text.replace(f"q{axis}_mm", f"q{axis}_deg", 1))
    code, _, err = cli(capsys, "predict", d / "robot.toml", d / "deg.csv", "--out", d / "x.csv")
    assert code != 0
    one_error(err, "deg.csv", "row 1", f"'q{axis}_deg'", "prismatic", f"q{axis}_mm")
    lines = text.splitlines()
    row = lines[1].split(",")
    row[axis - 1] = "9000.0"                     # beyond the axis' max_mm
    (d / "far.csv").write_text("\n".join([lines[0], ",".join(row)] + lines[2:]) + "\n")
    code, _, err = cli(capsys, "calibrate", d / "robot.toml", d / "far.csv", "--model", "kinematic",
                       "--out", d / "x.json")
    assert code != 0
    one_error(err, "far.csv", "row 2", f"'q{axis}_mm'", "9000 mm", "max_mm")
    rev = f"q{axis + 1}_deg"
    (d / "mm.csv").write_text(text.replace(rev, f"q{axis + 1}_mm", 1))
    code, _, err = cli(capsys, "predict", d / "robot.toml", d / "mm.csv", "--out", d / "x.csv")
    one_error(err, "mm.csv", "row 1", f"'q{axis + 1}_mm'", "revolute", rev)
    assert math.isfinite(float(lines[1].split(",")[0]))


def test_export_writes_the_axis_as_a_prismatic_joint(arm, capsys):
    """The URDF has the linear axis as a prismatic joint, and its tool point (yourdfpy, readings in m) is the
    calibration's; the parameter table says which joint slides."""
    import yourdfpy

    name, axis, d = arm
    ok(capsys, "export", d / "cal.json", "--urdf", d / "cal.urdf", "--table", d / "table.csv", "--quiet",
       "--as-fitted")
    u = yourdfpy.URDF.load(str(d / "cal.urdf"), load_meshes=False)
    assert u.joint_map[f"joint_{axis}"].type == "prismatic"
    assert [j.type for j in u.robot.joints].count("prismatic") == 1
    from casadical import load_calibration
    cal = load_calibration(d / "cal.json")
    val = Measurements.read_csv(d / "val.csv", robot=cal.model.robot)
    ref = []
    for row in val.q[:10]:
        u.update_cfg(row)
        ref.append(u.get_transform("tool_point", "measurement_frame")[:3, 3])
    assert np.abs(np.array(ref) - cal.predict(val.subset(np.arange(10)))).max() < 1e-9
    assert f"joint {axis} prismatic" in (d / "table.csv").read_text().splitlines()[0]
    robot = load_robot(d / "cal.urdf")            # read back: the axis is prismatic again
    assert robot.prismatic[axis - 1] and sum(robot.prismatic) == 1


def test_the_accuracy_map_spans_the_axis_travel_in_mm(arm, capsys):
    """The accuracy map over a linear axis: its grid spans the axis' limits in mm, its labels say mm."""
    from casadical.prediction import accuracy_map
    from casadical.result import load_calibration

    name, axis, d = arm
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        ok(capsys, "calibrate", d / "robot.toml", d / "cal.csv", "--model", "kinematic", "--out", d / "map.json")
    res = load_calibration(d / "map.json")
    robot = res.model.robot
    other = next(j for j in range(1, robot.n + 1) if j != axis)
    cal = Measurements.read_csv(d / "cal.csv", robot=robot)
    m = accuracy_map(res, cal.q, (min(axis, other), max(axis, other)), n=9)
    grid = m["x"] if axis < other else m["y"]
    lo, hi = (v * 1000 for v in robot.limits[axis - 1])
    assert grid[0] == pytest.approx(lo) and grid[-1] == pytest.approx(hi)
    assert m["units"][axis - 1] == "mm" and m["units"][other - 1] == "deg"
    measured = m["measured"][:, 0 if axis < other else 1]
    np.testing.assert_allclose(measured, cal.q[:, axis - 1] * 1000)
    assert np.all(m["std_mm"] > 0)


PROBLEMS_ROBOTS = PROBLEMS / "robots"


def _track_protocol(tmp_path, truth: str) -> Path:
    """problems/protocols/track6.toml with more lines in its ``[truth]`` table."""
    text = (PROBLEMS / "protocols" / "track6.toml").read_text()
    text = text.replace('"../robots/track6.toml"', repr(str(PROBLEMS / "robots" / "track6.toml")).replace("'", '"'))
    text = text.replace("calibration = 120", "calibration = 300").replace("validation = 60", "validation = 200")
    (tmp_path / "p.toml").write_text(text.replace("[workspace]", truth + "\n\n[workspace]"))
    return tmp_path / "p.toml"


def test_a_protocol_states_the_axis_errors_and_the_diagnosis_names_them(tmp_path, capsys):
    """A study protocol hides a track's straightness and its carriage's roll (in mm and mrad); the diagnosis of
    the simulated data names the two where they are, and nothing else on the track."""
    p = _track_protocol(tmp_path, 'straightness_mm = [[1, "x", 0.25, 0.0]]\n'
                                  'carriage_angle_mrad = [[1, "roll", 0.3, 0.0]]')
    ok(capsys, "simulate", p, "--out-dir", tmp_path / "sim")
    ok(capsys, "diagnose", PROBLEMS_ROBOTS / "track6.toml", tmp_path / "sim" / "calibration.csv", "--validate",
       tmp_path / "sim" / "validation.csv", "--json", tmp_path / "r.json", "--no-blackbox", "--quiet")
    found = {(f["cause"], f.get("joint"), f.get("direction"), f.get("angle"))
             for f in json.loads((tmp_path / "r.json").read_text())["findings"]}
    assert ("straightness", 1, "x", None) in found and ("carriage_angle", 1, None, "roll") in found, found
    assert not [f for f in found if f[1] == 1 and f[0] not in ("straightness", "carriage_angle")], found


@pytest.mark.parametrize("line, column, words", [
    ("stiffness = {1 = 1e6}", "'truth.stiffness.1'", "prismatic"),
    ("backlash_mm = {2 = 0.01}", "'truth.backlash_mm.2'", "revolute"),
    ('periodic_mm = [[2, 5, 0.01, 0.0]]', "'truth.periodic_mm[1]'", "revolute"),
    ('periodic_deg = [[1, 5, 0.01, 0.0]]', "'truth.periodic_deg[1]'", "periodic_mm"),
    ('straightness_mm = [[1, "z", 0.1, 0.0]]', "'truth.straightness_mm[1]'", "x, y"),
    ('carriage_angle_mrad = [[3, "roll", 0.1, 0.0]]', "'truth.carriage_angle_mrad[1]'", "revolute"),
    ('carriage_angle_mrad = [[1, "roll", 0.1]]', "'truth.carriage_angle_mrad[1]'", "p2_mrad"),
])
def test_a_protocol_error_of_the_wrong_kind_of_joint_is_one_line(tmp_path, capsys, line, column, words):
    p = _track_protocol(tmp_path, line)
    if line.startswith("stiffness"):
        p.write_text(p.read_text().replace("stiffness = {3 = 1.73e6, 4 = 1.203e6}\n", ""))
    code, _, err = cli(capsys, "simulate", p, "--out-dir", tmp_path / "sim")
    assert code != 0
    one_error(err, "p.toml", column, words)


def test_extrapolation_warnings_give_the_axis_in_mm(arm, tmp_path):
    """Calibrated on the lower half of the axis' travel, the poses of the upper half extrapolate: the warning
    gives the axis' range in mm (it said deg), from the fit and from its file read back."""
    import re

    from casadical import calibrate
    from casadical.calibration import load_calibration

    name, axis, d = arm
    robot = load_robot(d / "robot.toml")
    cal = Measurements.read_csv(d / "cal.csv", robot=robot)
    val = Measurements.read_csv(d / "val.csv", robot=robot)
    travel = cal.q[:, axis - 1]
    res = calibrate(robot, cal.subset(np.flatnonzero(travel < np.median(travel))), "kinematic", "lm", warn=False)
    res.save(tmp_path / "c.json")
    for r in (res, load_calibration(tmp_path / "c.json")):
        text = next(t for t in r.coverage.describe(val.q_deg, val.lines, "val.csv") if "outside the ranges" in t)
        assert re.search(rf"q{axis} -?[\d.]+\.\.-?[\d.]+ mm", text), text
        assert all(u == "deg" for j, u in enumerate(r.coverage.units) if j != axis - 1)
