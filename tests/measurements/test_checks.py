"""Bad input of every kind gives one clear line naming file, row and column, or a correct answer.

Each case of issue 10 is reproduced here first (through the real command
line where it is a command-line case), then required to be handled: hidden
unit mistakes, poses beyond the limits, calibrations of another robot,
malformed measurement files, options out of their domain. The issue's other
cases: robot files (tests/model/test_robot_file.py), calibration files and a
solver that leaves its bounds (tests/calibration/test_calibration_file.py),
malformed protocols (tests/model/test_simulate.py), Ctrl-C while compiling
(tests/runtime/test_interrupts.py).
"""

import functools
import math
import subprocess
import sys
import warnings

import numpy as np
import pytest

from casadical import calibrate, load_calibration, load_robot
from casadical.data import Effects, Measurements, check_poses, simulate
from casadical.errors import DataFileError, DataWarning
from casadical.robot import PROBLEMS, robot_from_dict
from tests.helpers.arms import ARMS
from tests.helpers.cli import cli, one_error

SEEDS = [0, 1, 2]
UR10_B = PROBLEMS / "datasets" / "ur10-ipa" / "series_b.csv"
ROBOTS = ["ys100", "arm4", "arm5", "arm7"]


def robot_of(name):
    return load_robot(name) if name == "ys100" else robot_from_dict(ARMS[name], name)


@functools.cache
def _sim(name, seed):
    robot = robot_of(name)
    data, _ = simulate(robot, 30, Effects(), seed=seed, floor_z=None if name != "ys100" else 0.0)
    return robot, data


def sim(name, seed):
    """A robot and 30 simulated poses of it (a fresh, unchecked copy each time)."""
    robot, data = _sim(name, seed)
    return robot, Measurements({k: v.copy() for k, v in data.columns.items()}, f"{name}-{seed}.csv")


def with_columns(data, **change):
    cols = {k: v.copy() for k, v in data.columns.items()}
    cols.update(change)
    return Measurements(cols, data.path)


# --- plausibility checks, hidden in simulated data of several robots ---------------------------


@pytest.mark.parametrize("seed", SEEDS)
@pytest.mark.parametrize("name", ROBOTS)
def test_good_poses_pass(name, seed):
    robot, data = sim(name, seed)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        check_poses(data, robot)
        check_poses(data.subset(np.arange(0, 30, 3)), robot)


def test_real_ur10_data_pass():
    data = Measurements.read_csv(UR10_B, n_joints=6, require_positions=True)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        check_poses(data, load_robot("ur10"))


@pytest.mark.parametrize("seed", SEEDS)
@pytest.mark.parametrize("name", ROBOTS)
def test_positions_in_metres_are_found(name, seed):
    robot, data = sim(name, seed)
    metres = with_columns(data, **{c: data.columns[c] / 1000 for c in ("x_mm", "y_mm", "z_mm")})
    with pytest.raises(DataFileError, match="multiply x_mm, y_mm, z_mm by 1000") as e:
        check_poses(metres, robot)
    assert e.value.file == data.path and e.value.column == "x_mm"
    check_poses(metres, robot, positions_are_mm=True)


@pytest.mark.parametrize("seed", SEEDS)
@pytest.mark.parametrize("name", ROBOTS)
def test_joints_in_radians_are_found(name, seed):
    robot, data = sim(name, seed)
    rad = {f"q{j}_deg": np.radians(data.columns[f"q{j}_deg"]) for j in range(1, robot.n + 1)}
    with pytest.raises(DataFileError, match=r"look like radians.*57\.2958"):
        check_poses(with_columns(data, **rad), robot)
    joints_only = Measurements(rad, data.path)
    check_poses(joints_only, robot, angles_are_degrees=True)
    # with positions, the override of the angle check still leaves the scale check to catch it
    with pytest.raises(DataFileError, match="spread"):
        check_poses(with_columns(data, **rad), robot, angles_are_degrees=True)


@pytest.mark.parametrize("seed", SEEDS)
@pytest.mark.parametrize("name", ROBOTS)
def test_pose_beyond_the_limits_is_found(name, seed):
    robot, data = sim(name, seed)
    rng = np.random.default_rng(seed)
    row, j = int(rng.integers(len(data))), int(rng.integers(robot.n))
    q = data.columns[f"q{j + 1}_deg"].copy()
    q[row] = math.degrees(robot.joints[j].max) + 3.0
    bad = with_columns(data, **{f"q{j + 1}_deg": q})
    with pytest.raises(DataFileError, match="outside joint") as e:
        check_poses(bad, robot)
    assert e.value.row == row + 2 and e.value.column == f"q{j + 1}_deg" and "--allow-outside-limits" in str(e.value)
    with pytest.warns(DataWarning, match="outside joint"):
        check_poses(bad, robot, allow_outside_limits=True)


