"""Tests of the UR10 (IPA) raw-format importer, casadical.importers._ur10."""

from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np
import pytest

from casadical.data import Measurements
from casadical.errors import DataFileError, DataWarning, InputError
from casadical.importers import convert_ur10, read_ur10

DATASET = Path(__file__).resolve().parents[2] / "problems" / "datasets" / "ur10-ipa"
RAW_A = DATASET / "raw" / "Series_A" / "measurements_grid.csv"
RAW_B = DATASET / "raw" / "Series_B" / "measurements_joint_configurations.csv"

HEADER = ("Timestamp;Goal x;Goal y;Goal z;Goal roll;Goal pitch;Goal yaw;"
          "shoulder_pan_joint;shoulder_lift_joint;elbow_joint;wrist_1_joint;"
          "wrist_2_joint;wrist_3_joint;measurement_temperature;measurement_x;"
          "measurement_y;measurement_z;measurement_rx;measurement_ry;measurement_rz")
ROW = ("20200714163904;0,365141;-0,000212669;1,4273;1,57002;1,57007;1,57073;"
       "-1,5708;-1,5708;0,0;-1,5708;0,0;0,0;23,6800003051758;2361,9831;"
       "-1368,5474;119,39713;-90,409151;-59,885105;-90,887438")


def _read_csv(path: Path) -> tuple[list[str], list[list[str]]]:
    with open(path, newline="") as handle:
        rows = list(csv.reader(handle))
    return rows[0], rows[1:]


def _raw_row(path: Path, line: int) -> dict[str, float | str]:
    """Field values of one line of a raw file, keyed by header name."""
    lines = path.read_text().splitlines()
    header = lines[0].split(";")
    return dict(zip(header, lines[line - 1].split(";")))


def _num(text: str) -> float:
    return float(text.replace(",", "."))


@pytest.fixture(scope="module")
def series_a(tmp_path_factory: pytest.TempPathFactory) -> tuple[int, Path]:
    out = tmp_path_factory.mktemp("ur10") / "series_a.csv"
    with pytest.warns(DataWarning, match="out of time order"):
        n = convert_ur10(RAW_A, out)
    return n, out


@pytest.fixture(scope="module")
def series_b(tmp_path_factory: pytest.TempPathFactory) -> tuple[int, Path]:
    out = tmp_path_factory.mktemp("ur10") / "series_b.csv"
    with pytest.warns(DataWarning, match="no usable timestamps"):
        n = convert_ur10(RAW_B, out)
    return n, out


def test_series_a_rows_and_first_row(series_a: tuple[int, Path]) -> None:
    n, out = series_a
    header, rows = _read_csv(out)
    # 11911 data lines below the header (the file has no final newline).
    assert n == len(rows) == 11911
    assert header[:11] == [f"q{i}_deg" for i in range(1, 7)] + [
        "x_mm", "y_mm", "z_mm", "temperature_c", "time_s"]
    for extra in ("rx_deg", "ry_deg", "rz_deg", "goal_x_m", "goal_y_m", "goal_z_m",
                  "goal_roll_rad", "goal_pitch_rad", "goal_yaw_rad"):
        assert extra in header
    assert "std_x_mm" not in header
    first = dict(zip(header, map(float, rows[0])))
    raw = _raw_row(RAW_A, 2)
    joints = ["shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint",
              "wrist_1_joint", "wrist_2_joint", "wrist_3_joint"]
    for i, joint in enumerate(joints, 1):
        assert first[f"q{i}_deg"] == pytest.approx(_num(raw[joint]) * 180.0 / math.pi,
                                                   rel=1e-15, abs=1e-15)
    assert first["q1_deg"] == pytest.approx(-1.5708 * 180.0 / math.pi, rel=1e-15)
    # Decimal comma: '2361,9831' is 2361.9831, not 23619831 or a split field.
    assert (first["x_mm"], first["y_mm"], first["z_mm"]) == (2361.9831, -1368.5474, 119.39713)
    assert first["temperature_c"] == 23.6800003051758
    assert first["goal_x_m"] == 0.365141
    assert first["rz_deg"] == -90.887438


def test_series_a_time_starts_at_zero_and_never_decreases(series_a: tuple[int, Path]) -> None:
    _, out = series_a
    header, rows = _read_csv(out)
    time = np.array([float(r[header.index("time_s")]) for r in rows])
    assert time[0] == 0.0
    assert np.all(np.diff(time) >= 0)
    # 2020-07-14 16:39:04 to 2020-07-18 21:27:57.
    assert time[-1] == (4 * 86400 + 4 * 3600 + 48 * 60 + 53)


