"""Corrected joint targets: the true robot lands on the targets, what is held is held, bad input is one line."""

import json
import math
import subprocess
import sys
import warnings

import numpy as np
import pytest

from casadical import Measurements, Model, calibrate, load_calibration, load_robot
from casadical.apply import TargetError, compensate
from casadical.cli import main
from casadical.data import Effects, sample_poses, simulate
from casadical.errors import ConvergenceWarning, InputError
from casadical.model import pose_to_base0
from casadical.robot import robot_from_dict

SEEDS = [0, 1, 2]
BASE = dict(base_xyz=(1.8, -0.6, 0.3), base_rpy=(0.01, -0.02, 2.4))  # a tracker anywhere, any rotation


def _joint(alpha, a, d, lo=-170, hi=170, mass=0.0, com=(0, 0, 0), **extra):
    return {"alpha_deg": alpha, "a_m": a, "d_m": d, "min_deg": lo, "max_deg": hi, "mass_kg": mass,
            "com_m": list(com), **extra}


ARM4_MDH = {  # base yaw + three parallel pitch axes (Hayati beta on joint 3): one redundant freedom
    "name": "four-axis MDH arm", "convention": "mdh",
    "joint": [_joint(0, 0, 0.4, mass=20, com=(0, 0, -0.1)),
              _joint(90, 0.1, 0, -10, 170, mass=15, com=(0.3, 0, 0)),
              _joint(0, 0.6, 0, -150, 150, mass=10, com=(0.25, 0, 0), beta_deg=0.0),
              _joint(0, 0.5, 0, mass=3, com=(0.1, 0, 0))],
    "tool": {"a_m": 0.12, "b_m": 0.0, "d_m": 0.05}, "payload": {"mass_kg": 5},
}
ARM5_DH = {  # no Hayati beta: two redundant freedoms
    "name": "five-axis DH arm", "convention": "dh",
    "joint": [_joint(90, 0.15, 0.45, mass=25, com=(0, -0.1, 0)),
              _joint(0, 0.7, 0, -10, 170, mass=18, com=(-0.35, 0, 0.05)),
              _joint(90, 0.1, 0, -150, 150, mass=8, com=(0, 0, 0.1)),
              _joint(-90, 0, 0.6, mass=5, com=(0, 0.2, 0)),
              _joint(0, 0, 0.1, mass=1, com=(0, 0, 0.05))],
    "tool": {"a_m": 0.05, "b_m": 0.0, "d_m": 0.1}, "payload": {"mass_kg": 4},
}
ARM7_DH = {  # seven axes: orientation held, one freedom left for the least change
    "name": "seven-axis DH arm", "convention": "dh",
    "joint": [_joint(-90, 0, 0.34, mass=4, com=(0, 0.03, 0.1)),
              _joint(90, 0, 0, -120, 120, mass=4, com=(0, -0.03, 0.1)),
              _joint(90, 0, 0.4, mass=3, com=(0, 0.03, 0.1)),
              _joint(-90, 0, 0, -120, 120, mass=2.7, com=(0, -0.03, 0.1)),
              _joint(-90, 0, 0.4, mass=1.7, com=(0, 0.03, 0.1)),
              _joint(90, 0, 0, -120, 120, mass=1.8, com=(0, 0, 0.0)),
              _joint(0, 0, 0.126, mass=0.3, com=(0, 0, 0.02))],
    "tool": {"a_m": 0.05, "b_m": 0.02, "d_m": 0.1}, "payload": {"mass_kg": 3},
}
ROBOTS = {"ys100": (lambda: load_robot("ys100"), {2: 1.5e6, 3: 1.2e6}, 110.0),
          "ur10": (lambda: load_robot("ur10"), {2: 2e4, 3: 3e4}, None),
          "arm4": (lambda: robot_from_dict(ARM4_MDH), {2: 5e4, 3: 4e4}, 20.0),
          "arm5": (lambda: robot_from_dict(ARM5_DH), {2: 5e4, 3: 4e4}, None),
          "arm7": (lambda: robot_from_dict(ARM7_DH), {2: 1e4, 4: 8e3}, None)}