def test_library_entry_points_check_and_take_overrides():
    robot, data = sim("arm5", 0)
    q = data.columns["q2_deg"].copy()
    q[4] = 175.0
    bad = with_columns(data, q2_deg=q)
    with pytest.raises(DataFileError, match="outside joint 2"):
        calibrate(robot, bad, "kinematic")
    with pytest.warns(DataWarning, match="outside joint 2"):
        res = calibrate(robot, bad, "nominal", allow_outside_limits=True, warn=False)
    assert np.isfinite(res.calibration.mean_mm)
    from casadical.diagnosis import DiagnosisSettings, diagnose
    with pytest.raises(DataFileError, match="outside joint 2"):
        diagnose(robot, data, with_columns(data, q2_deg=q))
    # allowed once at the entry point, the calibrations inside the diagnosis (subsets, folds) do not re-check
    quick = DiagnosisSettings(max_harmonic=2, max_rounds=1, blackbox=False)
    with pytest.warns(DataWarning, match="outside joint 2"):
        rep = diagnose(robot, with_columns(data, q2_deg=q), sim("arm5", 1)[1], quick, allow_outside_limits=True)
    assert rep.steps[0].model == "nominal"


# --- the command line, case by case ---------------------------------------------------------------


@pytest.fixture(scope="module")
def ys(tmp_path_factory):
    """Simulated YS100 calibration and validation files and a calibration JSON of them."""
    d = tmp_path_factory.mktemp("ys")
    robot = load_robot("ys100")
    cal, truth = simulate(robot, 30, Effects(), seed=3)
    val, _ = simulate(robot, 30, truth=truth, seed=4)
    cal.write_csv(d / "cal.csv")
    val.write_csv(d / "val.csv")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        calibrate(robot, cal, "kinematic").save(d / "cal.json")
    return d


def test_metres_and_radians_through_calibrate(ys, tmp_path, capsys):
    data = Measurements.read_csv(ys / "cal.csv")
    metres = with_columns(data, **{c: data.columns[c] / 1000 for c in ("x_mm", "y_mm", "z_mm")})
    metres.write_csv(tmp_path / "m.csv")
    code, _, err = cli(capsys, "calibrate", "ys100", tmp_path / "m.csv", "--out", tmp_path / "c.json")
    assert code == 2 and not (tmp_path / "c.json").exists()
    one_error(err, "m.csv", "'x_mm'", "multiply x_mm, y_mm, z_mm by 1000", "--positions-are-mm")
    rad = with_columns(data, **{f"q{j}_deg": np.radians(data.columns[f"q{j}_deg"]) for j in range(1, 7)})
    rad.write_csv(tmp_path / "r.csv")
    code, _, err = cli(capsys, "calibrate", "ys100", tmp_path / "r.csv", "--out", tmp_path / "c.json")
    assert code == 2
    one_error(err, "r.csv", "'q1_deg'", "radians", "--angles-are-degrees")


def test_pose_beyond_limits_and_huge_reading(ys, tmp_path, capsys):
    data = Measurements.read_csv(ys / "cal.csv")
    q2 = data.columns["q2_deg"].copy()
    q2[6] = 170.0                          # YS100 joint 2: 0..150 deg
    with_columns(data, q2_deg=q2).write_csv(tmp_path / "b.csv")
    code, _, err = cli(capsys, "calibrate", "ys100", tmp_path / "b.csv", "--out", tmp_path / "c.json")
    assert code == 2
    one_error(err, "b.csv", "row 8", "'q2_deg'", "170", "[0, 150]")
    code, out, err = cli(capsys, "calibrate", "ys100", tmp_path / "b.csv", "--out", tmp_path / "c.json",
                         "--model", "nominal", "--allow-outside-limits")
    assert code == 0 and any("warning" in e and "row 8" in e for e in err)
    q1 = data.columns["q1_deg"].copy()
    q1[0] = 1e6
    with_columns(data, q1_deg=q1).write_csv(tmp_path / "h.csv")
    code, _, err = cli(capsys, "predict", "ys100", tmp_path / "h.csv", "--out", tmp_path / "p.csv")
    assert code == 2 and not (tmp_path / "p.csv").exists()
    one_error(err, "h.csv", "row 2", "'q1_deg'", "1e+06")


