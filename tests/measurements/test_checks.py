"""Bad input of every kind gives one clear line naming file, row and column, or a correct answer.

Each case of issue 10 is reproduced here first (through the real command
line where it is a command-line case), then required to be handled: hidden
unit mistakes, poses beyond the limits, calibrations of another robot,
malformed files, options out of their domain, a solver that leaves its
bounds, Ctrl-C while compiling.
"""

import copy
import functools
import json
import math
import os
import shutil
import subprocess
import sys
import warnings

import numpy as np
import pytest
from arms import ARMS, to_toml

from casadical import calibrate, load_calibration, load_robot
from casadical.checks import check_poses
from casadical.cli import main
from casadical.data import Measurements
from casadical.errors import CalibrationFileError, DataFileError, DataWarning, RobotFileError
from casadical.robot import PROBLEMS, robot_from_dict
from casadical.simulate import Effects, simulate

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


def cli(capsys, *args):
    """The command line in-process: exit code, stdout, stderr lines."""
    code = main([str(a) for a in args])
    out, err = capsys.readouterr()
    return code, out, [line for line in err.strip().splitlines() if line]


def one_error(err, *parts):
    """Exactly one line, an error, naming every part."""
    assert len(err) == 1, err
    assert err[0].startswith("casadical: error: ") and "Traceback" not in err[0], err
    for p in parts:
        assert p in err[0], (p, err[0])


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
    from casadical.solvers.ipopt import Ipopt
    from casadical.solvers.lm import LevenbergMarquardt

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


# --- calibration JSON -----------------------------------------------------------------------------


def _set(path, value):
    def mutate(doc):
        *head, last = path
        for k in head:
            doc = doc[k]
        if value is KeyError:
            del doc[last]
        else:
            doc[last] = value
    return mutate


@pytest.mark.parametrize("mutate,column", [
    (_set(["parameters", 3, "value"], float("nan")), "parameters[3].value"),
    (_set(["parameters", 3, "value"], "abc"), "parameters[3].value"),
    (_set(["parameters", 3, "value"], 10 ** 400), "parameters[3].value"),
    (_set(["parameters", 3, "std"], -1.0), "parameters[3].std"),
    (_set(["parameters", 3, "name"], "zzz"), "parameters[3].name"),
    (_set(["parameters", 4, "name"], "base_x"), "parameters[4].name"),
    (_set(["parameters", 3], 7), "parameters[3]"),
    (_set(["parameters", 3, "fixed"], "no"), "parameters[3].fixed"),
    (lambda d: d["parameters"].pop(5), "parameters"),
    (_set(["parameters"], {}), "parameters"),
    (_set(["base0"], [1, 2]), "base0"),
    (_set(["base0"], [2.0] * 12), "base0"),
    (_set(["base0", 0], 1e200), "base0"),     # found by the slow fuzz test (R^T R overflowed)
    (_set(["base0"], KeyError), "base0"),
    (_set(["model"], 5), "model"),
    (_set(["model"], "kinematic+compliance[9]"), "model"),
    (_set(["terms"], []), "terms"),
    (_set(["terms", "kinematic", "bogus"], 3), "terms.kinematic.bogus"),
    (_set(["terms", "kinematic", "length_box"], 0), "terms.kinematic.length_box"),
    (_set(["calibration"], {"a": 1}), "calibration.a"),
    (_set(["calibration", "mean_mm"], None), "calibration.mean_mm"),
    (_set(["notes"], 3), "notes"),
    (_set(["robot", "joint"], 3), "robot.joint"),
    (_set(["robot", "joint", 1, "a_m"], 1e300), "robot.joint[2].a_m"),
    (_set(["robot"], KeyError), "robot"),
    (_set(["coverage", "poses_deg"], 10 ** 400), "coverage.poses_deg"),     # found by the slow fuzz test
    (_set(["coverage", "q_min_deg", 2], 10 ** 400), "coverage.q_min_deg"),
    (_set(["coverage", "poses_deg", 1], [1.0]), "coverage.poses_deg[1]"),
    (_set(["coverage", "spacing_deg"], KeyError), "coverage.spacing_deg"),
    (_set(["parameters", 3, "t"], "x"), "parameters[3].t"),
    (_set(["parameters", 3, "p"], 1.5), "parameters[3].p"),
    (_set(["parameters", 3, "relative_std"], -0.1), "parameters[3].relative_std"),
    (_set(["parameters", 3, "significant"], "yes"), "parameters[3].significant"),
    (_set(["parameters", 3, "ci95"], [1.0]), "parameters[3].ci95"),
    (_set(["parameters", 3, "ci95"], [1.0, "x"]), "parameters[3].ci95"),
    (_set(["statistics"], 3), "statistics"),
    (_set(["statistics", "dof"], 5), "statistics.dof"),
    (_set(["statistics", "aic"], None), "statistics.aic"),
    (_set(["statistics", "sigma_mm"], 0.0), "statistics.sigma_mm"),
    (_set(["statistics", "n_equations"], 2.5), "statistics.n_equations"),
    (_set(["statistics", "n_equations"], 10 ** 400), "statistics.n_equations"),
    (_set(["statistics", "level"], 95), "statistics.level"),
    (_set(["statistics", "bic"], KeyError), "statistics.bic"),
    (_set(["statistics", "more"], 1), "statistics.more"),
    (_set(["validation"], {"file": 3, "n_poses": 9, "mean_mm": 1, "max_mm": 2, "std_mm": 0.5, "rms_mm": 1.1}),
     "validation.file"),
    (_set(["validation"], {"file": "v.csv", "n_poses": 9, "mean_mm": -1, "max_mm": 2, "std_mm": 0.5,
                           "rms_mm": 1.1}), "validation.mean_mm"),
    (_set(["validation"], [1]), "validation"),
])
def test_malformed_calibration_json(ys, tmp_path, capsys, mutate, column):
    doc = json.loads((ys / "cal.json").read_text())
    mutate(doc)
    (tmp_path / "bad.json").write_text(json.dumps(doc))
    with pytest.raises(CalibrationFileError) as e:
        load_calibration(tmp_path / "bad.json")
    assert e.value.column == column and e.value.file == str(tmp_path / "bad.json")
    code, _, err = cli(capsys, "predict", tmp_path / "bad.json", ys / "val.csv", "--out", tmp_path / "o.csv")
    assert code == 2
    one_error(err, "bad.json", repr(column))


