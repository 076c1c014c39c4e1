"""Full-pose calibration: measured orientations (rx_deg, ry_deg, rz_deg) with positions.

Simulated arms that are not built in (MDH with 7 axes, DH with 5) carry a
probe mounted at a known rotation, geometric errors, and noise on positions
and orientations; the mounting and the geometry must come back within their
reported uncertainty, LM and IPOPT must agree on the full-pose objective,
and position-only stays what it was.
"""

import json
import math
import warnings

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from casadical import calibrate, load_calibration
from casadical.data import Effects, Measurements, simulate
from casadical.errors import CalibrationFileError, InputError
from casadical.robot import robot_from_dict
from tests.helpers.arms import ARM5, ARM7, to_toml

MOUNT = (0.3, -1.2, 2.5)    # rad: far from any reference, pitch 69 deg
EFFECTS = Effects(noise=50e-6, orientation_noise=math.radians(0.01), tool_rpy=MOUNT,
                  base_xyz=(1.5, -0.5, 0.3), base_rpy=(0.01, -0.02, 0.7))


def _data(robot, seed, n=60):
    """Full-pose data of a random true arm; parameters no pose set can identify carry no error in the truth."""
    data, truth = simulate(robot, n, EFFECTS, seed=seed, floor_z=-10.0)
    probe = calibrate(robot, data, "kinematic", "lm", warn=False)
    for u in probe.identifiability.unidentifiable:
        i = truth.model.parameters.index(u.name)
        truth.values[i] = truth.model.parameters.nominal[i]
    data, _ = simulate(robot, data.q, truth=truth, seed=seed + 1000)
    return data, truth


MOUNT_NAMES = ["tool_roll", "tool_pitch", "tool_yaw"]


@pytest.mark.parametrize("arm", [ARM7, ARM5], ids=["mdh7", "dh5"])
def test_mounting_and_geometry_recovered_within_reported_uncertainty(arm):
    """Normalised errors of the mounting rotation and of the geometry follow chi-square over 8 seeds."""
    robot = robot_from_dict(arm, "arm")
    mount, geometry, scales = [], [], []
    for seed in range(8):
        data, truth = _data(robot, seed)
        res = calibrate(robot, data, "kinematic", "lm", warn=False)
        assert res.full_pose and res.has_orientation and res.model.spec == "kinematic+tool_orientation"
        unc = res.uncertainty
        # the mounting: the rotation from the truth's to the estimate's, about the flange axes (small angles)
        e = Rotation.from_matrix(res.tool_rotation() @ truth.tool_rotation().T).as_rotvec()
        ii = [unc.names.index(n) for n in MOUNT_NAMES]
        mount.append(e @ np.linalg.solve(unc.covariance[np.ix_(ii, ii)], e) / 3)
        names = [n for n in unc.names if not n.startswith("base_") and n not in MOUNT_NAMES]
        idx = [unc.names.index(n) for n in names]
        err = np.array([res.parameters[n].value - truth.value(n) for n in names])
        geometry.append(err @ np.linalg.solve(unc.covariance[np.ix_(idx, idx)], err) / len(names))
        scales.append((res.loss.sigma / EFFECTS.noise, res.loss.sigma_rot / EFFECTS.orientation_noise))
        # the orientation rows count: 6 equations per pose
        assert unc.dof == 6 * len(data) - len(unc.names)
    # means of chi2(p)/p over 8 draws: 1 +- 0.3 (p = 3), 1 +- 0.1 (p ~ 20)
    assert 0.5 < np.mean(mount) < 1.6, mount
    assert 0.75 < np.mean(geometry) < 1.4, geometry
    # each kind's noise scale comes from its own residuals (the median of 60 norms, less the fitted dof's share)
    assert np.all(np.abs(np.mean(scales, axis=0) - 0.95) < 0.1), scales


