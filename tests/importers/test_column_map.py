"""``casadical import``: any tracker file with a column mapping (casadical.importers._mapped).

The main test writes a tracker file the way public UR5 / WAM data come
(target + deviation, ';' separated, decimal comma, radians and metres, a BOM,
CRLF and an empty trailing column) from a simulated robot that is not built
in, imports it with a mapping, and calibrates on it: the calibrated model
must predict the simulated robot's unseen poses at the noise level, which it
cannot if a unit or the deviation's sign is wrong (checked too).
"""

from __future__ import annotations

import csv
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from casadical import calibrate
from casadical.cli import main
from casadical.data import Effects, Measurements, simulate
from casadical.errors import ColumnMapError, DataFileError, DataWarning
from casadical.importers import import_file, load_column_map, read_mapped
from casadical.model import Model
from casadical.robot import robot_from_dict

ROOT = Path(__file__).resolve().parents[2]
DATASET = ROOT / "problems" / "datasets" / "ur10-ipa"
RAW_B = DATASET / "raw" / "Series_B" / "measurements_joint_configurations.csv"
SERIES_B = DATASET / "series_b.csv"

# Barrett WAM-like 7-axis arm (standard DH, no parallel axes: no Hayati beta)
WAM7 = {
    "name": "wam-like", "convention": "dh",
    "joint": [
        {"alpha_deg": -90, "a_m": 0.0, "d_m": 0.0, "min_deg": -150, "max_deg": 150, "mass_kg": 10.0},
        {"alpha_deg": 90, "a_m": 0.0, "d_m": 0.0, "min_deg": -113, "max_deg": 113, "mass_kg": 3.9},
        {"alpha_deg": -90, "a_m": 0.045, "d_m": 0.55, "min_deg": -157, "max_deg": 157, "mass_kg": 1.8},
        {"alpha_deg": 90, "a_m": -0.045, "d_m": 0.0, "min_deg": -50, "max_deg": 180, "mass_kg": 2.4},
        {"alpha_deg": -90, "a_m": 0.0, "d_m": 0.3, "min_deg": -270, "max_deg": 75, "mass_kg": 0.3},
        {"alpha_deg": 90, "a_m": 0.0, "d_m": 0.0, "min_deg": -90, "max_deg": 90, "mass_kg": 0.4},
        {"alpha_deg": 0, "a_m": 0.0, "d_m": 0.06, "min_deg": -170, "max_deg": 170, "mass_kg": 0.1},
    ],
    "tool": {"a_m": 0.03, "b_m": 0.02, "d_m": 0.1},
}
# 5-axis arm (modified DH, Hayati beta on joint 3: axes 2 and 3 parallel)
ARM5 = {
    "name": "five-axis test arm", "convention": "mdh",
    "joint": [
        {"alpha_deg": 0, "a_m": 0.0, "d_m": 0.4, "mass_kg": 20.0},
        {"alpha_deg": -90, "a_m": 0.1, "d_m": 0.0, "min_deg": -100, "max_deg": 100, "mass_kg": 12.0},
        {"alpha_deg": 0, "a_m": 0.5, "beta_deg": 0.0, "d_m": 0.0, "min_deg": -150, "max_deg": 150,
         "mass_kg": 8.0},
        {"alpha_deg": -90, "a_m": 0.05, "d_m": 0.45, "mass_kg": 3.0},
        {"alpha_deg": 90, "a_m": 0.0, "d_m": 0.0, "min_deg": -120, "max_deg": 120, "mass_kg": 1.0},
    ],
    "tool": {"a_m": 0.03, "d_m": 0.12},
}
ROBOTS = {"wam7-dh": WAM7, "arm5-mdh-beta": ARM5}
NOISE = 20e-6


def _comma(x: float) -> str:
    return repr(float(x)).replace(".", ",")


def _tracker_lines(data: Measurements, target_m: np.ndarray, sign: str) -> list[str]:
    """Lines of a ';' separated, decimal-comma tracker file: joints (rad), target (m), deviation (mm)."""
    n = data.n_joints
    header = (["Pose"] + [f"J{i}" for i in range(1, n + 1)] + ["X_target", "Y_target", "Z_target"]
              + ["dX", "dY", "dZ", "Temperature", "Note", ""])
    dev_mm = (data.xyz - target_m) * 1000.0
    if sign == "target-measured":
        dev_mm = -dev_mm
    lines = [";".join(header)]
    for k in range(len(data)):
        cells = ([str(k + 1)] + [_comma(v) for v in data.q[k]] + [_comma(v) for v in target_m[k]]
                 + [_comma(v) for v in dev_mm[k]] + [_comma(21.5 + 0.01 * k), f"pose {k + 1}", ""])
        lines.append(";".join(cells))
    return lines


