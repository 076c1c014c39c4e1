"""Measured orientations in a measurement file (rx_deg, ry_deg, rz_deg): all three or none, numbers, intrinsic XYZ
rotations that follow their columns (casadical/data/_measurements.py). Full-pose calibration:
tests/calibration/test_full_pose.py.
"""

import numpy as np
import pytest

from casadical.data import Measurements
from casadical.errors import DataFileError


@pytest.mark.parametrize("header,missing", [("rx_deg,ry_deg", "rz_deg"), ("ry_deg,rz_deg", "rx_deg"),
                                            ("rx_deg", "ry_deg")])
def test_only_some_orientation_columns(write, header, missing):
    n = header.count(",") + 1
    path = write("p.csv", f"q1_deg,q2_deg,x_mm,y_mm,z_mm,{header}\n1,2,3,4,5{',1' * n}\n")
    with pytest.raises(DataFileError) as e:
        Measurements.read_csv(path, n_joints=2)
    assert f"column {missing!r}" in str(e.value) and "row 1" in str(e.value) and "only some of rx_deg" in str(e.value)


def test_orientation_columns_must_be_numbers(write):
    path = write("p.csv", "q1_deg,q2_deg,rx_deg,ry_deg,rz_deg\n1,2,3,4,5\n1,2,3,x,5\n")
    with pytest.raises(DataFileError, match="row 3, column 'ry_deg': value is not a number"):
        Measurements.read_csv(path, n_joints=2)


def test_rotations_follow_intrinsic_xyz(write):
    d = Measurements.read_csv(write("p.csv", "q1_deg,rx_deg,ry_deg,rz_deg\n0,30,-50,120\n"))
    c, s = np.cos, np.sin
    a, b, g = np.radians([30, -50, 120])
    Rx = np.array([[1, 0, 0], [0, c(a), -s(a)], [0, s(a), c(a)]])
    Ry = np.array([[c(b), 0, s(b)], [0, 1, 0], [-s(b), 0, c(b)]])
    Rz = np.array([[c(g), -s(g), 0], [s(g), c(g), 0], [0, 0, 1]])
    assert np.allclose(d.rotations[0], Rx @ Ry @ Rz)
    back = d.with_orientations(d.rotations)
    assert np.allclose([back.columns[k][0] for k in ("rx_deg", "ry_deg", "rz_deg")], [30, -50, 120])
    assert back.columns["measured_rx_deg"][0] == 30


def test_rotations_are_kept_while_their_columns_keep_their_values(write):
    """Asked again, the same numbers, the caller's own to change; a column changed in place gives them anew."""
    d = Measurements.read_csv(write("p.csv", "q1_deg,rx_deg,ry_deg,rz_deg\n0,30,-50,120\n0,0,0,0\n"))
    R = d.rotations
    R[0] = 0.0
    assert np.allclose(d.rotations[1], np.eye(3)) and np.linalg.det(d.rotations[0]) > 0.99
    R = d.rotations
    d.columns["rz_deg"][1] = 90.0
    assert np.allclose(d.rotations[1], [[0, -1, 0], [1, 0, 0], [0, 0, 1]])
    assert np.allclose(d.rotations[0], R[0])
