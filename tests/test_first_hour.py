"""Issue 28: files an earlier version wrote, and what a new user trips on following the README and the guide.

Each test fails on the code before the issue (fe55b8a); the docstrings say what it did then.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from test_export import urdf_errors
from test_robust import cli

from casadical import Measurements

ROOT = Path(__file__).resolve().parents[1]
DATA = Path(__file__).resolve().parent / "data"
SERIES_B = ROOT / "problems" / "datasets" / "ur10-ipa" / "series_b.csv"


# --- a calibration file written by an earlier version ------------------------------------------------------


def test_a_calibration_file_of_an_earlier_version_is_exported(tmp_path, capsys):
    """tests/data/ur10-kc-b70ddc3.json was written by casadical at b70ddc3, before calibration files recorded
    their poses (tests/data/README.md). export refits its geometry over poses drawn within the joint limits and
    says so, naming --as-fitted; the URDF (read by yourdfpy) predicts series B better than the geometry as it
    was fitted. (Before: "the calibration holds no poses (coverage) to refit its geometry on: calibrate again".)"""
    old = DATA / "ur10-kc-b70ddc3.json"
    best, fitted = tmp_path / "best.urdf", tmp_path / "fitted.urdf"
    code, out, err = cli(capsys, "export", old, "--urdf", best, "--table", tmp_path / "t.csv")
    assert code == 0, err
    warning = [line for line in err if line.startswith("casadical: warning:")]
    assert len(warning) == 1 and "earlier casadical" in warning[0] and "drawn within the joint limits" in warning[0]
    assert "--as-fitted" in warning[0]
    assert any("over 500 poses drawn within the joint limits" in line for line in err)
    assert "over 500 poses drawn within the joint limits" in best.read_text()
    assert cli(capsys, "export", old, "--urdf", fitted, "--as-fitted", "-q")[0] == 0
    data = Measurements.read_csv(SERIES_B, n_joints=6)
    assert urdf_errors(best, data).mean() < 0.8 * urdf_errors(fitted, data).mean()