def test_lm_and_ipopt_agree_on_the_full_pose_objective():
    robot = robot_from_dict(ARM7, "arm")
    data, _ = simulate(robot, 50, EFFECTS, seed=3, floor_z=-10.0)
    a = calibrate(robot, data, "kinematic", "lm", warn=False)
    b = calibrate(robot, data, "kinematic", "ipopt", warn=False)
    assert a.solver.success and b.solver.success and b.solver.iterations > 0
    dv = (a.parameters.values - b.parameters.values) / a.parameters.scales
    assert np.abs(dv).max() < 1e-3
    assert math.isclose(a.loss.sigma_rot, b.loss.sigma_rot, rel_tol=1e-6)
    assert np.allclose(a.tool0, b.tool0, atol=1e-12)
    # the orientation weighs in: without it the mounting has no say and the geometry differs
    p = calibrate(robot, data, "kinematic", "lm", warn=False, position_only=True)
    assert not p.has_orientation and "tool_roll" not in p.parameters
    common = [n for n in p.parameters.names if not p.parameters[n].fixed and not a.parameters[n].fixed]
    assert max(abs(p.parameters[n].value - a.parameters[n].value) / a.parameters[n].scale for n in common) > 1e-3


@pytest.mark.parametrize("arm, spec", [(ARM7, "kinematic"), (ARM5, "kinematic+joint_compliance[2]")],
                         ids=["mdh7", "dh5-compliance"])
def test_exported_urdf_holds_the_probe_orientation(tmp_path, capsys, arm, spec):
    """The URDF of a full-pose calibration, read by yourdfpy: tool_point's axes are the probe's, as the
    calibration predicts them (its geometry as fitted, or the best geometry of a compliant model)."""
    import yourdfpy

    from casadical.cli import main

    robot = robot_from_dict(arm, "arm")
    data, _ = _data(robot, 3)
    res = calibrate(robot, data, spec, "lm", warn=False)
    res.save(tmp_path / "c.json")
    assert main(["export", str(tmp_path / "c.json"), "--urdf", str(tmp_path / "c.urdf")]) == 0
    capsys.readouterr()
    u = yourdfpy.URDF.load(str(tmp_path / "c.urdf"), load_meshes=False)
    angles, gaps = [], []
    predicted = res.predict_rotations(data)
    xyz = res.predict(data)
    for q, R, p in zip(data.q, predicted, xyz):
        u.update_cfg(q)
        T = u.get_transform("tool_point", "measurement_frame")
        angles.append(Rotation.from_matrix(T[:3, :3].T @ R).magnitude())
        gaps.append(np.linalg.norm(T[:3, 3] - p))
    if spec == "kinematic":          # exactly the calibration's model
        assert max(angles) < 1e-9 and max(gaps) < 1e-9
    else:                            # the best geometry: near the full model, and the probe's axes, not the flange's
        assert math.degrees(max(angles)) < 0.01 and max(gaps) < 1e-3
    assert math.degrees(Rotation.from_matrix(res.tool_rotation()).magnitude()) > 30


@pytest.mark.parametrize("full_pose", [True, False], ids=["full-pose", "positions"])
def test_the_loss_alone_is_the_linearisations_to_the_bit(monkeypatch, full_pose):
    """``CalibrationProblem.cost`` (IPOPT's line-search trials) is ``linearize(...).cost`` to the bit, over several
    chunks of poses, with the robust loss: the same residuals, each pose's ``u2`` formed alike, one sum (before:
    a sum per chunk, and the orientation's share as ``k^2 |r_o|^2``: 1-2 ulp apart at most points)."""
    from casadical.problem import CalibrationProblem

    monkeypatch.setattr("casadical.runtime._chunks.CHUNK", 16)
    robot = robot_from_dict(ARM7, "arm")
    data, _ = simulate(robot, 60, EFFECTS, seed=4, floor_z=-10.0)
    res = calibrate(robot, data, "kinematic", "lm", warn=False, position_only=not full_pose)
    assert res.loss.delta > 0 and res.full_pose == full_pose
    problem = CalibrationProblem(res.model, res.parameters.copy(), data.q, data.xyz, res.model.covariates(data),
                                 res.base0, res.loss, data.rotations @ res.tool0.T if full_pose else None)
    rng = np.random.default_rng(4)
    x = problem.x_from_values(res.parameters.values)
    for step in (0.0, 1e-3, 0.1, 1.0, 10.0):   # from the optimum to far from it (poses beyond the loss's bend)
        values = problem.values_from_x(x + step * rng.standard_normal(len(x)))
        assert problem.cost(values) == problem.linearize(values).cost