def taught(cal, targets, **options):
    """compensate holding what the programmer taught: the nominal flange orientation on 6 axes or more (these
    calibrations are position-only: compensate holds no orientation unless asked)."""
    return compensate(cal, targets, orientation=True if cal.model.robot.n >= 6 else None, **options)


def equations_jacobian(model, q, params, cov, base0, hold):
    """Jacobian of the equations compensate solves (position, and orientation if held)."""
    _, J = model.predict_q_jacobian(q, params, cov, base0)
    if hold:
        J = np.concatenate([J, model.flange_rotation_jacobian(q, params, cov, base0)[1]], axis=1)
    return J


def well_conditioned(robot, q, hold, floor=0.05):
    """Programmed poses away from singular configurations of the nominal model."""
    m = Model(robot, "nominal")
    s = np.linalg.svd(equations_jacobian(m, q, None, None, None, hold), compute_uv=False)
    return s[:, -1] > floor


def nominal_rotation_at_calibrated_base(cal, q0):
    """What the programmer taught, computed apart from compensate: a nominal model at the calibrated base."""
    xyz, rpy = cal.base_pose()
    from casadical.kinematics import base_pose_matrix
    T = base_pose_matrix(xyz, rpy)
    return Model(cal.model.robot, "nominal").flange_rotation(q0, base0=pose_to_base0(T))


def angle_between(R1, R2):
    c = (np.trace(R1 @ R2.transpose(0, 2, 1), axis1=1, axis2=2) - 1) / 2
    return np.arccos(np.clip(c, -1, 1))


def setup(name, seed, n_targets=40, spec="kinematic+compliance", effects=None):
    make, stiffness, payload_max = ROBOTS[name]
    robot = make()
    eff = effects or Effects(stiffness=stiffness, **BASE)
    rng = np.random.default_rng(seed)
    payload = (lambda k: rng.uniform(0, payload_max, k)) if payload_max else (lambda k: None)
    data, truth = simulate(robot, 70, eff, seed=seed, floor_z=None, payload_kg=payload(70))
    val, _ = simulate(robot, 200, truth=truth, seed=seed + 100, floor_z=None, payload_kg=payload(200))
    cal = calibrate(robot, data, spec, "lm", warn=False)
    # the calibrated model's own error: measured on the validation poses, and noise-free against the truth
    model_rms = rms(np.linalg.norm(cal.predict(val) - truth.predict(val), axis=1) * 1e3)
    hold = robot.n >= 6
    q0 = sample_poses(robot, 4 * n_targets, rng, floor_z=None)
    q0 = q0[well_conditioned(robot, q0, hold)][:n_targets]
    assert len(q0) == n_targets
    extra = {} if payload_max is None else {"payload_kg": payload(n_targets)}
    # the program: joints q0 and the points the nominal model says they reach, in the tracker frame
    goal = Model(robot, "nominal").predict(q0, base0=truth.base0)
    targets = Measurements.from_arrays(q0, goal, **extra)
    return robot, truth, cal, (cal.stats(val).rms_mm, model_rms), targets


def true_error_mm(truth, targets, q):
    at = Measurements.from_arrays(q, **{k: v for k, v in targets.columns.items() if k == "payload_kg"})
    return np.linalg.norm(truth.predict(at) - targets.xyz, axis=1) * 1e3


def rms(x):
    return float(np.sqrt(np.mean(np.square(x))))