def _write_tracker(path: Path, lines: list[str]) -> Path:
    """With a UTF-8 byte order mark and CRLF line ends, as spreadsheets export."""
    path.write_bytes(b"\xef\xbb\xbf" + ("\r\n".join(lines) + "\r\n").encode())
    return path


def _mapping(path: Path, n: int, sign: str, **changes: str) -> Path:
    keys = {
        "separator": '";"', "decimal": '","',
        "joints": "[" + ", ".join(f'"J{i}"' for i in range(1, n + 1)) + "]",
        "joint_unit": '"rad"',
        "target": '["X_target", "Y_target", "Z_target"]', "target_unit": '"m"',
        "deviation": '["dX", "dY", "dZ"]', "deviation_unit": '"mm"',
        "deviation_sign": f'"{sign}"',
    }
    keys.update(changes)
    path.write_text("\n".join(f"{k} = {v}" for k, v in keys.items())
                    + '\n\n[keep]\nTemperature = "temperature_c"\n')
    return path


def _campaign(robot, seed: int):
    eff = Effects(noise=NOISE, base_xyz=(2.0, -1.0, 0.3), base_rpy=(0.01, -0.02, 1.2))
    cal, truth = simulate(robot, 60, eff, seed=seed, floor_z=None)
    val, _ = simulate(robot, 100, truth=truth, seed=seed + 100, floor_z=None)
    # the tracker software's target: the nominal robot, placed in the tracker frame
    target = Model(robot, "nominal", jit=False).predict(cal.q, base0=truth.base0)
    return cal, val, target


@pytest.mark.parametrize("seed", [0, 1, 2])
@pytest.mark.parametrize("name", sorted(ROBOTS))
def test_target_deviation_file_recovers_the_simulated_robot(tmp_path, name, seed):
    robot = robot_from_dict(ROBOTS[name])
    cal, val, target = _campaign(robot, seed)
    n = robot.n
    src = _write_tracker(tmp_path / "tracker.csv", _tracker_lines(cal, target, "measured-target"))
    out = tmp_path / "poses.csv"
    imported = import_file(src, out, load_column_map([str(_mapping(tmp_path / "m.toml", n,
                                                                      "measured-target"))]))
    data = Measurements.read_csv(out, n_joints=n, require_positions=True)
    assert list(data.columns)[: n + 4] == [f"q{i}_deg" for i in range(1, n + 1)] + [
        "x_mm", "y_mm", "z_mm", "temperature_c"]
    assert list(data.columns)[n + 4:] == ["pose", "note"] and data.columns["note"][2] == "pose 3"
    assert len(imported) == len(cal) and [m.output for m in imported.mapped][n:n + 3] == ["x_mm", "y_mm", "z_mm"]
    np.testing.assert_allclose(data.q_deg, cal.q_deg, rtol=1e-14, atol=1e-12)
    np.testing.assert_allclose(data.xyz, cal.xyz, rtol=0, atol=1e-12)

    # the geometry identified from the imported file predicts unseen poses at the noise level
    nominal = calibrate(robot, data, "nominal", "lm", warn=False).stats(val).rms_mm
    rms = calibrate(robot, data, "kinematic", "lm", warn=False).stats(val).rms_mm
    noise_mm = NOISE * 1000 * np.sqrt(3)
    assert rms < 1.5 * noise_mm < 0.1 * nominal, (rms, nominal)

    # the same deviations written with the other sign give the same output when the mapping says so
    src2 = _write_tracker(tmp_path / "tracker2.csv", _tracker_lines(cal, target, "target-measured"))
    out2 = tmp_path / "poses2.csv"
    import_file(src2, out2, load_column_map([str(_mapping(tmp_path / "m2.toml", n, "target-measured"))]))
    assert out2.read_bytes() == out.read_bytes()

    # ... and a mapping with the wrong sign is caught by the calibration (the test can fail)
    wrong = read_mapped(src2, load_column_map([str(tmp_path / "m.toml")])).measurements()
    assert calibrate(robot, wrong, "kinematic", "lm", warn=False).stats(val).rms_mm > 20 * noise_mm


