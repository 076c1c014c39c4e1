"""Issue 21: every bad case is one clear line, naming the right rows, after bounded work; the robots that matter
are arms that are not built in (tests/helpers/arms.py).

The issue's other parts: interrupts stop the work (tests/runtime/test_interrupts.py), a fit that does not fit is
an error (tests/measurements/test_robot_mismatch.py).
"""

import gc
from pathlib import Path

import numpy as np
import pytest

from casadical import load_robot
from casadical.cli import main
from casadical.data import Effects, simulate
from casadical.errors import DataFileError
from casadical.robot import robot_from_dict
from tests.helpers.arms import ARM5
from tests.helpers.cli import arm_files, cli, one_error  # the command line in-process, its one-line errors

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def arms(tmp_path_factory):
    """``arms(name, n, seed)``: (robot TOML, simulated poses CSV) of a test arm, made once per module."""
    folder = str(tmp_path_factory.mktemp("arms"))
    return lambda name, n, seed=0: arm_files(folder, name, n, seed)


# --- every case one clear line, right rows, bounded work --------------------------------------------------


@pytest.fixture(scope="module")
def study_results(tmp_path_factory):
    """A finished 2-repetition study of a four-axis arm (serial) and its protocol."""
    from tests.study.test_study import write_study

    folder = tmp_path_factory.mktemp("study")
    protocol = write_study(folder, reps=2)
    assert main(["study", protocol, "--out", str(folder / "r"), "--serial", "--quiet"]) == 0
    return Path(protocol), folder / "r"


@pytest.mark.parametrize("damage", ["truncated", "empty", "garbage"])
def test_resuming_a_study_with_a_damaged_part(study_results, tmp_path, capsys, damage):
    import shutil

    protocol, results = study_results
    out = tmp_path / "r"
    shutil.copytree(results, out)
    part = next(out.glob("part-*.parquet"))
    part.write_bytes({"truncated": part.read_bytes()[:100], "empty": b"", "garbage": b"garbage\n"}[damage])
    bigger = tmp_path / protocol.name
    bigger.write_text(protocol.read_text().replace("repetitions = 2", "repetitions = 3"))
    shutil.copy(protocol.parent / "arm4-dh.toml", tmp_path)
    code, _, err = cli(capsys, "study", bigger, "--out", out, "--serial", "--quiet")
    assert code == 2
    one_error(err, str(part), "is damaged", "delete it")
    code, _, err = cli(capsys, "study", "--summary", out)
    assert code == 2
    one_error(err, str(part), "is damaged")


def test_absurd_repetitions_are_refused_at_once(study_results, tmp_path, capsys):
    protocol, _ = study_results
    big = tmp_path / protocol.name
    big.write_text(protocol.read_text().replace("repetitions = 2", "repetitions = 1000000000"))
    (tmp_path / "arm4-dh.toml").write_text((protocol.parent / "arm4-dh.toml").read_text())
    code, _, err = cli(capsys, "study", big, "--out", tmp_path / "r", "--serial")
    assert code == 2
    one_error(err, str(big), "'repetitions'", "at most 1,000,000")
    assert not (tmp_path / "r").exists()


def dask_clients() -> int:
    """The Dask clients alive in this process (no garbage collection first: what one is waiting for counts)."""
    import distributed

    return sum(isinstance(o, distributed.Client) for o in gc.get_objects())


def test_a_scheduler_that_cannot_be_reached_leaves_nothing(study_results, tmp_path, capsys):
    pytest.importorskip("distributed")
    protocol, _ = study_results
    before = dask_clients()
    code, _, err = cli(capsys, "study", protocol, "--out", tmp_path / "r", "--scheduler", "nosuch://host:1", "--quiet")
    assert code == 2
    assert dask_clients() <= before
    one_error(err, "nosuch://host:1", "cannot reach the Dask scheduler")
    assert not (tmp_path / "r").exists()


