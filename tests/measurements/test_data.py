"""Measurement CSV contract: round trip and every bad input."""

import numpy as np
import pytest

from casadical.data import Measurements
from casadical.errors import DataFileError, DataWarning, InputError

HEAD = "q1_deg,q2_deg,q3_deg,x_mm,y_mm,z_mm,payload_kg,note\n"
ROWS = "10,20,30,1000.5,-2.25,300,5,a\n-15.5,40,-60,900,10,250.125,0,b\n"


def test_round_trip(tmp_path, write):
    path = write("m.csv", HEAD + ROWS)
    d = Measurements.read_csv(path, n_joints=3, require_positions=True)
    assert len(d) == 2 and d.n_joints == 3
    np.testing.assert_allclose(d.q_deg[1], [-15.5, 40, -60])
    np.testing.assert_allclose(d.xyz[0], [1.0005, -0.00225, 0.3])
    assert list(d.columns["note"]) == ["a", "b"]
    out = tmp_path / "out.csv"
    d.write_csv(out)
    d2 = Measurements.read_csv(out, n_joints=3)
    assert list(d2.columns) == list(d.columns)
    for k in d.columns:
        assert list(d2.columns[k]) == list(d.columns[k])
    with pytest.raises(InputError, match="exists already"):
        d.write_csv(out)


def test_poses_without_positions(write):
    d = Measurements.read_csv(write("p.csv", "q1_deg,q2_deg\n1,2\n3,4\n"), n_joints=2)
    assert not d.has_positions


@pytest.mark.parametrize("text,row,column,what", [
    ("", 1, None, "empty"),
    (HEAD, 2, None, "no data rows"),
    (HEAD.replace("x_mm,", ""), 1, "x_mm", "only some"),
    ("x_mm,y_mm,z_mm\n1,2,3\n", 1, None, "no joint columns"),
    (HEAD.replace("q2_deg", "q4_deg"), 1, "q2_deg", "not consecutive"),
    (HEAD.replace("q3_deg,", "q3_deg,q4_deg,") + "1,2,3,4,5,6,7,8,a\n", 1, "q4_deg", "robot has 3"),
    ("q1_deg,q2_deg,x_mm,y_mm,z_mm\n1,2,3,4,5\n", 1, "q3_deg", "robot has 3"),
    (HEAD + "10,20,abc,1,2,3,4,c\n", 2, "q3_deg", "not a number"),
    (HEAD + "10,20,30,1,nan,3,4,c\n", 2, "y_mm", "finite"),
    (HEAD + ROWS + "10,20,30,1,2,inf,4,c\n", 4, "z_mm", "finite"),
    (HEAD + "10,20,30,1,2,3,,c\n", 2, "payload_kg", "empty"),
    (HEAD + "10,20,30,1,2,3\n", 2, None, "fields"),
    ("q1_deg,q2_deg,q3_deg,x_mm,y_mm,z_mm,x_mm\n1,2,3,4,5,6,7\n", 1, "x_mm", "duplicated"),
    (HEAD + "10,20,\"30,5\",1,2,3,4,c\n", 2, "q3_deg", "decimal comma"),
])
def test_bad_input_names_file_row_column(write, text, row, column, what):
    path = write("bad.csv", text)
    with pytest.raises(DataFileError) as e:
        Measurements.read_csv(path, n_joints=3)
    msg = str(e.value)
    assert path in msg and f"row {row}" in msg and what in msg and "\n" not in msg
    if column:
        assert repr(column) in msg


def test_missing_positions_when_required(write):
    with pytest.raises(DataFileError, match="x_mm"):
        Measurements.read_csv(write("p.csv", "q1_deg\n1\n"), require_positions=True)


def test_radians_warning(write):
    rows = "".join(f"{0.1 * i},{-0.2 * i},{0.3}\n" for i in range(10))
    with pytest.warns(DataWarning, match="radians"):
        Measurements.read_csv(write("r.csv", "q1_deg,q2_deg,q3_deg\n" + rows))


def test_no_file():
    with pytest.raises(DataFileError, match="no such file"):
        Measurements.read_csv("/nonexistent/m.csv")


@pytest.mark.parametrize("seed", [0, 1])
def test_rows_read_in_chunks_keep_every_value_and_name_the_bad_row(tmp_path, monkeypatch, seed):
    """Chunks of 4 rows: numbers, a column of words that appear only after the first chunk (kept as
    written), blank lines, and a bad value far down named by its file line."""
    import casadical.data._measurements as data_module
    monkeypatch.setattr(data_module, "READ_CHUNK", 4)
    rng = np.random.default_rng(seed)
    n = 23
    q = rng.uniform(-90, 90, (n, 3))
    label = [f"{v:.2f}" for v in rng.uniform(0, 1, n)]
    label[9] = "shot 10 (repeat)"
    text = "q1_deg,q2_deg,q3_deg,x_mm,y_mm,z_mm,label,std_mm\n"
    for i in range(n):
        text += ",".join(repr(float(v)) for v in q[i]) + f",{i},{2 * i},{3 * i},{label[i]},{0.01 * i}\n"
        if i == 5:
            text += "\n"
    path = tmp_path / "d.csv"
    path.write_text(text)
    d = Measurements.read_csv(path, n_joints=3)
    np.testing.assert_array_equal(d.q_deg, q)
    assert list(d.columns["label"]) == label and d.columns["std_mm"].dtype.kind == "f"
    assert d.line(6) == 9 and d.line(n - 1) == n + 2    # the blank line counts
    bad = text.splitlines()
    k = 15 + int(rng.integers(0, 5))
    fields = bad[k].split(",")
    fields[1] = "1,5"
    bad[k] = ",".join(fields[:1] + ['"1,5"'] + fields[2:])
    path.write_text("\n".join(bad) + "\n")
    with pytest.raises(DataFileError, match=r"decimal comma") as e:
        Measurements.read_csv(path, n_joints=3)
    assert f"row {k + 1}" in str(e.value) and "q2_deg" in str(e.value)


@pytest.mark.parametrize("name", ["X_MM", "Payload_kg", "Q1_deg", "Session", "TIME_S"])
def test_a_known_column_in_other_letter_case_is_an_error(tmp_path, name):
    """An unknown column is kept and not read: 'Payload_kg' would be a payload silently left out."""
    header = ["q1_deg", "q2_deg", "x_mm", "y_mm", "z_mm"]
    lower = name.lower()
    header = [name if h == lower else h for h in header] if lower in header else header + [name]
    (tmp_path / "d.csv").write_text(",".join(header) + "\n" + ",".join(["1"] * len(header)) + "\n")
    with pytest.raises(DataFileError, match=f"d.csv, row 1, column '{name}': column names are lower case: "
                                            f"write '{lower}'"):
        Measurements.read_csv(tmp_path / "d.csv")