def test_position_only_is_unchanged_by_orientation_columns():
    """--position-only on full-pose data gives the same bits as the same data without the columns."""
    robot = robot_from_dict(ARM5, "arm")
    data, _ = simulate(robot, 40, EFFECTS, seed=5, floor_z=-10.0)
    bare = Measurements({k: v for k, v in data.columns.items() if k not in ("rx_deg", "ry_deg", "rz_deg")})
    for solver in ("lm", "ipopt"):
        a = calibrate(robot, data, "kinematic", solver, warn=False, position_only=True)
        b = calibrate(robot, bare, "kinematic", solver, warn=False)
        assert np.array_equal(a.parameters.values, b.parameters.values)
        assert a.to_dict().keys() == b.to_dict().keys() and "orientation" not in b.to_dict()
        assert a.loss == b.loss and a.model.spec == b.model.spec == "kinematic"


def test_orientation_outlier_is_set_aside():
    robot = robot_from_dict(ARM7, "arm")
    data, truth = simulate(robot, 60, EFFECTS, seed=7, floor_z=-10.0)
    R = data.rotations
    R[10] = R[10] @ Rotation.from_rotvec([0.0, math.radians(2.0), 0.0]).as_matrix()   # a bad probe reading
    bad = data.with_orientations(R, prefix_existing="old_")
    res = calibrate(robot, bad, "kinematic", "lm", warn=False)
    assert [d["line"] for d in res.downweighted] == [12]
    assert 1.9 < res.downweighted[0]["orientation_deg"] < 2.1
    clean = calibrate(robot, data, "kinematic", "lm", warn=False)
    e = Rotation.from_matrix(res.tool_rotation() @ clean.tool_rotation().T).magnitude()
    assert math.degrees(e) < 0.005
    plain = calibrate(robot, bad, "kinematic", "lm", warn=False, robust="none")
    assert plain.loss.sigma_rot > 0 and plain.full_pose     # plain least squares is weighted too
    assert math.degrees(Rotation.from_matrix(plain.tool_rotation() @ clean.tool_rotation().T).magnitude()) > 0.02


def test_json_round_trip_predict_and_take_further(tmp_path):
    robot = robot_from_dict(ARM5, "arm")
    data, truth = simulate(robot, 60, EFFECTS, seed=2, floor_z=-10.0)
    val, _ = simulate(robot, 30, truth=truth, seed=20, floor_z=-10.0)
    res = calibrate(robot, data, "kinematic", "lm", warn=False)
    text = res.summary()
    assert "orientation:" in text and "full pose: positions and orientations weighted" in text
    path = tmp_path / "cal.json"
    res.save(path)
    doc = json.loads(path.read_text())
    ori = doc["orientation"]
    assert set(ori) == {"tool0", "tool_rotation", "full_pose", "sigma_mm", "sigma_deg", "calibration"}
    assert math.isclose(ori["calibration"]["mean_deg"], res.orientation.mean_deg)
    back = load_calibration(path)
    assert back.has_orientation and back.full_pose and math.isclose(back.loss.sigma_rot, res.loss.sigma_rot)
    assert np.allclose(back.predict_rotations(val), res.predict_rotations(val), atol=1e-12)
    # true orientation errors on held-out poses: near the orientation noise (0.01 deg per axis)
    assert res.orientation_stats(val).mean_deg < 0.03
    # taken further: the base and the mounting are estimated again (the probe may have been re-mounted)
    moved = calibrate(back, val, "base", "lm", warn=False)
    assert moved.full_pose and not moved.parameters["tool_roll"].fixed and moved.parameters["a2"].fixed
    # on positions only, the mounting is kept from the calibration
    kept = calibrate(back, val, "base", "lm", warn=False, position_only=True)
    assert not kept.full_pose and kept.parameters["tool_roll"].fixed
    assert np.allclose(kept.tool_rotation(), back.tool_rotation())
    assert "orientation" in kept.to_dict() and kept.to_dict()["orientation"]["sigma_deg"] is None


