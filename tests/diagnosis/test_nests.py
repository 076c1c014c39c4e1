"""The diagnosis of a tool of several points (issue 45 item 2): three reflector nests, each pose measured at each.

The truth (tests/helpers/nests.py) measures the six-axis DH arm of tests/helpers/arms.py (not built in) at three
nests per pose. A fold must leave a pose out whole (its three rows share the robot's error there: fitting two of
them and holding out the third holds out nothing), and the diagnosis must name a hidden encoder scale of joint 2
(400 ppm) and nothing else, with the final model at the noise floor and a nominal baseline that gives each nest
its own nominal offset.
"""

import json
import warnings

import numpy as np
import pytest

from casadical.diagnosis import DiagnosisSettings, diagnose, random_scheme, schemes
from tests.helpers import hidden
from tests.helpers.cli import cli
from tests.helpers.nests import three_nests
from tests.truth import Effects

SEEDS = (0, 1, 2)
#: the hidden effect and the one claim a diagnosis must make of it
SCALE = Effects(encoder_scale={2: 4e-4})
CLAIM = {("encoder_scale", 2, None, "robot")}


def test_a_fold_leaves_a_pose_out_whole(tmp_path):
    """Every fold of every scheme holds all three rows of a pose or none of them; data of distinct poses keep the
    folds they had (the random scheme of their rows)."""
    _, cal, _ = three_nests(0, tmp_path, n_cal=30, n_val=3).read()
    pose = np.repeat(np.arange(30), 3)        # the truth writes each pose's three nests in turn
    assert (np.diff(cal.q[pose == 4], axis=0) == 0).all()
    found = schemes(cal.q, cal.rows, 5, 0)
    assert {s.name for s in found} >= {"random", "time", "joint2"}
    for s in found:
        held = np.zeros(len(cal), int)
        for f in s.folds:
            held[f] += 1
            assert all(np.isin(np.flatnonzero(pose == p), f).all() for p in np.unique(pose[f])), s.name
        assert (held == 1).all(), s.name         # each row held out exactly once
    first = cal.subset(np.arange(0, len(cal), 3))
    assert [f.tolist() for f in schemes(first.q, first.rows, 5, 0)[0].folds] == \
        [f.tolist() for f in random_scheme(30, 5, 0).folds]


def run(seed, folder, **settings):
    data = three_nests(seed, folder, SCALE, n_cal=40, n_val=60)
    robot, cal, val = data.read()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return data, diagnose(robot, cal, val, DiagnosisSettings(seed=seed, **settings))


@pytest.mark.parametrize("seed", SEEDS)
def test_an_encoder_scale_is_named_through_three_nests(tmp_path, seed):
    """A 400 ppm encoder scale of joint 2 is named, nothing else is; the final model's held-out error is at most
    1.2 times the noise floor; the nominal model's baseline puts each nest at its own nominal offset (a few mm,
    not the tens of mm of every nest at one nest's); the noise floor is not read from the nests of one pose."""
    data, report = run(seed, tmp_path)
    hidden.assert_claims(report, CLAIM)
    assert report.final_validation.mean_mm <= 1.2 * data.floor_mm, (report.final_validation, data.floor_mm)
    nominal = report.steps[0]
    assert nominal.model == "nominal" and nominal.validation.mean_mm < 10, nominal.validation
    assert not report.noise or report.noise["sigma_mm"] < 0.1, report.noise


def test_diagnose_takes_a_solver(tmp_path, capsys):
    """``diagnose --solver ipopt``: every fit by IPOPT (the report's settings say so), the same cause named."""
    data = three_nests(1, tmp_path, SCALE, n_cal=40, n_val=60)
    out = tmp_path / "report.json"
    code, _, err = cli(capsys, "diagnose", data.robot_file, data.cal_file, "--validate", data.val_file,
                       "--solver", "ipopt", "--json", out, "--quiet")
    assert code == 0, err
    doc = json.loads(out.read_text())
    assert doc["settings"]["solver"] == "ipopt"
    named = {(f["cause"], f.get("joint")) for f in doc["findings"] if f.get("in_model") and f["cause"] != "geometric"}
    assert named == {("encoder_scale", 2)}, named