def test_key_value_pairs_are_the_same_mapping_as_the_toml(tmp_path):
    robot = robot_from_dict(WAM7)
    cal, _, target = _campaign(robot, 5)
    src = _write_tracker(tmp_path / "t.csv", _tracker_lines(cal.subset(np.arange(8)), target[:8],
                                                            "measured-target"))
    toml = _mapping(tmp_path / "m.toml", 7, "measured-target")
    a, b = tmp_path / "a.csv", tmp_path / "b.csv"
    assert main(["import", str(src), "--map", str(toml), "--out", str(a)]) == 0
    pairs = ["separator=;", "decimal=,", "joints=" + ",".join(f"J{i}" for i in range(1, 8)),
             "joint_unit=rad", "target=X_target,Y_target,Z_target", "target_unit=m",
             'deviation=["dX", "dY", "dZ"]', "deviation_unit=mm", "deviation_sign=measured-target",
             "keep.Temperature=temperature_c"]
    assert main(["import", str(src), *sum((["--map", p] for p in pairs), []), "--out", str(b)]) == 0
    assert a.read_bytes() == b.read_bytes()
    # an override wins over the file and errors in it name --map
    assert main(["import", str(src), "--map", str(toml), "--map", "others=drop", "--out", str(b),
                 "--force"]) == 0
    assert "note" not in Measurements.read_csv(b).columns
    with pytest.raises(ColumnMapError) as e:
        load_column_map([str(toml), "deviation_unit=cm"])
    assert (e.value.file, e.value.column) == ("--map", "deviation_unit")


# --- the reader: BOM, CRLF, quotes, decimal comma, separators, trailing columns, time -------------


def test_reader_handles_quotes_tabs_preamble_blank_lines_and_trailing_columns(tmp_path):
    text = ("Tracker export v2\n"
            "operator: \"A. N. Other\"\n"
            "a1\ta2\ttx\tty\ttz\tcomment\t\t\n"
            "10.5\t-20\t1000.25\t2e3\t-3.5\t\"says \"\"hi\"\"\tand more\"\t\t\n"
            "\n"
            "  11\t-21\t1001\t2001\t-4\tplain\n")
    src = tmp_path / "t.txt"
    src.write_text(text)
    cmap = load_column_map(["skip_lines=2", "joints=a1,a2", "joint_unit=deg", "position=tx,ty,tz",
                            "position_unit=mm"])
    assert cmap.separator is None  # guessed from the header: tab
    got = read_mapped(src, cmap)
    assert got.columns["q1_deg"].tolist() == [10.5, 11.0] and got.columns["y_mm"].tolist() == [2000.0, 2001.0]
    assert got.columns["comment"].tolist() == ['says "hi"\tand more', "plain"]
    # rows are file lines: the blank line 5 counts
    src.write_text(text.replace("  11\t", "1,5\t"))
    with pytest.raises(DataFileError, match="decimal mark ','") as e:
        read_mapped(src, cmap)
    assert (e.value.row, e.value.column) == (6, "a1")
    src.write_text(text.replace("  11\t", "1.234,5\t"))
    with pytest.raises(DataFileError, match="thousands separators"):
        read_mapped(src, cmap)


def test_time_column_sorts_rows_or_keeps_the_order(tmp_path):
    src = tmp_path / "t.csv"
    src.write_text("when,j,x,y,z\n2024-05-01 10:00:30,1,0,0,0\n2024-05-01 10:00:00,2,0,0,0\n"
                   "2024-05-01 10:01:00,3,0,0,0\n")
    cmap = load_column_map(["joints=j", "joint_unit=deg", "position=x,y,z", "position_unit=m",
                            "time.column=when", "time.format=%Y-%m-%d %H:%M:%S"])
    with pytest.warns(DataWarning, match=r"1 row\(s\) out of time order \(first: row 3\); rows sorted"):
        got = read_mapped(src, cmap)
    assert got.columns["q1_deg"].tolist() == [2.0, 1.0, 3.0] and got.columns["time_s"].tolist() == [0, 30, 60]
    with pytest.warns(DataWarning, match="file order kept"):
        kept = read_mapped(src, cmap, sort_by_time=False)
    assert kept.columns["time_s"].tolist() == [0, -30, 30]
    src.write_text(src.read_text().replace("10:01:00", "10:61:00"))
    with pytest.raises(DataFileError, match="does not match the format") as e:
        read_mapped(src, cmap)
    assert (e.value.row, e.value.column) == (4, "when")