def test_series_b_rows_no_time(series_b: tuple[int, Path]) -> None:
    n, out = series_b
    header, rows = _read_csv(out)
    assert n == len(rows) == 1495
    assert "time_s" not in header
    for extra in ("std_x_mm", "std_y_mm", "std_z_mm", "temperature_c"):
        assert extra in header
    first = dict(zip(header, map(float, rows[0])))
    assert first["q1_deg"] == pytest.approx(-3.14159 * 180.0 / math.pi, rel=1e-15)
    assert first["goal_yaw_rad"] == -2.78e-05
    assert first["std_x_mm"] == 0.031674


def test_shipped_csv_files_match_a_fresh_conversion(series_a: tuple[int, Path],
                                                    series_b: tuple[int, Path]) -> None:
    for (_, fresh), shipped in ((series_a, "series_a.csv"), (series_b, "series_b.csv")):
        assert (DATASET / shipped).read_text() == fresh.read_text()


def test_rows_out_of_time_order_are_sorted_or_kept(tmp_path: Path) -> None:
    later = ROW.replace("20200714163904", "20200714163950")
    path = tmp_path / "raw.csv"
    path.write_text("\r\n".join([HEADER, later, ROW]) + "\r\n")
    with pytest.warns(DataWarning, match=r"1 row\(s\) out of time order \(first: row 3\)"):
        cols = read_ur10(path)
    assert cols["time_s"].tolist() == [0.0, 46.0]
    with pytest.warns(DataWarning, match="file order kept"):
        kept = read_ur10(path, sort_by_time=False)
    assert kept["time_s"].tolist() == [0.0, -46.0]


def test_write_csv_round_trips_exactly(tmp_path: Path) -> None:
    values = [0.1 + 0.2, -1.5708 * 180 / math.pi, 1e-300, 123456789.123456789]
    out = tmp_path / "out.csv"
    Measurements({"q1_deg": np.array(values), "x_mm": np.array([0.0, 1.0, 2.0, 3.0])}).write_csv(out)
    header, rows = _read_csv(out)
    assert header == ["q1_deg", "x_mm"]
    assert [float(r[0]) for r in rows] == values


def _bad(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "bad.csv"
    path.write_text(text)
    return path


BAD_INPUTS = {
    # case: (file text, expected row, expected column)
    "wrong field count": (HEADER + "\n" + ROW + "\n" + ROW.rsplit(";", 2)[0] + "\n",
                          3, "measurement_ry"),
    "extra field": (HEADER + "\n" + ROW + ";1,0\n", 2, "measurement_rz"),
    "non-numeric value": (HEADER + "\n" + ROW + "\n" + ROW.replace("-1,5708;0,0;0,0", "-1,5708;abc;0,0")
                          + "\n", 3, "wrist_2_joint"),
    "empty value": (HEADER + "\n" + ROW.replace(";2361,9831;", ";;") + "\n", 2, "measurement_x"),
    "missing column": (HEADER.replace("elbow_joint;", "") + "\n"
                       + ROW.replace(";0,0;-1,5708;", ";-1,5708;", 1) + "\n", 1, "elbow_joint"),
    "empty file": ("", 1, "shoulder_pan_joint"),
    "bad timestamp": (HEADER + "\n" + ROW + "\n" + ROW.replace("20200714163904", "20201314163904")
                      + "\n", 3, "Timestamp"),
}


@pytest.mark.parametrize("case", sorted(BAD_INPUTS))
def test_bad_input_names_file_row_and_column(tmp_path: Path, case: str) -> None:
    text, row, column = BAD_INPUTS[case]
    path = _bad(tmp_path, text)
    with pytest.raises(DataFileError) as info:
        read_ur10(path)
    err = info.value
    assert (err.file, err.row, err.column) == (str(path), row, column)
    message = str(err)
    assert str(path) in message and f"row {row}" in message and repr(column) in message


def test_header_only_file_is_an_error(tmp_path: Path) -> None:
    with pytest.raises(DataFileError, match="no data rows") as info:
        read_ur10(_bad(tmp_path, HEADER + "\n"))
    assert info.value.row == 2


def test_missing_file_is_a_data_file_error(tmp_path: Path) -> None:
    with pytest.raises(DataFileError, match="cannot read"):
        read_ur10(tmp_path / "nope.csv")


def test_refuses_to_overwrite(tmp_path: Path) -> None:
    src = _bad(tmp_path, HEADER + "\n" + ROW + "\n")
    dst = tmp_path / "out.csv"
    dst.write_text("keep me\n")
    with pytest.raises(InputError, match="exists already") as info:
        convert_ur10(src, dst)
    assert info.value.file == str(dst)
    with pytest.raises(InputError, match="exists already"):
        Measurements({"q1_deg": np.array([1.0])}).write_csv(dst)
    assert dst.read_text() == "keep me\n"
    assert convert_ur10(src, dst, overwrite=True) == 1
    header, rows = _read_csv(dst)
    assert header[0] == "q1_deg" and len(rows) == 1