@pytest.mark.parametrize("content", [b"", b"null", b"[1, 2]", b"{\"robot\": ", b"\xff\xfe{}", b"[" * 100000])
def test_not_a_calibration_json(tmp_path, content):
    (tmp_path / "x.json").write_bytes(content)
    with pytest.raises(CalibrationFileError):
        load_calibration(tmp_path / "x.json")


# --- Levenberg-Marquardt on a stiff joint ----------------------------------------------------------


def test_lm_with_compliance_below_zero_is_saved_and_reported(tmp_path, capsys):
    """A stiff joint (true compliance ~0): LM comes out negative on some seeds, never inf stiffness."""
    robot = load_robot("ys100")
    negative = 0
    for seed in range(4):
        data, _ = simulate(robot, 40, Effects(stiffness={2: 1.5e6, 3: 1e12}), seed=seed)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            res = calibrate(robot, data, "kinematic+compliance[2,3]", "lm")
        c3 = res.parameters["c3"].value
        res.save(tmp_path / f"lm{seed}.json")
        doc = json.loads((tmp_path / f"lm{seed}.json").read_text())
        k3 = next(p for p in doc["parameters"] if p["name"] == "k3")
        if c3 <= 0:
            negative += 1
            assert k3["value"] is None and "no positive stiffness" in k3["reason"]
            assert "no positive stiffness" in res.summary()
            data.write_csv(tmp_path / f"stiff{seed}.csv")
            code, out, _ = cli(capsys, "calibrate", "ys100", tmp_path / f"stiff{seed}.csv", "--solver", "lm",
                               "--model", "kinematic+compliance[2,3]", "--out", tmp_path / f"cli{seed}.json")
            assert code == 0 and "k3: no positive stiffness" in out and (tmp_path / f"cli{seed}.json").exists()
        else:
            assert k3["value"] == pytest.approx(1 / c3)
        back = load_calibration(tmp_path / f"lm{seed}.json")
        np.testing.assert_allclose(back.predict(data), res.predict(data), atol=1e-12)
    assert negative >= 1


# --- Ctrl-C while the model compiles ----------------------------------------------------------------


@pytest.mark.skipif(not (shutil.which("gcc") or shutil.which("cc")), reason="no C compiler")
def test_ctrl_c_during_the_jit_stops_cleanly(tmp_path):
    """A terminal's Ctrl-C (SIGINT to the whole process group) while gcc runs: exit 130, no output, no JIT folder,
    nothing in the compiled-function cache."""
    robot = load_robot("ys100")
    q = np.random.default_rng(0).uniform(robot.limits[:, 0] + 0.1, robot.limits[:, 1] - 0.1, (400, 6))
    Measurements.from_arrays(q).write_csv(tmp_path / "poses.csv")
    env = dict(os.environ, CASADICAL_JIT="1", TMPDIR=str(tmp_path), CASADICAL_CACHE=str(tmp_path / "cache"),
               CASADICAL_SIGNAL_AT="compile:SIGINT:group")    # the process group's Ctrl-C once gcc started
    p = subprocess.Popen([sys.executable, "-m", "casadical", "predict", "ys100", str(tmp_path / "poses.csv"),
                          "--out", str(tmp_path / "out.csv")], env=env, stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE, text=True, start_new_session=True)
    _, err = p.communicate(timeout=60)
    assert p.returncode == 130, err
    assert "interrupted" in err and "Traceback" not in err and "virtual machine" not in err
    assert not (tmp_path / "out.csv").exists()
    assert not list(tmp_path.glob("casadical-jit-*"))
    assert not (tmp_path / "cache").exists() or not list((tmp_path / "cache").iterdir())


@pytest.mark.parametrize("text", [
    'robot = "ys100"\nsets = 3\n',
    'robot = "ys100"\n[sets]\na = "x"\n',
    'robot = "ys100"\n[sets]\na = 5\n[truth]\nperiodic_deg = [[1, 2]]\n',
    'robot = "ys100"\n[sets]\na = 5\n[workspace]\nbox_min_m = [0, 0]\nbox_max_m = [1, 1, 1]\n',
    'robot = "nosuch.toml"\n[sets]\na = 5\n',
])
def test_malformed_protocol(tmp_path, capsys, text):
    (tmp_path / "p.toml").write_text(text)
    code, _, err = cli(capsys, "simulate", tmp_path / "p.toml", "--out-dir", tmp_path / "out")
    assert code == 2
    one_error(err)