def test_unmapped_column_that_would_clash_with_the_contract(tmp_path):
    src = tmp_path / "t.csv"
    src.write_text("j1,X,Y,Z,x_mm\n1,2,3,4,5\n")
    cmap = load_column_map(["joints=j1", "joint_unit=deg", "position=X,Y,Z", "position_unit=mm"])
    with pytest.raises(DataFileError, match="others = \"drop\"") as e:
        read_mapped(src, cmap)
    assert (e.value.row, e.value.column) == (1, "x_mm")
    got = read_mapped(src, load_column_map(["joints=j1", "joint_unit=deg", "position=X,Y,Z",
                                            "position_unit=mm", "others=drop"]))
    assert list(got.columns) == ["q1_deg", "x_mm", "y_mm", "z_mm"] and got.dropped == ["x_mm"]
    # an unmapped column that becomes a contract column must hold numbers
    src.write_text("j1,X,Y,Z,Temperature C\n1,2,3,4,21.5\n1,2,3,4,warm\n")
    with pytest.raises(DataFileError, match="not a number: 'warm'") as e:
        read_mapped(src, cmap)
    assert (e.value.row, e.value.column) == (3, "Temperature C")


def test_a_column_named_twice_for_joints_or_positions(tmp_path):
    src = tmp_path / "t.csv"
    src.write_text("j1,X,Y,Z\n1,2,3,4\n")
    with pytest.raises(DataFileError, match=r"named twice by the mapping \(joints\[1\] and position\[1\]\)"):
        read_mapped(src, load_column_map(["joints=j1", "joint_unit=deg", "position=J1,Y,Z",
                                          "position_unit=mm"]))


def test_radians_declared_as_degrees_are_flagged(tmp_path):
    src = tmp_path / "t.csv"
    src.write_text("j1,x,y,z\n" + "".join(f"{0.3 * k},1,2,3\n" for k in range(6)))
    with pytest.warns(DataWarning, match="these look like radians"):
        read_mapped(src, load_column_map(["joints=j1", "joint_unit=deg", "position=x,y,z",
                                          "position_unit=m"]))


@pytest.mark.parametrize("pairs, key", [
    (["joint_unit=rad"], "joints"),
    (["joints=a"], "joint_unit"),
    (["joints=a", "joint_unit=rad", "position=x,y"], "position"),
    (["joints=a", "joint_unit=rad", "position=x,y,z"], "position_unit"),
    (["joints=a", "joint_unit=rad", "target=x,y,z", "target_unit=m"], "deviation"),
    (["joints=a", "joint_unit=rad", "target=x,y,z", "target_unit=m", "deviation=u,v,w",
      "deviation_unit=mm"], "deviation_sign"),
    (["joints=a", "joint_unit=rad", "position=x,y,z", "position_unit=mm", "deviation_sign=measured-target"],
     "deviation_sign"),
    (["joints=a,a", "joint_unit=rad"], "joints"),
    (["joints=a", "joint_unit=rad", "decimal=;"], "decimal"),
    (["joints=a", "joint_unit=rad", "skip_lines=-1"], "skip_lines"),
    (["joints=a", "joint_unit=rad", "encoding=klingon"], "encoding"),
    (["joints=a", "joint_unit=rad", "keep.t=q2_deg"], "keep.t"),
    (["joints=a", "joint_unit=rad", "keep.t=temp c"], "keep.t"),
    (["joints=a", "joint_unit=rad", "keep.t=c", "keep_if_present.u=c"], "keep_if_present.u"),
    (["joints=a", "joint_unit=rad", "time.column=t"], "time.format"),
    (["joints=a,b", "joint_unit=rad", "linear_axes=3", "linear_unit=m"], "linear_axes"),
    (["joints=a,b", "joint_unit=rad", "linear_axes=1,1", "linear_unit=m"], "linear_axes"),
    (["joints=a,b", "joint_unit=rad", "linear_axes=1"], "linear_unit"),
    (["joints=a,b", "joint_unit=rad", "linear_axes=1", "linear_unit=in"], "linear_unit"),
    (["joints=a,b", "joint_unit=rad", "linear_unit=mm"], "linear_unit"),
])
def test_invalid_mapping_names_the_key(pairs, key):
    with pytest.raises(ColumnMapError) as e:
        load_column_map(pairs)
    assert e.value.column == key and e.value.file == "--map"
    assert len(str(e.value).splitlines()) == 1