def test_a_refused_scheduler_says_it_is_trying_and_leaves_nothing(study_results, tmp_path, capsys, monkeypatch):
    """A TCP address nothing listens at: Dask retries until the timeout, and the user is told so at once."""
    pytest.importorskip("distributed")
    from casadical.study import _runner as runner

    monkeypatch.setattr(runner, "CONNECT_TIMEOUT_S", 1)
    protocol, _ = study_results
    before = dask_clients()
    code, _, err = cli(capsys, "study", protocol, "--out", tmp_path / "r", "--scheduler", "tcp://127.0.0.1:1")
    assert code == 2
    # the client that failed to connect is closed before the error is said, not left to a garbage collection that
    # may come inside another client's start and hang the process (Dask's loop runners share one lock)
    assert dask_clients() <= before
    assert any("connecting to the Dask scheduler at tcp://127.0.0.1:1 (trying for up to 1 s)" in line for line in err)
    assert "cannot reach the Dask scheduler" in err[-1] and "tcp://127.0.0.1:1" in err[-1]
    assert not (tmp_path / "r").exists()


URDF_LINK = '<link name="{}"/>'
URDF_JOINT = ('<joint name="{n}" type="revolute"><parent link="{p}"/><child link="{c}"/><origin xyz="{o}" rpy="0 0 0"/>'
              '<axis xyz="{ax}"/><limit lower="-2" upper="2" effort="1" velocity="1"/></joint>')


def _urdf(origin2="0 0 0.3") -> str:
    body = "".join(URDF_LINK.format(x) for x in "abcde")
    body += URDF_JOINT.format(n="j1", p="a", c="b", o="0 0 0.4", ax="0 0 1")
    body += "\n" + URDF_JOINT.format(n="j2", p="b", c="c", o=origin2, ax="0 1 0")
    body += "\n" + URDF_JOINT.format(n="j3", p="c", c="d", o="0 0 0.7", ax="0 1 0")
    body += '\n<joint name="t" type="fixed"><parent link="d"/><child link="e"/><origin xyz="0.5 0 0"/></joint>'
    return '<?xml version="1.0"?>\n<robot name="hand-written arm">\n' + body + "\n</robot>\n"


def test_urdf_joint_origin_of_1e300(tmp_path, capsys):
    (tmp_path / "r.urdf").write_text(_urdf("1e300 0 0.3"))
    code, _, err = cli(capsys, "inspect", tmp_path / "r.urdf")
    assert code == 2
    one_error(err, "r.urdf, row 4", "joint 'j2'", "1e+300 m", "metres")


def test_compliance_of_a_urdf_without_inertial(tmp_path, capsys):
    from casadical import load_robot

    (tmp_path / "r.urdf").write_text(_urdf())
    data, _ = simulate(load_robot(tmp_path / "r.urdf"), 40, Effects(), seed=0, floor_z=None)
    data.write_csv(tmp_path / "d.csv")
    code, _, err = cli(capsys, "calibrate", tmp_path / "r.urdf", tmp_path / "d.csv", "--model",
                       "kinematic+compliance", "--out", tmp_path / "c.json")
    assert code == 2
    one_error(err, "r.urdf", "no link masses", "<inertial>", "--model kinematic")
    assert cli(capsys, "calibrate", tmp_path / "r.urdf", tmp_path / "d.csv", "--model", "kinematic",
               "--out", tmp_path / "c.json")[0] == 0


def test_negative_payload_in_a_data_file(arms, tmp_path, capsys):
    from casadical.data import Measurements

    robot, data = arms("arm5", 40)
    d = Measurements.read_csv(data)
    Measurements({**d.columns, "payload_kg": np.full(len(d), 5.0)}).write_csv(tmp_path / "p.csv")
    lines = (tmp_path / "p.csv").read_text().splitlines()
    col = lines[0].split(",").index("payload_kg")
    cells = lines[4].split(",")
    cells[col] = "-20"                                              # row 5 of the file
    lines[4] = ",".join(cells)
    (tmp_path / "p.csv").write_text("\n".join(lines) + "\n")
    code, _, err = cli(capsys, "calibrate", robot, tmp_path / "p.csv", "--out", tmp_path / "c.json")
    assert code == 2
    one_error(err, "p.csv, row 5, column 'payload_kg'", "-20 kg")
    with pytest.raises(DataFileError, match="row 5, column 'payload_kg'.*-20 kg"):     # made in memory, too
        Measurements({**d.columns, "payload_kg": np.where(np.arange(len(d)) == 3, -20.0, 5.0)})
    with pytest.raises(DataFileError, match="-3 kg"):
        simulate(load_robot(robot), 10, Effects(), seed=0, payload_kg=-3.0)