def test_predict_reports_errors_and_refuses_another_robots_poses(ys, tmp_path, capsys):
    code, out, err = cli(capsys, "predict", ys / "cal.json", ys / "val.csv", "--out", tmp_path / "p.csv")
    assert code == 0
    line = next(o for o in out.splitlines() if o.startswith("error against the measured positions"))
    mean = float(line.split("mean ")[1].split()[0])
    cal = load_calibration(ys / "cal.json")
    val = Measurements.read_csv(ys / "val.csv")
    assert mean == pytest.approx(cal.stats(val).mean_mm, abs=1e-4) and mean < 1.0
    # another robot with the same joints and limits: links 20-30 % longer
    other = load_robot("ys100")
    for j in other.joints:
        j.a, j.d = 1.25 * j.a, 1.2 * j.d
    poses, _ = simulate(other, 30, Effects(), seed=5)
    poses.write_csv(tmp_path / "other.csv")
    code, _, err = cli(capsys, "predict", ys / "cal.json", tmp_path / "other.csv", "--out", tmp_path / "q.csv")
    assert code == 2 and not (tmp_path / "q.csv").exists()
    one_error(err, "other.csv", "cal.json", "mean error of", "--allow-mismatch")
    code, _, err = cli(capsys, "predict", ys / "cal.json", tmp_path / "other.csv", "--out", tmp_path / "q.csv",
                       "--allow-mismatch")
    assert code == 0 and (tmp_path / "q.csv").exists()
    # joints only: the calibration's robot limits are the check (a UR10 pose set on a YS100 calibration)
    ur = Measurements.read_csv(UR10_B).subset(np.arange(20))
    Measurements({f"q{j}_deg": ur.columns[f"q{j}_deg"] for j in range(1, 7)}).write_csv(tmp_path / "ur.csv")
    code, _, err = cli(capsys, "predict", ys / "cal.json", tmp_path / "ur.csv", "--out", tmp_path / "u.csv")
    assert code == 2
    one_error(err, "ur.csv", "outside joint", "YS100")


@pytest.mark.parametrize("args,what", [
    (["calibrate", "ys100", "{cal}", "--out", "{out}", "--max-iter", "0"], "--max-iter: must be at least 1"),
    (["calibrate", "ys100", "{cal}", "--out", "{out}", "--max-iter", "-5"], "--max-iter: must be at least 1"),
    (["diagnose", "ys100", "{cal}", "--validate", "{cal}", "--json", "{out}", "--alpha", "2"], "--alpha"),
    (["diagnose", "ys100", "{cal}", "--validate", "{cal}", "--json", "{out}", "--alpha", "-0.1"], "--alpha"),
    (["candidates", "ys100", "-n", "10", "--out", "{out}", "--margin-deg", "500"], "--margin-deg"),
    (["calibrate", "ys100", "{cal}", "--out", "{out}", "--fix", "a2,zzz"], "'zzz'"),
    (["calibrate", "ys100", "{cal}", "--out", "{out}", "--model", "kinematic+periodic[2]"], "joint:harmonic"),
])
def test_options_out_of_their_domain(ys, tmp_path, capsys, monkeypatch, args, what):
    from casadical.solvers import Ipopt, LevenbergMarquardt

    def solve(*_):
        raise AssertionError("a solver ran: the option was not refused before the work")

    for solver in (Ipopt, LevenbergMarquardt):
        monkeypatch.setattr(solver, "solve", solve)     # refused before the work: no solver runs
    args = [a.format(cal=ys / "cal.csv", out=tmp_path / "o.json") for a in args]
    code, _, err = cli(capsys, *args)
    assert code == 2 and not (tmp_path / "o.json").exists()
    one_error(err, what)


def test_identical_candidates_are_refused(ys, tmp_path, capsys):
    lines = (ys / "cal.csv").read_text().splitlines()
    (tmp_path / "same.csv").write_text("\n".join([lines[0]] + [lines[1]] * 40) + "\n")
    code, _, err = cli(capsys, "plan-poses", "ys100", tmp_path / "same.csv", "-m", "15", "--out", tmp_path / "s.csv")
    assert code == 2 and not (tmp_path / "s.csv").exists()
    one_error(err, "same.csv", "only 1 distinct pose")


@pytest.mark.parametrize("header,column", [("q0_deg", "q0_deg"), ("q01_deg", "q01_deg")])
def test_joint_headers_numbered_wrong(tmp_path, capsys, header, column):
    (tmp_path / "h.csv").write_text(f"{header},q2_deg,q3_deg,q4_deg,q5_deg,q6_deg\n1,2,3,4,5,6\n")
    code, _, err = cli(capsys, "predict", "ys100", tmp_path / "h.csv", "--out", tmp_path / "o.csv")
    assert code == 2
    one_error(err, "h.csv", "row 1", repr(column))


def test_huge_joint_number_in_a_header(tmp_path):
    (tmp_path / "h.csv").write_text("q1_deg,q2_deg,q99999999999_deg\n1,2,3\n")
    r = subprocess.run([sys.executable, "-m", "casadical", "predict", "ys100", str(tmp_path / "h.csv"),
                        "--out", str(tmp_path / "o.csv")], capture_output=True, text=True, timeout=60)
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1 and "q3_deg" in r.stderr