# --- bad input through the command line: exit 2, one line, file / row / column -----------------


def test_help(capsys):
    with pytest.raises(SystemExit) as e:
        main(["import", "--help"])
    assert e.value.code == 0 and "ur10-ipa" in capsys.readouterr().out


def _cli(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "casadical", *args], capture_output=True, text=True)


def _bad_file_cases(lines: list[str]) -> dict[str, tuple[list[str], int, str]]:
    bad_cell = lines[4].split(";")
    bad_cell[3] = "n/a"
    return {
        "non-numeric cell": (lines[:4] + [";".join(bad_cell)] + lines[5:], 5, "J3"),
        "wrong field count": (lines[:6] + [lines[6].rsplit(";", 8)[0]] + lines[7:], 7, "Y_target"),
    }


def test_bad_input_through_the_cli_is_one_line(tmp_path):
    robot = robot_from_dict(ARM5)
    cal, _, target = _campaign(robot, 3)
    lines = _tracker_lines(cal.subset(np.arange(10)), target[:10], "measured-target")
    good_map = _mapping(tmp_path / "m.toml", 5, "measured-target")
    src = _write_tracker(tmp_path / "t.csv", lines)
    out = tmp_path / "o.csv"
    cases = [
        # (what, source, mapping, expected file, row, column)
        ("missing column", src, _mapping(tmp_path / "m1.toml", 5, "measured-target",
                                         target='["X_target", "Y_target", "Z_tgt"]'), src, 1, "Z_tgt"),
        ("bad unit word", src, _mapping(tmp_path / "m2.toml", 5, "measured-target", joint_unit='"radians"'),
         tmp_path / "m2.toml", None, "joint_unit"),
    ]
    for what, (bad_lines, row, column) in _bad_file_cases(lines).items():
        path = _write_tracker(tmp_path / f"{what.replace(' ', '_')}.csv", bad_lines)
        cases.append((what, path, good_map, path, row, column))
    for what, source, mapping, file, row, column in cases:
        r = _cli("import", str(source), "--map", str(mapping), "--out", str(out))
        assert r.returncode == 2, (what, r.stderr)
        msg = r.stderr.strip().splitlines()
        assert len(msg) == 1 and "Traceback" not in r.stderr, (what, r.stderr)
        expected = f"{file}" + (f", row {row}" if row else "") + f", column {column!r}: "
        assert msg[0].startswith("casadical: error: " + expected), (what, msg[0])
        assert not out.exists()
    assert main(["import", str(src), "--map", str(good_map), "--out", str(out)]) == 0


def test_degrees_mapped_as_radians_are_an_error_that_writes_nothing(tmp_path):
    """Series B (joint readings in degrees, up to 200 on joint 4) mapped with joint_unit = "rad": one line of error
    naming the key, and no file (issue 47: a warning, exit 0, and a file with readings of -10,313 deg that
    calibrate then refused); a joint that turns more than once is allowed on request, and then the readings are
    converted as asked."""
    src = tmp_path / "b.csv"
    src.write_text("\n".join(SERIES_B.read_text().splitlines()[:20]) + "\n")
    out = tmp_path / "o.csv"
    maps = ["--map", "joints=q1_deg,q2_deg,q3_deg,q4_deg,q5_deg,q6_deg", "--map", "joint_unit=rad",
            "--map", "position=x_mm,y_mm,z_mm", "--map", "position_unit=mm", "--map", "others=drop"]
    r = _cli("import", str(src), *maps, "--out", str(out))
    msg = r.stderr.strip().splitlines()
    assert r.returncode == 2 and len(msg) == 1 and not out.exists(), r.stderr
    assert msg[0].startswith("casadical: error: --map, column 'joint_unit': joint readings of ") \
        and "'q4_deg'" in msg[0] and 'set joint_unit = "deg"' in msg[0] and "--allow-multiturn" in msg[0], msg
    r = _cli("import", str(src), *maps, "--out", str(out), "--allow-multiturn")
    assert r.returncode == 0 and "warning" not in r.stderr, r.stderr
    raw, got = _csv_columns(src), _csv_columns(out)
    assert np.allclose(np.degrees(np.array(raw["q4_deg"], float)), np.array(got["q4_deg"], float))


