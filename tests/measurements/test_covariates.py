"""The user's own columns (issue 49): a column constant within each session is a session covariate, one that changes
from pose to pose a sensor's; neither is a reading, a measured value, the time or a column ``split`` writes."""

import numpy as np

from casadical.data import Measurements, own_columns, pose_covariates, session_covariates


def data(sessions=("A", "A", "B", "B", "C", "C")) -> Measurements:
    n = len(sessions)
    rng = np.random.default_rng(0)
    cols = {"q1_deg": rng.uniform(-90, 90, n), "q2_deg": rng.uniform(-90, 90, n), "x_mm": rng.normal(size=n),
            "y_mm": rng.normal(size=n), "z_mm": rng.normal(size=n), "time_s": np.arange(n, dtype=float),
            "source_row": np.arange(1, n + 1), "move1": np.ones(n), "payload_kg": np.full(n, 5.0),
            "height_m": np.array([{"A": 1.0, "B": 1.6, "C": 2.2}[s] for s in sessions]),
            "tilt_x_rad": rng.normal(0.0, 1e-3, n), "station": np.full(n, 3.0),
            "note": np.array(["a"] * n, dtype=object), "session": np.array(sessions, dtype=object)}
    return Measurements(cols)


def test_a_column_constant_in_each_session_is_a_session_covariate():
    d = data()
    assert session_covariates(d) == {"height_m": {"A": 1.0, "B": 1.6, "C": 2.2}}
    assert session_covariates(d.subset(d.sessions == "A")) == {}          # one session: nothing to follow


def test_a_column_that_changes_within_a_session_is_a_sensors():
    d = data()
    assert pose_covariates(d) == ["tilt_x_rad"]
    assert set(own_columns(d)) == {"payload_kg", "height_m", "tilt_x_rad", "station"}


def test_a_column_with_a_value_that_is_not_a_number_is_none():
    d = data()
    bad = d.with_columns({**d.columns, "tilt_x_rad": np.where(np.arange(len(d)) == 2, np.nan, d.get("tilt_x_rad"))})
    assert pose_covariates(bad) == [] and "tilt_x_rad" not in own_columns(bad)