@pytest.mark.parametrize("mutate,column", [
    (lambda d: d.pop("orientation"), "orientation"),
    (lambda d: d["orientation"].update(tool0=[1, 0, 0, 0, 1, 0, 0, 0, 2]), "orientation.tool0"),
    (lambda d: d["orientation"].update(tool0=[1, 0, 0]), "orientation.tool0"),
    (lambda d: d["orientation"].update(sigma_deg=-1), "orientation.sigma_deg"),
    (lambda d: d["orientation"]["calibration"].update(mean_deg="x"), "orientation.calibration.mean_deg"),
])
def test_malformed_orientation_in_calibration_json(tmp_path, mutate, column):
    robot = robot_from_dict(ARM5, "arm")
    data, _ = simulate(robot, 40, EFFECTS, seed=1, floor_z=-10.0)
    path = tmp_path / "cal.json"
    calibrate(robot, data, "kinematic", "lm", warn=False).save(path)
    doc = json.loads(path.read_text())
    mutate(doc)
    path.write_text(json.dumps(doc))
    with pytest.raises(CalibrationFileError) as e:
        load_calibration(path)
    assert f"column {column!r}" in str(e.value) and "\n" not in str(e.value)


def test_position_only_calibration_json_refuses_an_orientation_key(tmp_path):
    robot = robot_from_dict(ARM5, "arm")
    data, _ = simulate(robot, 40, EFFECTS, seed=1, floor_z=-10.0)
    path = tmp_path / "cal.json"
    calibrate(robot, data, "kinematic", "lm", warn=False, position_only=True).save(path)
    doc = json.loads(path.read_text())
    doc["orientation"] = {"tool0": [1, 0, 0, 0, 1, 0, 0, 0, 1]}
    path.write_text(json.dumps(doc))
    with pytest.raises(CalibrationFileError, match="column 'orientation': the model has no probe orientation"):
        load_calibration(path)


