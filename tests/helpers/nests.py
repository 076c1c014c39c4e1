"""Data of a tool of several points for the tests: the independent truth's tracker rows of three reflector nests
(tests/truth/touch.py ``tool_rows``) and touch rows of two balls in a fixture's sockets, read back as a user's
files, with the robot file that names each point's nominal offset (``[tool.NAME]``, docs/formats.md).

Each nest's true offset is its nominal plus a few millimetres (Gaussian, 2 mm per axis): what a user's drawing of
the nest holder knows. The arm is the six-axis DH arm of tests/helpers/arms.py (not built in).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from tests.helpers.arms import ARM6, to_toml
from tests.truth import Arm, Effects, Session, TrueRobot, sample
from tests.truth.touch import fixture_toml, random_pose, reachable_point, socket_rows, tool_rows, two_sockets

#: three reflector nests on a ring of 60 mm about the flange axis, 80 mm out (m, last link frame)
NESTS = {"smr1": np.array([0.06, 0.0, 0.08]), "smr2": np.array([-0.03, 0.052, 0.08]),
         "smr3": np.array([-0.03, -0.052, 0.08])}
#: two balls of a touch probe (m, last link frame)
BALLS = {"ball_a": np.array([0.03, 0.0, 0.08]), "ball_b": np.array([-0.02, 0.01, 0.12])}
#: where the tracker stood: the robot's base in the measurement frame
TRACKER = Session("A", base_xyz=(1.5, -0.5, 0.3), base_rpy=(0.0, 0.0, math.radians(40.0)))
#: the tracker's noise per axis (m)
NOISE = 20e-6
#: a tool point's offset in a robot file: along x, y, z of the last link frame
AXES = ("a_m", "b_m", "d_m")


@dataclass
class NestData:
    """Files of a tool of several points, what the truth hid, and the noise floor of the validation rows."""

    folder: Path
    robot_file: Path
    cal_file: Path
    val_file: Path
    true: TrueRobot
    points: dict            # each point's true offset (m, last link frame)
    floor_mm: float         # tracker rows: mean distance of the measured validation points from the true ones

    def read(self):
        """(robot, cal, val): casadical's robot and the two files as a user's program reads them."""
        from casadical.data import Measurements
        from casadical.loading import load_robot
        robot = load_robot(str(self.robot_file))
        return (robot, Measurements.read_csv(self.cal_file, robot=robot),
                Measurements.read_csv(self.val_file, robot=robot))


def robot_toml(nominal: dict | None) -> str:
    """The arm's robot file, with a ``[tool.NAME]`` table per point of ``nominal`` (None: none)."""
    return to_toml(ARM6) + "".join(f"\n[tool.{k}]\n" + "".join(f"{c} = {float(x)!r}\n" for c, x in zip(AXES, v))
                                   for k, v in (nominal or {}).items())


def three_nests(seed: int, folder: str | Path, effects: Effects | None = None, n_cal: int = 40, n_val: int = 60,
                declared: bool = True) -> NestData:
    """Tracker rows of the three nests of :data:`NESTS` (each pose measured at each nest), ``n_cal`` and
    ``n_val`` poses, on the arm with ``effects``; ``declared``: the robot file names the nests' nominal
    offsets (else it has ``[tool]`` alone)."""
    rng = np.random.default_rng(seed)
    true = TrueRobot.draw(Arm.from_dict(ARM6), effects or Effects(), rng)
    points = {k: v + rng.normal(0.0, 0.002, 3) for k, v in NESTS.items()}
    folder = Path(folder)
    cal = tool_rows(true, sample(true, n_cal, rng), points, rng, TRACKER, noise=NOISE)
    q_val = sample(true, n_val, rng)
    val = tool_rows(true, q_val, points, rng, TRACKER, noise=NOISE)
    exact = tool_rows(true, q_val, points, rng, TRACKER, noise=0.0)
    floor = float(np.mean(np.linalg.norm(val.xyz - exact.xyz, axis=1))) * 1000
    robot_file = folder / "arm6.toml"
    robot_file.write_text(robot_toml(NESTS if declared else None))
    return NestData(folder, robot_file, cal.write_csv(folder / "cal.csv"), val.write_csv(folder / "val.csv"),
                    true, points, floor)


def two_balls(seed: int, folder: str | Path, per_socket: int = 8, placements: tuple[int, int] = (3, 2),
              contact_noise: float = 10e-6) -> NestData:
    """Touch rows of the two balls of :data:`BALLS` in the two sockets of a fixture 50 mm apart: at each
    placement of the fixture (a session each) each ball ``per_socket`` times in each socket; ``placements``:
    (calibration, validation). Its ``floor_mm`` is the contact noise's mean distance (``contact_noise`` per
    axis: 1.6 times it)."""
    rng = np.random.default_rng(seed)
    true = TrueRobot.draw(Arm.from_dict(ARM6), Effects(), rng)
    points = {k: v + rng.normal(0.0, 0.001, 3) for k, v in BALLS.items()}
    fixture = two_sockets()
    folder = Path(folder)

    def placement(name):
        session = Session(name)
        for _ in range(20):         # a placement where the robot reaches every socket with both balls
            pose = random_pose(rng, reachable_point(true, rng, session), math.radians(5.0))
            try:
                parts = [socket_rows(true, fixture.place(pose), per_socket, rng, session, tool=k, offset=v,
                                     contact_noise=contact_noise) for k, v in points.items()]
            except ValueError:
                continue
            return parts[0] + parts[1]
        raise ValueError("no placement of the fixture where both balls reach both sockets")

    n_cal, n_val = placements
    files = []
    for name, names in (("cal", range(n_cal)), ("val", range(n_cal, n_cal + n_val))):
        rows = [placement(f"p{i}") for i in names]
        files.append(sum(rows[1:], rows[0]).write_csv(folder / f"{name}.csv", session_column=True))
    (folder / "fixture.toml").write_text(fixture_toml([fixture]))
    robot_file = folder / "arm6.toml"
    robot_file.write_text(robot_toml(BALLS))
    return NestData(folder, robot_file, files[0], files[1], true, points, math.sqrt(8 / math.pi) * contact_noise * 1000)