@pytest.mark.parametrize("seed", SEEDS)
@pytest.mark.parametrize("name", list(ROBOTS))
def test_true_robot_lands_on_the_targets(name, seed):
    robot, truth, cal, (val_rms, model_rms), targets = setup(name, seed)
    res = taught(cal, targets)
    before = true_error_mm(truth, targets, targets.q)
    after = true_error_mm(truth, targets, res.q)
    assert rms(before) > 0.5 and rms(before) > 10 * rms(after), (rms(before), rms(after))
    assert rms(after) < 2 * val_rms + 0.01, (rms(after), val_rms)
    assert rms(after) < 2 * model_rms + 0.002, (rms(after), model_rms)
    assert np.all(res.residual <= 1e-7) and res.converged.all()
    # the calibrated model itself, evaluated apart from the solver, puts the tool on the targets
    at = Measurements.from_arrays(res.q, **{k: v for k, v in targets.columns.items() if k == "payload_kg"})
    assert np.abs(cal.predict(at) - targets.xyz).max() < 1e-9
    hold = robot.n >= 6
    cov = cal.model.covariates(targets)
    J = equations_jacobian(cal.model, res.q, cal.parameters.values, cov, cal.base0, hold)
    if hold:
        assert "flange orientation" in res.held
        R = cal.model.flange_rotation(res.q, cal.parameters.values, cov, cal.base0)
        assert angle_between(R, nominal_rotation_at_calibrated_base(cal, targets.q)).max() < 1e-6
        assert res.orientation_held.all()
    else:
        assert res.orientation_error is None and "least joint change" in res.held
    if J.shape[1] >= J.shape[2]:
        return
    # least joint change: the correction has no component the equations do not see
    _, s, Vt = np.linalg.svd(J)
    null = Vt[:, J.shape[1]:]
    leftover = np.linalg.norm(np.einsum("mkn,mn->mk", null, res.dq), axis=1)
    assert np.all(leftover <= 1e-6 * np.linalg.norm(res.dq, axis=1)), leftover.max()


@pytest.mark.parametrize("seed", SEEDS)
def test_periodic_gear_error_is_compensated(seed):
    """A gear error depends on the joint angle: only a model with it lands within its own error."""
    eff = Effects(stiffness={2: 1.5e6}, periodic=[(2, 3, math.radians(0.02), 0.7)], **BASE)
    robot, truth, cal, (val_rms, model_rms), targets = setup("ys100", seed, effects=eff,
                                                             spec="kinematic+compliance[2]+periodic[2:3]")
    after = true_error_mm(truth, targets, taught(cal, targets).q)
    assert rms(after) < 2 * val_rms + 0.01, (rms(after), val_rms)
    assert rms(after) < 2 * model_rms + 0.002, (rms(after), model_rms)
    plain = calibrate(robot, _calibration_data(robot, truth, seed), "kinematic+compliance[2]", "lm", warn=False)
    missed = true_error_mm(truth, targets, taught(plain, targets).q)
    assert rms(missed) > 2 * rms(after), (rms(missed), rms(after))


def _calibration_data(robot, truth, seed):
    rng = np.random.default_rng(seed)
    data, _ = simulate(robot, 70, truth=truth, seed=seed, floor_z=None, payload_kg=rng.uniform(0, 110, 70))
    return data


def test_a_smooth_correction_in_predict_is_honoured():
    """Whatever CalibrationResult.predict adds (e.g. a residual compensator) is part of the equations."""
    robot, truth, cal, _, targets = setup("arm7", 5, n_targets=20)

    class Corrected(type(cal)):
        def predict(self, data):
            q = data.q
            return super().predict(data) + 0.4e-3 * np.column_stack([np.sin(q[:, 0] + q[:, 1]), np.cos(q[:, 3]),
                                                                     np.sin(2 * q[:, 2])])

    corrected = Corrected(**vars(cal))
    res = taught(corrected, targets)
    at = Measurements.from_arrays(res.q)
    assert np.abs(corrected.predict(at) - targets.xyz).max() < 1e-7
    assert np.abs(cal.predict(at) - targets.xyz).max() > 0.1e-3  # the correction did move the joints


def test_joint_jacobians_are_exact():
    """predict_q_jacobian and the flange's angular Jacobian against central differences, every term on."""
    robot = robot_from_dict(ARM7_DH)
    model = Model(robot, "kinematic+compliance+periodic[2:3,4:5]")
    rng = np.random.default_rng(3)
    p = model.parameters.values.copy()
    for k, prm in enumerate(model.parameters):
        if prm.term != "geometric" or prm.group != "base":
            p[k] += rng.normal(0, 1e-4) if prm.term != "joint_compliance" else 2e-5
    q = sample_poses(robot, 5, rng, floor_z=None)
    xyz, J = model.predict_q_jacobian(q, p)
    R, W = model.flange_rotation_jacobian(q, p)
    np.testing.assert_allclose(xyz, model.predict(q, p), atol=1e-15)
    np.testing.assert_allclose(R, model.flange_rotation(q, p), atol=1e-15)
    h = 1e-6
    for k in range(robot.n):
        e = np.zeros(robot.n)
        e[k] = h
        np.testing.assert_allclose((model.predict(q + e, p) - model.predict(q - e, p)) / (2 * h), J[:, :, k],
                                   atol=1e-8)
        S = (model.flange_rotation(q + e, p) - model.flange_rotation(q - e, p)) / (2 * h) @ R.transpose(0, 2, 1)
        np.testing.assert_allclose(np.stack([S[:, 2, 1], S[:, 0, 2], S[:, 1, 0]], axis=1), W[:, :, k], atol=1e-8)


