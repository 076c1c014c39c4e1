"""A fit that does not fit is an error: another robot's poses, or positions in the wrong unit, are refused by every
command that fits or predicts, and the rule never fires on real data (casadical/data/_checks.py; issue 21).
"""


import numpy as np
import pytest

from casadical.data import Effects, simulate
from casadical.robot import robot_from_dict
from tests.helpers.arms import ARM4
from tests.helpers.cli import arm_files, cli, one_error


@pytest.fixture(scope="module")
def arms(tmp_path_factory):
    """``arms(name, n, seed)``: (robot TOML, simulated poses CSV) of a test arm, made once per module."""
    folder = str(tmp_path_factory.mktemp("arms"))
    return lambda name, n, seed=0: arm_files(folder, name, n, seed)


# --- another robot's poses -------------------------------------------------------------------------------


def _palletiser_poses(tmp_path, n=60, seed=3):
    """Poses of the four-axis test arm (ARM4_BETA) within the limits of the four-axis palletiser (ARM4):
    another robot's data that passes every check of joints and units."""
    from tests.helpers.arms import ARM4_BETA

    other = {**ARM4_BETA, "joint": [dict(j, min_deg=max(j["min_deg"], k["min_deg"]),
                                         max_deg=min(j["max_deg"], k["max_deg"]))
                                    for j, k in zip(ARM4_BETA["joint"], ARM4["joint"])]}
    data, _ = simulate(robot_from_dict(other, "other"), n, Effects(), seed=seed)
    path = tmp_path / "other-robot.csv"
    data.write_csv(path, overwrite=True)
    return str(path)


def test_another_robots_poses_are_refused_by_calibrate(arms, tmp_path, capsys):
    robot, _ = arms("arm4", 60)
    other = _palletiser_poses(tmp_path)
    code, _, err = cli(capsys, "calibrate", robot, other, "--model", "kinematic", "--out", tmp_path / "c.json")
    assert code == 2
    one_error(err, other, "the nominal model of robot four-axis palletiser", "do not belong together",
              "--allow-mismatch")
    assert not (tmp_path / "c.json").exists()
    code, _, err = cli(capsys, "calibrate", robot, other, "--model", "kinematic", "--out", tmp_path / "c.json",
                       "--allow-mismatch")
    assert code == 0 and any("allowed by --allow-mismatch" in line for line in err)


def test_another_robots_poses_are_refused_by_predict_with_the_robot(arms, tmp_path, capsys):
    """``predict ROBOT OTHER.csv``: the nominal model judges the poses as calibrate's does."""
    robot, data = arms("arm4", 60)
    assert cli(capsys, "predict", robot, data, "--out", tmp_path / "own.csv")[0] == 0
    other = _palletiser_poses(tmp_path)
    code, _, err = cli(capsys, "predict", robot, other, "--out", tmp_path / "p.csv")
    assert code == 2
    one_error(err, other, "the nominal model of robot four-axis palletiser", "do not belong together",
              "--allow-mismatch")
    assert not (tmp_path / "p.csv").exists()
    code, _, err = cli(capsys, "predict", robot, other, "--out", tmp_path / "p.csv", "--allow-mismatch")
    assert code == 0 and any("allowed by --allow-mismatch" in line for line in err)


def test_another_robots_poses_are_refused_by_a_calibration_taken_further(arms, tmp_path, capsys):
    """``calibrate CAL.json OTHER.csv --model base``: the base pose alone cannot bring them near."""
    robot, data = arms("arm4", 60)
    assert cli(capsys, "calibrate", robot, data, "--model", "kinematic", "--out", tmp_path / "cal.json")[0] == 0
    _, own_data = arms("arm4", 40, 7)
    code, _, _ = cli(capsys, "calibrate", tmp_path / "cal.json", own_data, "--model", "base",
                     "--out", tmp_path / "b.json")
    assert code == 0                     # its own robot's poses: taken further as before
    other = _palletiser_poses(tmp_path)
    code, _, err = cli(capsys, "calibrate", tmp_path / "cal.json", other, "--model", "base",
                       "--out", tmp_path / "x.json")
    assert code == 2
    one_error(err, other, f"the calibration {tmp_path / 'cal.json'}", "with its base pose fitted",
              "do not belong together", "--allow-mismatch")


def test_another_robots_poses_are_refused_by_diagnose_transfer(arms, tmp_path, capsys):
    robot, data = arms("arm4", 60)
    _, val = arms("arm4", 40, 5)
    other = _palletiser_poses(tmp_path, 80)
    code, _, err = cli(capsys, "diagnose", robot, data, "--validate", val, "--transfer", other,
                       "--json", tmp_path / "r.json", "--quiet")
    assert code == 2
    one_error(err, other, "do not belong together", "--allow-mismatch")
    assert not (tmp_path / "r.json").exists()


def test_the_mismatch_rule_never_fires_on_real_data():
    """The bundled UR10 series, every seed-paper protocol's pose sets and the test arms' simulated poses
    pass (with a margin of 10 to the rule), as does a calibration of series B taken to series A."""
    from casadical import calibrate, load_robot
    from casadical.data import REACH_SHARE, Measurements, base_fitted_errors, check_poses, load_protocol
    from casadical.model import Model
    from casadical.robot import PROBLEMS
    from casadical.terms import reach
    from tests.helpers.arms import ARM3, ARM4_BETA, ARM7_DH, ARMS

    cases = [(load_robot("ur10"), Measurements.read_csv(PROBLEMS / "datasets" / "ur10-ipa" / f"series_{s}.csv"))
             for s in "ab"]
    for f in sorted((PROBLEMS / "protocols").glob("*.toml")):
        proto = load_protocol(str(f))
        cases += [(proto.robot, d) for d in proto.generate(None)[0].values()]
    for name, arm in {**ARMS, "arm3": ARM3, "arm4b": ARM4_BETA, "arm7dh": ARM7_DH}.items():
        robot = robot_from_dict(arm, name)
        cases.append((robot, simulate(robot, 100, Effects(), seed=0)[0]))
    for robot, data in cases:
        check_poses(data, robot)
        p = Model(robot, "nominal", jit=False).predict(data.q)
        median = np.median(base_fitted_errors(p, data.xyz))
        assert median < REACH_SHARE / 10 * reach(robot), (robot.name, data.path)   # measured: 0.22 % at most
    b, a = cases[1][1], cases[0][1]
    cal = calibrate(load_robot("ur10"), b.subset(np.arange(300)), "kinematic", "lm", warn=False)
    calibrate(cal, a, "base", "lm", warn=False)


def test_positions_in_mm_declared_as_metres_in_an_import_map(tmp_path, capsys):
    src = tmp_path / "tracker.txt"
    rng = np.random.default_rng(0)
    rows = ["j1;j2;j3;X;Y;Z"] + [";".join(f"{v:.4f}" for v in (*rng.uniform(-90, 90, 3),
                                                                 *rng.uniform(-900, 900, 3))) for _ in range(10)]
    src.write_text("\n".join(rows) + "\n")
    base = ["--map", "separator=;", "--map", "joints=j1,j2,j3", "--map", "joint_unit=deg",
            "--map", "position=X,Y,Z"]
    code, _, err = cli(capsys, "import", src, *base, "--map", "position_unit=m", "--out", tmp_path / "o.csv")
    assert code == 2
    one_error(err, "--map, column 'position_unit'", "km around their centre", 'set position_unit = "mm"')
    assert not (tmp_path / "o.csv").exists()
    assert cli(capsys, "import", src, *base, "--map", "position_unit=mm", "--out", tmp_path / "o.csv")[0] == 0