def test_simulate_leaves_no_folder_behind_when_the_protocol_fails(tmp_path, capsys):
    """A protocol whose workspace keeps too few poses fails in the work: --out-dir is not made."""
    text = (Path(__file__).parents[2] / "problems" / "protocols" / "ca-ys100.toml").read_text()
    (tmp_path / "p.toml").write_text(text.replace("floor_z_m = 0.0", "floor_z_m = 50.0"))
    code, _, err = cli(capsys, "simulate", tmp_path / "p.toml", "--out-dir", tmp_path / "new" / "sim")
    assert code == 2
    one_error(err, "too few poses")
    assert not (tmp_path / "new").exists()
    (tmp_path / "file").write_text("x")
    code, _, err = cli(capsys, "simulate", "ca-ys100", "--out-dir", tmp_path / "file")
    assert code == 2
    one_error(err, "file", "names a file, not a folder")


@pytest.fixture(scope="module")
def arm_calibration(arms, tmp_path_factory):
    robot, data = arms("arm4", 60)
    path = tmp_path_factory.mktemp("cal") / "cal.json"
    assert main(["calibrate", robot, data, "--model", "kinematic", "--solver", "lm", "--out", str(path)]) == 0
    return path


def test_calibration_from_a_future_version(arm_calibration, tmp_path, capsys):
    import json

    doc = json.loads(arm_calibration.read_text())
    doc["casadical_version"] = "99.0"
    (tmp_path / "future.json").write_text(json.dumps(doc))
    code, _, err = cli(capsys, "export", tmp_path / "future.json", "--urdf", tmp_path / "r.urdf")
    assert code == 2
    one_error(err, "future.json, column 'casadical_version'", "written by casadical 99.0", "update casadical")
    assert not (tmp_path / "r.urdf").exists()


def test_hand_edited_huge_link_length_is_not_exported(arm_calibration, tmp_path, capsys):
    import json

    doc = json.loads(arm_calibration.read_text())
    k = next(i for i, p in enumerate(doc["parameters"]) if p["name"] == "a3")
    doc["parameters"][k]["value"] = 1e308
    (tmp_path / "huge.json").write_text(json.dumps(doc))
    code, _, err = cli(capsys, "export", tmp_path / "huge.json", "--urdf", tmp_path / "r.urdf", "--table",
                       tmp_path / "t.csv")
    assert code == 2
    one_error(err, f"huge.json, column 'parameters[{k}].value'", "a3", "length in mm")
    assert not (tmp_path / "r.urdf").exists() and not (tmp_path / "t.csv").exists()


@pytest.mark.parametrize("variable, value", [("CASADICAL_CACHE_MAX_MB", "lots"), ("CASADICAL_CACHE_MAX_MB", "-1"),
                                             ("CASADICAL_JIT", "maybe")])
def test_bad_cache_variables_are_errors(monkeypatch, capsys, variable, value):
    monkeypatch.setenv(variable, value)
    code, _, err = cli(capsys, "cache", "--info")
    assert code == 2
    one_error(err, variable, repr(value))


def _oversized(path: Path, sep: str) -> None:
    """A measurement file whose row 5 has a field too large for Python's csv reader (131,072 characters)."""
    rows = ["q1_deg,q2_deg,q3_deg,q4_deg,x_mm,y_mm,z_mm"] + [",".join(["1"] * 7)] * 6
    rows[4] = ",".join(["1", "2" * 200_000] + ["1"] * 5)
    path.write_text("\n".join(r.replace(",", sep) for r in rows) + "\n")


