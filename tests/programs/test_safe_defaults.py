"""compensate holds what the calibration measured (issue 47, item 4).

On the YS100 on its track (problems/robots/track6.toml) a position-only calibration used to hold the nominal
flange orientation by default: joints moved by up to 3.69 deg and the track by 2.57 mm to correct misses of
0.033 mm. Now the orientation is held only by a full-pose calibration or when asked (--hold-orientation), and
compensate says what it held (terminal and --json).
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from casadical import calibrate, load_robot
from casadical.apply import compensate
from casadical.data import Measurements
from casadical.robot import BUILTIN_DIR
from tests.helpers.cli import cli
from tests.truth import Arm, Effects, Session, TrueRobot, measure, sample


@pytest.fixture(scope="module")
def track(tmp_path_factory):
    d = tmp_path_factory.mktemp("track")
    arm = Arm.from_toml((BUILTIN_DIR / "track6.toml").read_text())
    rng = np.random.default_rng(3)
    true = TrueRobot.draw(arm, Effects(), rng, length_sigma=0.05e-3, angle_sigma=math.radians(0.005))
    session = Session(base_xyz=(1.0, -2.0, 0.1), base_rpy=(0.0, 0.0, 0.3))
    measure(true, sample(true, 150, rng, floor_z=None), rng, session=session, noise=10e-6,
            orientation_noise=math.radians(0.002)).write_csv(d / "cal.csv")
    q = sample(true, 30, rng, floor_z=None)
    measure(true, q, rng, session=session, noise=0.0).write_csv(d / "targets.csv")
    return d, load_robot(BUILTIN_DIR / "track6.toml")


def _largest_changes(res):
    dq = res.dq
    prism = np.array(res.targets.prismatic)
    return float(np.degrees(np.abs(dq[:, ~prism])).max()), float(np.abs(dq[:, prism]).max() * 1e3)


def test_position_only_calibration_holds_no_orientation_by_default(track, capsys):
    d, robot = track
    data = Measurements.read_csv(d / "cal.csv", robot=robot)
    cal = calibrate(robot, data, "kinematic", "lm", warn=False, position_only=True)
    targets = Measurements.read_csv(d / "targets.csv", robot=robot)     # where the true robot is: small misses
    default = compensate(cal, targets)
    assert default.orientation_error is None and "measured positions alone" in default.held
    deg, mm = _largest_changes(default)
    miss = default.start_residual.max() * 1e3
    # the least joint change for a miss of hundredths of a millimetre: hundredths of a degree, of a millimetre
    assert miss < 0.1 and deg < 0.05 and mm < 0.1, (miss, deg, mm)
    with pytest.warns(Warning, match="near a singular configuration"):
        held = compensate(cal, targets, orientation=True)               # asked: held, and it costs motion
    assert held.orientation_error is not None and _largest_changes(held)[0] > 2 * deg
    cal.save(d / "position.json")
    code, out, err = cli(capsys, "compensate", d / "position.json", d / "targets.csv", "--out", d / "j.csv",
                         "--json", d / "held.json")
    assert code == 0, err
    assert "held: nothing else, as the calibration measured positions alone" in out
    assert json.loads((d / "held.json").read_text())["orientation_held"] is False


def test_full_pose_calibration_still_holds_the_orientation(track, capsys):
    d, robot = track
    data = Measurements.read_csv(d / "cal.csv", robot=robot)
    cal = calibrate(robot, data, "kinematic", "lm", warn=False)
    assert cal.full_pose
    bare = Measurements.read_csv(d / "targets.csv", robot=robot)
    targets = Measurements({k: v for k, v in bare.columns.items() if k not in ("rx_deg", "ry_deg", "rz_deg")})
    with pytest.warns(Warning, match="near a singular configuration"):      # a few rows, named
        res = compensate(cal, targets)
    assert res.orientation_error is not None and "flange orientation" in res.held
    assert res.orientation_held.mean() > 0.8
    cal.save(d / "full.json")
    Measurements(targets.columns).write_csv(d / "bare.csv")
    code, out, err = cli(capsys, "compensate", d / "full.json", d / "bare.csv", "--out", d / "jf.csv",
                         "--json", d / "full_held.json")
    assert code == 0, err
    assert json.loads((d / "full_held.json").read_text())["orientation_held"] is True