def test_singular_wrist_reaches_the_point_and_says_so():
    """At a stretched wrist the orientation cannot be held near the program: position only, with a warning."""
    robot, truth, cal, _, targets = setup("ur10", 0, n_targets=5)
    q0 = targets.q.copy()
    q0[:, 4] = 0.0  # UR10 wrist singular: axes 4 and 6 aligned
    goal = Model(robot, "nominal").predict(q0, base0=truth.base0)
    singular = Measurements.from_arrays(q0, goal)
    with pytest.warns(ConvergenceWarning, match="cannot be held"):
        res = taught(cal, singular)
    assert res.converged.all() and not res.orientation_held.all()
    assert rms(true_error_mm(truth, singular, res.q)) < rms(true_error_mm(truth, singular, q0)) / 10


# --- bad input -------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    """A calibration JSON and a good targets file of a simulated YS100."""
    d = tmp_path_factory.mktemp("compensate")
    robot, truth, cal, _, targets = setup("ys100", 4, n_targets=8, spec="kinematic+compliance[2,3]")
    cal.save(d / "cal.json")
    cols = dict(targets.columns)
    cols["tag"] = np.array([f"p{i}" for i in range(len(targets))], dtype=object)
    Measurements(cols).write_csv(d / "targets.csv")
    return d, cal, truth


def run(*args):
    return subprocess.run([sys.executable, "-m", "casadical", *args], capture_output=True, text=True)


def test_cli_writes_corrected_joints(files, capsys):
    d, cal, truth = files
    out = d / "joints.csv"
    assert main(["compensate", str(d / "cal.json"), str(d / "targets.csv"), "--out", str(out),
                 "--hold-orientation"]) == 0
    text = capsys.readouterr().out
    assert "largest correction" in text and "flange orientation" in text
    targets = Measurements.read_csv(d / "targets.csv", n_joints=6)
    joints = Measurements.read_csv(out, n_joints=6)
    names = list(joints.columns)
    assert names[:len(targets.columns)] == list(targets.columns)  # input columns first, in order
    q = [f"q{j}_deg" for j in range(1, 7)]
    assert names[len(targets.columns):] == (["programmed_" + c for c in q] + ["d" + c for c in q]
                                            + ["residual_mm", "orientation_error_deg"])
    assert list(joints.columns["tag"]) == list(targets.columns["tag"])
    np.testing.assert_array_equal(joints.xyz, targets.xyz)
    for c in q:
        np.testing.assert_array_equal(joints.columns["programmed_" + c], targets.columns[c])
        np.testing.assert_allclose(joints.columns["d" + c], joints.columns[c] - targets.columns[c], atol=1e-12)
    assert joints.columns["residual_mm"].max() <= 1e-4
    back = load_calibration(d / "cal.json")
    np.testing.assert_allclose(back.predict(joints), targets.xyz, atol=1e-9)
    # the same as the Python API; the output is not overwritten without --force
    np.testing.assert_allclose(joints.q, taught(cal, targets).q, atol=1e-12)
    before = out.read_text()
    assert "exists already" in cli_error(capsys, d / "cal.json", d / "targets.csv", "--out", out)
    assert out.read_text() == before


def one_line_error(r):
    lines = r.stderr.strip().splitlines()
    assert r.returncode == 2 and len(lines) == 1 and "Traceback" not in r.stderr, r.stderr
    return lines[0]