def test_an_oversized_cell_is_reported_in_its_row(tmp_path, capsys):
    _oversized(tmp_path / "d.csv", ",")
    code, _, err = cli(capsys, "split", tmp_path / "d.csv", "-n", "2", "--out-cal", tmp_path / "a.csv",
                       "--out-val", tmp_path / "b.csv")
    assert code == 2
    one_error(err, "d.csv, row 5", "field larger than field limit")
    _oversized(tmp_path / "t.txt", ";")
    code, _, err = cli(capsys, "import", tmp_path / "t.txt", "--map", "separator=;", "--map",
                       "joints=q1_deg,q2_deg,q3_deg,q4_deg", "--map", "joint_unit=deg", "--map",
                       "position=x_mm,y_mm,z_mm", "--map", "position_unit=mm", "--out", tmp_path / "o.csv")
    assert code == 2
    one_error(err, "t.txt, row 5", "field larger than field limit")


def test_too_few_poses_name_the_file(arms, tmp_path, capsys):
    robot, data = arms("arm5", 40)
    lines = Path(data).read_text().splitlines()
    for n, what in ((6, "poses give"), (3, "at least 3 measured poses")):
        (tmp_path / f"few{n}.csv").write_text("\n".join(lines[:n]) + "\n")
        code, _, err = cli(capsys, "calibrate", robot, tmp_path / f"few{n}.csv", "--out", tmp_path / "c.json")
        assert code == 2
        one_error(err, f"few{n}.csv: ", what)


def test_a_huge_skip_lines_is_bounded_work_and_names_the_key(tmp_path, capsys):
    _oversized(tmp_path / "t.txt", ";")
    code, _, err = cli(capsys, "import", tmp_path / "t.txt", "--map", "separator=;", "--map",
                       "joints=q1_deg,q2_deg,q3_deg,q4_deg", "--map", "joint_unit=deg", "--map",
                       "position=x_mm,y_mm,z_mm", "--map", "position_unit=mm", "--map", "skip_lines=2147483648",
                       "--out", tmp_path / "o.csv")
    assert code == 2
    one_error(err, "--map, column 'skip_lines'", "2,147,483,648", "has 7")


# --- the same measurements twice ----------------------------------------------------------------------------


def test_validation_poses_that_are_calibration_poses(arms, tmp_path, capsys):
    """``--validate`` with the calibration file (or a copy) is an error: nothing would be held out; some shared
    rows are a warning with their count and the first one's row. calibrate, diagnose and compare alike."""
    import shutil

    robot, data = arms("arm5", 60)
    _, val = arms("arm5", 40, 1)
    shutil.copy(data, tmp_path / "copy.csv")
    for cmd in (["calibrate", robot, data, "--out", tmp_path / "c.json"],
                ["diagnose", robot, data, "--json", tmp_path / "r.json", "--quiet"],
                ["compare", robot, data, "--methods", "KM"]):
        code, _, err = cli(capsys, *cmd, "--validate", tmp_path / "copy.csv")
        assert code == 2, cmd
        one_error(err, "copy.csv", "every one of its 60 poses is a calibration pose of", "not held out",
                  "casadical split")
        assert not (tmp_path / "c.json").exists() and not (tmp_path / "r.json").exists()
    _, other = arms("arm5", 50, 2)
    code, _, err = cli(capsys, "diagnose", robot, data, "--validate", other, "--transfer", tmp_path / "copy.csv",
                       "--json", tmp_path / "r.json", "--quiet")
    assert code == 2
    one_error(err, "copy.csv", "every one of its 60 poses is a calibration pose of", "no test of another series")
    assert not (tmp_path / "r.json").exists()
    # 5 calibration rows among the validation poses: a warning naming them, the rest is done
    lines = Path(val).read_text().splitlines()
    (tmp_path / "mixed.csv").write_text("\n".join(lines[:11] + Path(data).read_text().splitlines()[3:8]
                                                  + lines[11:]) + "\n")
    code, _, err = cli(capsys, "calibrate", robot, data, "--out", tmp_path / "c.json", "--validate",
                       tmp_path / "mixed.csv")
    assert code == 0
    assert any("mixed.csv: 5 of its 45 poses (the first in row 12) are calibration poses of" in e for e in err), err