def test_tool_orientation_without_orientation_data_is_an_error():
    robot = robot_from_dict(ARM5, "arm")
    data, _ = simulate(robot, 40, Effects(), seed=1, floor_z=-10.0)
    with pytest.raises(InputError, match="tool_orientation needs measured orientations"):
        calibrate(robot, data, "kinematic+tool_orientation", "lm", warn=False)
    full, _ = simulate(robot, 40, EFFECTS, seed=1, floor_z=-10.0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = calibrate(robot, full, "kinematic+tool_orientation", "lm")   # named: the same as automatic
    assert res.model.spec == "kinematic+tool_orientation"
    with pytest.raises(InputError, match="and no --position-only"):
        calibrate(robot, full, "kinematic+tool_orientation", "lm", warn=False, position_only=True)


def test_compensate_holds_the_targets_probe_orientation():
    """Targets that are full poses the calibrated model reaches at known joints: compensate finds those joints."""
    from casadical import load_robot
    from casadical.apply import compensate
    robot = load_robot("ur10")
    eff = Effects(noise=20e-6, orientation_noise=math.radians(0.005), tool_rpy=(0.0, 0.0, -1.5708))
    data, truth = simulate(robot, 80, eff, seed=1)
    cal = calibrate(robot, data, "kinematic", "lm", warn=False)
    prog, _ = simulate(robot, 10, truth=truth, seed=2)
    q_true = prog.q + np.radians(np.random.default_rng(3).normal(0, 0.3, prog.q.shape))
    want = Measurements.from_arrays(q_true)
    targets = Measurements.from_arrays(prog.q, cal.predict(want)).with_orientations(cal.predict_rotations(want))
    # targets 0.3 deg per joint from the program: reached exactly, also where a correction of 1 mm would move the
    # joints more than compensate's default bound of 2 deg (one of these rows, 7 deg per mm): a bound above that
    res = compensate(cal, targets, max_deg_per_mm=10)
    assert res.probe and "probe orientation of the targets" in res.held and "probe orientation held" in res.summary()
    assert np.degrees(np.abs(res.q - q_true)).max() < 1e-6
    # the nominal flange orientation instead: other joints (that orientation is not the targets')
    alone = compensate(cal, targets, orientation=False)
    assert not alone.probe and np.degrees(np.abs(alone.q - q_true)).max() > 0.01
    # a position-only calibration has no probe mounting to hold the targets' orientation with
    flat = calibrate(robot, data, "kinematic", "lm", warn=False, position_only=True)
    with pytest.raises(InputError, match="column 'rx_deg': holds the probe orientation.*--position-only"):
        compensate(flat, targets)
    assert compensate(flat, targets, orientation=False).converged.all()


def test_cli_full_pose_calibrate_predict_and_position_only(tmp_path, capsys):
    from casadical.cli import main
    robot = robot_from_dict(ARM7, "arm")
    data, truth = simulate(robot, 60, EFFECTS, seed=4, floor_z=-10.0)
    val, _ = simulate(robot, 20, truth=truth, seed=40, floor_z=-10.0)
    (tmp_path / "arm.toml").write_text(to_toml(ARM7))
    data.write_csv(tmp_path / "cal.csv")
    val.write_csv(tmp_path / "val.csv")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        assert main(["calibrate", str(tmp_path / "arm.toml"), str(tmp_path / "cal.csv"), "--model", "kinematic",
                     "--solver", "lm", "--out", str(tmp_path / "full.json")]) == 0
        out = capsys.readouterr().out
        assert "model kinematic+tool_orientation" in out and "full pose: positions and orientations" in out
        assert main(["predict", str(tmp_path / "full.json"), str(tmp_path / "val.csv"), "--out",
                     str(tmp_path / "pred.csv")]) == 0
        assert "error against the measured orientations: mean" in capsys.readouterr().out
        pred = Measurements.read_csv(tmp_path / "pred.csv", n_joints=7)
        assert "measured_rx_deg" in pred.columns
        e = Rotation.from_matrix(np.einsum("nji,njk->nik", pred.rotations, truth.predict_rotations(val))).magnitude()
        assert np.degrees(e).max() < 0.01
        assert main(["calibrate", str(tmp_path / "arm.toml"), str(tmp_path / "cal.csv"), "--model", "kinematic",
                     "--solver", "lm", "--position-only", "--out", str(tmp_path / "pos.json")]) == 0
        out = capsys.readouterr().out
        assert "model kinematic\n" in out and "full pose" not in out and "orientation:" not in out
        assert "orientation" not in json.loads((tmp_path / "pos.json").read_text())


def test_diagnosis_fits_the_full_pose_and_reports_orientation():
    """A compliant joint hidden in full-pose data: found with the full-pose loss; every full fit reports its
    orientation error on the validation poses; --position-only is the diagnosis as it was."""
    from casadical import load_robot
    from casadical.diagnosis import DiagnosisSettings, diagnose
    robot = load_robot("ys100")
    eff = Effects(stiffness={3: 1.2e6}, orientation_noise=math.radians(0.003), tool_rpy=(0.2, -0.3, 1.0))
    cal, truth = simulate(robot, 80, eff, seed=1)
    val, _ = simulate(robot, 200, truth=truth, seed=501)
    rep = diagnose(robot, cal, val, DiagnosisSettings(seed=1, blackbox=False))
    assert [(f.cause, f.candidate.joint) for f in rep.findings] == [("geometric", None), ("joint_compliance", 3)]
    assert rep.final.full_pose and rep.final.has_orientation
    full = [s for s in rep.steps if s.accepted]
    assert all(s.orientation is not None for s in full) and full[-1].orientation.mean_deg < 0.01
    doc = rep.to_dict()
    assert "orientation" in doc["final"] and "orientation" in doc["steps"][0]
    assert "val deg" in rep.text() and any(n.startswith("full pose:") for n in rep.notes)
    flat = diagnose(robot, cal, val, DiagnosisSettings(seed=1, blackbox=False, position_only=True))
    assert not flat.final.has_orientation and "orientation" not in flat.to_dict()["final"]
    assert "val deg" not in flat.text()
