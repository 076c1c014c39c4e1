"""The bundled MUKCa socket data (problems/datasets/panda-mukca) and its converter (benchmarks/datasets/mukca.py).

The converted files must equal a fresh conversion of the raw files; the conversion is checked against the raw
text by hand (radians to degrees, one row per raw line, the socket named by its file); bad raw files name the
file, the row and the column.
"""

import csv
import hashlib
import math
import re
import sys
import tomllib
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]
DATASET = ROOT / "problems" / "datasets" / "panda-mukca"
RAW = DATASET / "raw" / "data" / "panda_2"
sys.path.insert(0, str(ROOT / "benchmarks" / "datasets"))
import mukca  # noqa: E402


def rows_of(path: Path) -> tuple[list[str], list[dict]]:
    with open(path, newline="") as fh:
        r = list(csv.reader(fh))
    return r[0], [dict(zip(r[0], x)) for x in r[1:]]


def test_the_bundled_files_equal_a_fresh_conversion():
    fresh = mukca.converted_files(RAW)
    assert sorted(fresh) == sorted(["panda_2.csv", "two_sockets.toml"]
                                   + [f"placements/{p}.csv" for p in mukca.PANDA2_PLACEMENTS])
    for rel, text in fresh.items():
        assert (DATASET / rel).read_text() == text, rel
    assert mukca.convert_dataset(DATASET, check=True) == []


def test_the_raw_files_are_the_repositorys_as_the_readme_lists_them():
    """Every raw file's sha256 as the README gives it (the files are bundled byte for byte)."""
    listed = dict(reversed(m.groups()) for m in re.finditer(r"^([0-9a-f]{64})  (\S+)$",
                                                             (DATASET / "README.md").read_text(), re.M))
    on_disk = sorted(str(p.relative_to(DATASET)) for p in (DATASET / "raw").rglob("*") if p.is_file())
    assert sorted(k for k in listed if k.startswith("raw/")) == on_disk
    for rel, digest in listed.items():
        assert hashlib.sha256((DATASET / rel).read_bytes()).hexdigest() == digest, rel


@pytest.mark.parametrize("placement", mukca.PANDA2_PLACEMENTS)
def test_each_placement_by_hand(placement):
    head, rows = rows_of(DATASET / "placements" / f"{placement}.csv")
    assert head == [f"q{j}_deg" for j in range(1, 8)] + ["point"]
    raw = {k: (RAW / placement / f"hole_{k}.csv").read_text().splitlines() for k in (0, 1)}
    expected = [(k, line) for k in (0, 1) for line in raw[k]]
    assert len(rows) == len(expected)
    for row, (k, line) in zip(rows, expected):
        assert row["point"] == f"socket{k}"
        rad = [float(v) for v in line.split(",")]
        deg = [float(row[f"q{j}_deg"]) for j in range(1, 8)]
        assert deg == pytest.approx([math.degrees(v) for v in rad], rel=1e-15, abs=1e-13)
    # within the URDF's joint limits (radians there, degrees here), and not radians
    limits = {j.get("name"): j.find("limit") for j in ET.parse(DATASET / "raw" / "urdf" / "panda.urdf").getroot()
              .findall("joint")}
    q = np.array([[float(r[f"q{j}_deg"]) for j in range(1, 8)] for r in rows])
    for j in range(7):
        lim = limits[f"panda_joint{j + 1}"]
        assert math.degrees(float(lim.get("lower"))) <= q[:, j].min() <= q[:, j].max() <= math.degrees(
            float(lim.get("upper")))
    assert np.abs(q).max() > 6.3


def test_all_placements_in_one_file():
    head, rows = rows_of(DATASET / "panda_2.csv")
    assert head[-2:] == ["point", "session"]
    assert len(rows) == 559
    assert list(dict.fromkeys(r["session"] for r in rows)) == list(mukca.PANDA2_PLACEMENTS)
    for placement in mukca.PANDA2_PLACEMENTS:
        _, alone = rows_of(DATASET / "placements" / f"{placement}.csv")
        mine = [{k: v for k, v in r.items() if k != "session"} for r in rows if r["session"] == placement]
        assert mine == alone
    # the held-out file: the same rows but front_center's, in the same order
    held_head, held = rows_of(DATASET / mukca.HELD_OUT)
    assert held_head == head and held == [r for r in rows if r["session"] != "front_center"] and len(held) == 499


def test_the_fixture_file():
    doc = tomllib.loads((DATASET / "two_sockets.toml").read_text())
    (block,) = doc["fixture"]
    assert block["name"] == "two_sockets" and block["sd_mm"] > 0
    p = {k: np.array(v) for k, v in block["points"].items()}
    assert set(p) == {"socket0", "socket1"}
    assert np.linalg.norm(p["socket1"] - p["socket0"]) == 50.0


BAD = {
    # case: (file text, row, column)
    "not a number": ("1.0,2.0,3.0\n1.0,x,3.0\n", 2, 2),
    "a field short": ("1.0,2.0,3.0\n1.0,2.0\n", 2, 3),
    "a field more": ("1.0,2.0,3.0\n1.0,2.0,3.0,4.0\n", 2, 4),
    "not finite": ("1.0,nan,3.0\n", 1, 2),
    "empty": ("", 1, None),
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_a_bad_raw_file_names_file_row_and_column(tmp_path, case):
    text, row, column = BAD[case]
    path = tmp_path / "hole_0.csv"
    path.write_text(text)
    with pytest.raises(mukca.RawFileError) as info:
        mukca.read_socket_file(path)
    assert (info.value.file, info.value.row, info.value.column) == (str(path), row, column)
    assert str(path) in str(info.value) and f"row {row}" in str(info.value)


def test_sockets_of_another_joint_count_are_an_error(tmp_path):
    (tmp_path / "hole_0.csv").write_text("1.0,2.0,3.0\n")
    (tmp_path / "hole_1.csv").write_text("1.0,2.0\n")
    with pytest.raises(mukca.RawFileError, match="2 fields where the file has 3 joints"):
        mukca.read_placement(tmp_path)


def test_the_panda_with_its_masses():
    """panda_masses.urdf: the nominal Panda with the published link masses: the same points at every bundled row,
    each joint carrying the links that move with it (joint 7: link 7, the hand and its fingers); the masses are
    added once."""
    from casadical import Measurements, load_robot
    from casadical.model import Model

    nominal = load_robot(DATASET / "raw" / "urdf" / "panda.urdf", tip="ball_link")
    weighed = load_robot(DATASET / mukca.PANDA_MASSES_URDF, tip="ball_link")
    data = Measurements.read_csv(DATASET / "panda_2.csv", robot=nominal)
    assert np.abs(Model(nominal, "nominal").predict(data.q) - Model(weighed, "nominal").predict(data.q)).max() < 1e-12
    assert sum(j.mass for j in nominal.joints) == 0.0
    masses = [j.mass for j in weighed.joints]
    assert masses[:6] == pytest.approx([4.970684, 0.646926, 3.228604, 3.587895, 1.225946, 1.666555], abs=1e-12)
    assert masses[6] == pytest.approx(0.735522 + 0.73 + 2 * 0.015, abs=1e-12)
    text = (DATASET / mukca.PANDA_MASSES_URDF).read_text()
    assert text.count("<inertial>") == len(mukca.PANDA_INERTIALS)
    with pytest.raises(ValueError, match="has an <inertial> already"):
        mukca.with_masses(text)
    with pytest.raises(ValueError, match="no link 'nosuch'"):
        mukca.with_masses(text, {"nosuch": (1.0, (0.0, 0.0, 0.0))})