def test_a_session_given_twice(arms, tmp_path, capsys):
    """The same file (or its copy) as two sessions would count every pose twice: an error. Two sessions that
    measured one joint program (the same readings, other points) are what sessions are for."""
    import shutil

    from casadical.data import Measurements

    robot, data = arms("arm5", 60)
    shutil.copy(data, tmp_path / "b.csv")
    code, _, err = cli(capsys, "calibrate", robot, data, data, "--out", tmp_path / "c.json")
    assert code == 2
    one_error(err, "every one of its 60 poses is also in", "the same file given twice", "count twice")
    code, _, err = cli(capsys, "calibrate", robot, data, tmp_path / "b.csv", "--out", tmp_path / "c.json")
    assert code == 2
    one_error(err, "b.csv", "every one of its 60 poses is also in", "count twice")
    d = Measurements.read_csv(data)
    moved = dict(d.columns)
    for axis in ("x_mm", "y_mm", "z_mm"):       # the same joint program, measured again from elsewhere
        moved[axis] = d.columns[axis] + 250.0 + np.random.default_rng(0).normal(0, 0.01, len(d))
    Measurements(moved).write_csv(tmp_path / "again.csv")
    code, _, err = cli(capsys, "calibrate", robot, data, tmp_path / "again.csv", "--out", tmp_path / "c.json")
    assert code == 0 and not any("also in" in e for e in err)


def test_row_spacing_on_a_file_with_times_says_the_times_are_used(arms, tmp_path, capsys):
    from casadical.data import Measurements

    robot, data = arms("arm5", 40)
    d = Measurements.read_csv(data)
    Measurements({**d.columns, "time_s": np.arange(len(d)) * 7.0}).write_csv(tmp_path / "t.csv")
    code, _, err = cli(capsys, "calibrate", robot, tmp_path / "t.csv", "--model", "kinematic", "--row-spacing-s", "2",
                       "--out", tmp_path / "c.json")
    assert code == 0
    assert any("t.csv: has a time_s column, whose times are used; --row-spacing-s applies to files without one" in e
               for e in err), err


def test_keep_compensator_needs_a_calibration_with_one(arms, arm_calibration, tmp_path, capsys):
    robot, data = arms("arm4", 60)
    for source, words in ((robot, "give a calibration JSON in place of ROBOT"), (arm_calibration, "has none")):
        code, _, err = cli(capsys, "calibrate", source, data, "--model", "base", "--keep-compensator",
                           "--out", tmp_path / "c.json")
        assert code == 2
        one_error(err, "--keep-compensator", words)


def test_compare_refuses_poses_of_another_tracker_set_up(arms, tmp_path, capsys):
    """compare --validate / --extra in another measurement frame (the tracker moved) are judged by metres: one
    line before the work; --allow-mismatch lets them through with a warning."""
    robot, data = arms("arm5", 60)
    _, val = arms("arm5", 40, 1)
    moved, _ = simulate(robot_from_dict(ARM5, "arm5"), 40, Effects(base_xyz=(1.5, -0.5, 0.3),
                                                                   base_rpy=(0.0, 0.0, 1.0)), seed=9)
    moved.write_csv(tmp_path / "moved.csv")
    for option in ("--validate", "--extra"):
        args = ["--validate", val] if option == "--extra" else []
        code, _, err = cli(capsys, "compare", robot, data, *args, option, tmp_path / "moved.csv", "--methods", "KM")
        assert code == 2
        one_error(err, "moved.csv", f"the {'extra' if option == '--extra' else 'validation'} poses are missed by",
                  "not in that measurement frame", "--allow-mismatch")
    code, _, err = cli(capsys, "compare", robot, data, "--validate", tmp_path / "moved.csv", "--methods", "KM",
                       "--allow-mismatch")
    assert code == 0 and any("allowed by --allow-mismatch" in e for e in err)


def test_transfer_options_need_a_transfer(arms, tmp_path, capsys):
    robot, data = arms("arm5", 60)
    _, val = arms("arm5", 40, 1)
    code, _, err = cli(capsys, "diagnose", robot, data, "--validate", val, "--transfer-base-poses", "10",
                       "--json", tmp_path / "r.json")
    assert code == 2
    one_error(err, "--transfer-base-poses", "give --transfer OTHER.csv")