def cli_error(capsys, *args):
    """The one stderr line of a command that must fail with exit status 2 (in process)."""
    capsys.readouterr()
    assert main(["compensate", *map(str, args)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("casadical: error: "), err
    return err[0]


def test_unreachable_target_is_an_error_naming_the_row(files, tmp_path):
    d, cal, _ = files
    targets = Measurements.read_csv(d / "targets.csv", n_joints=6)
    targets.columns["x_mm"][2] += 8000.0  # 8 m beyond: outside the reach
    path = tmp_path / "far.csv"
    targets.write_csv(path)
    with pytest.raises(TargetError, match=r"row 4: .*does not reach this target"):
        compensate(cal, Measurements.read_csv(path, n_joints=6))
    out = tmp_path / "joints.csv"
    line = one_line_error(run("compensate", str(d / "cal.json"), str(path), "--out", str(out)))
    assert f"{path}, row 4:" in line and "reach" in line
    assert not out.exists()


def test_solution_beyond_a_joint_limit_is_an_error_naming_row_and_column(files, tmp_path, capsys):
    d, cal, _ = files
    targets = Measurements.read_csv(d / "targets.csv", n_joints=6)
    res = taught(cal, targets)
    i, j = np.unravel_index(np.argmax(np.abs(res.dq)), res.dq.shape)
    # a limit between the programmed and the corrected joint: the program is legal, its correction is not
    doc = json.loads((d / "cal.json").read_text())
    limit = math.degrees(res.q0[i, j] + res.dq[i, j] / 2)
    doc["robot"]["joint"][j]["max_deg" if res.dq[i, j] > 0 else "min_deg"] = limit
    tight = tmp_path / "tight.json"
    tight.write_text(json.dumps(doc))
    # the rows whose programmed joint is within the tightened limit (row i is; a program beyond a limit is
    # refused by the plausibility check before any solving)
    side = np.sign(res.dq[i, j])
    legal = np.flatnonzero(side * (np.degrees(res.q0[:, j]) - limit) <= 0)
    path = tmp_path / "legal.csv"
    Measurements({k: v[legal] for k, v in targets.columns.items()}).write_csv(path)
    targets = Measurements.read_csv(path, n_joints=6)
    beyond = np.flatnonzero(side * (np.degrees(res.q[legal, j]) - limit) > 0)
    first = beyond[0] + 2  # file row of the first row beyond the limit (the header is row 1)
    with pytest.raises(TargetError, match=rf"row {first}, column 'q{j + 1}_deg': the corrected joint would be"):
        taught(load_calibration(tight), targets)
    out = tmp_path / "joints.csv"
    line = cli_error(capsys, tight, path, "--out", out, "--hold-orientation")
    assert f"row {first}, column 'q{j + 1}_deg'" in line and f"beyond its limit {limit:g} deg" in line
    assert not out.exists()


@pytest.mark.parametrize("header, body, column", [
    ("q1_deg,q2_deg,q3_deg,q4_deg,q5_deg,q6_deg", "0,90,0,0,30,0", "x_mm"),            # no target points
    ("q1_deg,q2_deg,q3_deg,q4_deg,q5_deg,x_mm,y_mm,z_mm", "0,90,0,0,30,1500,0,900", "q6_deg"),  # 5 joints
    ("q1_deg,q2_deg,q3_deg,q4_deg,q5_deg,q6_deg,x_mm,y_mm", "0,90,0,0,30,0,1500,0", "z_mm"),     # partial
    ("q1_deg,q2_deg,q3_deg,q4_deg,q5_deg,q6_deg,x_mm,y_mm,z_mm,dq1_deg", "0,90,0,0,30,0,1,2,3,0", "dq1_deg"),
])
def test_bad_targets_file_is_one_line(files, tmp_path, capsys, header, body, column):
    d, cal, _ = files
    path = tmp_path / "bad.csv"
    path.write_text(header + "\n" + body + "\n")
    out = tmp_path / "joints.csv"
    line = cli_error(capsys, d / "cal.json", path, "--out", out)
    assert str(path) in line and "row 1" in line and f"'{column}'" in line
    assert not out.exists()
    with pytest.raises(InputError):
        compensate(cal, Measurements.read_csv(path))


def test_blank_lines_do_not_shift_the_row_named(files, tmp_path):
    d, cal, _ = files
    lines = (d / "targets.csv").read_text().splitlines()
    fields = lines[3].split(",")
    fields[6] = str(float(fields[6]) + 8000.0)  # row 4 of the original file, x_mm
    path = tmp_path / "blank.csv"
    path.write_text("\n".join(lines[:2] + ["", ""] + [lines[2], ",".join(fields)] + lines[4:]) + "\n")
    with pytest.raises(TargetError, match=r"row 6: "):
        compensate(cal, Measurements.read_csv(path, n_joints=6))


def test_options_are_checked(capsys):
    assert "must be in" in cli_error(capsys, "cal.json", "t.csv", "--out", "o.csv", "--tolerance-mm", "0")
    assert "at least 1" in cli_error(capsys, "cal.json", "t.csv", "--out", "o.csv", "--max-iter", "0")
    assert "must be in" in cli_error(capsys, "cal.json", "t.csv", "--out", "o.csv", "--max-change-deg", "-1")


def test_help(capsys):
    with pytest.raises(SystemExit) as e:
        main(["compensate", "--help"])
    assert e.value.code == 0 and "TARGETS.csv" in capsys.readouterr().out


def test_position_only_on_six_axes_changes_less(files):
    _, cal, _ = files
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        targets = Measurements.read_csv(files[0] / "targets.csv", n_joints=6)
        held = taught(cal, targets)
        free = compensate(cal, targets, orientation=False)
    assert free.orientation_error is None and "least joint change" in free.held
    assert np.all(np.linalg.norm(free.dq, axis=1) <= np.linalg.norm(held.dq, axis=1) + 1e-12)


@pytest.mark.parametrize("change, expected, override", [
    (lambda c: [c.__setitem__(f"q{j}_deg", np.radians(c[f"q{j}_deg"])) for j in range(1, 7)],
     "these look like radians", "--angles-are-degrees"),
    (lambda c: [c.__setitem__(k, c[k] / 1000) for k in ("x_mm", "y_mm", "z_mm")], "--positions-are-mm",
     "--positions-are-mm"),
    (lambda c: c["q1_deg"].__setitem__(3, 400.0), "row 5, column 'q1_deg'", "--allow-outside-limits"),
])
def test_implausible_targets_are_one_line_naming_the_fix(files, tmp_path, capsys, change, expected, override):
    """Radian joints, metre points, a programmed joint beyond its limit: the check says so before any solving."""
    d, cal, _ = files
    targets = Measurements.read_csv(d / "targets.csv", n_joints=6)
    cols = {k: np.array(v, dtype=v.dtype) for k, v in targets.columns.items()}
    change(cols)
    path = tmp_path / "implausible.csv"
    Measurements(cols).write_csv(path)
    out = tmp_path / "joints.csv"
    line = cli_error(capsys, d / "cal.json", path, "--out", out)
    assert str(path) in line and expected in line and override in line and not out.exists()
    # the override lets it through the check (here to the solver, which cannot reach such targets)
    main(["compensate", str(d / "cal.json"), str(path), "--out", str(out), override])
    errors = [e for e in capsys.readouterr().err.splitlines() if e.startswith("casadical: error")]
    assert all(expected not in e for e in errors)


# --- near a singular configuration (issue 28) ---------------------------------------------------------------


def _weakest(cal, q, hold):
    """Singular values and directions of the equations compensate solves at ``q`` (the calibrated model)."""
    cov = cal.model.covariates(Measurements.from_arrays(q))
    J = equations_jacobian(cal.model, q, cal.parameters.values, cov, cal.base0, hold)
    return np.linalg.svd(J)


@pytest.mark.parametrize("seed", SEEDS)
def test_near_a_stretched_elbow_the_correction_is_damped_and_said(seed):
    """A five-axis arm (the point alone) programmed near a stretched elbow, where the exact correction of a
    0.4 mm miss would move the joints by degrees: no joint moves more than the bound allows (2 deg per mm of
    correction), the row keeps part of its miss, and a warning names it with its conditioning; the other rows
    are exact. A small miss is corrected by the closed-form damped least squares of the documented damping,
    computed here from the model's Jacobian. A larger bound reaches the target with larger joint motions.
    (Before: the joints moved by degrees without a word on their conditioning.)"""
    robot, truth, cal, _, targets = setup("arm5", seed, n_targets=6)
    rng = np.random.default_rng(seed)
    pool = sample_poses(robot, 4000, rng, floor_z=None)
    s = _weakest(cal, pool, False)[1]
    order = np.argsort(s[:, -1])[:2]
    near = pool[order]                                          # the two poses nearest a singular configuration
    assert np.all(np.degrees(1 / s[order, -1]) / 1e3 > 5)       # an exact correction would move > 5 deg per mm
    q0 = np.concatenate([targets.q[:4], near])
    miss = rng.normal(size=(len(q0), 3))
    miss *= 0.4e-3 / np.linalg.norm(miss, axis=1, keepdims=True)
    goal = cal.predict(Measurements.from_arrays(q0)) + miss
    prog = Measurements.from_arrays(q0, goal)
    prog.path = "program.csv"
    with pytest.warns(ConvergenceWarning, match="near a singular configuration") as caught:
        res = taught(cal, prog)
    text = str(caught[0].message)
    assert "rows 6 (condition number" in text and ", 7 (condition number" in text and "--max-deg-per-mm" in text
    assert res.damped.tolist() == [False] * 4 + [True] * 2 and res.converged.all()
    moved = np.degrees(np.linalg.norm(res.dq, axis=1))
    assert np.all(moved[4:] <= 2.0 * 0.4 * 1.01), moved                  # the bound, per mm of correction
    assert np.all(res.residual[4:] > 1e-6) and np.all(res.residual[:4] <= 1e-7)
    # the bound on exact rows changes nothing; a larger bound reaches the near-singular ones
    loose = taught(cal, prog, max_deg_per_mm=1e4)
    assert np.all(loose.residual <= 1e-7) and np.allclose(loose.q[:4], res.q[:4], atol=1e-9)
    assert np.degrees(np.linalg.norm(loose.dq[4:], axis=1)).max() > 2 * moved[4:].max()
    # a small miss: the damped least squares of the linearised equations, singular value by singular value
    small = Measurements.from_arrays(q0[4:], cal.predict(Measurements.from_arrays(q0[4:])) + miss[4:] * 1e-3)
    with pytest.warns(ConvergenceWarning):
        dq = taught(cal, small).dq
    U, s, Vt = _weakest(cal, q0[4:], False)
    eps = 1 / (np.radians(2.0) * 1e3)
    gain = np.where(s >= eps, 1 / s, 2 * s / (eps ** 2 + s ** 2))
    expect = np.einsum("mkn,mk->mn", Vt[:, :3], gain * np.einsum("mik,mi->mk", U, miss[4:] * 1e-3))
    np.testing.assert_allclose(dq, expect, rtol=0.02, atol=1e-3 * np.abs(expect).max())


def test_near_the_singular_ur10_wrist_no_joint_moves_by_degrees():
    """Issue 28's pose (UR10 q2 = -90, q3 = 0, q5 = 0) and two near it, with a 0.4 mm miss and the flange
    orientation held: no joint moves by degrees (before: 2.1 deg for 0.4 mm at q3 = 20, q5 = 1, silently),
    each row is named with its conditioning, and a 5 mm miss at the singular pose is reached."""
    robot, truth, cal, _, _ = setup("ur10", 0, n_targets=5)
    q0 = np.radians([[10, -90, 0, 30, 0, 20], [10, -90, 20, 30, 1, 20], [10, -90, 10, 30, 5, 20],
                     [10, -90, 0, 30, 0, 20]])
    miss = np.array([[0.4, 0, 0], [0.4, 0, 0], [0.4, 0, 0], [5, 0, 0]]) * 1e-3
    prog = Measurements.from_arrays(q0, cal.predict(Measurements.from_arrays(q0)) + miss)
    prog.path = "program.csv"
    with pytest.warns(ConvergenceWarning, match="near a singular configuration") as caught:
        res = taught(cal, prog)
    assert any("rows 2 (condition number" in str(w.message) for w in caught)
    assert res.converged.all() and np.all(res.residual <= 1e-7)
    moved = np.degrees(np.abs(res.dq)).max(axis=1)
    assert np.all(moved[:3] < 0.5), moved