# --- the UR10 preset and the guide's worked example --------------------------------------------


def _csv_columns(path: Path) -> dict[str, list[str]]:
    with open(path, newline="") as fh:
        rows = list(csv.reader(fh))
    return {h: [r[i] for r in rows[1:]] for i, h in enumerate(rows[0])}


def test_ur10_preset_and_the_guides_mapping_give_the_bundled_csv(tmp_path, capsys):
    out = tmp_path / "b.csv"
    assert main(["import", str(RAW_B), "--map", "ur10-ipa", "--out", str(out)]) == 0
    printed, warned = capsys.readouterr()
    assert "no usable timestamps" in warned
    assert "shoulder_pan_joint -> q1_deg" in printed and "(rad -> deg)" in printed
    assert "1495 rows" in printed
    assert out.read_bytes() == (DATASET / "series_b.csv").read_bytes()

    guide = (ROOT / "docs" / "guide.md").read_text()
    section = guide.split("## Import any tracker file", 1)[1]
    toml = re.search(r"```toml\n(.*?)```", section, re.S).group(1)
    mapping = tmp_path / "ur10-mapping.toml"
    mapping.write_text(toml)
    out2 = tmp_path / "b2.csv"
    assert main(["import", str(RAW_B), "--map", str(mapping), "--out", str(out2)]) == 0
    mine, bundled = _csv_columns(out2), _csv_columns(DATASET / "series_b.csv")
    assert list(mine)[:10] == list(bundled)[:10]
    assert all(mine[c] == bundled[c] for c in mine)


@pytest.mark.parametrize("seed", [0, 1])
def test_a_linear_axis_is_imported_as_a_position_in_mm(tmp_path, seed):
    """A four-axis arm on a 4 m track (not built in; the independent truth measures it): the tracker file gives the
    track's position in m, the arm's joints in rad and the point in m. With linear_axes = [1] and linear_unit = "m"
    the import writes q1_mm (the track in mm) beside q2_deg ..; read with the robot file the readings are the
    truth's, and a kinematic calibration of the imported file predicts other poses at the noise level."""
    from tests.helpers.arms import ARM4_TRACK
    from tests.truth import Arm, Effects, Session, TrueRobot, measure, sample

    rng = np.random.default_rng(seed)
    true = TrueRobot.draw(Arm.from_dict(ARM4_TRACK), Effects(), rng)
    session = Session(base_xyz=(1.5, -0.5, 0.3), base_rpy=(0.0, 0.0, 0.6))
    q = sample(true, 80, rng)
    shots = measure(true, q, rng, session=session, noise=NOISE)
    lines = ["Track;J2;J3;J4;J5;X;Y;Z"] + [";".join(_comma(v) for v in (*q[k], *shots.xyz[k])) for k in range(len(q))]
    src = _write_tracker(tmp_path / "track.csv", lines)
    out = tmp_path / "poses.csv"
    cmap = load_column_map(["separator=;", "decimal=,", "joints=Track,J2,J3,J4,J5", "joint_unit=rad",
                            "linear_axes=1", "linear_unit=m", "position=X,Y,Z", "position_unit=m"])
    imported = import_file(src, out, cmap)
    assert [m.output for m in imported.mapped][:5] == ["q1_mm", "q2_deg", "q3_deg", "q4_deg", "q5_deg"]
    assert imported.mapped[0].note == "m -> mm"
    robot = robot_from_dict(ARM4_TRACK)
    data = Measurements.read_csv(out, robot=robot, require_positions=True)
    np.testing.assert_allclose(data.q, q, rtol=1e-13, atol=1e-13)
    val = Measurements.read_csv(measure(true, sample(true, 60, rng), rng, session=session, noise=NOISE)
                                .write_csv(tmp_path / "val.csv"), robot=robot, require_positions=True)
    rms = calibrate(robot, data, "kinematic", "lm", warn=False).stats(val).rms_mm
    assert rms < 1.5 * NOISE * 1000 * np.sqrt(3), rms
